//! The defensive mixture `(1 − α)·p_learned + α·cos/π`: blob versions, validation of α, its
//! exact density (χ² against its samples, with a failing control), the weight bound, and
//! α = 0 as a pass-through.

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
