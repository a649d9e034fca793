//! The defensive mixture `(1 − α)·p_learned + α·cos/π`: blob versions, validation of α, its
//! exact density (χ² against its samples, with a failing control), the weight bound, and
//! α = 0 as a pass-through; isotropic blobs (the learned part sees `wi` at azimuth 0).

use neusample::{
    Blob, BlobWriter, DType, Defensive, Error, Prepared, Sample, Sampler, SamplerKind, TensorRole,
    Vec2, Vec3,
};
use neusample_host_tests::{
    bonferroni, chi2_checked, chi2_test, fixture_blobs_dir, fixture_conditions, rng, uniform2,
};

/// A fixture blob's bytes rewritten with the defensive weight `alpha`.
fn defended(bytes: &[u8], alpha: f32) -> Vec<u8> {
    BlobWriter::from_blob(&Blob::open(bytes).unwrap())
        .defensive(alpha)
        .to_bytes()
}

fn fixture(rel: &str) -> Vec<u8> {
    std::fs::read(fixture_blobs_dir().join(rel)).unwrap()
}

#[test]
fn versions_and_validation() {
    // A fixture whose defensive weight was chosen as 0: a version-1 blob.
    let bytes = fixture("goat_leather_neural/histogram-mixture.nsb");
    let v1 = Blob::open(&bytes).unwrap();
    assert_eq!((v1.version(), v1.defensive()), (1, 0.0));
    // α = 0 writes version 1, byte for byte the blob it came from.
    assert_eq!(defended(&bytes, 0.0), bytes);
    let v2 = defended(&bytes, 0.125);
    assert_eq!(u32::from_le_bytes(v2[8..12].try_into().unwrap()), 2);
    let b = Blob::open(&v2).unwrap();
    assert_eq!((b.version(), b.defensive()), (2, 0.125));
    assert_eq!(b.sampler().unwrap().alpha(), 0.125);
    assert_eq!(
        b.sampler_as::<neusample::samplers::HistogramMixtureSampler<_>>()
            .unwrap()
            .alpha(),
        0.125
    );
    for bad in [-0.1f32, 1.0, 1.5, f32::NAN, f32::INFINITY] {
        assert_eq!(
            Blob::open(&defended(&bytes, bad)).unwrap_err(),
            Error::HeaderInvalid,
            "α = {bad}"
        );
    }
    // A neural material has no sampler to defend.
    let m = std::fs::read(fixture_blobs_dir().join("../materials/neural/goat_leather_neural.nsb"))
        .unwrap();
    let mb = Blob::open(&m).unwrap();
    let w = BlobWriter::from_blob(&mb).defensive(0.1);
    assert_eq!(Blob::open(&w.to_bytes()).unwrap_err(), Error::HeaderInvalid);
    // Every truncation of a version-2 blob is a typed error, never a panic.
    for n in 0..v2.len() {
        assert!(Blob::open(&v2[..n]).is_err());
    }
}

#[test]
fn alpha_zero_is_the_learned_sampler_bit_for_bit() {
    let bytes = fixture("victorian_fabric_neural/flow.nsb");
    let blob = Blob::open(&bytes).unwrap();
    let plain = *blob.sampler().unwrap().inner();
    let wrapped = Defensive::plain(plain);
    let conds = fixture_conditions(&fixture_blobs_dir().join("victorian_fabric_neural"));
    let mut r = rng(5);
    for (phi, wi) in conds.iter().take(4) {
        let (a, b) = (
            plain.prepare(phi, *wi).unwrap(),
            wrapped.prepare(phi, *wi).unwrap(),
        );
        for _ in 0..2000 {
            let u = uniform2(&mut r);
            assert_eq!(a.sample(u), b.sample(u));
            let wo = Vec3::new(u.x - 0.5, u.y - 0.5, 0.6);
            assert_eq!(a.pdf(wo).to_bits(), b.pdf(wo).to_bits());
            assert_eq!(a.invert(wo), b.invert(wo));
        }
    }
}

#[test]
fn defensive_samplers_pass_chi2_and_bound_the_weights() {
    let alpha = 0.2f32;
    let cases = [
        "victorian_fabric_neural/flow.nsb",
        "goat_leather_neural/histogram-mixture.nsb",
        "brushed_metal_neural/analytic.nsb",
    ];
    let tests = cases.len() * 2;
    let level = bonferroni(0.01, tests);
    for rel in cases {
        let dir = fixture_blobs_dir()
            .join(rel)
            .parent()
            .unwrap()
            .to_path_buf();
        let conds = fixture_conditions(&dir);
        let bytes = defended(&fixture(rel), alpha);
        let blob = Blob::open(&bytes).unwrap();
        let s = blob.sampler().unwrap();
        let learned = *s.inner();
        let mut r = rng(77);
        for (phi, wi) in conds.iter().take(2) {
            let p = s.prepare(phi, *wi).unwrap();
            let l = learned.prepare(phi, *wi).unwrap();
            let pv = chi2_checked(&format!("{rel} α = {alpha}"), &p, &mut r, 200_000);
            assert!(pv >= level, "{rel}: χ² p-value {pv}");
            for _ in 0..5000 {
                let u = uniform2(&mut r);
                if let Some(x) = p.sample(u) {
                    // A sample's density is the density of its direction, exactly.
                    assert_eq!(x.pdf.to_bits(), p.pdf(x.wo).to_bits(), "{rel}");
                }
                // The mixture's density, from both parts, and the defensive bound.
                let wo = Vec3::new(2.0 * u.x - 1.0, 2.0 * u.y - 1.0, 0.3).normalize();
                let want = (1.0 - alpha) * l.pdf(wo) + alpha * wo.z / std::f32::consts::PI;
                let got = p.pdf(wo);
                assert!(
                    (got - want).abs() <= 1e-6 * want.max(1e-6),
                    "{rel}: {got} vs {want}"
                );
                assert!(got >= alpha * wo.z / std::f32::consts::PI * (1.0 - 1e-6));
            }
        }
    }
}

/// A sampler that draws from one α and reports the density of another: the χ² test must
/// reject it (the control that shows the test can fail).
struct Mismatched<P> {
    draws: P,
    reports: P,
}

impl<P: Prepared> Prepared for Mismatched<P> {
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let s = self.draws.sample(u)?;
        Sample::from_disk(
            Vec2::new(s.wo.x, s.wo.y),
            self.reports.pdf_disk(Vec2::new(s.wo.x, s.wo.y)),
        )
    }
    fn pdf_disk(&self, p: Vec2) -> f32 {
        self.reports.pdf_disk(p)
    }
}

#[test]
fn chi2_rejects_a_mixture_with_the_wrong_weight() {
    let rel = "victorian_fabric_neural/flow.nsb";
    let conds = fixture_conditions(&fixture_blobs_dir().join("victorian_fabric_neural"));
    let (phi, wi) = conds[0];
    let b1 = defended(&fixture(rel), 0.3);
    let b2 = defended(&fixture(rel), 0.1);
    let (s1, s2) = (
        Blob::open(&b1).unwrap().sampler().unwrap(),
        Blob::open(&b2).unwrap().sampler().unwrap(),
    );
    let bad = Mismatched {
        draws: s1.prepare(&phi, wi).unwrap(),
        reports: s2.prepare(&phi, wi).unwrap(),
    };
    let out = chi2_test(&bad, &mut rng(3), 32, 16, 200_000, 5.0);
    assert!(
        out.p_value < 1e-6,
        "the wrong weight passed: p = {}",
        out.p_value
    );
}

#[test]
fn writer_keeps_alpha_for_every_kind() {
    for kind in SamplerKind::ALL {
        if kind == SamplerKind::HistogramMixture {
            continue;
        }
        let mut w = BlobWriter::new(kind, DType::F32, "k").defensive(0.05);
        if kind != SamplerKind::Cosine {
            w.tensor(TensorRole::Params, &vec![0.0; kind.param_count()]);
        }
        let bytes = w.to_bytes();
        let b = Blob::open(&bytes).unwrap_or_else(|e| panic!("{}: {e}", kind.name()));
        assert_eq!(b.sampler().unwrap().alpha(), 0.05, "{}", kind.name());
    }
}

/// `v` turned about the normal by `a` radians.
fn turned(v: Vec3, a: f32) -> Vec3 {
    let (s, c) = a.sin_cos();
    Vec3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
}

#[test]
fn isotropic_blobs_turn_the_condition_to_azimuth_zero() {
    let rel = "brushed_metal_neural/analytic.nsb";
    let bytes = fixture(rel);
    let plain_blob = Blob::open(&bytes).unwrap();
    assert!(!plain_blob.isotropic());
    let iso = |alpha: f32| {
        BlobWriter::from_blob(&plain_blob)
            .defensive(alpha)
            .isotropic(true)
            .to_bytes()
    };
    // Version 3 whatever α; the flag and α read back; every truncation is an error.
    for alpha in [0.0, 0.2] {
        let v3 = iso(alpha);
        assert_eq!(u32::from_le_bytes(v3[8..12].try_into().unwrap()), 3);
        let b = Blob::open(&v3).unwrap();
        assert_eq!(
            (b.version(), b.defensive(), b.isotropic()),
            (3, alpha, true)
        );
        assert!(b.sampler().unwrap().is_isotropic());
        assert_eq!(BlobWriter::from_blob(&b).to_bytes(), v3);
        for n in 0..v3.len() {
            assert!(Blob::open(&v3[..n]).is_err());
        }
    }
    // A neural material is never isotropic.
    let m = std::fs::read(fixture_blobs_dir().join("../materials/neural/goat_leather_neural.nsb"))
        .unwrap();
    let w = BlobWriter::from_blob(&Blob::open(&m).unwrap()).isotropic(true);
    assert_eq!(Blob::open(&w.to_bytes()).unwrap_err(), Error::HeaderInvalid);

    let conds = fixture_conditions(&fixture_blobs_dir().join("brushed_metal_neural"));
    let mut r = rng(31);
    let level = bonferroni(0.01, 4);
    for alpha in [0.0, 0.2] {
        let bytes = iso(alpha);
        let blob = Blob::open(&bytes).unwrap();
        let s = blob.sampler().unwrap();
        let local = Defensive::new(*s.inner(), alpha).unwrap();
        for (k, (phi, wi)) in conds.iter().take(2).enumerate() {
            // The learned part at `wi` turned to azimuth 0, the directions turned back.
            let a = wi.y.atan2(wi.x);
            let wi0 = neusample::samplers::Turn::aligning(*wi).1;
            assert!((wi0 - Vec3::new(wi.x.hypot(wi.y), 0.0, wi.z)).length() <= 1e-6);
            let p = s.prepare(phi, *wi).unwrap();
            let l = local.prepare(phi, wi0).unwrap();
            let pv = chi2_checked(&format!("{rel} isotropic α = {alpha}"), &p, &mut r, 200_000);
            assert!(pv >= level, "{rel} isotropic α = {alpha}: χ² p-value {pv}");
            // The same condition seen from another azimuth: the same densities there.
            let b = 1.0 + k as f32;
            let q = s.prepare(phi, turned(*wi, b)).unwrap();
            for _ in 0..5000 {
                let u = uniform2(&mut r);
                match (p.sample(u), l.sample(u)) {
                    (Some(x), Some(y)) => {
                        assert!((x.wo - turned(y.wo, a)).length() <= 1e-5, "{x:?} {y:?}");
                        assert_eq!((x.pdf, x.mis_pdf), (y.pdf, y.mis_pdf));
                        // Turned back and forth, the direction moves by rounding only.
                        let back = p.pdf(x.wo);
                        assert!((x.pdf - back).abs() <= 1e-4 * x.pdf, "{x:?}: {back}");
                    }
                    (x, y) => assert_eq!(x.is_none(), y.is_none()),
                }
                let wo = Vec3::new(2.0 * u.x - 1.0, 2.0 * u.y - 1.0, 0.3).normalize();
                let want = l.pdf(turned(wo, -a));
                let got = p.pdf(wo);
                assert!(
                    (got - want).abs() <= 1e-4 * want.max(1e-3),
                    "{got} vs {want}"
                );
                let there = q.pdf(turned(wo, b));
                assert!(
                    (got - there).abs() <= 1e-4 * got.max(1e-3),
                    "{got} vs {there}"
                );
                if alpha == 0.0 {
                    if let Some(v) = p.invert(wo) {
                        let back = p.sample(v).map(|x| x.wo).unwrap_or(Vec3::ZERO);
                        assert!((back - wo).length() <= 1e-3, "{wo} → {v} → {back}");
                    }
                }
            }
        }
    }
}
