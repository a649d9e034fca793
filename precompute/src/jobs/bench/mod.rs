//! `neusample bench`: the runtime's cost per shading point, measured as a renderer calls it.
//!
//! For every sampler blob of a material folder (the committed fixtures by default) and the
//! neural material, single-threaded: ns per shading point of `prepare`, `sample` and `pdf`
//! through the scalar API and through the batched API at N = 1, 8, 64 and 1024 lanes, for
//! the run-time chosen instruction set and the portable path; the neural material's
//! `features` and `eval` likewise; the decoder's dense layers in multiply-adds per second
//! next to this CPU's measured multiply-add peak; and the same network shapes through a kept
//! GEMM library ([`library`]), whose large product also checks the peak estimate. Figures are
//! medians over passes; the machine should be otherwise idle. Nothing here is an assertion.

pub mod library;

use std::fmt::Write;
use std::hint::black_box;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use neusample::wavefront::{self, BatchSampler, Isa, RgbMut};
use neusample::{Blob, NeuralMaterial, Sampler, Tensor, TensorRole, Vec3, Weights};
use serde::{Deserialize, Serialize};

use crate::bake;
use crate::eval::cost::{self, batched_split, scalar_split, time_per, Inputs, Rows, Split};
use crate::materials::neural::NeuralMaterialModel;
use neusample::wavefront::SamplerVisitor;

/// The batch sizes measured.
pub const BATCH_SIZES: [usize; 4] = [1, 8, 64, 1024];

/// Multiply-adds of one decoder evaluation (`core/ARCHITECTURES.md` §7: 14→64→64→64→3).
const DECODER_MACS: f64 = {
    use neusample::neural_material::{DECODER_HIDDEN as H, DECODER_INPUTS, DECODER_OUTPUTS};
    (DECODER_INPUTS * H + 2 * H * H + H * DECODER_OUTPUTS) as f64
};

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
    /// Only these sampler methods (blob file stems); empty: every blob of the folder.
    pub methods: Vec<String>,
    /// A measured material (RGL `.bsdf`) whose eval and own sampler are measured too.
    pub measured: Option<PathBuf>,
    /// The instruction set of the dispatched figures; `None`: the best this CPU has.
    pub isa: Option<Isa>,
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
            methods: Vec::new(),
            measured: Some(root.join("measured/chm_mint_rgb.bsdf")),
            isa: None,
        }
    }
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
    /// The method (blob file stem; with ` α=…` for a blob with a defensive weight, and
    /// ` α=0` for its learned part alone).
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

/// A measured material's figures, ns per shading point, each with its own `prepare(wi)`:
/// the scalar path, and the batched one per batch size.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct MeasuredCost {
    /// The `.bsdf` file.
    pub file: String,
    /// `prepare` alone.
    pub prepare_ns: f64,
    /// `prepare` + `eval(wo)` (f, no cosine).
    pub eval_ns: f64,
    /// `prepare` + `pdf(wo)` of the data's sampler.
    pub pdf_ns: f64,
    /// `prepare` + `sample(u)` (direction, pdf and weight).
    pub sample_ns: f64,
    /// The batched path per batch size (N = 64, 1024), `(N, eval, pdf, sample)` in ns per
    /// lane, each with its prepare; empty in reports written before it existed.
    #[serde(default)]
    pub batched: Vec<MeasuredBatched>,
}

/// The measured material's batched calls at one batch size, ns per lane.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct MeasuredBatched {
    /// Lanes per call.
    pub n: usize,
    /// `eval_batch`.
    pub eval_ns: f64,
    /// `pdf_batch`.
    pub pdf_ns: f64,
    /// `sample_batch` (directions, densities and weights).
    pub sample_ns: f64,
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
    /// The same peak measurement on AVX2 + FMA vectors (x86-64-v3), where this CPU has them:
    /// the ceiling of a library whose widest kernels are AVX2 + FMA.
    #[serde(default)]
    pub peak_gmacs_x86_v3: Option<f64>,
}

/// The machine a report was measured on.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Machine {
    /// The CPU's model name (Linux's `/proc/cpuinfo`), or the architecture where unknown.
    pub cpu: String,
    /// The architecture (`x86_64`, `aarch64`).
    pub arch: String,
    /// The vector extensions the CPU reports that the runtime's kernels may use.
    pub features: Vec<String>,
    /// Logical CPUs (the bench uses one thread).
    pub threads: usize,
}

impl Machine {
    /// This machine.
    #[must_use]
    pub fn this() -> Self {
        let cpu = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find(|l| l.starts_with("model name"))
                    .and_then(|l| l.split_once(':'))
                    .map(|(_, v)| v.trim().to_string())
            })
            .unwrap_or_else(|| std::env::consts::ARCH.to_string());
        #[allow(unused_mut)]
        let mut features = Vec::new();
        #[cfg(target_arch = "x86_64")]
        for (name, has) in [
            ("avx2", std::arch::is_x86_feature_detected!("avx2")),
            ("fma", std::arch::is_x86_feature_detected!("fma")),
            ("avx512f", std::arch::is_x86_feature_detected!("avx512f")),
        ] {
            if has {
                features.push(name.to_string());
            }
        }
        #[cfg(target_arch = "aarch64")]
        if std::arch::is_aarch64_feature_detected!("neon") {
            features.push("neon".to_string());
        }
        Self {
            cpu,
            arch: std::env::consts::ARCH.to_string(),
            features,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        }
    }

    /// `"AMD EPYC (x86_64: avx2 fma), 2 threads"`.
    #[must_use]
    pub fn describe(&self) -> String {
        format!(
            "{} ({}: {}), {} threads",
            self.cpu,
            self.arch,
            self.features.join(" "),
            self.threads
        )
    }
}

/// Everything `neusample bench` measures (`--json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct BenchReport {
    /// Where it was measured.
    pub machine: Machine,
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
    /// The measured material (absent in reports written before it was measured).
    #[serde(default)]
    pub measured: Option<MeasuredCost>,
    /// The dense layers.
    pub dense: DenseThroughput,
    /// The histogram mixture's table layouts (when the folder has one).
    pub tables: Option<TableLayouts>,
    /// The network shapes through a GEMM library, and the peak check.
    pub library: library::LibraryReference,
}

/// One table layout of the folder's histogram mixture.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LayoutCost {
    /// `values` (f32 densities + f32 running sums) or `compact` (u16 row CDFs).
    pub layout: String,
    /// Bytes of the four or five table tensors.
    pub table_bytes: usize,
    /// Batched prepare + sample + pdf at N = 64 (dispatched), ns per shading point.
    pub batched: Split,
    /// Mean KL(p* ‖ p) against the neural material's ground truth, nats.
    pub kl: f64,
}

/// The row search of the compact tables: the binary search the sampler runs against a guide
/// table (pbrt's `PiecewiseConstant1D` shortcut: per row, the first cell of each of N equal
/// slices of the CDF, then a short linear scan). An alias table would be O(1) too but is not
/// monotone, so it would break `invert` and stratification; it is not a candidate.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RowSearch {
    /// Cells per row.
    pub resolution: usize,
    /// Binary search over the u16 row CDF, ns per lookup.
    pub binary_ns: f64,
    /// Guide table + linear scan, ns per lookup.
    pub guide_ns: f64,
}

/// The histogram mixture in both table layouts, or in the compact one alone.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TableLayouts {
    /// `values` and `compact`, or `compact` alone.
    pub layouts: Vec<LayoutCost>,
    /// Conditions of the KL figures (each tabulated at 64², 2 × 2 points per cell).
    pub kl_conditions: usize,
    /// Row search, on the compact tables' rows.
    pub search: RowSearch,
}

/// Conditions of the table layouts' KL figures.
const KL_CONDITIONS: usize = 64;

/// Bytes of the histogram-mixture table tensors of `blob`.
fn table_bytes(blob: &Blob<'_>) -> usize {
    [
        TensorRole::Mass,
        TensorRole::Table,
        TensorRole::Marginal,
        TensorRole::Conditional,
    ]
    .into_iter()
    .filter_map(|r| blob.tensor(r))
    .map(|t| t.len() as usize * t.dtype().size())
    .sum()
}

/// The folder's histogram mixture in both layouts (`None` without one); a blob that is
/// already compact has lost its values and is measured alone.
fn table_layouts(cfg: &BenchConfig, rows: &Rows) -> Result<Option<TableLayouts>> {
    let path = cfg.blobs.join("histogram-mixture.nsb");
    let Ok(stored) = std::fs::read(&path) else {
        return Ok(None);
    };
    let compact_only = Blob::open(&stored)
        .with_context(|| path.display().to_string())?
        .is_compact();
    let candidates = if compact_only {
        vec![("compact", stored)]
    } else {
        let compact = bake::compact_blob(&stored)?;
        vec![("values", stored), ("compact", compact)]
    };
    let material = NeuralMaterialModel::load(&cfg.material)?;
    let mut layouts = Vec::new();
    let mut search = None;
    for (layout, bytes) in &candidates {
        let blob = Blob::open(bytes).with_context(|| format!("{layout} tables"))?;
        let s = blob.sampler()?;
        let batched = s.visit(BatchedAt {
            rows,
            n: 64,
            passes: cfg.passes,
        });
        let fit = crate::eval::fit(&s, &material, KL_CONDITIONS, 64, 0xF17);
        layouts.push(LayoutCost {
            layout: layout.to_string(),
            table_bytes: table_bytes(&blob),
            batched,
            kl: fit.kl_divergence,
        });
        if blob.is_compact() {
            search = Some(row_search(&blob, cfg.passes)?);
        }
    }
    Ok(Some(TableLayouts {
        layouts,
        kl_conditions: KL_CONDITIONS,
        search: search.context("no compact tables")?,
    }))
}

/// [`batched_split`] at one batch size through the concrete sampler type.
struct BatchedAt<'r> {
    rows: &'r Rows,
    n: usize,
    passes: usize,
}

impl SamplerVisitor for BatchedAt<'_> {
    type Output = Split;
    fn visit<S: Sampler + BatchSampler + Copy + Sync>(self, s: S) -> Split
    where
        S::Lane: Send,
    {
        batched_split(&s, self.rows, self.n, self.passes)
    }
}

/// Times [`RowSearch`] on the compact blob's row CDFs.
fn row_search(blob: &Blob<'_>, passes: usize) -> Result<RowSearch> {
    let t = blob
        .tensor(TensorRole::Conditional)
        .context("no conditional tensor")?;
    let n = blob.header().resolution as usize;
    let cdf: Vec<u16> = (0..t.len()).map(|i| t.at(i) as u16).collect();
    let rows: Vec<&[u16]> = cdf
        .chunks_exact(n)
        .filter(|r| r.last() == Some(&u16::MAX))
        .collect();
    if rows.is_empty() {
        bail!("the compact tables have no non-empty row");
    }
    // Guides: for slice g of N, the first cell whose CDF exceeds g/N of the row.
    let guides: Vec<Vec<u16>> = rows
        .iter()
        .map(|r| {
            (0..n)
                .map(|g| {
                    let target = (g as u64 * u64::from(u16::MAX) / n as u64) as u16;
                    r.partition_point(|&c| c <= target) as u16
                })
                .collect()
        })
        .collect();
    // Lookups: a fixed sequence of (row, target).
    let lookups: Vec<(usize, u16)> = (0..1usize << 16)
        .map(|i| {
            let h = crate::util::rng::splitmix64(i as u64);
            ((h >> 32) as usize % rows.len(), h as u16)
        })
        .collect();
    let binary_ns = time_per(passes, lookups.len(), || {
        for &(r, x) in &lookups {
            black_box(rows[r].partition_point(|&c| c <= x));
        }
    });
    let guide_ns = time_per(passes, lookups.len(), || {
        for &(r, x) in &lookups {
            let row = rows[r];
            let g = (usize::from(x) * n) >> 16;
            let mut i = usize::from(guides[r][g]);
            while i + 1 < n && row[i] <= x {
                i += 1;
            }
            black_box(i);
        }
    });
    Ok(RowSearch {
        resolution: n,
        binary_ns,
        guide_ns,
    })
}

/// The folder's conditions (`conditions.txt`: φ then wi per line).
fn read_conditions(blobs: &Path) -> Result<Vec<([f32; 8], Vec3)>> {
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
    Ok(base)
}

/// Both splits of a concrete sampler type at every batch size.
struct BatchedAll<'r> {
    rows: &'r Rows,
    passes: usize,
    isa: Option<Isa>,
}

impl SamplerVisitor for BatchedAll<'_> {
    type Output = Vec<Batched>;
    fn visit<S: Sampler + BatchSampler + Copy + Sync>(self, s: S) -> Vec<Batched>
    where
        S::Lane: Send,
    {
        BATCH_SIZES
            .iter()
            .map(|&n| {
                wavefront::prefer_isa(Some(Isa::Portable));
                let portable = batched_split(&s, self.rows, n, self.passes);
                wavefront::prefer_isa(self.isa);
                let dispatched = batched_split(&s, self.rows, n, self.passes);
                Batched {
                    n,
                    dispatched,
                    portable,
                }
            })
            .collect()
    }
}

/// `eval_batch` of the neural material, ns per lane at `n` lanes per call.
fn eval_batch_ns(m: &NeuralMaterial<Tensor<'_>>, rows: &Rows, n: usize, passes: usize) -> f64 {
    cost::eval_batch_ns(
        |phi, wi, wo, out| m.eval_batch(phi, wi, wo, out).expect("lengths agree"),
        rows,
        n,
        passes,
    )
}

/// Independent multiply-add chains on one instruction set's widest vectors: the peak loop.
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

/// The measured multiply-add peak of one core, 10⁹/s, through `run` (which calls [`Peak`]
/// on some instruction set): independent multiply-add chains on its widest vectors.
fn peak_of(passes: usize, run: impl Fn(Peak) -> (f32, usize)) -> f64 {
    let iters = 2_000_000u64;
    let width = run(Peak(1)).1;
    let ns = time_per(passes, 1, || {
        black_box(run(Peak(black_box(iters))));
    });
    (iters * 12 * width as u64) as f64 / ns
}

/// [`peak_of`] on the run-time chosen instruction set.
fn peak_gmacs(passes: usize) -> f64 {
    let arch = pulp::Arch::new();
    peak_of(passes, |p| arch.dispatch(p))
}

/// [`peak_of`] on AVX2 + FMA (`None` where this CPU lacks them).
fn peak_gmacs_x86_v3(passes: usize) -> Option<f64> {
    #[cfg(target_arch = "x86_64")]
    {
        pulp::x86::V3::try_new().map(|v3| peak_of(passes, |p| pulp::Simd::vectorize(v3, p)))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = passes;
        None
    }
}

/// Makes the batched kernels run with `isa` (the best available for `None`); an error names
/// an instruction set this CPU lacks.
fn use_isa(isa: Option<Isa>) -> Result<()> {
    if let Some(i) = isa {
        if !i.is_available() {
            bail!("this CPU cannot run the instruction set {}", i.name());
        }
    }
    wavefront::prefer_isa(isa);
    Ok(())
}

/// Runs the benchmark.
pub fn run(cfg: &BenchConfig) -> Result<BenchReport> {
    check_methods(cfg)?;
    use_isa(cfg.isa)?;
    let inp = Inputs::cycling(&read_conditions(&cfg.blobs)?, cfg.lanes_per_pass.max(1));
    let rows = Rows::new(&inp);
    let passes = cfg.passes;
    let mbytes = std::fs::read(&cfg.material)
        .with_context(|| format!("reading {}", cfg.material.display()))?;
    let mblob = Blob::open(&mbytes).with_context(|| cfg.material.display().to_string())?;
    let m = mblob
        .neural_material()
        .with_context(|| cfg.material.display().to_string())?;

    let neural_material = material_cost(&m, &inp, &rows, passes, cfg.isa);
    let at = |v: &[(usize, f64)], n: usize| v.iter().find(|x| x.0 == n).map_or(0.0, |x| x.1);
    let eval_batch = &neural_material.eval_batch_ns;
    let decoder_gmacs = DECODER_MACS / at(eval_batch, 1024);
    let decoder_gmacs_portable = DECODER_MACS / at(&neural_material.eval_batch_portable_ns, 1024);
    let peak = peak_gmacs(passes);
    let measured = match &cfg.measured {
        Some(path) => Some(measured_cost(path, &inp, passes)?),
        None => None,
    };

    let methods = sampler_costs(cfg, &inp, &rows, at(eval_batch, 64))?;
    Ok(BenchReport {
        machine: Machine::this(),
        blobs: cfg.blobs.display().to_string(),
        material: cfg.material.display().to_string(),
        isa: wavefront::current_isa().name().to_string(),
        methods,
        neural_material,
        measured,
        dense: DenseThroughput {
            decoder_gmacs,
            decoder_gmacs_portable,
            peak_gmacs: peak,
            fraction_of_peak: decoder_gmacs / peak,
            peak_gmacs_x86_v3: peak_gmacs_x86_v3(passes),
        },
        tables: table_layouts(cfg, &rows)?,
        library: library::run(cfg.lanes_per_pass, passes),
    })
}

/// The neural material's feature lookup and eval, scalar and batched (on the chosen
/// instruction set and portably) at every batch size.
fn material_cost(
    m: &NeuralMaterial<Tensor<'_>>,
    inp: &Inputs,
    rows: &Rows,
    passes: usize,
    isa: Option<Isa>,
) -> MaterialCost {
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
    let features_batch_ns = cost::features_batch_ns(
        |uv, phi| m.features_batch(uv, phi).expect("lengths agree"),
        rows,
        rows.len(),
        passes,
    );
    let mut eval_batch = Vec::new();
    let mut eval_portable = Vec::new();
    for &n in &BATCH_SIZES {
        wavefront::prefer_isa(Some(Isa::Portable));
        eval_portable.push((n, eval_batch_ns(m, rows, n, passes)));
        wavefront::prefer_isa(isa);
        eval_batch.push((n, eval_batch_ns(m, rows, n, passes)));
    }
    MaterialCost {
        features_ns,
        eval_ns,
        features_batch_ns,
        eval_batch_ns: eval_batch,
        eval_batch_portable_ns: eval_portable,
    }
}

/// Every sampler blob of `cfg.blobs` (the `--methods` among them), scalar and batched; a
/// blob with a defensive weight also with its learned part alone. `eval64`: the material's
/// batched eval at N = 64, the ratio's denominator.
fn sampler_costs(
    cfg: &BenchConfig,
    inp: &Inputs,
    rows: &Rows,
    eval64: f64,
) -> Result<Vec<MethodCost>> {
    let passes = cfg.passes;
    let mut methods = Vec::new();
    // The sampler blobs, by kind name (`<method>.nsb`), in `SamplerKind::ALL` order.
    for method in neusample::SamplerKind::ALL.map(neusample::SamplerKind::name) {
        if !cfg.methods.is_empty() && !cfg.methods.iter().any(|m| m == method) {
            continue;
        }
        let path = cfg.blobs.join(format!("{method}.nsb"));
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(_) if method == "cosine" => neusample::BlobWriter::new(
                neusample::SamplerKind::Cosine,
                neusample::DType::F32,
                "cosine",
            )
            .to_bytes(),
            // Trained on the integrand: only the folders of neural materials have one.
            Err(_) if method == neusample::SamplerKind::Reparam.name() => continue,
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        };
        let blob = Blob::open(&bytes).with_context(|| path.display().to_string())?;
        let s = blob.sampler().with_context(|| path.display().to_string())?;
        // A blob with a defensive weight is measured as stored and, beside it, its learned
        // part alone (α = 0): the mixture's own cost in the same run.
        let mut variants = vec![(method.to_string(), s)];
        if s.is_mixed() {
            variants[0].0 = format!("{method} α={}", s.alpha());
            variants.push((
                format!("{method} α=0"),
                neusample::Defensive::plain(*s.inner()).with_isotropic(s.is_isotropic()),
            ));
        }
        for (name, s) in variants {
            let scalar = scalar_split(&s, inp, passes);
            let batched = s.visit(BatchedAll {
                rows,
                passes,
                isa: cfg.isa,
            });
            let b64 = batched
                .iter()
                .find(|b| b.n == 64)
                .map_or(0.0, |b| b.dispatched.total_ns);
            methods.push(MethodCost {
                method: name,
                scalar,
                batched,
                vs_material_eval: b64 / eval64,
            });
        }
    }
    Ok(methods)
}

/// The measured material at `path` over the bench's conditions (their `wi`, `wo` and `u`).
fn measured_cost(path: &Path, inp: &Inputs, passes: usize) -> Result<MeasuredCost> {
    let data = neusample_owned::measured::OwnedMeasured::open(path)?;
    let m = data.material();
    let n = inp.conds.len();
    let prepare_ns = time_per(passes, n, || {
        for (_, wi) in &inp.conds {
            black_box(m.prepare(*wi));
        }
    });
    let eval_ns = time_per(passes, n, || {
        for ((_, wi), wo) in inp.conds.iter().zip(&inp.wos) {
            black_box(m.prepare(*wi).map(|p| p.eval(*wo)));
        }
    });
    let pdf_ns = time_per(passes, n, || {
        for ((_, wi), wo) in inp.conds.iter().zip(&inp.wos) {
            black_box(m.prepare(*wi).map(|p| p.pdf(*wo)));
        }
    });
    let sample_ns = time_per(passes, n, || {
        for ((_, wi), u) in inp.conds.iter().zip(&inp.us) {
            black_box(m.prepare(*wi).and_then(|p| p.sample(*u)));
        }
    });
    let rows = Rows::new(inp);
    let batched = [64, 1024]
        .into_iter()
        .map(|b| measured_batched(m, &rows, b, passes))
        .collect();
    Ok(MeasuredCost {
        file: path.display().to_string(),
        prepare_ns,
        eval_ns,
        pdf_ns,
        sample_ns,
        batched,
    })
}

/// The measured material's batched eval, pdf and sample at `n` lanes per call.
fn measured_batched(
    m: &neusample::MeasuredMaterial<Vec<f32>>,
    rows: &Rows,
    n: usize,
    passes: usize,
) -> MeasuredBatched {
    let total = rows.len();
    let eval_ns = cost::eval_batch_ns(
        |_, wi, wo, out| m.eval_batch(wi, wo, out).expect("lengths agree"),
        rows,
        n,
        passes,
    );
    let mut pdf = vec![0.0f32; total];
    let pdf_ns = time_per(passes, total, || {
        for (a, b) in rows.calls(n) {
            m.pdf_batch(rows.wi.at(a, b), rows.wo.at(a, b), &mut pdf[a..b])
                .expect("lengths agree");
        }
    });
    let mut out = vec![0.0f32; 8 * total];
    let sample_ns = time_per(passes, total, || {
        let mut cols = out.chunks_exact_mut(total);
        let mut col = || cols.next().expect("eight columns");
        let (x, y, z, p, q) = (col(), col(), col(), col(), col());
        let (r, g, bl) = (col(), col(), col());
        for (a, b) in rows.calls(n) {
            let samples = neusample::wavefront::SamplesMut {
                wo: neusample::wavefront::Vec3sMut {
                    x: &mut x[a..b],
                    y: &mut y[a..b],
                    z: &mut z[a..b],
                },
                pdf: &mut p[a..b],
                mis_pdf: &mut q[a..b],
            };
            let weight = RgbMut {
                r: &mut r[a..b],
                g: &mut g[a..b],
                b: &mut bl[a..b],
            };
            m.sample_batch(rows.wi.at(a, b), rows.u.at(a, b), samples, weight)
                .expect("lengths agree");
        }
    });
    MeasuredBatched {
        n,
        eval_ns,
        pdf_ns,
        sample_ns,
    }
}

/// The `--methods` name of the neural material in a profiling run ([`profile`]).
pub const PROFILE_MATERIAL: &str = "material";
/// The `--methods` name of the measured material (`--measured`) in a profiling run: its
/// batched eval, pdf and sample at N = 64.
pub const PROFILE_MEASURED: &str = "measured";

/// Refuses a method name that is no sampler kind's.
fn check_methods(cfg: &BenchConfig) -> Result<()> {
    let names = neusample::SamplerKind::ALL.map(neusample::SamplerKind::name);
    if let Some(bad) = cfg.methods.iter().find(|m| !names.contains(&m.as_str())) {
        bail!("unknown method `{bad}` (methods: {})", names.join(", "));
    }
    Ok(())
}

/// A profiling run: the batched API at N = 64 (run-time chosen instruction set) of each of
/// `cfg.methods` (at least one), `prepare`, `sample` and `pdf` over the bench's conditions,
/// repeated for `seconds` per method and nothing else, so that a sampling profiler (`perf
/// record -g -- neusample bench --methods M --profile-seconds S`) sees only the hot path.
/// The method [`PROFILE_MATERIAL`] profiles the neural material's batched `eval` at N = 64,
/// [`PROFILE_MEASURED`] the measured material's batched calls.
/// Returns the passes made per method.
pub fn profile(cfg: &BenchConfig, seconds: f64) -> Result<Vec<(String, usize)>> {
    if cfg.methods.is_empty() {
        bail!("a profile needs --methods");
    }
    use_isa(cfg.isa)?;
    let samplers = BenchConfig {
        methods: (cfg.methods.iter())
            .filter(|m| *m != PROFILE_MATERIAL && *m != PROFILE_MEASURED)
            .cloned()
            .collect(),
        ..cfg.clone()
    };
    if !samplers.methods.is_empty() {
        check_methods(&samplers)?;
    }
    let inp = Inputs::cycling(&read_conditions(&cfg.blobs)?, cfg.lanes_per_pass.max(1));
    let rows = Rows::new(&inp);
    let mut done = Vec::new();
    for method in &cfg.methods {
        if method == PROFILE_MEASURED {
            let path = (cfg.measured.as_ref()).context("profiling `measured` needs --measured")?;
            let data = neusample_owned::measured::OwnedMeasured::open(path)?;
            let start = std::time::Instant::now();
            let mut passes = 0;
            while start.elapsed().as_secs_f64() < seconds {
                measured_batched(data.material(), &rows, 64, 1);
                passes += 1;
            }
            done.push((method.clone(), passes));
            continue;
        }
        if method == PROFILE_MATERIAL {
            let bytes = std::fs::read(&cfg.material)
                .with_context(|| format!("reading {}", cfg.material.display()))?;
            let blob = Blob::open(&bytes).with_context(|| cfg.material.display().to_string())?;
            let m = (blob.neural_material()).with_context(|| cfg.material.display().to_string())?;
            let start = std::time::Instant::now();
            let mut passes = 0;
            while start.elapsed().as_secs_f64() < seconds {
                eval_batch_ns(&m, &rows, 64, 1);
                passes += 1;
            }
            done.push((method.clone(), passes));
            continue;
        }
        let path = cfg.blobs.join(format!("{method}.nsb"));
        let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
        let blob = Blob::open(&bytes).with_context(|| path.display().to_string())?;
        let s = blob.sampler().with_context(|| path.display().to_string())?;
        let start = std::time::Instant::now();
        let mut passes = 0;
        while start.elapsed().as_secs_f64() < seconds {
            s.visit(BatchedAt {
                rows: &rows,
                n: 64,
                passes: 1,
            });
            passes += 1;
        }
        done.push((method.clone(), passes));
    }
    Ok(done)
}

/// The report as text tables.
#[must_use]
pub fn text(r: &BenchReport) -> String {
    let mut s = String::new();
    sampler_table(&mut s, r);
    material_lines(&mut s, r);
    dense_lines(&mut s, r);
    if let Some(t) = &r.tables {
        table_layout_lines(&mut s, t);
    }
    s
}

/// Every sampler's scalar and batched costs, on the chosen instruction set and portably.
fn sampler_table(s: &mut String, r: &BenchReport) {
    let _ = writeln!(
        s,
        "neusample bench — {} (instruction set: {}), ns per shading point, single thread, medians",
        r.blobs, r.isa
    );
    let _ = writeln!(s, "machine: {}", r.machine.describe());
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
}

/// The neural and measured materials' costs.
fn material_lines(s: &mut String, r: &BenchReport) {
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
    if let Some(mc) = &r.measured {
        let _ = writeln!(
            s,
            "\nmeasured material {} (scalar, each with its prepare): prepare {:.0} ns, eval {:.0} ns, data's sampler pdf {:.0} ns, sample {:.0} ns",
            mc.file, mc.prepare_ns, mc.eval_ns, mc.pdf_ns, mc.sample_ns
        );
        for b in &mc.batched {
            let _ = writeln!(
                s,
                "  batched N={}: eval {:.0} ns, pdf {:.0} ns, sample {:.0} ns",
                b.n, b.eval_ns, b.pdf_ns, b.sample_ns
            );
        }
    }
}

/// The dense layers' throughput against the peak and against a GEMM library.
fn dense_lines(s: &mut String, r: &BenchReport) {
    let d = &r.dense;
    let _ = writeln!(
        s,
        "\ndense layers: the decoder's whole eval at N = 1024 {:.1} G multiply-adds/s ({:.0} % of the measured peak {:.1}; its layers alone below, \"runtime kernel\"); portable path {:.1}",
        d.decoder_gmacs,
        100.0 * d.fraction_of_peak,
        d.peak_gmacs,
        d.decoder_gmacs_portable
    );
    let lib = &r.library;
    let _ = writeln!(
        s,
        "\nlibrary reference: {} (ns per point; 10⁹ multiply-adds/s)",
        lib.library
    );
    for n in &lib.networks {
        let cells: Vec<String> = n
            .ns_per_point
            .iter()
            .map(|&(b, ns)| format!("N={b} {ns:.0} ns ({:.1} G/s)", n.gmacs(b)))
            .collect();
        let _ = writeln!(
            s,
            "  {:<24} {:<18} {:>5} MACs  {}",
            n.network,
            n.widths,
            n.macs,
            cells.join("  ")
        );
    }
    let ours = &lib.runtime_decoder;
    let cells: Vec<String> = ours
        .ns_per_point
        .iter()
        .map(|&(b, ns)| {
            let g = ours.gmacs(b);
            format!(
                "N={b} {ns:.0} ns ({g:.1} G/s, {:.0} % of peak)",
                100.0 * g / d.peak_gmacs
            )
        })
        .collect();
    let _ = writeln!(
        s,
        "  {:<24} {:<18} {:>5} MACs  {}",
        "decoder, runtime kernel",
        ours.widths,
        ours.macs,
        cells.join("  ")
    );
    if let Some(dec) = lib.networks.first() {
        let ratio = |b: usize| ours.gmacs(b) / dec.gmacs(b);
        let _ = writeln!(
            s,
            "  runtime kernel ÷ library, decoder throughput: N=64 {:.2}×, N=1024 {:.2}×",
            ratio(64),
            ratio(1024)
        );
    }
    let [lm, lk, ln] = lib.large_shape;
    let v3 = d.peak_gmacs_x86_v3.map_or(String::new(), |p| {
        format!(
            ", {:.0} % of the AVX2 + FMA peak {p:.1}",
            100.0 * lib.large_gmacs / p
        )
    });
    let _ = writeln!(
        s,
        "  peak check, {lm}×{lk} by {lk}×{ln}: {:.1} G/s = {:.0} % of the measured peak {:.1}{v3}{}",
        lib.large_gmacs,
        100.0 * lib.large_gmacs / d.peak_gmacs,
        d.peak_gmacs,
        if lib.large_gmacs > d.peak_gmacs {
            "  — ABOVE the peak estimate: the estimate is wrong"
        } else {
            ""
        }
    );
}

/// The histogram mixture's table layouts and row searches.
fn table_layout_lines(s: &mut String, t: &TableLayouts) {
    let _ = writeln!(
        s,
        "\nhistogram mixture, table layouts (batched N = 64; KL over {} conditions):",
        t.kl_conditions
    );
    for l in &t.layouts {
        let _ = writeln!(
            s,
            "  {:<8} tables {:>9} B  prepare {:.0}  sample {:.0}  pdf {:.0}  total {:.0} ns  KL {:.4}",
            l.layout,
            l.table_bytes,
            l.batched.prepare_ns,
            l.batched.sample_ns,
            l.batched.pdf_ns,
            l.batched.total_ns,
            l.kl
        );
    }
    let _ = writeln!(
        s,
        "  row search ({} cells): binary {:.1} ns, guide table {:.1} ns per lookup",
        t.search.resolution, t.search.binary_ns, t.search.guide_ns
    );
}

fn r_total(m: &MethodCost, n: usize) -> f64 {
    m.batched
        .iter()
        .find(|b| b.n == n)
        .map_or(0.0, |b| b.dispatched.total_ns)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_method_lists_are_refused_before_any_work() {
        let mut cfg = BenchConfig::fixtures();
        cfg.methods = vec!["flow".into(), "flwo".into()];
        let e = run(&cfg).unwrap_err().to_string();
        assert!(e.contains("unknown method `flwo`"), "{e}");
        let e = profile(&cfg, 1.0).unwrap_err().to_string();
        assert!(e.contains("unknown method `flwo`"), "{e}");
        let e = profile(&BenchConfig::fixtures(), 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--methods"), "{e}");
    }

    #[test]
    fn the_measured_material_is_timed_and_a_bad_file_named() {
        let cfg = BenchConfig::fixtures();
        let inp = Inputs::cycling(&read_conditions(&cfg.blobs).unwrap(), 256);
        let path = cfg.measured.expect("the default measures the mint");
        let m = measured_cost(&path, &inp, 1).unwrap();
        for v in [m.prepare_ns, m.eval_ns, m.pdf_ns, m.sample_ns] {
            assert!(v.is_finite() && v > 0.0, "{m:?}");
        }
        let bad = path.with_file_name("no_such_rgb.bsdf");
        let e = format!("{:#}", measured_cost(&bad, &inp, 1).unwrap_err());
        assert!(e.contains("no_such_rgb.bsdf"), "{e}");
    }
}
