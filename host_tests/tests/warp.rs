//! Warps and the cosine sampler: inverses, densities that integrate to 1, χ², golden values
//! of the encodings.

use neusample::nn::{encode_condition, CONDITION_DIM};
use neusample::nn::{encode_scalar, Activation};
use neusample::samplers::CosineSampler;
use neusample::warp::{self, Frame};
use neusample::{Prepared, Sampler, Vec2, Vec3};
use neusample_host_tests::{chi2_test, disk_integral, rng, uniform2};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

#[test]
fn concentric_disk_invert_of_sample_is_identity_on_a_stratified_grid() {
    let n = 64;
    let mut max_err = 0f32;
    for i in 0..n {
        for j in 0..n {
            let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            let p = warp::sample_uniform_disk_concentric(u);
            assert!(p.length_squared() <= 1.0 + 1e-6);
            let back = warp::invert_uniform_disk_concentric(p);
            max_err = max_err.max((back - u).abs().max_element());
        }
    }
    eprintln!("concentric disk: max |invert(sample(u)) − u| = {max_err:e}");
    assert!(max_err < 2e-6);
}

#[test]
fn cosine_hemisphere_triple_is_consistent() {
    let mut r = rng(3);
    let mut max_err = 0f32;
    for _ in 0..10_000 {
        let u = uniform2(&mut r);
        let w = warp::sample_cosine_hemisphere(u);
        assert!((w.length() - 1.0).abs() < 1e-5 && w.z >= 0.0);
        let pdf = warp::cosine_hemisphere_pdf(w.z);
        assert!((pdf - w.z / std::f32::consts::PI).abs() < 1e-7);
        let back = warp::invert_cosine_hemisphere_sample(w);
        max_err = max_err.max((back - u).abs().max_element());
    }
    eprintln!("cosine hemisphere: max |invert(sample(u)) − u| = {max_err:e}");
    assert!(max_err < 2e-5);
}

#[test]
fn cosine_sampler_density_integrates_to_one_and_passes_chi2() {
    let s = CosineSampler;
    let p = s.prepare(&[0.0; 8], Vec3::new(0.1, 0.2, 0.97)).unwrap();
    let integral = disk_integral(&p, 2048);
    eprintln!("cosine sampler: ∫disk pdf = {integral:.6}");
    assert!((integral - 1.0).abs() < 2e-3);
    let out = chi2_test(&p, &mut rng(5), 24, 16, 200_000, 5.0);
    eprintln!("cosine sampler χ²: p = {:.4}, dof {}", out.p_value, out.dof);
    assert!(out.p_value > 0.01);
    // Solid-angle pdf over the hemisphere integrates to 1 as well (θ, φ quadrature).
    let n = 512;
    let mut acc = 0.0f64;
    for i in 0..n {
        let theta = (i as f64 + 0.5) / n as f64 * std::f64::consts::FRAC_PI_2;
        for j in 0..n {
            let phi = (j as f64 + 0.5) / n as f64 * std::f64::consts::TAU;
            let w = Vec3::new(
                (theta.sin() * phi.cos()) as f32,
                (theta.sin() * phi.sin()) as f32,
                theta.cos() as f32,
            );
            acc += f64::from(p.pdf(w)) * theta.sin();
        }
    }
    acc *= (std::f64::consts::FRAC_PI_2 / n as f64) * (std::f64::consts::TAU / n as f64);
    eprintln!("cosine sampler: ∫hemisphere pdf dω = {acc:.6}");
    assert!((acc - 1.0).abs() < 1e-3);
}

#[test]
fn measure_conversion_round_trips() {
    for &c in &[1.0f32, 0.5, 0.01] {
        let p = 0.7;
        assert!((warp::solid_angle_to_disk(warp::disk_to_solid_angle(p, c), c) - p).abs() < 1e-6);
    }
    assert_eq!(warp::solid_angle_to_disk(1.0, 0.0), 0.0);
}

#[test]
fn frames_are_orthonormal_and_invertible() {
    let mut r = rng(9);
    for _ in 0..1000 {
        let u = uniform2(&mut r);
        let n = warp::sample_cosine_hemisphere(u) * if u.x < 0.5 { 1.0 } else { -1.0 };
        let n = if n.length_squared() > 0.0 {
            n.normalize()
        } else {
            Vec3::Z
        };
        for f in [
            Frame::from_normal(n),
            Frame::from_normal_tangent(n, Vec3::new(0.3, 1.0, -0.2)),
        ] {
            assert!(
                f.t.dot(f.b).abs() < 1e-5 && f.t.dot(f.n).abs() < 1e-5 && f.b.dot(f.n).abs() < 1e-5
            );
            let v = Vec3::new(0.2, -0.5, 0.84);
            assert!((f.to_local(f.from_local(v)) - v).length() < 1e-5);
            assert!((f.to_local(n) - Vec3::Z).length() < 1e-5);
        }
    }
}

#[test]
fn encodings_have_golden_values() {
    let mut out = [0.0f32; 11];
    encode_scalar::<5, 11>(0.3, &mut out, 0);
    let mut expect = [0.0f64; 11];
    expect[0] = 0.3;
    for k in 0..5 {
        let a = std::f64::consts::PI * 0.3 * f64::from(1u32 << k);
        expect[1 + 2 * k] = a.sin();
        expect[2 + 2 * k] = a.cos();
    }
    for i in 0..11 {
        assert!(
            (f64::from(out[i]) - expect[i]).abs() < 2e-6,
            "band {i}: {} vs {}",
            out[i],
            expect[i]
        );
    }
    let c = encode_condition(
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0],
        Vec3::new(0.3, -0.4, 0.866),
    );
    assert_eq!(c.len(), CONDITION_DIM);
    assert_eq!(CONDITION_DIM, 30);
    assert_eq!(&c[..8], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]);
    assert_eq!(c[8], 0.3);
    assert_eq!(c[19], -0.4);
    assert!((c[20] - (-0.4f32 * std::f32::consts::PI).sin()).abs() < 1e-6);
    // Activations.
    assert_eq!(Activation::Relu.apply(-1.0), 0.0);
    assert_eq!(Activation::LeakyRelu.apply(-1.0), -0.01);
    assert!((Activation::Softplus.apply(0.0) - 2f32.ln()).abs() < 1e-6);
    assert!((Activation::Sigmoid.apply(0.0) - 0.5).abs() < 1e-7);
    assert_eq!(Activation::Softplus.apply(100.0), 100.0);
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        rng_seed: RngSeed::Fixed(0xa4b),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]
    /// The cosine sampler and the warps are total: no panic, no NaN, for any input.
    #[test]
    fn cosine_sampler_is_total(
        wx in prop::num::f32::ANY, wy in prop::num::f32::ANY, wz in prop::num::f32::ANY,
        ux in prop::num::f32::ANY, uy in prop::num::f32::ANY,
    ) {
        let s = CosineSampler;
        let wi = Vec3::new(wx, wy, wz);
        if let Some(p) = s.prepare(&[0.0; 8], wi) {
            if let Some(smp) = p.sample(Vec2::new(ux, uy)) {
                prop_assert!(smp.pdf.is_finite() && smp.pdf > 0.0);
                prop_assert!(smp.wo.z > 0.0);
            }
            let pdf = p.pdf(wi);
            prop_assert!(pdf.is_finite() && pdf >= 0.0);
            let _ = p.invert(wi);
        }
        prop_assert!(warp::upper_hemisphere(wi).is_none_or(|w| w.is_finite() && w.z > 0.0));
    }
}
