//! The batched ("wavefront") API against the scalar API: for every committed fixture blob
//! (and f16 and unaligned copies of some), every neural material, both instruction-set paths
//! (portable and run-time dispatched), batches of awkward sizes mixed with adversarial lanes
//! (NaN, ±∞, below the horizon, zero vectors, u = 1, u out of range), prepare / sample / pdf /
//! invert / fused calls must give the scalar path's results within stated tolerances per
//! lane (and agree exactly inside one batched path), and bad lanes must not disturb the
//! others. Length mismatches are errors that write nothing.

use std::path::PathBuf;

use neusample::wavefront::{
    prefer_isa, AnyScratch, BatchSampler, Features, FeaturesMut, Isa, LaneState, SamplesMut,
    Scratch, Vec2s, Vec2sMut, Vec3s, Vec3sMut,
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
    mis: Vec<f32>,
}

impl Out {
    fn new(n: usize) -> Out {
        Out {
            wo: [0, 1, 2].map(|_| vec![-7.0; n]),
            pdf: vec![-7.0; n],
            mis: vec![-7.0; n],
        }
    }
    fn view(&mut self) -> SamplesMut<'_> {
        let [x, y, z] = &mut self.wo;
        SamplesMut {
            wo: Vec3sMut { x, y, z },
            pdf: &mut self.pdf,
            mis_pdf: &mut self.mis,
        }
    }
}

fn bits(v: f32) -> u32 {
    v.to_bits()
}

/// Relative tolerance between the batched path (any instruction set) and the scalar path on
/// a density at the same direction (`wavefront` docs): the x86-64 paths run the networks with
/// fused multiply-adds, which moves a network output by about its own rounding error, and a
/// flow's density is `exp` of a sum of spline log-derivatives whose steepest bins amplify
/// that. Measured over every fixture blob with adversarial lanes: at most 6.3e-5.
const PDF_RTOL: f64 = 5e-4;
/// Relative tolerance between the batched and the scalar neural material's `eval`: `exp`
/// of a network output whose rounding differs as above.
const EVAL_RTOL: f64 = 1e-4;
/// Absolute tolerance on a sampled direction (unit vector) or an inverted `u` (measured: at
/// most 1.2e-4 away from u = 1, where the sampling maps are steep).
const DIR_ATOL: f64 = 1e-3;

/// `|a − b|` relative to the larger magnitude (0 when both are 0).
fn rel(a: f32, b: f32) -> f64 {
    let (a, b) = (f64::from(a), f64::from(b));
    let m = a.abs().max(b.abs());
    if m == 0.0 {
        0.0
    } else {
        (a - b).abs() / m
    }
}

/// The largest deviations of a batched path from the scalar one, and the lanes that differ
/// discretely (one path refuses what the other accepts, or a sample lands elsewhere).
#[derive(Default, Debug)]
struct Deviation {
    lanes: usize,
    pdf: f64,
    sample_pdf: f64,
    wo: f64,
    u: f64,
    discrete: Vec<String>,
}

impl Deviation {
    fn add(&mut self, o: Deviation) {
        self.lanes += o.lanes;
        self.pdf = self.pdf.max(o.pdf);
        self.sample_pdf = self.sample_pdf.max(o.sample_pdf);
        self.wo = self.wo.max(o.wo);
        self.u = self.u.max(o.u);
        self.discrete.extend(o.discrete);
    }
}

/// Checks every batched call of `s` against its scalar API on `lanes`: within one batched
/// path exactly (a sample's MIS density is `pdf_batch` at its direction bit for bit; fused
/// calls equal unfused ones; no lane is disturbed by another), against the scalar path within
/// the tolerances (returned, for the caller to bound).
/// What the unfused batched calls give for a batch: lane states, samples, pdfs at `wo`, and
/// the inverses at `wo` (`ux`, `uy`, `ok`).
struct Batched<L> {
    states: Vec<L>,
    out: Out,
    pdf: Vec<f32>,
    ux: Vec<f32>,
    uy: Vec<f32>,
    ok: Vec<bool>,
}

/// Prepare, sample, pdf and invert of the lanes of `soa`, the outputs prefilled with
/// sentinels; sample and pdf in `scratch` if given (else each call's own).
fn run_batched<S: BatchSampler>(
    s: &S,
    soa: &Soa,
    scratch: Option<&mut S::Scratch>,
) -> Batched<S::Lane> {
    let n = soa.wi().len();
    let mut states = vec![S::Lane::default(); n];
    s.prepare_batch(soa.phi(), soa.wi(), &mut states).unwrap();
    let mut out = Out::new(n);
    let mut pdf = vec![-7.0f32; n];
    if let Some(scratch) = scratch {
        s.sample_batch_in(&states, soa.u(), out.view(), scratch)
            .unwrap();
        s.pdf_batch_in(&states, soa.wo(), &mut pdf, scratch)
            .unwrap();
    } else {
        s.sample_batch(&states, soa.u(), out.view()).unwrap();
        s.pdf_batch(&states, soa.wo(), &mut pdf).unwrap();
    }
    let (mut ux, mut uy, mut ok) = (vec![-7.0f32; n], vec![-7.0f32; n], vec![false; n]);
    let u = Vec2sMut {
        x: &mut ux,
        y: &mut uy,
    };
    s.invert_batch(&states, soa.wo(), u, &mut ok).unwrap();
    Batched {
        states,
        out,
        pdf,
        ux,
        uy,
        ok,
    }
}

fn check_sampler<S>(s: &S, lanes: &[Lane], what: &str, turned: bool) -> Deviation
where
    S: Sampler + BatchSampler,
{
    let n = lanes.len();
    let soa = Soa::new(lanes);
    let Batched {
        states,
        out,
        pdf,
        ux,
        uy,
        ok,
    } = run_batched(s, &soa, None);
    let mut fused = Out::new(n);
    s.sample_fused(soa.phi(), soa.wi(), soa.u(), fused.view())
        .unwrap();
    let mut fused_pdf = vec![-7.0f32; n];
    s.pdf_fused(soa.phi(), soa.wi(), soa.wo(), &mut fused_pdf)
        .unwrap();
    // The density of every sampled direction, through the same path.
    let mut again = vec![-7.0f32; n];
    s.pdf_batch(
        &states,
        Vec3s {
            x: &out.wo[0],
            y: &out.wo[1],
            z: &out.wo[2],
        },
        &mut again,
    )
    .unwrap();
    let mis = &out.mis;

    let mut dev = Deviation {
        lanes: n,
        ..Deviation::default()
    };
    for (i, l) in lanes.iter().enumerate() {
        let ctx = || format!("{what}: lane {i} of {n}: {l:?}");
        // Inside the batched path: exact.
        let got = [out.wo[0][i], out.wo[1][i], out.wo[2][i], out.pdf[i], mis[i]];
        let got_fused = [
            fused.wo[0][i],
            fused.wo[1][i],
            fused.wo[2][i],
            fused.pdf[i],
            fused.mis[i],
        ];
        assert_eq!(
            got.map(bits),
            got_fused.map(bits),
            "sample (fused) {}",
            ctx()
        );
        assert_eq!(bits(pdf[i]), bits(fused_pdf[i]), "pdf (fused) {}", ctx());
        assert!(pdf[i] >= 0.0 && pdf[i].is_finite(), "pdf {}", ctx());
        assert!(
            out.pdf[i] >= 0.0 && out.pdf[i].is_finite(),
            "sample pdf {}",
            ctx()
        );
        assert!(mis[i] >= 0.0 && mis[i].is_finite(), "mis_pdf {}", ctx());
        if out.pdf[i] > 0.0 {
            // Every kind's MIS density is its pdf at the sample, bit for bit. An isotropic
            // blob's turn there and back rounds the direction, which a sharp lobe turns into
            // a visible density change: `defensive.rs` bounds that on a real blob; here the
            // batched sample is held to the scalar sample below.
            if !turned {
                assert_eq!(bits(again[i]), bits(mis[i]), "pdf at the sample {}", ctx());
            }
            let len = got[..3].iter().map(|v| f64::from(*v).powi(2)).sum::<f64>();
            assert!(
                (len - 1.0).abs() < 1e-5 && got[2] > 0.0,
                "sample wo {}",
                ctx()
            );
        } else {
            assert_eq!(&got[..3], &[0.0; 3], "refused sample {}", ctx());
            assert_eq!(mis[i], 0.0, "refused sample's MIS density {}", ctx());
        }
        if !ok[i] {
            assert_eq!(
                [ux[i], uy[i]],
                [-7.0, -7.0],
                "invert wrote a refused lane {}",
                ctx()
            );
        }
        // Against the scalar path: within the tolerances, or a discrete difference.
        let p = s.prepare(&l.phi, l.wi);
        assert_eq!(states[i].is_prepared(), p.is_some(), "prepared {}", ctx());
        let sample = p.as_ref().and_then(|p| p.sample(l.u));
        // u = 1 is clamped below 1 and mapped to the far tail of a lobe or spline, where the
        // sample moves by far more than its inputs' rounding: only its validity is compared.
        let edge = l.u.x >= 1.0 || l.u.y >= 1.0;
        match (&p, sample) {
            (Some(p), Some(x)) if out.pdf[i] > 0.0 => {
                let wo = Vec3::new(got[0], got[1], got[2]);
                // The scalar density at the batched sample: the sample's own pdf, well
                // conditioned wherever the density is continuous. A density other than the
                // MIS density (the reparameterization sampler's warp) exists only at its own
                // draws: the scalar sample's, where the two samples coincide.
                let r = if turned && edge {
                    0.0
                } else if turned {
                    rel(got[3], x.pdf).max(rel(mis[i], x.mis_pdf))
                } else if x.pdf == x.mis_pdf {
                    rel(got[3], p.pdf(wo))
                } else if edge {
                    0.0
                } else {
                    rel(got[3], x.pdf)
                };
                let d = (0..3)
                    .map(|k| (f64::from(got[k]) - f64::from(x.wo[k])).abs())
                    .fold(0.0, f64::max);
                // The MIS density of the batched sample is the scalar `pdf` there, for every
                // kind.
                let r = if turned {
                    r
                } else {
                    r.max(rel(mis[i], p.pdf(wo)))
                };
                if r > PDF_RTOL || (!edge && d > DIR_ATOL) {
                    dev.discrete
                        .push(format!("sample {got:?} vs {x:?} {}", ctx()));
                } else {
                    dev.sample_pdf = dev.sample_pdf.max(r);
                    if !edge {
                        dev.wo = dev.wo.max(d);
                    }
                }
            }
            (_, None) if out.pdf[i] == 0.0 => {}
            // Near u = 1 a sample may leave the disk on one path and not on the other.
            (Some(_), _) if edge => {}
            _ => dev
                .discrete
                .push(format!("sample {got:?} vs {sample:?} {}", ctx())),
        }
        let want = p.as_ref().map_or(0.0, |p| p.pdf(l.wo));
        let r = rel(pdf[i], want);
        if r > PDF_RTOL {
            dev.discrete
                .push(format!("pdf {} vs {want} {}", pdf[i], ctx()));
        } else {
            dev.pdf = dev.pdf.max(r);
        }
        let inv = p.as_ref().and_then(|p| p.invert(l.wo));
        match inv {
            Some(v) if ok[i] => {
                // u.y is an angle for the Gaussian bases: it wraps around at 1.
                let dy = (f64::from(uy[i]) - f64::from(v.y)).abs();
                let d = (f64::from(ux[i]) - f64::from(v.x))
                    .abs()
                    .max(dy.min(1.0 - dy));
                if d > DIR_ATOL {
                    dev.discrete
                        .push(format!("invert {} {} vs {v:?} {}", ux[i], uy[i], ctx()));
                } else {
                    dev.u = dev.u.max(d);
                }
            }
            None if !ok[i] => {}
            _ => dev
                .discrete
                .push(format!("invert {} vs {inv:?} {}", ok[i], ctx())),
        }
    }
    dev
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

/// Runs `f` with each instruction set this machine has (portable first). The choice is
/// global to the process and the paths differ within the tolerances: the tests of this file
/// take turns.
fn for_each_isa(mut f: impl FnMut(Isa)) {
    static TURN: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _turn = TURN
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    for isa in Isa::ALL {
        if prefer_isa(Some(isa)) == isa {
            f(isa);
        }
    }
    prefer_isa(None);
}

/// Runs the checks of one sampler through [`AnySampler`] and its concrete type.
fn check_both(s: &BlobSampler<'_>, ls: &[Lane], what: &str) -> Deviation {
    let mut d = check_sampler(s, ls, &format!("{what} AnySampler"), s.is_isotropic());
    d.add(check_concrete(s, ls, what));
    d
}

/// Bounds the deviations of one instruction set's batched path from the scalar path.
fn assert_within(isa: Isa, dev: &Deviation, what: &str) {
    eprintln!(
        "{what} ({}): {} lanes, largest deviations: pdf {:.2e}, sample pdf {:.2e}, wo {:.2e}, u {:.2e}; {} discrete",
        isa.name(),
        dev.lanes,
        dev.pdf,
        dev.sample_pdf,
        dev.wo,
        dev.u,
        dev.discrete.len()
    );
    for d in dev.discrete.iter().take(5) {
        eprintln!("  {d}");
    }
    assert!(
        dev.discrete.is_empty(),
        "{what} ({}): {} lanes beyond the tolerances, e.g. {}",
        isa.name(),
        dev.discrete.len(),
        dev.discrete[0]
    );
}

#[test]
fn every_fixture_sampler_batched_equals_scalar() {
    let blobs = fixture_samplers();
    for_each_isa(|isa| {
        let mut r = rng(7);
        // The isotropic variants' own stream: the other checks see the lanes they always saw.
        let mut ri = rng(9);
        let mut total = Deviation::default();
        for (path, bytes, conds) in &blobs {
            let blob = Blob::open(bytes).unwrap();
            let sampler = blob.sampler().unwrap();
            let mut dev = Deviation::default();
            for &n in &SIZES {
                let ls = lanes(&mut r, conds, n);
                let what = format!("{} ({}, n = {n})", path.display(), isa.name());
                dev.add(check_both(&sampler, &ls, &what));
            }
            // The same blob with a defensive weight: the learned part's batched kernels
            // with the cosine lanes gathered, against the scalar mixture.
            let defended = BlobWriter::from_blob(&blob).defensive(0.25).to_bytes();
            let blob = Blob::open(&defended).unwrap();
            assert_eq!((blob.version(), blob.defensive()), (2, 0.25));
            let sampler = blob.sampler().unwrap();
            let ls = lanes(&mut r, conds, 97);
            let what = format!("{} α = 0.25 ({})", path.display(), isa.name());
            dev.add(check_both(&sampler, &ls, &what));
            // Isotropic, with and without α: the lanes' turns around the learned part.
            for alpha in [0.0, 0.25] {
                let iso = BlobWriter::from_blob(&blob)
                    .defensive(alpha)
                    .isotropic(true)
                    .to_bytes();
                let blob = Blob::open(&iso).unwrap();
                let sampler = blob.sampler().unwrap();
                let ls = lanes(&mut ri, conds, 37);
                let what = format!("{} isotropic α = {alpha} ({})", path.display(), isa.name());
                dev.add(check_both(&sampler, &ls, &what));
            }
            assert_within(isa, &dev, &path.display().to_string());
            total.add(dev);
        }
        assert_within(isa, &total, "all fixtures");
    });
}

/// The same checks through a concrete sampler type under [`Defensive`] (its own lane type, as
/// `Blob::sampler_as` returns it), for the direct histogram; other kinds give no deviation.
/// Every kind's batched code is the code [`AnySampler`] dispatches to, which `check_both`
/// checks for all of them; each further concrete type here would be another copy of its
/// batched kernels for this test crate to compile.
fn check_concrete(s: &BlobSampler<'_>, ls: &[Lane], what: &str) -> Deviation {
    match *s.inner() {
        AnySampler::DirectHistogram(x) => {
            let d = Defensive::new_unchecked(x, s.alpha()).with_isotropic(s.is_isotropic());
            check_sampler(&d, ls, what, s.is_isotropic())
        }
        _ => Deviation::default(),
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
                let dev = check_concrete(&s, &ls, &what);
                assert_within(isa, &dev, &what);
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
            let mut worst = 0.0f64;
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
                    let r = (0..3).map(|c| rel(got[c], want[c])).fold(0.0, f64::max);
                    worst = worst.max(r);
                    assert!(
                        r <= EVAL_RTOL && got.iter().all(|v| *v >= 0.0 && v.is_finite()),
                        "eval {what} lane {i}: {got:?} vs {want:?}, {l:?}"
                    );
                }
            }
            eprintln!(
                "{} ({}): largest eval deviation {worst:.2e}",
                f.display(),
                isa.name()
            );
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

/// One dense layer `dense(I, O)` of random f32 weights over the lanes of `x`: the first `m`
/// lanes computed alone (the kernel's lane-by-lane path for one or two lanes) equal, bit
/// for bit, the same lanes computed in a full chunk (the lane tiles).
fn small_products_equal_tiles<const I: usize, const O: usize>(r: &mut TestRng) {
    use neusample::nn::Activation;
    use neusample::wavefront::dense_layer;
    const B: usize = 32;
    let w: Vec<f32> = (0..I * O + O)
        .map(|_| r.random::<f32>() * 2.0 - 1.0)
        .collect();
    let mut x = [[0.0f32; B]; I];
    for row in x.iter_mut() {
        for v in row.iter_mut() {
            *v = r.random::<f32>() * 4.0 - 2.0;
        }
    }
    for act in [
        Activation::Identity,
        Activation::Relu,
        Activation::LeakyRelu,
    ] {
        let mut full = [[0.0f32; B]; O];
        dense_layer::<_, I, O, B>(&w, 0, &x, act, &mut full, B);
        for m in [1, 2, 3] {
            let mut y = [[0.0f32; B]; O];
            dense_layer::<_, I, O, B>(&w, 0, &x, act, &mut y, m);
            for (j, (a, b)) in y.iter().zip(full.iter()).enumerate() {
                for l in 0..m {
                    assert_eq!(
                        a[l].to_bits(),
                        b[l].to_bits(),
                        "dense({I}, {O}) {act:?}, {m} lanes: output {j} lane {l}"
                    );
                }
            }
        }
    }
}

#[test]
fn small_batches_give_the_tiles_sums() {
    for_each_isa(|_| {
        let mut r = rng(7);
        small_products_equal_tiles::<39, 32>(&mut r);
        small_products_equal_tiles::<32, 59>(&mut r);
        small_products_equal_tiles::<64, 3>(&mut r);
        small_products_equal_tiles::<14, 64>(&mut r);
        small_products_equal_tiles::<32, 16>(&mut r);
    });
}

/// Every batched result of `lanes` as bits, lane by lane: the sample (direction, pdf, MIS
/// density), the pdf at `wo`, the inverse at `wo` and whether it exists (sample and pdf in
/// `scratch` if given).
fn batch_bits<S: BatchSampler>(
    s: &S,
    lanes: &[Lane],
    scratch: Option<&mut S::Scratch>,
) -> Vec<[u32; 9]> {
    let n = lanes.len();
    let Batched {
        out,
        pdf,
        ux,
        uy,
        ok,
        ..
    } = run_batched(s, &Soa::new(lanes), scratch);
    (0..n)
        .map(|i| {
            let v = [
                out.wo[0][i],
                out.wo[1][i],
                out.wo[2][i],
                out.pdf[i],
                out.mis[i],
                pdf[i],
                ux[i],
                uy[i],
            ];
            let mut b = [0u32; 9];
            b[..8].copy_from_slice(&v.map(bits));
            b[8] = u32::from(ok[i]);
            b
        })
        .collect()
}

/// A lane's batched results do not depend on how many lanes share its call, nor on the
/// working memory's history: every fixture blob (plain and with a defensive weight), one
/// batch against the same lanes in calls of 1 to 33 lanes (below, at and past the narrow
/// width of small calls, a chunk and a tile), each call also in one working memory kept
/// across all calls, sizes and kinds (a caller's [`AnyScratch`]).
#[test]
fn lane_results_do_not_depend_on_the_batch_size() {
    const SPLITS: [usize; 9] = [1, 8, 9, 2, 16, 17, 7, 33, 3];
    let blobs = fixture_samplers();
    for_each_isa(|isa| {
        let mut r = rng(11);
        let mut kept = Box::new(AnyScratch::NEW);
        for (path, bytes, conds) in &blobs {
            let blob = Blob::open(bytes).unwrap();
            let defended = BlobWriter::from_blob(&blob).defensive(0.25).to_bytes();
            let isotropic = BlobWriter::from_blob(&blob)
                .defensive(0.25)
                .isotropic(true)
                .to_bytes();
            for b in [bytes, &defended, &isotropic] {
                let blob = Blob::open(b).unwrap();
                let s = blob.sampler().unwrap();
                let ls = lanes(&mut r, conds, SPLITS.iter().sum());
                let whole = batch_bits(&s, &ls, None);
                let mut at = 0;
                for n in SPLITS {
                    let part = batch_bits(&s, &ls[at..at + n], None);
                    let in_kept = batch_bits(&s, &ls[at..at + n], Some(&mut kept));
                    let calls = part.iter().zip(&in_kept).zip(&whole[at..]).enumerate();
                    for (k, ((a, c), b)) in calls {
                        let ctx = || {
                            format!(
                                "{} α = {} ({}): lane {} in a call of {n} lanes vs of {}: {:?}",
                                path.display(),
                                blob.defensive(),
                                isa.name(),
                                at + k,
                                whole.len(),
                                ls[at + k]
                            )
                        };
                        assert_eq!(a, b, "{}", ctx());
                        assert_eq!(c, b, "kept working memory: {}", ctx());
                    }
                    at += n;
                }
            }
        }
    });
}
