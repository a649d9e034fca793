//! The main job (`neusample demo`) and the fixture generator (`neusample fixtures`).
//!
//! The demo trains every method on the default materials (or loads the committed fixture
//! blobs), bakes and verifies each blob, evaluates it through the runtime's public API, and
//! writes `report.md` and `report.json` (schema in README.md) into an output folder.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use neusample::blob::{Blob, BlobWriter, SamplerKind};
use neusample::{CosineSampler, DType};
use serde::Serialize;

use crate::bake;
use crate::eval::{self, Cost, Fit};
use crate::io;
use crate::materials::{self, Material};
use crate::train::{self, Method, TrainConfig};

/// The built-in materials the demo and the fixtures use: an isotropic highlight under strong
/// normal mapping, an anisotropic highlight with varying tangents, and a multi-lobe fabric.
pub const DEFAULT_MATERIALS: [&str; 3] = ["goat_leather", "brushed_metal", "victorian_fabric"];

/// Options of `neusample demo`.
#[derive(clap::Args, Clone, Debug)]
pub struct DemoArgs {
    /// CI-sized run: short training, fewer evaluation conditions.
    #[arg(long)]
    pub quick: bool,
    /// Output folder (created; files are replaced atomically).
    #[arg(long, default_value = "neusample-report")]
    pub out: PathBuf,
    /// Use the committed fixture blobs instead of training.
    #[arg(long)]
    pub use_fixtures: bool,
    /// Materials (built-in names or files); default: the three demo materials.
    #[arg(long, value_delimiter = ',')]
    pub materials: Vec<String>,
    /// Seed of training and evaluation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// A material given as a file path or a built-in name.
pub fn resolve_material(spec: &str) -> Result<Box<dyn Material>> {
    let p = Path::new(spec);
    if p.exists() {
        materials::load(p)
    } else if spec.ends_with(".toml") || spec.ends_with(".json") || spec.contains('/') {
        anyhow::bail!("material file {spec} does not exist")
    } else {
        materials::builtin(spec)
    }
}

/// One method's results on one material.
#[derive(Clone, Debug, Serialize)]
pub struct MethodReport {
    /// Method name (`cosine`, `baseline`, …).
    pub method: String,
    /// Training time in seconds (0 for cosine and for fixture blobs).
    pub train_seconds: f64,
    /// Final training loss (null for cosine and fixtures).
    pub final_loss: Option<f32>,
    /// Blob size in bytes.
    pub blob_bytes: usize,
    /// Largest relative difference between the blob and the trained model.
    pub blob_vs_model: Option<f64>,
    /// Mean KL(p* ‖ p), nats.
    pub kl_divergence: f64,
    /// Mean squared pdf difference on the disk.
    pub pdf_mse: f64,
    /// Mass inside the disk.
    pub mass_in_disk: f64,
    /// Single-thread cost.
    pub cost: Cost,
    /// prepare + sample + pdf, ns (same as cost.total_ns).
    pub ns_per_sample: f64,
}

/// All methods on one material.
#[derive(Clone, Debug, Serialize)]
pub struct MaterialReport {
    /// Material name.
    pub material: String,
    /// Per method.
    pub methods: Vec<MethodReport>,
}

/// The whole report (`report.json`).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Schema version of this JSON.
    pub schema: u32,
    /// Whether the run was `--quick`.
    pub quick: bool,
    /// Whether fixture blobs were used instead of training.
    pub fixtures: bool,
    /// Seed.
    pub seed: u64,
    /// Evaluation conditions per material and method.
    pub eval_conditions: usize,
    /// Ground-truth resolution of the evaluation.
    pub eval_res: usize,
    /// Per material.
    pub materials: Vec<MaterialReport>,
}

fn fixture_config(method: Method) -> TrainConfig {
    let mut c = TrainConfig::default_for(method);
    c.hist_t_levels = 8;
    c.hist_res = 32;
    c
}

fn fixture_path(dir: &Path, material: &str, method: &str) -> PathBuf {
    dir.join(material).join(format!("{method}.nsb"))
}

/// The folder of the committed fixture blobs.
#[must_use]
pub fn fixtures_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/blobs")
}

fn bar(len: u64, msg: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg:>28} [{bar:30}] {pos}/{len} {elapsed_precise}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_message(msg.to_string());
    pb
}

/// `neusample fixtures`: trains every method on the default materials with fixed seeds and
/// writes `<out>/<material>/<method>.nsb` (f32, histogram tables T = 8, N = 32) plus
/// `<out>/cosine.nsb`.
pub fn regenerate_fixtures(out: &Path, quick: bool) -> Result<()> {
    let pb = bar(
        (DEFAULT_MATERIALS.len() * Method::ALL.len()) as u64,
        "fixtures",
    );
    io::atomic_write(
        &out.join("cosine.nsb"),
        &BlobWriter::new(SamplerKind::Cosine, DType::F32, "cosine").to_bytes(),
    )?;
    for name in DEFAULT_MATERIALS {
        let m = materials::builtin(name)?;
        // Conditions drawn from the material, for the runtime's statistical tests (which do
        // not link the materials): one "φ0 … φ7 wi.x wi.y wi.z" line each.
        let conds = crate::groundtruth::conditions(m.as_ref(), 256, 0xC0DE);
        let mut text =
            String::from("# phi0..phi7 wi.x wi.y wi.z (local frame), from the material\n");
        for c in &conds {
            for v in c.phi {
                text.push_str(&format!("{v:e} "));
            }
            text.push_str(&format!("{:e} {:e} {:e}\n", c.wi.x, c.wi.y, c.wi.z));
        }
        io::atomic_write(&out.join(name).join("conditions.txt"), text.as_bytes())?;
        for method in Method::ALL {
            pb.set_message(format!("{name}/{method}"));
            let mut cfg = if quick {
                TrainConfig::quick()
            } else {
                fixture_config(method)
            };
            cfg.seed = 1;
            let trained = train::train(m.as_ref(), method, &cfg)?;
            let label = format!(
                "fixture material={name} method={method} steps={} seed=1",
                cfg.steps
            );
            let bytes = bake::blob_bytes(&trained, DType::F32, &label)?;
            bake::verify(&trained, &bytes, m.as_ref(), 8, 7)
                .with_context(|| format!("fixture {name}/{method}"))?;
            io::atomic_write(&fixture_path(out, name, method.name()), &bytes)?;
            pb.inc(1);
        }
    }
    pb.finish_with_message("fixtures written");
    eprintln!("fixtures written to {}", out.display());
    Ok(())
}

/// `neusample demo`.
pub fn run(a: &DemoArgs) -> Result<()> {
    let started = Instant::now();
    let names: Vec<String> = if a.materials.is_empty() {
        DEFAULT_MATERIALS.iter().map(|s| s.to_string()).collect()
    } else {
        a.materials.clone()
    };
    let (eval_conditions, eval_res, cost_n, cost_passes) = if a.quick {
        (24, 64, 2000, 3)
    } else {
        (128, 96, 20000, 7)
    };
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create output folder {}", a.out.display()))?;
    let out = a.out.canonicalize()?;
    eprintln!("neusample demo: writing to {}", out.display());

    let pb = bar((names.len() * (Method::ALL.len() + 1)) as u64, "demo");
    let mut report = Report {
        schema: 1,
        quick: a.quick,
        fixtures: a.use_fixtures,
        seed: a.seed,
        eval_conditions,
        eval_res,
        materials: Vec::new(),
    };
    for name in &names {
        let m = resolve_material(name)?;
        let mname = m.name().to_string();
        let mut methods = Vec::new();

        pb.set_message(format!("{mname}/cosine"));
        let fit = eval::fit(
            &CosineSampler,
            m.as_ref(),
            eval_conditions,
            eval_res,
            a.seed + 100,
        );
        let cost = eval::cost(&CosineSampler, m.as_ref(), cost_n, cost_passes);
        methods.push(method_report("cosine", 0.0, None, 0, None, fit, cost));
        pb.inc(1);

        for method in Method::ALL {
            pb.set_message(format!("{mname}/{method}"));
            let (bytes, secs, loss, check) = if a.use_fixtures {
                let p = fixture_path(&fixtures_dir(), name, method.name());
                (io::read_blob(&p)?, 0.0, None, None)
            } else {
                let mut cfg = if a.quick {
                    TrainConfig::quick()
                } else {
                    TrainConfig::default_for(method)
                };
                cfg.seed = a.seed;
                let trained = train::train(m.as_ref(), method, &cfg)
                    .with_context(|| format!("training {method} on {mname}"))?;
                let label = format!("demo material={mname} method={method} steps={}", cfg.steps);
                let bytes = bake::blob_bytes(&trained, DType::F32, &label)?;
                let v = bake::verify(&trained, &bytes, m.as_ref(), 8, a.seed + 7)?;
                (
                    bytes,
                    trained.seconds,
                    trained.loss_history.last().copied(),
                    Some(v.max_relative),
                )
            };
            io::atomic_write(
                &out.join("blobs").join(&mname).join(format!("{method}.nsb")),
                &bytes,
            )?;
            let blob = Blob::open(&bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
            let sampler = blob.sampler().map_err(|e| anyhow::anyhow!("{e}"))?;
            let fit = eval::fit(
                &sampler,
                m.as_ref(),
                eval_conditions,
                eval_res,
                a.seed + 100,
            );
            let cost = eval::cost(&sampler, m.as_ref(), cost_n, cost_passes);
            methods.push(method_report(
                method.name(),
                secs,
                loss,
                bytes.len(),
                check,
                fit,
                cost,
            ));
            pb.inc(1);
        }
        report.materials.push(MaterialReport {
            material: mname,
            methods,
        });
    }
    pb.finish_with_message("done");

    let json = serde_json::to_string_pretty(&report)?;
    io::atomic_write(&out.join("report.json"), json.as_bytes())?;
    io::atomic_write(&out.join("report.md"), markdown(&report).as_bytes())?;
    eprintln!(
        "neusample demo finished in {:.0} s: {}",
        started.elapsed().as_secs_f64(),
        out.join("report.md").display()
    );
    Ok(())
}

fn method_report(
    method: &str,
    train_seconds: f64,
    final_loss: Option<f32>,
    blob_bytes: usize,
    blob_vs_model: Option<f64>,
    fit: Fit,
    cost: Cost,
) -> MethodReport {
    MethodReport {
        method: method.to_string(),
        train_seconds,
        final_loss,
        blob_bytes,
        blob_vs_model,
        kl_divergence: fit.kl_divergence,
        pdf_mse: fit.pdf_mse,
        mass_in_disk: fit.mass_in_disk,
        ns_per_sample: cost.total_ns,
        cost,
    }
}

/// The Markdown report.
#[must_use]
pub fn markdown(r: &Report) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "# neusample report\n");
    let _ = writeln!(
        s,
        "{} run, {}, seed {}. Fit: mean over {} random conditions (φ, wi), ground truth on a {}² grid. \
         Cost: single thread, ns per call (median of passes).\n",
        if r.quick { "Quick" } else { "Full" },
        if r.fixtures { "committed fixture blobs" } else { "freshly trained samplers" },
        r.seed,
        r.eval_conditions,
        r.eval_res
    );
    for m in &r.materials {
        let _ = writeln!(s, "## {}\n", m.material);
        let _ = writeln!(
            s,
            "| method | KL(p*‖p) | pdf MSE | mass in disk | prepare ns | sample ns | pdf ns | prepare+sample+pdf ns | ×material eval | train s | blob bytes |"
        );
        let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
        for x in &m.methods {
            let _ = writeln!(
                s,
                "| {} | {:.4} | {:.3e} | {:.4} | {:.0} | {:.0} | {:.0} | {:.0} | {:.2} | {:.1} | {} |",
                x.method,
                x.kl_divergence,
                x.pdf_mse,
                x.mass_in_disk,
                x.cost.prepare_ns,
                x.cost.sample_ns,
                x.cost.pdf_ns,
                x.cost.total_ns,
                x.cost.total_ns / x.cost.material_eval_ns.max(1e-9),
                x.train_seconds,
                x.blob_bytes
            );
        }
        let _ = writeln!(s);
    }
    s
}
