//! A bare-metal binary that prepares, samples and evaluates every `neusample` sampler, the
//! neural material's `features` and `eval`, and the measured material, with opaque inputs
//! (`black_box`), so that none of them is optimised away. Built for `thumbv7em-none-eabihf`
//! to measure the code size the samplers and the materials add to firmware.
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
    exercise(&neusample::samplers::CosineSampler)
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_flow() -> f32 {
    exercise(&neusample::samplers::SplineFlowSampler::new_unchecked(weights()))
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_affine_flow() -> f32 {
    exercise(&neusample::samplers::AffineFlowSampler::new_unchecked(weights()))
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_baseline() -> f32 {
    exercise(&neusample::samplers::ImprovedBaselineSampler::new_unchecked(weights()))
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_analytic() -> f32 {
    exercise(&neusample::samplers::AnalyticMixtureSampler::new_unchecked(weights()))
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_direct_histogram() -> f32 {
    exercise(&neusample::samplers::DirectHistogramSampler::new_unchecked(weights()))
}

#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_histogram_mixture() -> f32 {
    let s = neusample::samplers::HistogramMixtureSampler::new_unchecked(
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

/// The neural material's decoder: `eval(φ, wi, wo)` (14 → 64 → 64 → 64 → 3 and the exp),
/// folded into one number.
#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_neural_eval() -> f32 {
    let m = neusample::NeuralMaterial::new_unchecked(
        weights(),
        weights(),
        black_box(256),
        black_box(256),
    );
    let phi: [f32; FEATURE_DIM] = black_box([0.1; FEATURE_DIM]);
    let wi = black_box(Vec3::new(0.1, 0.2, 0.9));
    let wo = black_box(Vec3::new(-0.2, 0.1, 0.8));
    let f = m.eval(&phi, wi, wo);
    f[0] + f[1] + f[2]
}

/// The neural material's texture lookup: `features(uv)` (bilinear, wrapping).
#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_neural_features() -> f32 {
    let m = neusample::NeuralMaterial::new_unchecked(
        weights(),
        weights(),
        black_box(256),
        black_box(256),
    );
    let phi = m.features(black_box(Vec2::new(0.3, 1.7)));
    let mut acc = 0.0;
    let mut k = 0;
    while k < FEATURE_DIM {
        acc += phi[k];
        k += 1;
    }
    acc
}

/// The measured material (RGL data): prepare, the data's own sampler (luminance and VNDF
/// warps, reflection), the density and `f` of a second direction, folded into one number.
#[inline(never)]
#[no_mangle]
pub extern "C" fn ns_measured() -> f32 {
    let shape = neusample::MeasuredShape {
        n_phi: black_box(1),
        n_theta: black_box(6),
        ndf: black_box([32, 32]),
        sigma: black_box([32, 32]),
        vndf: black_box([32, 32]),
        rgb: black_box([32, 32]),
    };
    let tables = neusample::MeasuredTables::from_array([weights(); 11]);
    let m = neusample::MeasuredMaterial::new_unchecked(shape, tables, black_box(true));
    let wi = black_box(Vec3::new(0.1, 0.2, 0.9));
    let u = black_box(Vec2::new(0.3, 0.7));
    let wo2 = black_box(Vec3::new(-0.2, 0.1, 0.8));
    match m.prepare(wi) {
        Some(p) => {
            let a = match p.sample(u) {
                Some(s) => s.pdf + s.wo.x + s.weight[0],
                None => 0.0,
            };
            let f = p.eval(wo2);
            a + p.pdf(wo2) + f[0] + f[1] + f[2]
        }
        None => -1.0,
    }
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
    acc += ns_neural_eval();
    acc += ns_neural_features();
    acc += ns_measured();
    black_box(acc);
    loop {}
}

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    loop {}
}
