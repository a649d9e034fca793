//! `neusample bench`: the runtime's cost per shading point, measured as a renderer calls it.
//!
//! For every sampler blob of a material folder (the committed fixtures by default) and the
//! neural material, single-threaded: ns per shading point of `prepare`, `sample` and `pdf`
//! through the scalar API and through the batched API at N = 1, 8, 64 and 1024 lanes, for
//! the run-time chosen instruction set and the portable path; the neural material's
//! `features` and `eval` likewise; the decoder's dense layers in multiply-adds per second
//! next to this CPU's measured multiply-add peak. Figures are medians over passes; the
//! machine should be otherwise idle. Nothing here is an assertion.

use std::hint::black_box;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use neusample::wavefront::{
    self, BatchSampler, Features, FeaturesMut, Isa, RgbMut, SamplesMut, Vec2s, Vec3s, Vec3sMut,
};
use neusample::{AnySampler, Blob, NeuralMaterial, Prepared, Sampler, Tensor, Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::util::timing::{median_of_passes, ns_per_call};

/// The batch sizes measured.
pub const BATCH_SIZES: [usize; 4] = [1, 8, 64, 1024];

/// Multiply-adds of one decoder evaluation (`core/ARCHITECTURES.md` §7: 14→64→64→64→3).
const DECODER_MACS: f64 = (14 * 64 + 64 * 64 + 64 * 64 + 64 * 3) as f64;

/// What to measure.
#[derive(Clone, Debug)]
pub struct BenchConfig {
    /// A folder of sampler blobs (`<method>.nsb`) with its `conditions.txt`.
    pub blobs: PathBuf,
    /// The neural material those samplers were trained for.
    pub material: PathBuf,
    /// Lanes evaluated per timed pass (each batch size repeats to reach it).
    pub lanes_per_pass: usize,
    /// Timed passes per figure (the median is reported).
    pub passes: usize,
}

impl BenchConfig {
    /// The committed goat-leather fixtures, the reference material of the cost targets.
    #[must_use]
    pub fn fixtures() -> Self {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures");
        BenchConfig {
            blobs: root.join("blobs/goat_leather_neural"),
            material: root.join("materials/neural/goat_leather_neural.nsb"),
            lanes_per_pass: 1 << 14,
            passes: 7,
        }
    }
}

/// Per-shading-point costs of one call sequence, in ns.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Split {
    /// `prepare` (or `prepare_batch` per lane).
    pub prepare_ns: f64,
    /// `sample`.
    pub sample_ns: f64,
    /// `pdf` of another direction (the MIS query).
    pub pdf_ns: f64,
    /// The sum: one shading point's prepare + sample + pdf.
    pub total_ns: f64,
}

/// The batched API at one batch size.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Batched {
    /// Lanes per call.
    pub n: usize,
    /// With the run-time chosen instruction set.
    pub dispatched: Split,
    /// With the portable path.
    pub portable: Split,
}

/// One sampler's figures.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct MethodCost {
    /// The method (blob file stem).
    pub method: String,
    /// The scalar API, one shading point at a time.
    pub scalar: Split,
    /// The batched API, per batch size.
    pub batched: Vec<Batched>,
    /// Batched total at N = 64 (dispatched) over the neural material's batched `eval`.
    pub vs_material_eval: f64,
}

/// The neural material's figures, ns per shading point (per direction pair for `eval`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct MaterialCost {
    /// Scalar `features(uv)`.
    pub features_ns: f64,
    /// Scalar `eval(φ, wi, wo)`.
    pub eval_ns: f64,
    /// `features_batch` at N = 1024 (dispatched).
    pub features_batch_ns: f64,
    /// `eval_batch` per batch size (dispatched).
    pub eval_batch_ns: Vec<(usize, f64)>,
    /// `eval_batch` per batch size (portable).
    pub eval_batch_portable_ns: Vec<(usize, f64)>,
}

/// The dense layers' throughput.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DenseThroughput {
    /// The decoder's multiply-adds per second at N = 1024 (dispatched), 10⁹/s.
    pub decoder_gmacs: f64,
    /// The same with the portable path.
    pub decoder_gmacs_portable: f64,
    /// This core's multiply-add peak, measured with independent fused multiply-adds on the
    /// widest vectors of the chosen instruction set, 10⁹/s.
    pub peak_gmacs: f64,
    /// `decoder_gmacs / peak_gmacs`.
    pub fraction_of_peak: f64,
}

/// Everything `neusample bench` measures (`--json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct BenchReport {
    /// The blob folder.
    pub blobs: String,
    /// The neural material.
    pub material: String,
    /// The run-time chosen instruction set (`x86-64-v3`, `portable`).
    pub isa: String,
    /// Per sampler.
    pub methods: Vec<MethodCost>,
    /// The neural material.
    pub neural_material: MaterialCost,
    /// The dense layers.
    pub dense: DenseThroughput,
}

/// The median over `passes` of `f`'s ns per `per` calls, after one warm-up pass.
fn time_per(passes: usize, per: usize, mut f: impl FnMut()) -> f64 {
    f();
    median_of_passes(passes, || [ns_per_call(per, &mut f)])[0]
}

/// The inputs every measurement cycles through.
struct Inputs {
    conds: Vec<([f32; 8], Vec3)>,
    us: Vec<Vec2>,
    wos: Vec<Vec3>,
    uvs: Vec<Vec2>,
}

impl Inputs {
    /// `n` lanes from the folder's conditions, with seeded `u`, MIS directions and uv.
    fn new(blobs: &Path, n: usize) -> Result<Inputs> {
        let text = std::fs::read_to_string(blobs.join("conditions.txt"))
            .with_context(|| format!("{}: no conditions.txt", blobs.display()))?;
        let base: Vec<([f32; 8], Vec3)> = text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .map(|l| -> Result<_> {
                let v: Vec<f32> = l
                    .split_whitespace()
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .with_context(|| format!("bad line in conditions.txt: {l}"))?;
                if v.len() != 11 {
                    bail!("bad line in conditions.txt: {l}");
                }
                let mut phi = [0.0f32; 8];
                phi.copy_from_slice(&v[..8]);
                Ok((phi, Vec3::new(v[8], v[9], v[10])))
            })
            .collect::<Result<_>>()?;
        if base.is_empty() {
            bail!("{}: conditions.txt lists no condition", blobs.display());
        }
        // A fixed low-discrepancy-ish sequence: reproducible without an RNG dependency.
        let frac = |x: f64| (x - x.floor()) as f32;
        let (g1, g2) = (0.754_877_666_246_692_8, 0.569_840_290_998_053_2);
        let us: Vec<Vec2> = (0..n)
            .map(|i| Vec2::new(frac(0.5 + g1 * i as f64), frac(0.5 + g2 * i as f64)))
            .collect();
        let wos = us
            .iter()
            .map(|u| {
                let (r, a) = (0.98 * u.y.sqrt(), std::f32::consts::TAU * u.x);
                Vec3::new(r * a.cos(), r * a.sin(), (1.0 - r * r).sqrt())
            })
            .collect();
        let uvs = us.iter().map(|u| Vec2::new(u.y * 3.0, u.x * 2.0)).collect();
        Ok(Inputs {
            conds: (0..n).map(|i| base[i % base.len()]).collect(),
            us,
            wos,
            uvs,
        })
    }
}

/// Structure-of-arrays rows of the inputs.
struct Rows {
    phi: Vec<Vec<f32>>,
    wi: [Vec<f32>; 3],
    u: [Vec<f32>; 2],
    wo: [Vec<f32>; 3],
    uv: [Vec<f32>; 2],
}

impl Rows {
    fn new(inp: &Inputs) -> Rows {
        Rows {
            phi: (0..8)
                .map(|c| inp.conds.iter().map(|x| x.0[c]).collect())
                .collect(),
            wi: [0, 1, 2].map(|k| inp.conds.iter().map(|x| x.1[k]).collect()),
            u: [0, 1].map(|k| inp.us.iter().map(|x| x[k]).collect()),
            wo: [0, 1, 2].map(|k| inp.wos.iter().map(|x| x[k]).collect()),
            uv: [0, 1].map(|k| inp.uvs.iter().map(|x| x[k]).collect()),
        }
    }
    fn phi(&self, a: usize, b: usize) -> Features<'_> {
        Features {
            channels: std::array::from_fn(|c| &self.phi[c][a..b]),
        }
    }
    fn wi(&self, a: usize, b: usize) -> Vec3s<'_> {
        Vec3s {
            x: &self.wi[0][a..b],
            y: &self.wi[1][a..b],
            z: &self.wi[2][a..b],
        }
    }
    fn wo(&self, a: usize, b: usize) -> Vec3s<'_> {
        Vec3s {
            x: &self.wo[0][a..b],
            y: &self.wo[1][a..b],
            z: &self.wo[2][a..b],
        }
    }
    fn u(&self, a: usize, b: usize) -> Vec2s<'_> {
        Vec2s {
            x: &self.u[0][a..b],
            y: &self.u[1][a..b],
        }
    }
}

/// The scalar API's split: each call cycles through the lanes.
fn scalar_split<S: Sampler>(s: &S, inp: &Inputs, passes: usize) -> Split {
    let n = inp.conds.len();
    let prepare_ns = time_per(passes, n, || {
        for (phi, wi) in &inp.conds {
            black_box(s.prepare(black_box(phi), *wi).is_some());
        }
    });
    let prepared: Vec<_> = inp.conds.iter().map(|(p, w)| s.prepare(p, *w)).collect();
    let sample_ns = time_per(passes, n, || {
        for (p, u) in prepared.iter().zip(&inp.us) {
            if let Some(p) = p {
                black_box(p.sample(*u));
            }
        }
    });
    let pdf_ns = time_per(passes, n, || {
        for (p, wo) in prepared.iter().zip(&inp.wos) {
            if let Some(p) = p {
                black_box(p.pdf(*wo));
            }
        }
    });
    Split {
        prepare_ns,
        sample_ns,
        pdf_ns,
        total_ns: prepare_ns + sample_ns + pdf_ns,
    }
}

/// The batched API's split at `n` lanes per call over all of `rows`.
fn batched_split<S: BatchSampler>(s: &S, rows: &Rows, n: usize, passes: usize) -> Split {
    let total = rows.wi[0].len();
    let mut lanes = vec![S::Lane::default(); total];
    let mut wo = [0, 1, 2].map(|_| vec![0.0f32; total]);
    let mut pdf = vec![0.0f32; total];
    let mut pdf2 = vec![0.0f32; total];
    let starts: Vec<usize> = (0..total).step_by(n).collect();
    let prepare_ns = time_per(passes, total, || {
        for &a in &starts {
            let b = (a + n).min(total);
            s.prepare_batch(rows.phi(a, b), rows.wi(a, b), &mut lanes[a..b])
                .expect("lengths agree");
        }
    });
    let sample_ns = time_per(passes, total, || {
        let [x, y, z] = &mut wo;
        for &a in &starts {
            let b = (a + n).min(total);
            let out = SamplesMut {
                wo: Vec3sMut {
                    x: &mut x[a..b],
                    y: &mut y[a..b],
                    z: &mut z[a..b],
                },
                pdf: &mut pdf[a..b],
            };
            s.sample_batch(&lanes[a..b], rows.u(a, b), out)
                .expect("lengths agree");
        }
    });
    let pdf_ns = time_per(passes, total, || {
        for &a in &starts {
            let b = (a + n).min(total);
            s.pdf_batch(&lanes[a..b], rows.wo(a, b), &mut pdf2[a..b])
                .expect("lengths agree");
        }
    });
    black_box((&pdf, &pdf2));
    Split {
        prepare_ns,
        sample_ns,
        pdf_ns,
        total_ns: prepare_ns + sample_ns + pdf_ns,
    }
}

/// Both splits of a concrete sampler type at every batch size.
fn batched_all<S: BatchSampler>(s: &S, rows: &Rows, passes: usize) -> Vec<Batched> {
    BATCH_SIZES
        .iter()
        .map(|&n| {
            wavefront::prefer_isa(Some(Isa::Portable));
            let portable = batched_split(s, rows, n, passes);
            wavefront::prefer_isa(None);
            let dispatched = batched_split(s, rows, n, passes);
            Batched {
                n,
                dispatched,
                portable,
            }
        })
        .collect()
}

/// [`batched_all`] through the blob's concrete sampler type (its own lanes).
fn batched_any(s: &AnySampler<'_>, rows: &Rows, passes: usize) -> Vec<Batched> {
    match s {
        AnySampler::Cosine(x) => batched_all(x, rows, passes),
        AnySampler::ImprovedBaseline(x) => batched_all(x, rows, passes),
        AnySampler::AnalyticMixture(x) => batched_all(x, rows, passes),
        AnySampler::Flow(x) => batched_all(x, rows, passes),
        AnySampler::AffineFlow(x) => batched_all(x, rows, passes),
        AnySampler::DirectHistogram(x) => batched_all(x, rows, passes),
        AnySampler::HistogramMixture(x) => batched_all(x, rows, passes),
    }
}

/// `eval_batch` ns per lane at `n` lanes per call.
fn eval_batch_ns(m: &NeuralMaterial<Tensor<'_>>, rows: &Rows, n: usize, passes: usize) -> f64 {
    let total = rows.wi[0].len();
    let mut rgb = vec![0.0f32; 3 * total];
    let starts: Vec<usize> = (0..total).step_by(n).collect();
    time_per(passes, total, || {
        let (r, gb) = rgb.split_at_mut(total);
        let (g, bl) = gb.split_at_mut(total);
        for &a in &starts {
            let b = (a + n).min(total);
            let out = RgbMut {
                r: &mut r[a..b],
                g: &mut g[a..b],
                b: &mut bl[a..b],
            };
            m.eval_batch(rows.phi(a, b), rows.wi(a, b), rows.wo(a, b), out)
                .expect("lengths agree");
        }
    })
}

/// The measured multiply-add peak of one core, 10⁹/s: independent multiply-add chains on the
/// widest vectors of the chosen instruction set.
fn peak_gmacs(passes: usize) -> f64 {
    struct Peak(u64);
    impl pulp::WithSimd for Peak {
        type Output = (f32, usize);
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, simd: S) -> (f32, usize) {
            let b = simd.splat_f32s(0.999_999);
            let c = simd.splat_f32s(1e-7);
            let mut acc = [simd.splat_f32s(1.0); 12];
            for _ in 0..self.0 {
                for a in acc.iter_mut() {
                    *a = simd.mul_add_e_f32s(*a, b, c);
                }
            }
            let mut s = simd.splat_f32s(0.0);
            for a in acc {
                s = simd.add_f32s(s, a);
            }
            (simd.reduce_sum_f32s(s), S::F32_LANES)
        }
    }
    let arch = pulp::Arch::new();
    let iters = 2_000_000u64;
    let width = arch.dispatch(Peak(1)).1;
    let ns = time_per(passes, 1, || {
        black_box(arch.dispatch(Peak(black_box(iters))));
    });
    (iters * 12 * width as u64) as f64 / ns
}

/// Runs the benchmark.
pub fn run(cfg: &BenchConfig) -> Result<BenchReport> {
    let inp = Inputs::new(&cfg.blobs, cfg.lanes_per_pass)?;
    let rows = Rows::new(&inp);
    let passes = cfg.passes;
    let mbytes = std::fs::read(&cfg.material)
        .with_context(|| format!("reading {}", cfg.material.display()))?;
    let mblob = Blob::open(&mbytes).with_context(|| cfg.material.display().to_string())?;
    let m = mblob
        .neural_material()
        .with_context(|| cfg.material.display().to_string())?;

    // The neural material.
    let features_ns = time_per(passes, inp.uvs.len(), || {
        for uv in &inp.uvs {
            black_box(m.features(*uv));
        }
    });
    let eval_ns = time_per(passes, inp.conds.len(), || {
        for ((phi, wi), wo) in inp.conds.iter().zip(&inp.wos) {
            black_box(m.eval(phi, *wi, *wo));
        }
    });
    let total = inp.uvs.len();
    let mut phi_rows = vec![0.0f32; 8 * total];
    let features_batch_ns = time_per(passes, total, || {
        let phi = FeaturesMut::from_rows(&mut phi_rows, total).expect("sized");
        m.features_batch(
            Vec2s {
                x: &rows.uv[0],
                y: &rows.uv[1],
            },
            phi,
        )
        .expect("lengths agree");
    });
    let mut eval_batch = Vec::new();
    let mut eval_portable = Vec::new();
    for &n in &BATCH_SIZES {
        wavefront::prefer_isa(Some(Isa::Portable));
        eval_portable.push((n, eval_batch_ns(&m, &rows, n, passes)));
        wavefront::prefer_isa(None);
        eval_batch.push((n, eval_batch_ns(&m, &rows, n, passes)));
    }
    let at = |v: &[(usize, f64)], n: usize| v.iter().find(|x| x.0 == n).map_or(0.0, |x| x.1);
    let eval64 = at(&eval_batch, 64);
    let decoder_gmacs = DECODER_MACS / at(&eval_batch, 1024);
    let decoder_gmacs_portable = DECODER_MACS / at(&eval_portable, 1024);
    let peak = peak_gmacs(passes);

    // The samplers.
    let mut methods = Vec::new();
    // The sampler blobs, by kind name (`<method>.nsb`), in `SamplerKind::ALL` order.
    for method in neusample::SamplerKind::ALL.map(neusample::SamplerKind::name) {
        let path = cfg.blobs.join(format!("{method}.nsb"));
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(_) if method == "cosine" => neusample::BlobWriter::new(
                neusample::SamplerKind::Cosine,
                neusample::DType::F32,
                "cosine",
            )
            .to_bytes(),
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        };
        let blob = Blob::open(&bytes).with_context(|| path.display().to_string())?;
        let s = blob.sampler().with_context(|| path.display().to_string())?;
        let scalar = scalar_split(&s, &inp, passes);
        let batched = batched_any(&s, &rows, passes);
        let b64 = batched
            .iter()
            .find(|b| b.n == 64)
            .map_or(0.0, |b| b.dispatched.total_ns);
        methods.push(MethodCost {
            method: method.to_string(),
            scalar,
            batched,
            vs_material_eval: b64 / eval64,
        });
    }
    Ok(BenchReport {
        blobs: cfg.blobs.display().to_string(),
        material: cfg.material.display().to_string(),
        isa: wavefront::current_isa().name().to_string(),
        methods,
        neural_material: MaterialCost {
            features_ns,
            eval_ns,
            features_batch_ns,
            eval_batch_ns: eval_batch,
            eval_batch_portable_ns: eval_portable,
        },
        dense: DenseThroughput {
            decoder_gmacs,
            decoder_gmacs_portable,
            peak_gmacs: peak,
            fraction_of_peak: decoder_gmacs / peak,
        },
    })
}

/// The report as text tables.
#[must_use]
pub fn text(r: &BenchReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "neusample bench — {} (instruction set: {}), ns per shading point, single thread, medians",
        r.blobs, r.isa
    );
    let _ = writeln!(
        s,
        "\n{:<18} {:>24} | {:>26} | {:>8} {:>8} {:>8} {:>8} | {:>9}",
        "method",
        "scalar prep/samp/pdf",
        "batched N=64 prep/samp/pdf",
        "N=1",
        "N=8",
        "N=64",
        "N=1024",
        "÷eval(64)"
    );
    for m in &r.methods {
        let b = |n: usize| r_total(m, n);
        let b64 = m.batched.iter().find(|b| b.n == 64);
        let (p, sm, pd) = b64.map_or((0.0, 0.0, 0.0), |b| {
            (
                b.dispatched.prepare_ns,
                b.dispatched.sample_ns,
                b.dispatched.pdf_ns,
            )
        });
        let _ = writeln!(
            s,
            "{:<18} {:>6.0} {:>6.0} {:>6.0} ={:>5.0} | {:>6.0} {:>6.0} {:>6.0} ={:>5.0} | {:>8.0} {:>8.0} {:>8.0} {:>8.0} | {:>8.2}×",
            m.method,
            m.scalar.prepare_ns,
            m.scalar.sample_ns,
            m.scalar.pdf_ns,
            m.scalar.total_ns,
            p,
            sm,
            pd,
            p + sm + pd,
            b(1),
            b(8),
            b(64),
            b(1024),
            m.vs_material_eval
        );
    }
    let _ = writeln!(s, "\nportable path (no run-time dispatch), batched totals:");
    for m in &r.methods {
        let t: Vec<String> = m
            .batched
            .iter()
            .map(|b| format!("N={} {:.0}", b.n, b.portable.total_ns))
            .collect();
        let _ = writeln!(s, "  {:<18} {}", m.method, t.join("  "));
    }
    let nm = &r.neural_material;
    let fmt = |v: &[(usize, f64)]| {
        v.iter()
            .map(|(n, t)| format!("N={n} {t:.0}"))
            .collect::<Vec<_>>()
            .join("  ")
    };
    let _ = writeln!(
        s,
        "\nneural material: features {:.0} ns (batched {:.0}), eval {:.0} ns\n  eval batched: {}\n  eval batched, portable: {}",
        nm.features_ns,
        nm.features_batch_ns,
        nm.eval_ns,
        fmt(&nm.eval_batch_ns),
        fmt(&nm.eval_batch_portable_ns)
    );
    let d = &r.dense;
    let _ = writeln!(
        s,
        "\ndense layers (decoder at N = 1024): {:.1} G multiply-adds/s ({:.0} % of the measured peak {:.1}); portable path {:.1}",
        d.decoder_gmacs,
        100.0 * d.fraction_of_peak,
        d.peak_gmacs,
        d.decoder_gmacs_portable
    );
    s
}

fn r_total(m: &MethodCost, n: usize) -> f64 {
    m.batched
        .iter()
        .find(|b| b.n == n)
        .map_or(0.0, |b| b.dispatched.total_ns)
}
