//! Lobe mixtures (`neusample::samplers::{improved_baseline, analytic_mixture}`, paper Eq. 1–2) with random weights: sample/pdf
//! consistency, mass on the disk against the fraction of samples inside it, χ² goodness of
//! fit, and totality on hostile input.

use neusample::samplers::analytic_mixture::{
    AnalyticMixturePrepared, AnalyticMixtureSampler, ANALYTIC_OUTPUTS,
};
use neusample::samplers::improved_baseline::{
    ImprovedBaselinePrepared, ImprovedBaselineSampler, BASELINE_OUTPUTS,
};
use neusample::{Prepared, Sampler, Vec2, Vec3, FEATURE_DIM};
use neusample_host_tests::{
    bonferroni, chi2_checked, disk_integral, full_tests, rng, uniform2, TestRng,
};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use rand::RngExt;

// ---------------------------------------------------------------------------------------
// Random models
// ---------------------------------------------------------------------------------------

/// Random dense layers (input-major weights, then bias): uniform weights with variance
/// 1/fan_in (the last layer scaled by `out_scale`), small biases.
fn random_mlp(r: &mut TestRng, layers: &[(usize, usize)], out_scale: f32) -> Vec<f32> {
    let mut p = Vec::new();
    for (li, &(i, o)) in layers.iter().enumerate() {
        let last = li + 1 == layers.len();
        let s = (3.0 / i as f32).sqrt() * if last { out_scale } else { 1.0 };
        for _ in 0..i * o {
            p.push((r.random::<f32>() * 2.0 - 1.0) * s);
        }
        for _ in 0..o {
            p.push((r.random::<f32>() * 2.0 - 1.0) * 0.1);
        }
    }
    p
}

/// Sets the output bias `j` (the last `outputs` values of `p`) to `v`.
fn set_out_bias(p: &mut [f32], outputs: usize, j: usize, v: f32) {
    let n = p.len();
    p[n - outputs + j] = v;
}

fn uniform(r: &mut TestRng, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * r.random::<f32>()
}

/// A baseline model. `sharp`: log σ biases anywhere in [−7, 1] and large output weights;
/// otherwise σ in roughly [0.05, 0.4] so that a 32 × 32 χ² grid resolves the lobes.
fn baseline_params(r: &mut TestRng, sharp: bool) -> Vec<f32> {
    let mut p = random_mlp(
        r,
        &[(30, 32), (32, 32), (32, 32), (32, 5)],
        if sharp { 1.0 } else { 0.3 },
    );
    set_out_bias(&mut p, 5, 0, uniform(r, -0.7, 0.7));
    set_out_bias(&mut p, 5, 1, uniform(r, -0.7, 0.7));
    let ls = if sharp {
        uniform(r, -7.5, 1.5)
    } else {
        uniform(r, -2.5, -1.2)
    };
    set_out_bias(&mut p, 5, 2, ls);
    set_out_bias(&mut p, 5, 3, uniform(r, -1.5, 1.5));
    set_out_bias(&mut p, 5, 4, uniform(r, -1.5, 1.5));
    p
}

fn analytic_params(r: &mut TestRng, sharp: bool) -> Vec<f32> {
    let mut p = random_mlp(r, &[(30, 32), (32, 11)], if sharp { 1.0 } else { 0.3 });
    for j in 0..4 {
        set_out_bias(&mut p, 11, j, uniform(r, -0.7, 0.7));
    }
    for j in 4..8 {
        let ls = if sharp {
            uniform(r, -7.5, 1.5)
        } else {
            uniform(r, -2.7, -1.2)
        };
        set_out_bias(&mut p, 11, j, ls);
    }
    for j in 8..11 {
        set_out_bias(&mut p, 11, j, uniform(r, -1.5, 1.5));
    }
    p
}

fn random_condition(r: &mut TestRng) -> ([f32; FEATURE_DIM], Vec3) {
    let mut phi = [0.0; FEATURE_DIM];
    for v in &mut phi {
        *v = uniform(r, -1.5, 1.5);
    }
    // Uniform over the upper hemisphere's projected disk, away from the horizon.
    let (a, rad) = (
        uniform(r, 0.0, std::f32::consts::TAU),
        0.97 * r.random::<f32>().sqrt(),
    );
    let (x, y) = (rad * a.cos(), rad * a.sin());
    (phi, Vec3::new(x, y, (1.0 - x * x - y * y).sqrt()))
}

// ---------------------------------------------------------------------------------------
// Shared checks
// ---------------------------------------------------------------------------------------

/// Draws `count` samples and checks each against the pdf. Returns (drawn inside, max
/// relative difference between `pdf(wo)` and `sample.pdf`).
fn check_samples<P: Prepared>(p: &P, r: &mut TestRng, count: usize) -> (usize, f64) {
    let mut inside = 0;
    let mut worst = 0.0f64;
    for _ in 0..count {
        let u = uniform2(r);
        let Some(s) = p.sample(u) else { continue };
        inside += 1;
        assert!(s.wo.z > 0.0 && s.pdf > 0.0 && s.pdf.is_finite(), "{s:?}");
        assert!((s.wo.length() - 1.0).abs() < 1e-5, "{s:?}");
        assert_eq!(s.pdf, s.pdf_disk * s.wo.z);
        // The same function at the same point.
        assert_eq!(p.pdf_disk(Vec2::new(s.wo.x, s.wo.y)), s.pdf_disk);
        // Through the solid-angle interface (which renormalises wo).
        let q = p.pdf(s.wo);
        let rel = f64::from((q - s.pdf).abs() / s.pdf);
        worst = worst.max(rel);
    }
    (inside, worst)
}

// ---------------------------------------------------------------------------------------
// Construction
// ---------------------------------------------------------------------------------------

#[test]
fn param_counts_and_lengths() {
    assert_eq!(ImprovedBaselineSampler::<&[f32]>::PARAM_COUNT, 3269);
    assert_eq!(AnalyticMixtureSampler::<&[f32]>::PARAM_COUNT, 1355);
    let v = vec![0.0f32; 4000];
    assert!(ImprovedBaselineSampler::new(&v[..3269]).is_some());
    assert!(ImprovedBaselineSampler::new(&v[..3268]).is_none());
    assert!(ImprovedBaselineSampler::new(&v[..3270]).is_none());
    assert!(AnalyticMixtureSampler::new(&v[..1355]).is_some());
    assert!(AnalyticMixtureSampler::new(&v[..1354]).is_none());
    assert!(AnalyticMixtureSampler::new(&v[..0]).is_none());
}

/// With all parameters zero the outputs are zero: equal weights, μ = 0, σ = 1.
#[test]
fn zero_model_lobes() {
    let v = vec![0.0f32; 3269];
    let s = ImprovedBaselineSampler::new(&v[..]).unwrap();
    let p = s.prepare(&[0.0; 8], Vec3::Z).unwrap();
    assert_eq!(p.weights(), [0.5, 0.5]);
    assert_eq!(p.mean(), Vec2::ZERO);
    assert_eq!(p.sigma(), 1.0);
    let expect = 0.5 / std::f32::consts::PI + 0.5 / (2.0 * std::f32::consts::PI);
    assert!((p.pdf_disk(Vec2::ZERO) - expect).abs() < 1e-6);

    let v = vec![0.0f32; 1355];
    let s = AnalyticMixtureSampler::new(&v[..]).unwrap();
    let p = s.prepare(&[0.0; 8], Vec3::Z).unwrap();
    for w in p.weights() {
        assert!((w - 1.0 / 3.0).abs() < 1e-6);
    }
}

/// The network's outputs land in the documented slots.
#[test]
fn output_layout() {
    let o = [0.25, -0.5, -1.0, 0.0, (3.0f32).ln()];
    let p = ImprovedBaselinePrepared::from_outputs(&o);
    assert_eq!(p.mean(), Vec2::new(0.25, -0.5));
    assert!((p.sigma() - (-1.0f32).exp()).abs() < 1e-6);
    assert!((p.weights()[1] - 0.75).abs() < 1e-6);
    // log σ is clamped to [−7, 1].
    let p = ImprovedBaselinePrepared::from_outputs(&[0.0, 0.0, -20.0, 0.0, 0.0]);
    assert!((p.sigma() - (-7.0f32).exp()).abs() < 1e-9);

    let o = [0.1, 0.2, -0.3, 0.4, -1.0, -2.0, 0.5, 3.0, 0.0, 0.0, 0.0];
    let p = AnalyticMixturePrepared::from_outputs(&o);
    assert_eq!(p.means(), [Vec2::new(0.1, 0.2), Vec2::new(-0.3, 0.4)]);
    let s = p.sigmas();
    assert!((s[0].x - (-1.0f32).exp()).abs() < 1e-6 && (s[0].y - (-2.0f32).exp()).abs() < 1e-6);
    assert!((s[1].x - (0.5f32).exp()).abs() < 1e-6 && (s[1].y - 1.0f32.exp()).abs() < 1e-5);
}

// ---------------------------------------------------------------------------------------
// Consistency and statistics
// ---------------------------------------------------------------------------------------

#[test]
fn sample_pdf_consistency_random_models() {
    let mut r = rng(0x10be5);
    let (mut worst_b, mut worst_a) = (0.0f64, 0.0f64);
    let models = if full_tests() { 64 } else { 16 };
    for m in 0..models {
        let sharp = m % 2 == 0;
        let pb = baseline_params(&mut r, sharp);
        let pa = analytic_params(&mut r, sharp);
        let sb = ImprovedBaselineSampler::new(&pb[..]).unwrap();
        let sa = AnalyticMixtureSampler::new(&pa[..]).unwrap();
        for _ in 0..4 {
            let (phi, wi) = random_condition(&mut r);
            let p = sb.prepare(&phi, wi).unwrap();
            worst_b = worst_b.max(check_samples(&p, &mut r, 2000).1);
            let p = sa.prepare(&phi, wi).unwrap();
            worst_a = worst_a.max(check_samples(&p, &mut r, 2000).1);
        }
    }
    eprintln!(
        "max |pdf(wo) − sample.pdf| / sample.pdf: baseline {worst_b:.2e}, analytic {worst_a:.2e}"
    );
    // pdf(wo) renormalises wo (1 ulp), which moves the point by ~1e−7; lobes as narrow as
    // σ = e⁻⁷ amplify that to ~1e−4 relative.
    assert!(worst_b < 2e-3 && worst_a < 2e-3);
}

#[test]
fn disk_integral_matches_inside_fraction() {
    let mut r = rng(0xd15c);
    let n = 200_000;
    let mut worst = 0.0f64;
    for m in 0..6 {
        let (phi, wi) = random_condition(&mut r);
        let pb = baseline_params(&mut r, false);
        let pa = analytic_params(&mut r, false);
        let sb = ImprovedBaselineSampler::new(&pb[..]).unwrap();
        let sa = AnalyticMixtureSampler::new(&pa[..]).unwrap();
        let pbp = sb.prepare(&phi, wi).unwrap();
        let pap = sa.prepare(&phi, wi).unwrap();
        for (name, integral, inside) in [
            (
                "baseline",
                disk_integral(&pbp, 1024),
                check_samples(&pbp, &mut r, n).0,
            ),
            (
                "analytic",
                disk_integral(&pap, 1024),
                check_samples(&pap, &mut r, n).0,
            ),
        ] {
            let frac = inside as f64 / n as f64;
            let d = (integral - frac).abs();
            worst = worst.max(d);
            eprintln!(
                "model {m} {name}: ∫disk pdf {integral:.5}, inside fraction {frac:.5}, |Δ| {d:.1e}"
            );
            let sd = (frac * (1.0 - frac) / n as f64).sqrt();
            assert!(d < 5.0 * sd + 1e-3, "{name}: {integral} vs {frac}");
        }
    }
    eprintln!("max |∫pdf − inside fraction| = {worst:.2e}");
}

#[test]
fn chi2_random_conditions() {
    let mut r = rng(0xc412);
    let conditions = if full_tests() { 16 } else { 6 };
    let samples = if full_tests() { 1_000_000 } else { 200_000 };
    let alpha = bonferroni(0.01, 2 * conditions);
    let mut min_p = 1.0f64;
    for i in 0..conditions {
        let (phi, wi) = random_condition(&mut r);
        let pb = baseline_params(&mut r, false);
        let pa = analytic_params(&mut r, false);
        let sb = ImprovedBaselineSampler::new(&pb[..]).unwrap();
        let sa = AnalyticMixtureSampler::new(&pa[..]).unwrap();
        let p = sb.prepare(&phi, wi).unwrap();
        eprintln!(
            "  baseline lobes: w {:?} μ {:?} σ {:.3}",
            p.weights(),
            p.mean(),
            p.sigma()
        );
        min_p = min_p.min(chi2_checked(&format!("baseline #{i}"), &p, &mut r, samples));
        let p = sa.prepare(&phi, wi).unwrap();
        min_p = min_p.min(chi2_checked(&format!("analytic #{i}"), &p, &mut r, samples));
    }
    eprintln!("min χ² p-value {min_p:.4} (Bonferroni threshold {alpha:.2e})");
    assert!(min_p > alpha, "χ² failed: min p {min_p}");
}

/// A mixture whose Gaussians lie mostly outside the disk: `None` samples carry the missing
/// mass, and the density still integrates to the inside fraction.
#[test]
fn mass_outside_the_disk() {
    let o = [0.9, 0.9, -1.0, -2.0, 1.0];
    let p = ImprovedBaselinePrepared::from_outputs(&o);
    let mut r = rng(7);
    let n = if full_tests() { 4_000_000 } else { 400_000 };
    let (inside, _) = check_samples(&p, &mut r, n);
    let frac = inside as f64 / n as f64;
    let integral = disk_integral(&p, 2048);
    // Independent reference: w_L + w_G · ∫disk N(μ, σ²I), by the midpoint rule in polar
    // coordinates (smooth integrand, no boundary error), in f64.
    let (w, mu, sg) = (p.weights(), p.mean(), f64::from(p.sigma()));
    let (nr, nt) = (2000, 2000);
    let mut g = 0.0;
    for i in 0..nr {
        let rr = (i as f64 + 0.5) / nr as f64;
        for j in 0..nt {
            let t = (j as f64 + 0.5) / nt as f64 * std::f64::consts::TAU;
            let dx = (rr * t.cos() - f64::from(mu.x)) / sg;
            let dy = (rr * t.sin() - f64::from(mu.y)) / sg;
            g += (-0.5 * (dx * dx + dy * dy)).exp() * rr;
        }
    }
    g *= std::f64::consts::TAU / (nr * nt) as f64 / (std::f64::consts::TAU * sg * sg);
    let exact = f64::from(w[0]) + f64::from(w[1]) * g;
    let sd = (exact * (1.0 - exact) / n as f64).sqrt();
    eprintln!(
        "off-centre baseline: exact mass {exact:.5}, ∫disk pdf (grid) {integral:.5}, \
         inside fraction {frac:.5} ({:.1} σ)",
        (frac - exact) / sd
    );
    assert!(frac < 0.8 && (integral - exact).abs() < 2e-3);
    assert!((frac - exact).abs() < 5.0 * sd);
}

// ---------------------------------------------------------------------------------------
// Hostile input
// ---------------------------------------------------------------------------------------

fn hostile_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(0.0f32),
        Just(-0.0f32),
        Just(1.0f32),
        Just(-1.0f32),
        Just(1.0 - f32::EPSILON / 2.0),
        Just(f32::MAX),
        Just(f32::MIN_POSITIVE),
        -2.0f32..2.0,
        proptest::num::f32::ANY,
    ]
}

fn assert_total<P: Prepared>(p: &P, u: Vec2, wo: Vec3, q: Vec2) -> Result<(), TestCaseError> {
    if let Some(s) = p.sample(u) {
        prop_assert!(s.pdf.is_finite() && s.pdf > 0.0 && s.wo.is_finite() && s.wo.z > 0.0);
    }
    let d = p.pdf(wo);
    prop_assert!(d.is_finite() && d >= 0.0);
    let d = p.pdf_disk(q);
    prop_assert!(d.is_finite() && d >= 0.0);
    prop_assert!(p.invert(wo).is_none());
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 512,
        rng_seed: RngSeed::Fixed(0x1a2b_3c4d),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Hostile φ, wi, wo, u and raw network outputs never panic or produce NaN.
    #[test]
    fn prop_hostile_inputs(
        phi in proptest::array::uniform8(hostile_f32()),
        wi in proptest::array::uniform3(hostile_f32()),
        wo in proptest::array::uniform3(hostile_f32()),
        u in proptest::array::uniform2(hostile_f32()),
        ob in proptest::array::uniform5(hostile_f32()),
        oa in proptest::collection::vec(hostile_f32(), ANALYTIC_OUTPUTS),
        seed in 0u64..4,
    ) {
        let mut r = rng(seed);
        let pb = baseline_params(&mut r, true);
        let pa = analytic_params(&mut r, true);
        let sb = ImprovedBaselineSampler::new(&pb[..]).unwrap();
        let sa = AnalyticMixtureSampler::new(&pa[..]).unwrap();
        let (wi, wo, u) = (Vec3::from(wi), Vec3::from(wo), Vec2::from(u));
        let q = Vec2::new(wo.x, wo.y);
        let bad = phi.iter().any(|v| !v.is_finite());
        let prepared = sb.prepare(&phi, wi);
        if bad || wi.z.is_nan() || wi.z <= 0.0 {
            prop_assert!(prepared.is_none());
        }
        if let Some(p) = prepared {
            assert_total(&p, u, wo, q)?;
        }
        if let Some(p) = sa.prepare(&phi, wi) {
            assert_total(&p, u, wo, q)?;
        }
        prop_assert!(sb.prepare(&phi, Vec3::new(0.3, 0.2, -0.5)).is_none());
        // Arbitrary raw network outputs.
        let p = ImprovedBaselinePrepared::from_outputs(&ob);
        prop_assert!(p.weights().iter().all(|w| w.is_finite() && *w >= 0.0));
        prop_assert!((p.weights()[0] + p.weights()[1] - 1.0).abs() < 1e-5);
        assert_total(&p, u, wo, q)?;
        let oa: [f32; ANALYTIC_OUTPUTS] = oa.try_into().unwrap();
        let p = AnalyticMixturePrepared::from_outputs(&oa);
        prop_assert!(p.weights().iter().all(|w| w.is_finite() && *w >= 0.0));
        assert_total(&p, u, wo, q)?;
        let _ = BASELINE_OUTPUTS;
    }

    /// For valid u, the sample (when inside the disk) agrees with the pdf exactly.
    #[test]
    fn prop_sample_pdf(seed in 0u64..1000, ux in 0.0f32..1.0, uy in 0.0f32..1.0) {
        let mut r = rng(seed);
        let (phi, wi) = random_condition(&mut r);
        let pb = baseline_params(&mut r, seed % 2 == 0);
        let p = ImprovedBaselineSampler::new(&pb[..]).unwrap().prepare(&phi, wi).unwrap();
        if let Some(s) = p.sample(Vec2::new(ux, uy)) {
            prop_assert_eq!(p.pdf_disk(Vec2::new(s.wo.x, s.wo.y)), s.pdf_disk);
            prop_assert!((p.pdf(s.wo) - s.pdf).abs() <= 2e-3 * s.pdf);
        }
        let pa = analytic_params(&mut r, seed % 2 == 0);
        let p = AnalyticMixtureSampler::new(&pa[..]).unwrap().prepare(&phi, wi).unwrap();
        if let Some(s) = p.sample(Vec2::new(ux, uy)) {
            prop_assert_eq!(p.pdf_disk(Vec2::new(s.wo.x, s.wo.y)), s.pdf_disk);
            prop_assert!((p.pdf(s.wo) - s.pdf).abs() <= 2e-3 * s.pdf);
        }
    }
}

/// u at the ends of [0, 1] and just outside.
#[test]
fn edge_u() {
    let mut r = rng(3);
    let pb = baseline_params(&mut r, false);
    let (phi, wi) = random_condition(&mut r);
    let p = ImprovedBaselineSampler::new(&pb[..])
        .unwrap()
        .prepare(&phi, wi)
        .unwrap();
    let one = 1.0 - f32::EPSILON / 2.0;
    for u in [0.0, 1.0, one, 0.5] {
        for v in [0.0, 1.0, one, 0.5] {
            if let Some(s) = p.sample(Vec2::new(u, v)) {
                assert!(s.pdf.is_finite() && s.pdf > 0.0);
            }
        }
    }
    for bad in [-1e-7, 1.0 + 1e-6, f32::NAN, f32::INFINITY] {
        assert!(p.sample(Vec2::new(bad, 0.5)).is_none());
        assert!(p.sample(Vec2::new(0.5, bad)).is_none());
    }
}
