//! `neusample train-material`, `import-material` and `material-cost` (`NEURAL.md`).

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use neusample::DType;
use neusample_precompute::jobs::material::{
    self, FitSettings, ImportMaterialJob, TrainMaterialJob,
};
use neusample_precompute::materials;
use neusample_precompute::train::neural_material::NeuralTrainConfig;
use neusample_precompute::util::io;

use crate::output::print_json;

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

/// Parses `N` or `WxH`.
fn parse_texture(s: &str) -> Result<(u32, u32)> {
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

fn dtype(f16: bool) -> DType {
    if f16 {
        DType::F16
    } else {
        DType::F32
    }
}

impl TryFrom<&TrainMaterialArgs> for TrainMaterialJob {
    type Error = anyhow::Error;

    fn try_from(a: &TrainMaterialArgs) -> Result<TrainMaterialJob> {
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
        Ok(TrainMaterialJob {
            source: a.material.clone(),
            out: a.out.clone(),
            safetensors: a.safetensors.clone(),
            name: a.name.clone(),
            dtype: dtype(a.f16),
            training: cfg,
            fit: FitSettings {
                points: a.eval_points,
                conditions: a.eval_conditions,
                res: a.eval_res,
            },
        })
    }
}

/// `neusample train-material`.
pub fn train_material(a: &TrainMaterialArgs) -> Result<()> {
    let report = material::train_material(&TrainMaterialJob::try_from(a)?)?;
    if let Some(p) = &a.report {
        io::atomic_write(p, serde_json::to_string_pretty(&report)?.as_bytes())?;
    }
    if a.json {
        print_json(&report)?;
    }
    Ok(())
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

impl From<&ImportMaterialArgs> for ImportMaterialJob {
    fn from(a: &ImportMaterialArgs) -> Self {
        ImportMaterialJob {
            safetensors: a.safetensors.clone(),
            out: a.out.clone(),
            name: a.name.clone(),
            dtype: dtype(a.f16),
            source: a.source.clone(),
        }
    }
}

/// `neusample import-material`.
pub fn import_material(a: &ImportMaterialArgs) -> Result<()> {
    let report = material::import_material(&a.into())?;
    if a.json {
        print_json(&report)?;
    }
    Ok(())
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

/// `neusample material-cost`: single-thread ns per `eval` and per `features` call of any
/// material (the denominator of the paper's Table 1 ratio).
pub fn material_cost(a: &MaterialCostArgs) -> Result<()> {
    let m = materials::resolve(&a.material)?;
    let c = material::material_cost(m.as_ref(), a.n, a.passes);
    if a.json {
        print_json(&c)?;
    } else {
        println!(
            "{}: eval {:.0} ns/call, features {:.0} ns/call (single thread, median of {} passes × {})",
            c.material, c.eval_ns, c.features_ns, a.passes, a.n
        );
    }
    Ok(())
}
