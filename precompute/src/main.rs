//! The `neusample` command-line tool: materials → ground truth → training → baking →
//! evaluation.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use neusample::blob::{Blob, TensorRole};
use neusample::{DType, Weights};
use neusample_precompute::train::{self, Method, TrainConfig};
use neusample_precompute::{bake, demo, io, materials};

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
        /// Output folder.
        #[arg(long, default_value = "fixtures/blobs")]
        out: PathBuf,
        /// Quick training (for tests of the command itself).
        #[arg(long)]
        quick: bool,
    },
    /// The main job: train every method on the default materials, evaluate, report.
    Demo(demo::DemoArgs),
}

#[derive(Args)]
struct TrainArgs {
    /// A material file (TOML/JSON) or the name of a built-in material.
    #[arg(long)]
    material: String,
    /// The method: baseline, analytic, flow, affine-flow, direct-histogram, histogram-mixture.
    #[arg(long)]
    method: Method,
    /// Where to write the blob (atomically).
    #[arg(long)]
    out: PathBuf,
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
        Command::Fixtures { out, quick } => demo::regenerate_fixtures(&out, quick),
        Command::Demo(a) => demo::run(&a),
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

fn train_cmd(a: TrainArgs) -> Result<()> {
    let material = demo::resolve_material(&a.material)?;
    let mut cfg = if a.quick {
        TrainConfig::quick()
    } else {
        TrainConfig::default_for(a.method)
    };
    cfg.seed = a.seed;
    cfg.progress = true;
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
        if !(1..=neusample::histogram::MAX_T).contains(&t) {
            bail!("--t-levels must be in 1..={}", neusample::histogram::MAX_T);
        }
        cfg.hist_t_levels = t;
    }
    if let Some(n) = a.hist_res {
        if !(1..=neusample::histogram::MAX_N).contains(&n) {
            bail!("--hist-res must be in 1..={}", neusample::histogram::MAX_N);
        }
        cfg.hist_res = n;
    }
    if a.nearest_t {
        cfg.interpolate_t = false;
    }
    let dtype = if a.f16 { DType::F16 } else { DType::F32 };
    let trained = train::train(material.as_ref(), a.method, &cfg)?;
    let label = format!(
        "material={} method={} steps={} seed={} dtype={:?}",
        material.name(),
        a.method,
        cfg.steps,
        cfg.seed,
        dtype
    );
    let bytes = bake::blob_bytes(&trained, dtype, &label)?;
    let v = bake::verify(&trained, &bytes, material.as_ref(), 16, cfg.seed ^ 0x5EED)
        .with_context(|| format!("verifying the blob for {}", a.out.display()))?;
    io::atomic_write(&a.out, &bytes)?;
    eprintln!(
        "wrote {} ({} bytes): trained in {:.1} s, final loss {:.4}, blob matches model to {:.2e} (tolerance {:.0e})",
        a.out.display(),
        bytes.len(),
        trained.seconds,
        trained.loss_history.last().copied().unwrap_or(f32::NAN),
        v.max_relative,
        v.tolerance
    );
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
            "{}: {} sampler, {} bytes, format v{}, checksum ok",
            path.display(),
            h.kind.name(),
            bytes.len(),
            neusample::blob::FORMAT_VERSION
        );
        println!(
            "  storage {:?}, φ dim {}, {} params",
            h.dtype, h.feature_dim, h.param_count
        );
        if h.t_levels > 0 {
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
