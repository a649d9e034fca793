//! The `neusample` command-line tool: materials → ground truth → training → baking →
//! evaluation.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use neusample::{Blob, TensorRole};
use neusample::{DType, Weights};
use neusample_precompute::train::{self, Method, TrainConfig};
use neusample_precompute::{bake, demo, eval, io, materials};

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(
    name = "neusample",
    version,
    about = "Learned importance sampling for neural materials: train, bake, inspect, evaluate."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the built-in materials.
    Materials {
        /// Machine-readable output.
        #[arg(long)]
        json: bool,
    },
    /// Train a sampler for a material and write its blob (verified against the model).
    Train(TrainArgs),
    /// Describe a blob: kind, dimensions, tensors, checksum status.
    Inspect {
        /// The blob file.
        blob: PathBuf,
        /// Machine-readable output (schema in README.md).
        #[arg(long)]
        json: bool,
    },
    /// Regenerate the committed fixture blobs (deterministic).
    Fixtures {
        /// Output folder of the sampler blobs.
        #[arg(long, default_value = "fixtures/blobs")]
        out: PathBuf,
        /// Output folder of the neural materials.
        #[arg(long, default_value = "fixtures/materials/neural")]
        materials_out: PathBuf,
        /// Which fixtures: samplers on the procedural materials, the neural materials and
        /// their samplers, or all.
        #[arg(long, value_enum, default_value_t = demo::FixtureSet::All)]
        set: demo::FixtureSet,
        /// Quick training (for tests of the command itself).
        #[arg(long)]
        quick: bool,
    },
    /// The main job: train every method on the default materials, evaluate, report.
    Demo(demo::DemoArgs),
    /// Fit a neural material (feature texture + decoder) to a material (NEURAL.md).
    TrainMaterial(neusample_precompute::neural::cli::TrainMaterialArgs),
    /// Import a neural material from safetensors (NEURAL.md).
    ImportMaterial(neusample_precompute::neural::cli::ImportMaterialArgs),
    /// The runtime's cost per shading point: every sampler and the neural material, scalar
    /// and batched, with the dense layers' throughput against the CPU's peak.
    Bench(BenchArgs),
    /// Single-thread cost of a material's eval and features (Table 1 ratio).
    MaterialCost(neusample_precompute::neural::cli::MaterialCostArgs),
}

#[derive(Args)]
struct BenchArgs {
    /// A folder of sampler blobs (`<method>.nsb`) with its `conditions.txt`; default: the
    /// committed goat-leather fixtures.
    #[arg(long)]
    blobs: Option<PathBuf>,
    /// The neural material (`.nsb`); default: the committed goat leather.
    #[arg(long)]
    material: Option<PathBuf>,
    /// Fewer lanes and passes (a smoke run; noisier figures).
    #[arg(long)]
    quick: bool,
    /// Machine-readable output (the `BenchReport` schema in `precompute/src/bench.rs`).
    #[arg(long)]
    json: bool,
}

impl From<&BenchArgs> for neusample_precompute::bench::BenchConfig {
    fn from(a: &BenchArgs) -> Self {
        let mut c = Self::fixtures();
        if let Some(b) = &a.blobs {
            c.blobs = b.clone();
        }
        if let Some(m) = &a.material {
            c.material = m.clone();
        }
        if a.quick {
            c.lanes_per_pass = 1 << 11;
            c.passes = 3;
        }
        c
    }
}

#[derive(Args)]
struct TrainArgs {
    /// A material file (TOML/JSON) or the name of a built-in material.
    #[arg(long)]
    material: String,
    /// The method: baseline, analytic, flow, affine-flow, direct-histogram, histogram-mixture,
    /// `all` (every method in turn, evaluated; needs --out-dir) or a comma-separated list
    /// (`flow,` for a one-method sweep).
    #[arg(long)]
    method: MethodArg,
    /// Where to write the blob (atomically); one method.
    #[arg(long, required_unless_present = "out_dir")]
    out: Option<PathBuf>,
    /// With `--method all`: folder receiving `<method>.nsb` and `summary.json`.
    #[arg(long)]
    out_dir: Option<PathBuf>,
    /// Multiplies every method's default step count (e.g. 0.5 for a shorter sweep).
    #[arg(long)]
    steps_scale: Option<f64>,
    /// With `--method all`: evaluation conditions for KL(p*‖p) and pdf MSE (grid 64²).
    #[arg(long, default_value_t = 24)]
    eval_conditions: usize,
    /// Store weights (and the histogram table) as f16 instead of f32.
    #[arg(long)]
    f16: bool,
    /// A short run (seconds) instead of the default (about a minute).
    #[arg(long)]
    quick: bool,
    /// Optimisation steps (overrides the preset).
    #[arg(long)]
    steps: Option<usize>,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Training threads (results are reproducible for a fixed count).
    #[arg(long)]
    threads: Option<usize>,
    /// Histogram mixture: latent-code levels T.
    #[arg(long)]
    t_levels: Option<usize>,
    /// Histogram mixture: table resolution N.
    #[arg(long)]
    hist_res: Option<usize>,
    /// Histogram mixture: nearest latent level instead of linear interpolation.
    #[arg(long)]
    nearest_t: bool,
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Materials { json } => list_materials(json),
        Command::Train(a) => train_cmd(a),
        Command::Inspect { blob, json } => inspect(&blob, json),
        Command::Fixtures {
            out,
            materials_out,
            set,
            quick,
        } => demo::regenerate_fixtures(&out, &materials_out, set, quick),
        Command::Demo(a) => demo::run(&a),
        Command::TrainMaterial(a) => {
            neusample_precompute::neural::cli::train_material(&a).map(|_| ())
        }
        Command::ImportMaterial(a) => {
            neusample_precompute::neural::cli::import_material(&a).map(|_| ())
        }
        Command::MaterialCost(a) => {
            neusample_precompute::neural::cli::material_cost(&a).map(|_| ())
        }
        Command::Bench(a) => {
            let report = neusample_precompute::bench::run(&(&a).into())?;
            if a.json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", neusample_precompute::bench::text(&report));
            }
            Ok(())
        }
    }
}

fn list_materials(json: bool) -> Result<()> {
    let names = materials::builtin_names();
    if json {
        println!("{}", serde_json::to_string_pretty(&names)?);
    } else {
        for n in names {
            println!("{n}");
        }
    }
    Ok(())
}

/// `--method`: one method, `all`, or a comma-separated list (a sweep, like `all`).
#[derive(Clone, Debug)]
enum MethodArg {
    One(Method),
    Sweep(Vec<Method>),
}

impl std::str::FromStr for MethodArg {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<MethodArg> {
        if s == "all" {
            Ok(MethodArg::Sweep(Method::ALL.to_vec()))
        } else if s.contains(',') {
            let mut list = Vec::new();
            for m in s.split(',').map(str::trim).filter(|m| !m.is_empty()) {
                let m: Method = m.parse()?;
                if !list.contains(&m) {
                    list.push(m);
                }
            }
            Ok(MethodArg::Sweep(list))
        } else {
            s.parse().map(MethodArg::One)
        }
    }
}

fn train_cmd(a: TrainArgs) -> Result<()> {
    let material = demo::resolve_material(&a.material)?;
    let method = match &a.method {
        MethodArg::Sweep(list) => {
            let dir = a.out_dir.clone().context("--method all needs --out-dir")?;
            return train_all(&a, list, material.as_ref(), &dir);
        }
        MethodArg::One(m) => *m,
    };
    let out = a
        .out
        .clone()
        .context("--out is required for a single method")?;
    let cfg = train_config(&a, method)?;
    let dtype = if a.f16 { DType::F16 } else { DType::F32 };
    let (trained, bytes, v) = train_verified(material.as_ref(), method, &cfg, dtype, &out)?;
    eprintln!(
        "wrote {} ({} bytes): trained in {:.1} s, final loss {:.4}, blob matches model to {:.2e} (tolerance {:.0e})",
        out.display(),
        bytes.len(),
        trained.seconds,
        trained.loss_history.last().copied().unwrap_or(f32::NAN),
        v.max_relative,
        v.tolerance
    );
    Ok(())
}

/// The training configuration of `method` from the command line.
fn train_config(a: &TrainArgs, method: Method) -> Result<TrainConfig> {
    let mut cfg = if a.quick {
        TrainConfig::quick()
    } else {
        TrainConfig::default_for(method)
    };
    cfg.seed = a.seed;
    cfg.progress = true;
    if let Some(f) = a.steps_scale {
        if !(f > 0.0 && f.is_finite()) {
            bail!("--steps-scale must be positive");
        }
        cfg.steps = ((cfg.steps as f64 * f).round() as usize).max(1);
    }
    if let Some(s) = a.steps {
        if s == 0 {
            bail!("--steps must be positive");
        }
        cfg.steps = s;
    }
    if let Some(t) = a.threads {
        if t == 0 {
            bail!("--threads must be positive");
        }
        cfg.threads = t;
    }
    if let Some(t) = a.t_levels {
        if !(1..=neusample::samplers::histogram_mixture::MAX_T).contains(&t) {
            bail!(
                "--t-levels must be in 1..={}",
                neusample::samplers::histogram_mixture::MAX_T
            );
        }
        cfg.hist_t_levels = t;
    }
    if let Some(n) = a.hist_res {
        if !(1..=neusample::samplers::histogram_mixture::MAX_N).contains(&n) {
            bail!(
                "--hist-res must be in 1..={}",
                neusample::samplers::histogram_mixture::MAX_N
            );
        }
        cfg.hist_res = n;
    }
    if a.nearest_t {
        cfg.interpolate_t = false;
    }
    Ok(cfg)
}

/// Trains `method`, bakes the blob, verifies it against the model and writes it atomically.
fn train_verified(
    material: &dyn materials::Material,
    method: Method,
    cfg: &TrainConfig,
    dtype: DType,
    out: &Path,
) -> Result<(train::Trained, Vec<u8>, bake::Verification)> {
    let trained = train::train(material, method, cfg)?;
    let label = format!(
        "material={} method={} steps={} seed={} dtype={:?}",
        material.name(),
        method,
        cfg.steps,
        cfg.seed,
        dtype
    );
    let bytes = bake::blob_bytes(&trained, dtype, &label)?;
    let v = bake::verify(&trained, &bytes, material, 16, cfg.seed ^ 0x5EED)
        .with_context(|| format!("verifying the blob for {}", out.display()))?;
    io::atomic_write(out, &bytes)?;
    Ok((trained, bytes, v))
}

/// `train --method all`: every method in turn on one material; each blob is written
/// atomically and verified, then evaluated through the runtime (KL(p*‖p), pdf MSE on a 64²
/// grid, the demo's evaluation seed). `<dir>/summary.json` is rewritten after every method;
/// a failing method is recorded and the sweep goes on (exit status 1 at the end).
fn train_all(
    a: &TrainArgs,
    methods: &[Method],
    material: &dyn materials::Material,
    dir: &Path,
) -> Result<()> {
    const EVAL_RES: usize = 64;
    let dtype = if a.f16 { DType::F16 } else { DType::F32 };
    let eval_seed = a.seed + 100;
    let fit = eval::fit(
        &neusample::CosineSampler,
        material,
        a.eval_conditions,
        EVAL_RES,
        eval_seed,
    );
    let mut rows = vec![serde_json::json!({
        "method": "cosine", "kl": fit.kl_divergence, "pdf_mse": fit.pdf_mse,
        "train_seconds": 0.0, "steps": 0,
    })];
    let mut failures = 0;
    let write_summary = |rows: &[serde_json::Value]| -> Result<()> {
        let summary = serde_json::json!({
            "material": material.name(),
            "seed": a.seed,
            "quick": a.quick,
            "steps_scale": a.steps_scale.unwrap_or(1.0),
            "eval_conditions": a.eval_conditions,
            "eval_res": EVAL_RES,
            "methods": rows,
        });
        io::atomic_write(
            &dir.join("summary.json"),
            serde_json::to_string_pretty(&summary)?.as_bytes(),
        )
    };
    for &method in methods {
        let out = dir.join(format!("{method}.nsb"));
        let row = train_config(a, method).and_then(|cfg| {
            let (trained, bytes, v) = train_verified(material, method, &cfg, dtype, &out)?;
            let blob = Blob::open(&bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
            let sampler = blob.sampler().map_err(|e| anyhow::anyhow!("{e}"))?;
            let fit = eval::fit(&sampler, material, a.eval_conditions, EVAL_RES, eval_seed);
            Ok(serde_json::json!({
                "method": method.name(), "kl": fit.kl_divergence, "pdf_mse": fit.pdf_mse,
                "train_seconds": trained.seconds, "steps": cfg.steps,
                "final_loss": trained.loss_history.last().copied(),
                "blob_bytes": bytes.len(), "blob_vs_model": v.max_relative,
            }))
        });
        match row {
            Ok(r) => rows.push(r),
            Err(e) => {
                eprintln!("error: {method} on {}: {e:#}", material.name());
                failures += 1;
                rows.push(serde_json::json!({"method": method.name(), "error": format!("{e:#}")}));
            }
        }
        write_summary(&rows)?;
    }
    println!(
        "{} ({} evaluation conditions)",
        material.name(),
        a.eval_conditions
    );
    println!(
        "{:<18} {:>9} {:>11} {:>9}",
        "method", "KL", "pdf MSE", "train s"
    );
    for r in &rows {
        if let Some(e) = r.get("error") {
            println!("{:<18} failed: {e}", r["method"].as_str().unwrap_or(""));
        } else {
            println!(
                "{:<18} {:>9.4} {:>11.3e} {:>9.1}",
                r["method"].as_str().unwrap_or(""),
                r["kl"].as_f64().unwrap_or(f64::NAN),
                r["pdf_mse"].as_f64().unwrap_or(f64::NAN),
                r["train_seconds"].as_f64().unwrap_or(0.0)
            );
        }
    }
    if failures > 0 {
        bail!("{failures} method(s) failed on {}", material.name());
    }
    Ok(())
}

fn inspect(path: &Path, json: bool) -> Result<()> {
    let bytes = io::read_blob(path)?;
    let blob = Blob::open(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let h = blob.header();
    let mut tensors = Vec::new();
    for role in TensorRole::ALL {
        if let (Some(e), Some(t)) = (blob.entry(role), blob.tensor(role)) {
            let n = t.len();
            let (mut lo, mut hi, mut sum) = (f32::INFINITY, f32::NEG_INFINITY, 0f64);
            for i in 0..n {
                let v = t.at(i);
                lo = lo.min(v);
                hi = hi.max(v);
                sum += f64::from(v);
            }
            tensors.push(serde_json::json!({
                "role": role.name(),
                "dtype": format!("{:?}", e.dtype).to_lowercase(),
                "offset": e.offset,
                "count": e.count,
                "min": lo, "max": hi, "mean": if n > 0 { sum / f64::from(n) } else { 0.0 },
            }));
        }
    }
    let out = serde_json::json!({
        "file": path.display().to_string(),
        "bytes": bytes.len(),
        "format_version": neusample::blob::FORMAT_VERSION,
        "kind": h.kind.name(),
        "dtype": format!("{:?}", h.dtype).to_lowercase(),
        "feature_dim": h.feature_dim,
        "param_count": h.param_count,
        "basis": h.basis,
        "t_levels": h.t_levels,
        "resolution": h.resolution,
        "interpolation": format!("{:?}", h.interpolation).to_lowercase(),
        "label": h.label,
        "checksum": "ok",
        "tensors": tensors,
    });
    if json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "{}: {} {}, {} bytes, format v{}, checksum ok",
            path.display(),
            h.kind.name(),
            if h.kind.is_sampler() {
                "sampler"
            } else {
                "blob"
            },
            bytes.len(),
            neusample::blob::FORMAT_VERSION
        );
        println!(
            "  storage {:?}, φ dim {}, {} params",
            h.dtype, h.feature_dim, h.param_count
        );
        if h.kind == neusample::SamplerKind::NeuralMaterial {
            println!(
                "  neural material: feature texture {}×{}×8 (NEURAL.md)",
                h.resolution, h.t_levels
            );
        } else if h.t_levels > 0 {
            println!(
                "  tables: K={} T={} N={} ({:?} in t)",
                h.basis, h.t_levels, h.resolution, h.interpolation
            );
        }
        println!("  label: {}", h.label);
        for t in &tensors {
            println!(
                "  tensor {:<12} {:>4} {:>8} elements at {:>7}  min {:.4} max {:.4} mean {:.4}",
                t["role"].as_str().unwrap_or(""),
                t["dtype"].as_str().unwrap_or(""),
                t["count"],
                t["offset"],
                t["min"].as_f64().unwrap_or(0.0),
                t["max"].as_f64().unwrap_or(0.0),
                t["mean"].as_f64().unwrap_or(0.0)
            );
        }
    }
    Ok(())
}
