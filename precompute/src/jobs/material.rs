//! Neural materials as jobs: fit one to a material and write its blob (`train-material`),
//! import one from safetensors (`import-material`), and measure a material's own cost
//! (`material-cost`). Every job checks the blob it writes with the runtime.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use neusample::DType;
use serde::{Deserialize, Serialize};

use crate::eval::{eval_cost, fit_report, EvalCost, FitReport};
use crate::materials::neural::safetensors::{self as st, ExportDtype};
use crate::materials::neural::{NeuralMaterialModel, NeuralParts};
use crate::materials::{self, Material};
use crate::train::neural_material::{self as nt, BlobCheck, NeuralTrainConfig};
use crate::util::io;
use crate::util::rng::Stream;
use crate::util::stats::mean;

/// Queries of the blob check (runtime vs training graph) of every written neural material.
const CHECK_QUERIES: usize = 512;
/// Random queries per pass of the cost measure.
const COST_QUERIES: usize = 20_000;
/// Passes of the cost measure (the median is reported).
const COST_PASSES: usize = 7;

/// Sizes of the fit measures of a neural material against its source ([`fit_report`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitSettings {
    /// Random queries of the RGB error measure.
    pub points: usize,
    /// Conditions of the p* KL and albedo measures.
    pub conditions: usize,
    /// Resolution of the tabulated p*.
    pub res: usize,
}

impl Default for FitSettings {
    fn default() -> Self {
        FitSettings {
            points: 20_000,
            conditions: 64,
            res: 64,
        }
    }
}

/// `train-material`: fit a neural material to `source` and write it to `out`.
#[derive(Clone, Debug)]
pub struct TrainMaterialJob {
    /// The source: a material file (TOML/JSON/.nsb) or the name of a built-in material.
    pub source: String,
    /// Where to write the neural-material blob (atomically).
    pub out: PathBuf,
    /// Also write the texture and decoder as safetensors (PyTorch layout, `NEURAL.md`).
    pub safetensors: Option<PathBuf>,
    /// Name of the neural material (default: `<source>_neural`).
    pub name: Option<String>,
    /// Storage type of the blob and the safetensors.
    pub dtype: DType,
    /// The training run.
    pub training: NeuralTrainConfig,
    /// The fit measures after training.
    pub fit: FitSettings,
}

impl TrainMaterialJob {
    /// The default run (f32, [`NeuralTrainConfig::default_run`], default measures).
    #[must_use]
    pub fn new(source: impl Into<String>, out: impl Into<PathBuf>) -> Self {
        TrainMaterialJob {
            source: source.into(),
            out: out.into(),
            safetensors: None,
            name: None,
            dtype: DType::F32,
            training: NeuralTrainConfig::default_run(),
            fit: FitSettings::default(),
        }
    }
}

/// What `train-material` reports.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainMaterialReport {
    /// Neural material name.
    pub name: String,
    /// Source material name.
    pub source: String,
    /// The configuration.
    pub config: NeuralTrainConfig,
    /// Training time, seconds.
    pub train_seconds: f64,
    /// Mean loss of the first and last 1 % of steps.
    pub loss_first: f64,
    /// See `loss_first`.
    pub loss_last: f64,
    /// Blob size in bytes.
    pub blob_bytes: usize,
    /// Core vs training graph.
    pub check: BlobCheck,
    /// Fit to the source, through core.
    pub fit: FitReport,
    /// Single-thread cost of the neural material.
    pub cost: EvalCost,
    /// Single-thread cost of the source material.
    pub source_cost: EvalCost,
}

fn print_fit(fit: &FitReport) {
    eprintln!(
        "  fit (through core): relative RGB error {:.2} % (disk) / {:.2} % (highlight region), \
         log-RMSE {:.4}, albedo error {:.2} %",
        100.0 * fit.relative_rgb_error,
        100.0 * fit.relative_rgb_error_lobe,
        fit.log_rmse,
        100.0 * fit.albedo_relative_error
    );
    eprintln!(
        "  KL(p*_source ‖ p*_neural) = {:.4} nats over {} conditions (cosine sampling: {:.4})",
        fit.kl_pstar, fit.conditions, fit.kl_pstar_vs_cosine
    );
}

fn print_cost(what: &str, c: &EvalCost) {
    eprintln!(
        "  {what}: eval {:.0} ns/call, features {:.0} ns/call (single thread)",
        c.eval_ns, c.features_ns
    );
}

/// `neusample train-material`: trains, writes the blob (and safetensors) atomically after the
/// runtime reproduced the trained model, measures the fit and the cost, prints a summary on
/// stderr and returns the report.
pub fn train_material(job: &TrainMaterialJob) -> Result<TrainMaterialReport> {
    let source = materials::resolve(&job.source)?;
    let cfg = &job.training;
    let name = job
        .name
        .clone()
        .unwrap_or_else(|| format!("{}_neural", source.name()));
    if name.chars().any(char::is_whitespace) || name.is_empty() {
        bail!("--name must be a non-empty word without spaces, got `{name}`");
    }
    let dtype = job.dtype;
    let trained = nt::train(source.as_ref(), cfg)?;
    let label = format!(
        "name={name} source={} texture={}x{} steps={} batch={} lr={} seed={} dtype={dtype:?} loss=l2-log(eps={})",
        source.name(),
        cfg.width,
        cfg.height,
        cfg.steps,
        cfg.batch,
        cfg.lr,
        cfg.seed,
        cfg.epsilon
    );
    let bytes = trained.parts.blob_bytes(dtype, &label)?;
    let check = nt::verify_blob(&bytes, CHECK_QUERIES, Stream::BlobCheck.of(cfg.seed))
        .with_context(|| format!("verifying the blob for {}", job.out.display()))?;
    io::atomic_write(&job.out, &bytes)?;
    if let Some(p) = &job.safetensors {
        write_safetensors(p, &trained.parts, dtype, &name, source.name())?;
    }
    let neural = NeuralMaterialModel::from_blob(&bytes, &name)?;
    let fit = fit_report(
        source.as_ref(),
        &neural,
        job.fit.points,
        job.fit.conditions,
        job.fit.res,
        cfg.epsilon,
        Stream::MaterialFit.of(cfg.seed),
    );
    let cost = eval_cost(&neural, COST_QUERIES, COST_PASSES);
    let source_cost = eval_cost(source.as_ref(), COST_QUERIES, COST_PASSES);
    let k = (trained.loss_history.len() / 100).max(1);
    let h = &trained.loss_history;
    let report = TrainMaterialReport {
        name,
        source: source.name().to_string(),
        config: cfg.clone(),
        train_seconds: trained.seconds,
        loss_first: mean(&h[..k.min(h.len())]),
        loss_last: mean(&h[h.len().saturating_sub(k)..]),
        blob_bytes: bytes.len(),
        check,
        fit,
        cost,
        source_cost,
    };
    eprintln!(
        "wrote {} ({} bytes, {}×{}×8 features, {:?}): trained in {:.1} s, loss {:.4} → {:.4}, \
         core matches the model to {:.1e} (features) / {:.1e} (eval)",
        job.out.display(),
        bytes.len(),
        cfg.width,
        cfg.height,
        dtype,
        trained.seconds,
        report.loss_first,
        report.loss_last,
        check.features_max_relative,
        check.eval_max_relative
    );
    print_fit(&fit);
    print_cost("neural material", &cost);
    print_cost("source material", &source_cost);
    Ok(report)
}

fn write_safetensors(
    path: &Path,
    parts: &NeuralParts,
    dtype: DType,
    name: &str,
    source: &str,
) -> Result<()> {
    let sd = match dtype {
        DType::F32 => ExportDtype::F32,
        DType::F16 => ExportDtype::F16,
        DType::U16 => anyhow::bail!("a neural material is stored as f32 or f16, not u16"),
    };
    let bytes = st::write(parts, sd, name, &[("source", source.to_string())])?;
    io::atomic_write(path, &bytes)?;
    eprintln!("wrote {} ({} bytes)", path.display(), bytes.len());
    Ok(())
}

/// `import-material`: a neural material from safetensors, written as a blob.
#[derive(Clone, Debug)]
pub struct ImportMaterialJob {
    /// The safetensors file (tensor names and shapes in `NEURAL.md`).
    pub safetensors: PathBuf,
    /// Where to write the neural-material blob (atomically).
    pub out: PathBuf,
    /// Name of the material (default: the file's `name` metadata, else its stem).
    pub name: Option<String>,
    /// Storage type of the blob.
    pub dtype: DType,
    /// Also measure the fit against this material (file or built-in name).
    pub source: Option<String>,
}

/// What `import-material` reports.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ImportReport {
    /// Material name.
    pub name: String,
    /// Texture width and height.
    pub texture: (u32, u32),
    /// Tensors of the file that were not used.
    pub ignored: Vec<String>,
    /// Blob size in bytes.
    pub blob_bytes: usize,
    /// Core vs the imported arrays through the burn graph.
    pub check: BlobCheck,
    /// Fit to `--source`, when given.
    pub fit: Option<FitReport>,
    /// Single-thread cost.
    pub cost: EvalCost,
}

/// `neusample import-material`: reads the safetensors, writes the blob atomically after the
/// runtime reproduced the imported arrays, measures the fit (with a source) and the cost.
pub fn import_material(job: &ImportMaterialJob) -> Result<ImportReport> {
    let imported = st::read_file(&job.safetensors)?;
    let stem = job
        .safetensors
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("imported");
    let name = job
        .name
        .clone()
        .or_else(|| imported.metadata.get("name").cloned())
        .unwrap_or_else(|| stem.to_string());
    let name: String = name
        .chars()
        .map(|c| if c.is_whitespace() { '_' } else { c })
        .collect();
    if !imported.ignored.is_empty() {
        eprintln!(
            "warning: ignoring {} tensor(s) not part of a neural material: {}",
            imported.ignored.len(),
            imported.ignored.join(", ")
        );
    }
    let dtype = job.dtype;
    let p = &imported.parts;
    let label = format!(
        "name={name} imported={} texture={}x{} dtype={dtype:?}",
        job.safetensors
            .file_name()
            .and_then(|s| s.to_str())
            .unwrap_or("?")
            .replace(char::is_whitespace, "_"),
        p.width,
        p.height
    );
    let bytes = p.blob_bytes(dtype, &label)?;
    let check = nt::verify_blob(&bytes, CHECK_QUERIES, 0x1A9)
        .with_context(|| format!("verifying the blob for {}", job.out.display()))?;
    io::atomic_write(&job.out, &bytes)?;
    let neural = NeuralMaterialModel::from_blob(&bytes, &name)?;
    let fit = match &job.source {
        Some(s) => {
            let source = materials::resolve(s)?;
            let f = FitSettings::default();
            let epsilon = NeuralTrainConfig::default_run().epsilon;
            Some(fit_report(
                source.as_ref(),
                &neural,
                f.points,
                f.conditions,
                f.res,
                epsilon,
                0xF17,
            ))
        }
        None => None,
    };
    let cost = eval_cost(&neural, COST_QUERIES, COST_PASSES);
    eprintln!(
        "wrote {} ({} bytes, {}×{}×8 features, {:?}); core matches the imported model to \
         {:.1e} (features) / {:.1e} (eval)",
        job.out.display(),
        bytes.len(),
        p.width,
        p.height,
        dtype,
        check.features_max_relative,
        check.eval_max_relative
    );
    if let Some(f) = &fit {
        print_fit(f);
    }
    print_cost("neural material", &cost);
    Ok(ImportReport {
        name,
        texture: (p.width, p.height),
        ignored: imported.ignored.clone(),
        blob_bytes: bytes.len(),
        check,
        fit,
        cost,
    })
}

/// What `material-cost --json` prints.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MaterialCostReport {
    /// Material name.
    pub material: String,
    /// `eval(φ, wi, wo)`, ns per call.
    pub eval_ns: f64,
    /// `features(uv)`, ns per call.
    pub features_ns: f64,
}

/// `neusample material-cost`: single-thread ns per `eval` and per `features` call of a
/// material (the denominator of the paper's Table 1 ratio), the median of `passes` passes
/// over `n` random queries.
pub fn material_cost(material: &dyn Material, n: usize, passes: usize) -> MaterialCostReport {
    let c = eval_cost(material, n, passes);
    MaterialCostReport {
        material: material.name().to_string(),
        eval_ns: c.eval_ns,
        features_ns: c.features_ns,
    }
}
