//! A bare-metal binary that prepares, samples and evaluates every `neusample` sampler with
//! opaque inputs (`black_box`), so that none of them is optimised away. Built for
//! `thumbv7em-none-eabihf` to measure the code size the samplers add to firmware.
//!
//! Each sampler sits in its own `#[inline(never)]` function, so `nm --size-sort` attributes
//! most of its code to that symbol (shared helpers such as libm stay separate).
#![no_std]
#![no_main]
// `loop {}` is the conventional bare-metal halt; this binary is measured, never run.
#![allow(clippy::empty_loop)]

use core::hint::black_box;
use core::panic::PanicInfo;

use neusample::{Prepared, Sampler, Vec2, Vec3, FEATURE_DIM};

/// prepare → sample → pdf of a second direction, folded into one number.
#[inline(always)]
fn exercise<S: Sampler>(s: &S) -> f32 {
    let phi: [f32; FEATURE_DIM] = black_box([0.1; FEATURE_DIM]);
    let wi = black_box(Vec3::new(0.1, 0.2, 0.9));
    let u = black_box(Vec2::new(0.3, 0.7));
    let wo2 = black_box(Vec3::new(-0.2, 0.1, 0.8));
    match s.prepare(&phi, wi) {
        Some(p) => {
            let a = match p.sample(u) {
                Some(smp) => smp.pdf + smp.wo.x,
                None => 0.0,
            };
            a + p.pdf(wo2)
        }
        None => -1.0,
    }
}

fn weights() -> &'static [f32] {
    black_box(&[])
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_cosine() -> f32 {
    exercise(&neusample::CosineSampler)
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_flow() -> f32 {
    exercise(&neusample::FlowSampler::new_unchecked(weights()))
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_affine_flow() -> f32 {
    exercise(&neusample::AffineFlowSampler::new_unchecked(weights()))
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_baseline() -> f32 {
    exercise(&neusample::ImprovedBaselineSampler::new_unchecked(weights()))
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_analytic() -> f32 {
    exercise(&neusample::AnalyticMixtureSampler::new_unchecked(weights()))
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_direct_histogram() -> f32 {
    exercise(&neusample::DirectHistogramSampler::new_unchecked(weights()))
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_histogram_mixture() -> f32 {
    let s = neusample::HistogramMixtureSampler::new_unchecked(
        weights(),
        weights(),
        weights(),
        weights(),
        weights(),
        black_box(8),
        black_box(32),
        black_box(neusample::Interpolation::Linear),
    );
    exercise(&s)
}

/// Entry point (no runtime: the binary is only measured, never run).
#[no_mangle]
pub extern "C" fn _start() -> ! {
    let mut acc = 0.0f32;
    acc += ns_cosine();
    acc += ns_flow();
    acc += ns_affine_flow();
    acc += ns_baseline();
    acc += ns_analytic();
    acc += ns_direct_histogram();
    acc += ns_histogram_mixture();
    black_box(acc);
    loop {}
}

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    loop {}
}
