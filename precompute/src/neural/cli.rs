//! The neural-material subcommands of the `neusample` tool: `train-material`,
//! `import-material` and `material-cost` (`NEURAL.md`).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use neusample::DType;
use serde::Serialize;

use super::safetensors::{self as st, ExportDtype};
use super::train::{self as nt, BlobCheck, FitReport, NeuralTrainConfig};
use super::{eval_cost, EvalCost, NeuralMaterialModel, NeuralParts};
use crate::demo::resolve_material;
use crate::io;
use crate::materials::Material;

/// Arguments of `neusample train-material`.
#[derive(Args, Debug, Clone)]
pub struct TrainMaterialArgs {
    /// The source: a material file (TOML/JSON/.nsb) or the name of a built-in material.
    #[arg(long)]
    pub material: String,
    /// Where to write the neural-material blob (atomically).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the texture and decoder as safetensors (PyTorch layout, `NEURAL.md`).
    #[arg(long)]
    pub safetensors: Option<PathBuf>,
    /// Name of the neural material (default: `<source>_neural`).
    #[arg(long)]
    pub name: Option<String>,
    /// Feature texture size: `N` (N × N) or `WxH` (default 128).
    #[arg(long)]
    pub texture: Option<String>,
    /// Optimisation steps (default 20000).
    #[arg(long)]
    pub steps: Option<usize>,
    /// Queries per step (default 4096).
    #[arg(long)]
    pub batch: Option<usize>,
    /// Peak learning rate (default 0.01).
    #[arg(long)]
    pub lr: Option<f64>,
    /// A short run (seconds) for tests of the command.
    #[arg(long)]
    pub quick: bool,
    /// Store the texture and decoder as f16 instead of f32 (blob and safetensors).
    #[arg(long)]
    pub f16: bool,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Training threads.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Conditions of the p* KL and albedo measures.
    #[arg(long, default_value_t = 64)]
    pub eval_conditions: usize,
    /// Resolution of the tabulated p* of the KL measure.
    #[arg(long, default_value_t = 64)]
    pub eval_res: usize,
    /// Random queries of the RGB error measure.
    #[arg(long, default_value_t = 20_000)]
    pub eval_points: usize,
    /// Write the report as JSON to this file.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `neusample import-material`.
#[derive(Args, Debug, Clone)]
pub struct ImportMaterialArgs {
    /// The safetensors file (tensor names and shapes in `NEURAL.md`).
    #[arg(long)]
    pub safetensors: PathBuf,
    /// Where to write the neural-material blob (atomically).
    #[arg(long)]
    pub out: PathBuf,
    /// Name of the material (default: the file's `name` metadata, else its stem).
    #[arg(long)]
    pub name: Option<String>,
    /// Store as f16 instead of f32.
    #[arg(long)]
    pub f16: bool,
    /// Also measure the fit against this material (file or built-in name).
    #[arg(long)]
    pub source: Option<String>,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `neusample material-cost`.
#[derive(Args, Debug, Clone)]
pub struct MaterialCostArgs {
    /// A material file (TOML/JSON/.nsb) or the name of a built-in material.
    #[arg(long)]
    pub material: String,
    /// Random queries per pass.
    #[arg(long, default_value_t = 20_000)]
    pub n: usize,
    /// Passes (the median is reported).
    #[arg(long, default_value_t = 7)]
    pub passes: usize,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// What `train-material` reports.
#[derive(Clone, Debug, Serialize)]
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

/// Parses `N` or `WxH`.
pub fn parse_texture(s: &str) -> Result<(u32, u32)> {
    let parse = |v: &str| -> Result<u32> {
        v.trim()
            .parse::<u32>()
            .with_context(|| format!("--texture: `{s}` is not `N` or `WxH`"))
    };
    let (w, h) = match s.split_once(['x', 'X']) {
        Some((w, h)) => (parse(w)?, parse(h)?),
        None => {
            let n = parse(s)?;
            (n, n)
        }
    };
    let max = neusample::neural_material::MAX_TEXTURE_SIZE;
    if w == 0 || h == 0 || w > max || h > max {
        bail!("--texture: {w}×{h} is outside 1..={max} per side");
    }
    Ok((w, h))
}

fn mean(v: &[f32]) -> f64 {
    v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len().max(1) as f64
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

/// `neusample train-material`.
pub fn train_material(a: &TrainMaterialArgs) -> Result<TrainMaterialReport> {
    let source = resolve_material(&a.material)?;
    let mut cfg = if a.quick {
        NeuralTrainConfig::quick()
    } else {
        NeuralTrainConfig::default_run()
    };
    if let Some(t) = &a.texture {
        (cfg.width, cfg.height) = parse_texture(t)?;
    }
    if let Some(s) = a.steps {
        cfg.steps = s;
    }
    if let Some(b) = a.batch {
        cfg.batch = b;
    }
    if let Some(lr) = a.lr {
        if !(lr > 0.0 && lr.is_finite()) {
            bail!("--lr must be positive");
        }
        cfg.lr = lr;
    }
    if let Some(t) = a.threads {
        cfg.threads = t;
    }
    cfg.seed = a.seed;
    cfg.progress = !a.json;
    let name = a
        .name
        .clone()
        .unwrap_or_else(|| format!("{}_neural", source.name()));
    if name.chars().any(char::is_whitespace) || name.is_empty() {
        bail!("--name must be a non-empty word without spaces, got `{name}`");
    }
    let dtype = if a.f16 { DType::F16 } else { DType::F32 };
    let trained = nt::train(source.as_ref(), &cfg)?;
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
    let check = nt::verify_blob(&bytes, 512, cfg.seed ^ 0x5EED)
        .with_context(|| format!("verifying the blob for {}", a.out.display()))?;
    io::atomic_write(&a.out, &bytes)?;
    if let Some(p) = &a.safetensors {
        write_safetensors(p, &trained.parts, dtype, &name, source.name())?;
    }
    let neural = NeuralMaterialModel::from_blob(&bytes, &name)?;
    let fit = nt::fit_report(
        source.as_ref(),
        &neural,
        a.eval_points,
        a.eval_conditions,
        a.eval_res,
        cfg.epsilon,
        cfg.seed ^ 0xF17,
    );
    let cost = eval_cost(&neural, 20_000, 7);
    let source_cost = eval_cost(source.as_ref(), 20_000, 7);
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
        a.out.display(),
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
    if let Some(p) = &a.report {
        io::atomic_write(p, serde_json::to_string_pretty(&report)?.as_bytes())?;
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    }
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
    };
    let bytes = st::write(parts, sd, name, &[("source", source.to_string())])?;
    io::atomic_write(path, &bytes)?;
    eprintln!("wrote {} ({} bytes)", path.display(), bytes.len());
    Ok(())
}

/// What `import-material` reports.
#[derive(Clone, Debug, Serialize)]
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

/// `neusample import-material`.
pub fn import_material(a: &ImportMaterialArgs) -> Result<ImportReport> {
    let imported = st::read_file(&a.safetensors)?;
    let stem = a
        .safetensors
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("imported");
    let name = a
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
    let dtype = if a.f16 { DType::F16 } else { DType::F32 };
    let p = &imported.parts;
    let label = format!(
        "name={name} imported={} texture={}x{} dtype={dtype:?}",
        a.safetensors
            .file_name()
            .and_then(|s| s.to_str())
            .unwrap_or("?")
            .replace(char::is_whitespace, "_"),
        p.width,
        p.height
    );
    let bytes = p.blob_bytes(dtype, &label)?;
    let check = nt::verify_blob(&bytes, 512, 0x1A9)
        .with_context(|| format!("verifying the blob for {}", a.out.display()))?;
    io::atomic_write(&a.out, &bytes)?;
    let neural = NeuralMaterialModel::from_blob(&bytes, &name)?;
    let fit = match &a.source {
        Some(s) => {
            let source = resolve_material(s)?;
            Some(nt::fit_report(
                source.as_ref(),
                &neural,
                20_000,
                64,
                64,
                0.01,
                0xF17,
            ))
        }
        None => None,
    };
    let cost = eval_cost(&neural, 20_000, 7);
    eprintln!(
        "wrote {} ({} bytes, {}×{}×8 features, {:?}); core matches the imported model to \
         {:.1e} (features) / {:.1e} (eval)",
        a.out.display(),
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
    let report = ImportReport {
        name,
        texture: (p.width, p.height),
        ignored: imported.ignored.clone(),
        blob_bytes: bytes.len(),
        check,
        fit,
        cost,
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    }
    Ok(report)
}

/// `neusample material-cost`: single-thread ns per `eval` and per `features` call of any
/// material (the denominator of the paper's Table 1 ratio).
pub fn material_cost(a: &MaterialCostArgs) -> Result<EvalCost> {
    let m: Box<dyn Material> = resolve_material(&a.material)?;
    let c = eval_cost(m.as_ref(), a.n, a.passes);
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "material": m.name(),
                "eval_ns": c.eval_ns,
                "features_ns": c.features_ns,
            }))?
        );
    } else {
        println!(
            "{}: eval {:.0} ns/call, features {:.0} ns/call (single thread, median of {} passes × {})",
            m.name(),
            c.eval_ns,
            c.features_ns,
            a.passes,
            a.n
        );
    }
    Ok(c)
}
