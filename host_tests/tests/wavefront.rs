//! The batched ("wavefront") API against the scalar API: for every committed fixture blob
//! (and f16 and unaligned copies of some), every neural material, both instruction-set paths
//! (portable and run-time dispatched), batches of awkward sizes mixed with adversarial lanes
//! (NaN, ±∞, below the horizon, zero vectors, u = 1, u out of range), prepare / sample / pdf /
//! invert / fused calls must give the scalar path's results **bit for bit** per lane, and
//! bad lanes must not disturb the others. Length mismatches are errors that write nothing.

use std::path::PathBuf;

use neusample::wavefront::{
    prefer_isa, BatchSampler, Features, FeaturesMut, Isa, SamplesMut, Vec2s, Vec2sMut, Vec3s,
    Vec3sMut,
};
use neusample::{
    AnySampler, Blob, BlobSampler, BlobWriter, DType, Defensive, Error, Prepared, Sampler,
    SamplerKind, TensorRole, Vec2, Vec3, FEATURE_DIM,
};
use neusample_host_tests::{fixture_blobs_dir, fixture_conditions, rng, Condition, TestRng};
use rand::RngExt;

/// Batch sizes: empty, one lane, partial tiles and chunks, several chunks plus a remainder.
const SIZES: [usize; 6] = [0, 1, 7, 33, 64, 301];

/// One lane of a test batch.
#[derive(Copy, Clone, Debug)]
struct Lane {
    phi: [f32; FEATURE_DIM],
    wi: Vec3,
    u: Vec2,
    wo: Vec3,
}

fn random_dir(r: &mut TestRng) -> Vec3 {
    let p = Vec2::new(r.random::<f32>() * 2.0 - 1.0, r.random::<f32>() * 2.0 - 1.0);
    let z = (1.0 - p.length_squared()).max(0.0).sqrt();
    Vec3::new(p.x, p.y, z + 0.05).normalize()
}

/// `n` lanes at the material's conditions, about one in six adversarial in some field.
fn lanes(r: &mut TestRng, conds: &[([f32; FEATURE_DIM], Vec3)], n: usize) -> Vec<Lane> {
    let bad_f = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e30, -0.0];
    (0..n)
        .map(|i| {
            let (mut phi, mut wi) = conds[i % conds.len()];
            let mut u = Vec2::new(r.random(), r.random());
            let mut wo = random_dir(r);
            match r.random_range(0..24u32) {
                0 => phi[r.random_range(0..FEATURE_DIM)] = bad_f[r.random_range(0..5)],
                1 => wi = Vec3::new(wi.x, wi.y, -wi.z.abs()),
                2 => wi = Vec3::ZERO,
                3 => wi = Vec3::new(f32::NAN, 0.0, 1.0),
                4 => u = Vec2::new(1.0, 1.0),
                5 => u = Vec2::new(f32::NAN, 0.5),
                6 => u = Vec2::new(-0.25, 1.5),
                7 => wo = Vec3::new(wo.x, wo.y, -wo.z),
                8 => wo = Vec3::new(f32::INFINITY, 0.0, 1.0),
                9 => wo = Vec3::ZERO,
                10 => u = Vec2::new(0.0, 0.0),
                _ => {}
            }
            Lane { phi, wi, u, wo }
        })
        .collect()
}

/// Structure-of-arrays copies of a batch's inputs.
struct Soa {
    phi: Vec<Vec<f32>>,
    wi: [Vec<f32>; 3],
    u: [Vec<f32>; 2],
    wo: [Vec<f32>; 3],
}

impl Soa {
    fn new(lanes: &[Lane]) -> Soa {
        Soa {
            phi: (0..FEATURE_DIM)
                .map(|c| lanes.iter().map(|l| l.phi[c]).collect())
                .collect(),
            wi: [0, 1, 2].map(|k| lanes.iter().map(|l| l.wi[k]).collect()),
            u: [0, 1].map(|k| lanes.iter().map(|l| l.u[k]).collect()),
            wo: [0, 1, 2].map(|k| lanes.iter().map(|l| l.wo[k]).collect()),
        }
    }
    fn phi(&self) -> Features<'_> {
        Features {
            channels: std::array::from_fn(|c| self.phi[c].as_slice()),
        }
    }
    fn wi(&self) -> Vec3s<'_> {
        Vec3s {
            x: &self.wi[0],
            y: &self.wi[1],
            z: &self.wi[2],
        }
    }
    fn wo(&self) -> Vec3s<'_> {
        Vec3s {
            x: &self.wo[0],
            y: &self.wo[1],
            z: &self.wo[2],
        }
    }
    fn u(&self) -> Vec2s<'_> {
        Vec2s {
            x: &self.u[0],
            y: &self.u[1],
        }
    }
}

/// Output buffers of a sample call, prefilled with a sentinel so unwritten lanes show.
struct Out {
    wo: [Vec<f32>; 3],
    pdf: Vec<f32>,
}

impl Out {
    fn new(n: usize) -> Out {
        Out {
            wo: [0, 1, 2].map(|_| vec![-7.0; n]),
            pdf: vec![-7.0; n],
        }
    }
    fn view(&mut self) -> SamplesMut<'_> {
        let [x, y, z] = &mut self.wo;
        SamplesMut {
            wo: Vec3sMut { x, y, z },
            pdf: &mut self.pdf,
        }
    }
}

fn bits(v: f32) -> u32 {
    v.to_bits()
}

/// Checks every batched call of `s` against its scalar API on `lanes`.
fn check_sampler<S>(s: &S, lanes: &[Lane], what: &str)
where
    S: Sampler + BatchSampler,
{
    let n = lanes.len();
    let soa = Soa::new(lanes);
    let mut states = vec![S::Lane::default(); n];
    s.prepare_batch(soa.phi(), soa.wi(), &mut states).unwrap();

    let mut out = Out::new(n);
    s.sample_batch(&states, soa.u(), out.view()).unwrap();
    let mut pdf = vec![-7.0f32; n];
    s.pdf_batch(&states, soa.wo(), &mut pdf).unwrap();
    let (mut ux, mut uy, mut ok) = (vec![-7.0f32; n], vec![-7.0f32; n], vec![false; n]);
    s.invert_batch(
        &states,
        soa.wo(),
        Vec2sMut {
            x: &mut ux,
            y: &mut uy,
        },
        &mut ok,
    )
    .unwrap();
    let mut fused = Out::new(n);
    s.sample_fused(soa.phi(), soa.wi(), soa.u(), fused.view())
        .unwrap();
    let mut fused_pdf = vec![-7.0f32; n];
    s.pdf_fused(soa.phi(), soa.wi(), soa.wo(), &mut fused_pdf)
        .unwrap();
    // The MIS density of every sample (`Prepared::mis_pdf`).
    let mut mis = out.pdf.clone();
    s.mis_pdf_batch(
        &states,
        Vec3s {
            x: &out.wo[0],
            y: &out.wo[1],
            z: &out.wo[2],
        },
        &mut mis,
    )
    .unwrap();

    for (i, l) in lanes.iter().enumerate() {
        let ctx = || format!("{what}: lane {i} of {n}: {l:?}");
        let p = s.prepare(&l.phi, l.wi);
        let sample = p.as_ref().and_then(|p| p.sample(l.u));
        let (wo, spdf) = match sample {
            Some(x) => (x.wo, x.pdf),
            None => (Vec3::ZERO, 0.0),
        };
        for (k, f) in [&out, &fused].into_iter().enumerate() {
            assert_eq!(
                [
                    bits(f.wo[0][i]),
                    bits(f.wo[1][i]),
                    bits(f.wo[2][i]),
                    bits(f.pdf[i])
                ],
                [bits(wo.x), bits(wo.y), bits(wo.z), bits(spdf)],
                "sample{} {}",
                if k == 1 { " (fused)" } else { "" },
                ctx()
            );
        }
        let want_mis = match (&p, sample) {
            (Some(p), Some(x)) => p.mis_pdf(&x),
            _ => 0.0,
        };
        assert_eq!(bits(mis[i]), bits(want_mis), "mis_pdf {}", ctx());
        if let Some(p) = &p {
            assert_eq!(s.exact_pdf(), p.exact_pdf(), "exact_pdf {}", ctx());
        }
        let want = p.as_ref().map_or(0.0, |p| p.pdf(l.wo));
        assert_eq!(bits(pdf[i]), bits(want), "pdf {}", ctx());
        assert_eq!(bits(fused_pdf[i]), bits(want), "pdf (fused) {}", ctx());
        assert!(pdf[i] >= 0.0 && pdf[i].is_finite(), "pdf {}", ctx());
        let inv = p.as_ref().and_then(|p| p.invert(l.wo));
        assert_eq!(ok[i], inv.is_some(), "invert {}", ctx());
        if let Some(v) = inv {
            assert_eq!(
                [bits(ux[i]), bits(uy[i])],
                [bits(v.x), bits(v.y)],
                "invert {}",
                ctx()
            );
        } else {
            assert_eq!(
                [ux[i], uy[i]],
                [-7.0, -7.0],
                "invert wrote a refused lane {}",
                ctx()
            );
        }
    }
}

fn fixture_samplers() -> Vec<(PathBuf, Vec<u8>, Vec<Condition>)> {
    let mut out = Vec::new();
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(fixture_blobs_dir())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    for dir in dirs {
        let conds = fixture_conditions(&dir);
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "nsb"))
            .collect();
        files.sort();
        for f in files {
            let bytes = std::fs::read(&f).unwrap();
            out.push((f, bytes, conds.clone()));
        }
    }
    assert!(
        out.len() >= 36,
        "expected every fixture blob, found {}",
        out.len()
    );
    out
}

/// Runs `f` with each instruction set this machine has (portable first).
fn for_each_isa(mut f: impl FnMut(Isa)) {
    let best = neusample::wavefront::detected_isa();
    for isa in [Isa::Portable, best] {
        assert_eq!(prefer_isa(Some(isa)), isa);
        f(isa);
        if best == Isa::Portable {
            break;
        }
    }
    prefer_isa(None);
}

#[test]
fn every_fixture_sampler_batched_equals_scalar() {
    let blobs = fixture_samplers();
    for_each_isa(|isa| {
        let mut r = rng(7);
        for (path, bytes, conds) in &blobs {
            let blob = Blob::open(bytes).unwrap();
            let sampler = blob.sampler().unwrap();
            for &n in &SIZES {
                let ls = lanes(&mut r, conds, n);
                let what = format!("{} ({}, n = {n})", path.display(), isa.name());
                check_sampler(&sampler, &ls, &format!("{what} AnySampler"));
                check_concrete(&sampler, &ls, &what);
            }
            // The same blob with a defensive weight: the learned part's batched kernels
            // with the cosine lanes gathered, against the scalar mixture.
            let defended = BlobWriter::from_blob(&blob).defensive(0.25).to_bytes();
            let blob = Blob::open(&defended).unwrap();
            assert_eq!((blob.version(), blob.defensive()), (2, 0.25));
            let sampler = blob.sampler().unwrap();
            let ls = lanes(&mut r, conds, 97);
            let what = format!("{} α = 0.25 ({})", path.display(), isa.name());
            check_sampler(&sampler, &ls, &format!("{what} AnySampler"));
            check_concrete(&sampler, &ls, &what);
        }
    });
}

/// The same checks through the concrete sampler type (its own lane type).
fn check_concrete(s: &BlobSampler<'_>, ls: &[Lane], what: &str) {
    let a = s.alpha();
    match *s.inner() {
        AnySampler::Cosine(x) => check_sampler(&Defensive::new_unchecked(x, a), ls, what),
        AnySampler::ImprovedBaseline(x) => check_sampler(&Defensive::new_unchecked(x, a), ls, what),
        AnySampler::AnalyticMixture(x) => check_sampler(&Defensive::new_unchecked(x, a), ls, what),
        AnySampler::Flow(x) => check_sampler(&Defensive::new_unchecked(x, a), ls, what),
        AnySampler::AffineFlow(x) => check_sampler(&Defensive::new_unchecked(x, a), ls, what),
        AnySampler::DirectHistogram(x) => check_sampler(&Defensive::new_unchecked(x, a), ls, what),
        AnySampler::HistogramMixture(x) => check_sampler(&Defensive::new_unchecked(x, a), ls, what),
        AnySampler::Reparam(x) => check_sampler(&Defensive::new_unchecked(x, a), ls, what),
    }
}

/// Re-encodes a blob's tensors as `dtype` (f16 exercises the widening of weight tiles).
fn reencode(bytes: &[u8], dtype: DType) -> Vec<u8> {
    let blob = Blob::open(bytes).unwrap();
    let h = *blob.header();
    let mut w = BlobWriter::new(h.kind, dtype, "re-encoded").defensive(blob.defensive());
    if h.kind == SamplerKind::HistogramMixture {
        w = w.histogram_dims(h.t_levels, h.resolution, h.interpolation);
    }
    for role in TensorRole::ALL {
        if let Some(t) = blob.tensor(role) {
            let mut v = vec![0.0f32; neusample::Weights::len(&t) as usize];
            blob.widen_into(role, &mut v).unwrap();
            w.tensor(role, &v);
        }
    }
    w.to_bytes()
}

#[test]
fn f16_and_unaligned_blobs_batched_equal_scalar() {
    let blobs = fixture_samplers();
    let mut r = rng(11);
    for (path, bytes, conds) in blobs.iter().filter(|(p, _, _)| {
        let s = p.to_string_lossy();
        s.contains("goat_leather_neural") && !s.ends_with("histogram-mixture.nsb")
    }) {
        let f16 = reencode(bytes, DType::F16);
        // The same bytes one byte into a buffer: f32 tensors are read unaligned.
        let mut shifted = vec![0u8; bytes.len() + 1];
        shifted[1..].copy_from_slice(bytes);
        for (label, b) in [("f16", &f16[..]), ("unaligned", &shifted[1..])] {
            let blob = Blob::open(b).unwrap();
            let s = blob.sampler().unwrap();
            for_each_isa(|isa| {
                let ls = lanes(&mut r, conds, 97);
                let what = format!("{} {label} ({})", path.display(), isa.name());
                check_concrete(&s, &ls, &what);
            });
        }
    }
}

#[test]
fn neural_material_batched_equals_scalar() {
    let dir = fixture_blobs_dir().join("../materials/neural");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    files.sort();
    assert!(
        files.len() >= 3,
        "expected the neural fixtures, found {}",
        files.len()
    );
    for f in files {
        let bytes = std::fs::read(&f).unwrap();
        let blob = Blob::open(&bytes).unwrap();
        let m = blob.neural_material().unwrap();
        for_each_isa(|isa| {
            let mut r = rng(3);
            for &n in &SIZES {
                let what = format!("{} ({}, n = {n})", f.display(), isa.name());
                let uv: [Vec<f32>; 2] = [0, 1].map(|_| {
                    (0..n)
                        .map(|i| match i % 17 {
                            0 => f32::NAN,
                            1 => -3.75,
                            2 => 1e9,
                            _ => r.random::<f32>() * 4.0 - 2.0,
                        })
                        .collect()
                });
                let mut phi_rows = vec![0.0f32; FEATURE_DIM * n];
                m.features_batch(
                    Vec2s {
                        x: &uv[0],
                        y: &uv[1],
                    },
                    FeaturesMut::from_rows(&mut phi_rows, n).unwrap(),
                )
                .unwrap();
                let phi = Features::from_rows(&phi_rows, n).unwrap();
                for i in 0..n {
                    let want = m.features(Vec2::new(uv[0][i], uv[1][i]));
                    assert_eq!(
                        phi.at(i).map(bits),
                        want.map(bits),
                        "features {what} lane {i}"
                    );
                }
                let conds: Vec<_> = (0..n).map(|i| (phi.at(i), random_dir(&mut r))).collect();
                let ls = if n == 0 {
                    Vec::new()
                } else {
                    lanes(&mut r, &conds, n)
                };
                let soa = Soa::new(&ls);
                let mut rgb = vec![-7.0f32; 3 * n];
                m.eval_batch(
                    soa.phi(),
                    soa.wi(),
                    soa.wo(),
                    neusample::wavefront::RgbMut::from_rows(&mut rgb, n).unwrap(),
                )
                .unwrap();
                for (i, l) in ls.iter().enumerate() {
                    let want = m.eval(&l.phi, l.wi, l.wo);
                    let got = [rgb[i], rgb[n + i], rgb[2 * n + i]];
                    assert_eq!(got.map(bits), want.map(bits), "eval {what} lane {i}: {l:?}");
                }
            }
        });
    }
}

#[test]
fn length_mismatches_are_errors_that_write_nothing() {
    let bytes = std::fs::read(fixture_blobs_dir().join("goat_leather_neural/flow.nsb")).unwrap();
    let blob = Blob::open(&bytes).unwrap();
    let s = blob.sampler().unwrap();
    let conds = fixture_conditions(&fixture_blobs_dir().join("goat_leather_neural"));
    let ls = lanes(&mut rng(1), &conds, 10);
    let soa = Soa::new(&ls);
    let mut states = vec![Default::default(); 9];
    assert!(matches!(
        s.prepare_batch(soa.phi(), soa.wi(), &mut states),
        Err(Error::BatchLength { .. })
    ));
    let mut states = vec![Default::default(); 10];
    s.prepare_batch(soa.phi(), soa.wi(), &mut states).unwrap();
    let mut short = vec![-7.0f32; 9];
    assert!(matches!(
        s.pdf_batch(&states, soa.wo(), &mut short),
        Err(Error::BatchLength { .. })
    ));
    assert!(short.iter().all(|&v| v == -7.0));
    let mut out = Out::new(10);
    out.pdf.pop();
    let err = s.sample_batch(&states, soa.u(), out.view()).unwrap_err();
    assert!(
        matches!(err, Error::BatchLength { what: "pdf", .. }),
        "{err}"
    );
    assert!(out.wo[0].iter().all(|&v| v == -7.0));
    assert!(Vec3s::from_rows(&[0.0; 8], 3).is_none());
}
