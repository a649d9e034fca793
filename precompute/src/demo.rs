//! The main job (`neusample demo`) and the fixture generator (`neusample fixtures`).
//!
//! The demo trains every method on the default materials (or loads the committed fixture
//! blobs), bakes and verifies each blob, and evaluates it through the runtime's public API:
//!
//! 1. **pdf fit** ([`eval::fit`]): KL(p* ‖ p) and pdf MSE over random conditions, and a
//!    Fig. 7-style grid of p* beside every method's p for a few conditions;
//! 2. **cost** ([`eval::cost`]): single-thread ns of prepare / sample / pdf, and the Table 1
//!    ratio to the material's own evaluation;
//! 3. **rendering** ([`crate::render`], [`crate::metrics`]): a patch and a sphere under a sky
//!    with a small bright sun, rendered with every method plus the tabulated oracle; MSE
//!    against a high-sample reference at equal spp and at equal time, convergence plots
//!    (Fig. 8), equal-time images (Figs. 1, 9) and the Table 2 speed-up over the improved
//!    baseline.
//!
//! It writes `report.md`, `report.json` (schema in README.md), `images/`, `plots/` and
//! `blobs/` into the output folder, every file atomically.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use neusample::{AnySampler, Blob, BlobWriter, SamplerKind};
use neusample::{CosineSampler, DType, Prepared, Sampler};
use serde::Serialize;

use crate::bake;
use crate::eval::{self, Cost, Fit};
use crate::figures::{self, Rgb8};
use crate::groundtruth::{self, TargetPdf};
use crate::io;
use crate::materials::{self, Material};
use crate::metrics::{self, ConvergencePoint, RenderSettings, Technique};
use crate::render::{self, EnvMap, Estimator, OracleSampler, SceneParams};
use crate::train::{self, Method, TrainConfig};

/// The built-in materials the demo and the fixtures use: an isotropic highlight under strong
/// normal mapping, an anisotropic highlight with varying tangents, and a multi-lobe fabric.
pub const DEFAULT_MATERIALS: [&str; 3] = ["goat_leather", "brushed_metal", "victorian_fabric"];

/// Schema version of `report.json` (README.md documents it).
pub const REPORT_SCHEMA: u32 = 3;

/// Suffix of a neural material's name: `goat_leather_neural` is the neural version of
/// `goat_leather` (`fixtures/materials/neural/goat_leather_neural.nsb`).
pub const NEURAL_SUFFIX: &str = "_neural";

/// Name of the improved baseline in reports (the reference of the speed-ups).
pub const BASELINE: &str = "baseline";

/// Name of the tabulated oracle in reports.
pub const ORACLE: &str = "oracle";

/// Options of `neusample demo`.
#[derive(clap::Args, Clone, Debug)]
pub struct DemoArgs {
    /// CI-sized run: short training, fewer evaluation conditions, a small image.
    #[arg(long)]
    pub quick: bool,
    /// Output folder (created; files are replaced atomically).
    #[arg(long, default_value = "neusample-report")]
    pub out: PathBuf,
    /// Use the committed fixture blobs instead of training.
    #[arg(long)]
    pub use_fixtures: bool,
    /// Materials (built-in names or files, `.nsb` neural materials included); default: the
    /// neural versions of the three demo materials (or the procedural ones with
    /// --procedural).
    #[arg(long, value_delimiter = ',')]
    pub materials: Vec<String>,
    /// Use the procedural source materials of the defaults instead of their neural versions
    /// (the paper's setting is neural materials).
    #[arg(long)]
    pub procedural: bool,
    /// Seed of training and evaluation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Multiplies every method's default training steps (1 = the defaults of `neusample
    /// train`; the demo's 0.5 keeps the full run within ten minutes on 2 cores, at some cost in
    /// fit: 1 gives the better samplers of `neusample train`). Not used with --quick or
    /// --use-fixtures.
    #[arg(long, default_value_t = 0.5)]
    pub steps_scale: f64,
    /// Image width in pixels (height = 3/4 of it); default 160, 64 with --quick.
    #[arg(long)]
    pub width: Option<usize>,
    /// Equal-spp sample count N (convergence up to it; the baseline's equal-time budget);
    /// default 32, 8 with --quick.
    #[arg(long)]
    pub spp: Option<u32>,
    /// Radiance of the sun disc (0: sky only).
    #[arg(long, default_value_t = 60.0)]
    pub sun_radiance: f32,
    /// Angular radius of the sun, degrees.
    #[arg(long, default_value_t = 4.0)]
    pub sun_size: f32,
    /// An equirectangular OpenEXR environment map (z-up, see `render::EnvMap`) instead of the
    /// procedural sky; the sun is added unless --sun-radiance is 0.
    #[arg(long)]
    pub envmap: Option<PathBuf>,
    /// Uniform white lighting instead of the sky (no sun): the render variance then measures
    /// the BSDF sampler alone (the paper's uniformly lit scenes).
    #[arg(long)]
    pub uniform_light: bool,
    /// Combine BSDF sampling with environment sampling (MIS, power heuristic) instead of
    /// BSDF sampling alone.
    #[arg(long)]
    pub mis: bool,
    /// Skip the rendering evaluation (fit and cost only).
    #[arg(long)]
    pub no_render: bool,
}

impl DemoArgs {
    /// The defaults of the command line, writing to `out`.
    #[must_use]
    pub fn new(out: impl Into<PathBuf>) -> Self {
        DemoArgs {
            quick: false,
            out: out.into(),
            use_fixtures: false,
            materials: Vec::new(),
            procedural: false,
            seed: 1,
            steps_scale: 0.5,
            width: None,
            spp: None,
            sun_radiance: 60.0,
            sun_size: 4.0,
            envmap: None,
            uniform_light: false,
            mis: false,
            no_render: false,
        }
    }
}

/// The committed neural version of a built-in material (`neusample fixtures` writes it).
#[must_use]
pub fn neural_fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/materials/neural")
        .join(format!("{name}{NEURAL_SUFFIX}.nsb"))
}

/// A material of the demo and, for a neural material, the source it approximates (the
/// reference of its fit).
pub struct DemoMaterial {
    /// What is rendered and sampled.
    pub material: Box<dyn Material>,
    /// The source of a neural material, when it is known (a built-in name or a file in its
    /// label's `source=` field).
    pub source: Option<Box<dyn Material>>,
}

/// Resolves a `--materials` entry (or, with `neural`, the neural version of a built-in
/// name), with the source of a neural material.
pub fn resolve_demo_material(spec: &str, neural: bool) -> Result<DemoMaterial> {
    if neural {
        let path = neural_fixture(spec);
        anyhow::ensure!(
            path.exists(),
            "no neural version of `{spec}` in fixtures ({}); make one with \
             `neusample train-material --material {spec} --out FILE` and pass the file",
            path.display()
        );
        return resolve_demo_material(&path.to_string_lossy(), false);
    }
    let material = resolve_material(spec)?;
    let p = Path::new(spec);
    let source = if p.exists() && crate::neural::is_blob_file(p) {
        let bytes = io::read_blob(p)?;
        let (_, label) = crate::neural::NeuralParts::from_blob(&bytes)?;
        match crate::neural::label_field(&label, "source") {
            Some(src) => match resolve_material(src) {
                Ok(m) => Some(m),
                Err(e) => {
                    eprintln!(
                        "note: source `{src}` of {} not found ({e:#}); fit against the source skipped",
                        p.display()
                    );
                    None
                }
            },
            None => None,
        }
    } else {
        None
    };
    Ok(DemoMaterial { material, source })
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

/// Rendering results of one method on one material (see [`crate::metrics`]).
#[derive(Clone, Debug, Serialize)]
pub struct RenderReport {
    /// Single-thread render-loop time per pixel sample, ns (oracle: table build excluded).
    pub ns_per_sample: f64,
    /// `ns_per_sample` relative to cosine sampling's (Table 1, "Rendering" row ratios).
    pub time_vs_cosine: f64,
    /// Samples per pixel of the equal-spp comparison.
    pub equal_spp: u32,
    /// MSE at `equal_spp` (reference noise subtracted).
    pub mse_equal_spp: f64,
    /// Samples per pixel this method affords in the baseline's time for `equal_spp`.
    pub equal_time_spp: u32,
    /// MSE of the equal-time render.
    pub mse_equal_time: f64,
    /// Speed-up over the improved baseline at equal quality (Table 2).
    pub speedup_vs_baseline: f64,
    /// The same speed-up from the measured MSEs against the reference (noisier).
    pub speedup_measured_mse: f64,
    /// Expected MSE at `equal_spp` from the per-pixel sample variances (what the speed-up
    /// uses).
    pub mse_expected_equal_spp: f64,
    /// Expected-MSE ratio baseline / method at equal spp (the speed-up if sampling cost
    /// nothing: the paper's "sampling rate" view).
    pub mse_ratio_equal_spp: f64,
    /// MSE vs spp and vs single-thread time.
    pub convergence: Vec<ConvergencePoint>,
    /// Equal-time image, linear (relative to the output folder).
    pub equal_time_exr: String,
    /// Equal-time image, tonemapped sRGB.
    pub equal_time_png: String,
    /// Equal-spp image, tonemapped sRGB.
    pub equal_spp_png: String,
}

/// One method's results on one material.
#[derive(Clone, Debug, Serialize)]
pub struct MethodReport {
    /// Method name (`cosine`, `baseline`, …, `oracle`).
    pub method: String,
    /// Training time in seconds (0 for cosine, the oracle and fixture blobs).
    pub train_seconds: f64,
    /// Final training loss (null for cosine, the oracle and fixtures).
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
    /// For a neural material with a known source: mean KL(p*_source ‖ p) in nats, the
    /// sampler (conditioned on the neural φ) against the source material's ground truth at
    /// the same uv and wi; null otherwise.
    pub kl_vs_source: Option<f64>,
    /// Single-thread cost.
    pub cost: Cost,
    /// prepare + sample + pdf, ns (same as cost.total_ns).
    pub ns_per_sample: f64,
    /// `cost.total_ns / cost.material_eval_ns` (Table 1: sampling vs material evaluation).
    pub cost_vs_material_eval: f64,
    /// Speed-up over the improved baseline (copy of `render.speedup_vs_baseline`; null
    /// without rendering).
    pub speedup_vs_baseline: Option<f64>,
    /// MSE at equal spp (copy of `render.mse_equal_spp`).
    pub mse_equal_spp: Option<f64>,
    /// MSE at equal time (copy of `render.mse_equal_time`).
    pub mse_equal_time: Option<f64>,
    /// Rendering results (null with `--no-render`).
    pub render: Option<RenderReport>,
}

/// The reference image of a material.
#[derive(Clone, Debug, Serialize)]
pub struct ReferenceReport {
    /// Samples per pixel.
    pub spp: u32,
    /// Oracle table resolution.
    pub res: usize,
    /// Always `mis`.
    pub estimator: Estimator,
    /// Expected MSE contribution of its own noise (subtracted from every MSE).
    pub noise: f64,
    /// Pixels hitting an object (where MSE is measured).
    pub pixels: usize,
    /// Wall time of its render, seconds.
    pub seconds: f64,
    /// Linear image.
    pub exr: String,
    /// Tonemapped image.
    pub png: String,
}

/// Figures of a material (paths relative to the output folder).
#[derive(Clone, Debug, Serialize)]
pub struct FigureReport {
    /// Reference and every method at equal time, labelled (Figs. 1, 9).
    pub equal_time: String,
    /// Reference and every method at equal spp, labelled.
    pub equal_spp: String,
    /// MSE vs spp and vs time, log-log (Fig. 8).
    pub convergence: String,
    /// p* beside every method's p at a few conditions (Fig. 7).
    pub pdfs: String,
}

/// How well a neural material reproduces its source ([`crate::neural::train::FitReport`]).
#[derive(Clone, Debug, Serialize)]
pub struct NeuralReport {
    /// Source material name.
    pub source: String,
    /// Fit measures against the source.
    pub fit: crate::neural::train::FitReport,
    /// Single-thread cost of the neural material (`features`, `eval`), ns.
    pub cost: crate::neural::EvalCost,
    /// The same for the source material.
    pub source_cost: crate::neural::EvalCost,
}

/// All methods on one material.
#[derive(Clone, Debug, Serialize)]
pub struct MaterialReport {
    /// Material name.
    pub material: String,
    /// For a neural material with a known source: its fit and cost (null otherwise).
    pub neural: Option<NeuralReport>,
    /// Per method.
    pub methods: Vec<MethodReport>,
    /// The reference render (null with `--no-render`).
    pub reference: Option<ReferenceReport>,
    /// Figures (null with `--no-render`).
    pub figures: Option<FigureReport>,
    /// Single-thread time budget of the equal-time renders, seconds per image.
    pub equal_time_budget_seconds: Option<f64>,
}

/// Rendering setup shared by all materials.
#[derive(Clone, Debug, Serialize)]
pub struct RenderSetup {
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Sun radiance.
    pub sun_radiance: f32,
    /// Sun angular radius, degrees.
    pub sun_radius_deg: f32,
    /// Environment map file, if any.
    pub env_map: Option<String>,
    /// Uniform white lighting instead of the sky.
    pub uniform_light: bool,
    /// Sizes, seeds and the estimator.
    pub settings: RenderSettings,
}

/// The whole report (`report.json`).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Schema version of this JSON ([`REPORT_SCHEMA`]).
    pub schema: u32,
    /// Whether the run was `--quick`.
    pub quick: bool,
    /// Whether fixture blobs were used instead of training.
    pub fixtures: bool,
    /// Seed.
    pub seed: u64,
    /// Training steps relative to `neusample train`'s defaults (null with --quick or
    /// fixtures).
    pub steps_scale: Option<f64>,
    /// Evaluation conditions per material and method.
    pub eval_conditions: usize,
    /// Ground-truth resolution of the evaluation.
    pub eval_res: usize,
    /// Rendering setup (null with `--no-render`).
    pub render: Option<RenderSetup>,
    /// Wall time of the whole run, seconds.
    pub seconds: f64,
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

/// Which fixtures `neusample fixtures` regenerates.
#[derive(clap::ValueEnum, Copy, Clone, Debug, PartialEq, Eq)]
pub enum FixtureSet {
    /// Samplers on the procedural default materials.
    Procedural,
    /// The neural versions of the default materials and the samplers trained on them.
    Neural,
    /// Both.
    All,
}

/// `neusample fixtures`: trains every method on the default materials with fixed seeds and
/// writes `<out>/<material>/<method>.nsb` (f32, histogram tables T = 8, N = 32) plus
/// `<out>/cosine.nsb`; for the neural set, first fits the neural version of each default
/// material (`train-material` defaults, seed 1, f32) into `<materials>/<name>_neural.nsb`
/// and then trains the samplers on it into `<out>/<name>_neural/`.
pub fn regenerate_fixtures(
    out: &Path,
    materials_out: &Path,
    set: FixtureSet,
    quick: bool,
) -> Result<()> {
    io::atomic_write(
        &out.join("cosine.nsb"),
        &BlobWriter::new(SamplerKind::Cosine, DType::F32, "cosine").to_bytes(),
    )?;
    if set != FixtureSet::Neural {
        for name in DEFAULT_MATERIALS {
            fixture_samplers(out, materials::builtin(name)?.as_ref(), quick)?;
        }
    }
    if set != FixtureSet::Procedural {
        for name in DEFAULT_MATERIALS {
            let path = materials_out.join(format!("{name}{NEURAL_SUFFIX}.nsb"));
            let args = crate::neural::cli::TrainMaterialArgs {
                material: name.to_string(),
                out: path.clone(),
                safetensors: None,
                name: None,
                texture: None,
                steps: None,
                batch: None,
                lr: None,
                quick,
                f16: false,
                seed: 1,
                threads: None,
                eval_conditions: 64,
                eval_res: 64,
                eval_points: 20_000,
                report: None,
                json: false,
            };
            crate::neural::cli::train_material(&args)
                .with_context(|| format!("neural fixture of {name}"))?;
            let m = crate::neural::NeuralMaterialModel::load(&path)?;
            fixture_samplers(out, &m, quick)?;
        }
    }
    eprintln!("fixtures written to {}", out.display());
    Ok(())
}

/// Every method trained on `m` into `<out>/<m.name()>/`, plus the conditions file.
fn fixture_samplers(out: &Path, m: &dyn Material, quick: bool) -> Result<()> {
    let name = slug(m.name());
    let pb = bar(Method::ALL.len() as u64, &format!("fixtures {name}"));
    // Conditions drawn from the material, for the runtime's statistical tests (which do not
    // link the materials): one "φ0 … φ7 wi.x wi.y wi.z" line each.
    let conds = crate::groundtruth::conditions(m, 256, 0xC0DE);
    let mut text = String::from("# phi0..phi7 wi.x wi.y wi.z (local frame), from the material\n");
    for c in &conds {
        for v in c.phi {
            text.push_str(&format!("{v:e} "));
        }
        text.push_str(&format!("{:e} {:e} {:e}\n", c.wi.x, c.wi.y, c.wi.z));
    }
    io::atomic_write(&out.join(&name).join("conditions.txt"), text.as_bytes())?;
    for method in Method::ALL {
        pb.set_message(format!("{name}/{method}"));
        let mut cfg = if quick {
            TrainConfig::quick()
        } else {
            fixture_config(method)
        };
        cfg.seed = 1;
        let trained = train::train(m, method, &cfg)?;
        let label = format!(
            "fixture material={name} method={method} steps={} seed=1",
            cfg.steps
        );
        let bytes = bake::blob_bytes(&trained, DType::F32, &label)?;
        bake::verify(&trained, &bytes, m, 8, 7)
            .with_context(|| format!("fixture {name}/{method}"))?;
        io::atomic_write(&fixture_path(out, &name, method.name()), &bytes)?;
        pb.inc(1);
    }
    pb.finish_with_message(format!("{name} done"));
    Ok(())
}

/// Sizes of a demo run.
struct Preset {
    eval_conditions: usize,
    eval_res: usize,
    cost_n: usize,
    cost_passes: usize,
    /// The oracle's `prepare` tabulates the material: measured on far fewer conditions.
    oracle_cost_n: usize,
    scene: SceneParams,
    settings: RenderSettings,
    pdf_conditions: usize,
    pdf_res: usize,
    pdf_size: usize,
}

fn preset(a: &DemoArgs) -> Result<Preset> {
    let width = a.width.unwrap_or(if a.quick { 64 } else { 160 });
    anyhow::ensure!(
        (8..=4096).contains(&width),
        "--width must be in 8..=4096, got {width}"
    );
    anyhow::ensure!(
        a.steps_scale > 0.0 && a.steps_scale.is_finite(),
        "--steps-scale must be positive, got {}",
        a.steps_scale
    );
    let spp = a.spp.unwrap_or(if a.quick { 8 } else { 32 });
    anyhow::ensure!((1..=65536).contains(&spp), "--spp must be in 1..=65536");
    anyhow::ensure!(
        a.sun_radiance.is_finite() && a.sun_radiance >= 0.0,
        "--sun-radiance must be finite and ≥ 0"
    );
    anyhow::ensure!(
        a.sun_size.is_finite() && a.sun_size > 0.0 && a.sun_size < 90.0,
        "--sun-size must be in (0, 90) degrees"
    );
    let env_map = match &a.envmap {
        Some(p) => Some(EnvMap::load_exr(p)?),
        None => None,
    };
    let q = a.quick;
    Ok(Preset {
        eval_conditions: if q { 24 } else { 128 },
        eval_res: if q { 64 } else { 96 },
        cost_n: if q { 2000 } else { 10000 },
        cost_passes: if q { 3 } else { 5 },
        oracle_cost_n: if q { 20 } else { 100 },
        scene: SceneParams {
            width,
            height: (width * 3 / 4).max(1),
            sun_radiance: a.sun_radiance,
            sun_radius_deg: a.sun_size,
            env_map,
            uniform_light: a.uniform_light,
            ..SceneParams::default()
        },
        settings: RenderSettings {
            max_spp: spp,
            ref_spp: if q { 128 } else { 256 },
            ref_res: if q { 32 } else { 40 },
            oracle_res: if q { 24 } else { 32 },
            timing_spp: 1,
            timing_passes: 3,
            max_equal_time_spp: 64 * spp,
            estimator: if a.mis {
                Estimator::Mis
            } else {
                Estimator::Bsdf
            },
            seed: a.seed,
        },
        pdf_conditions: if q { 2 } else { 4 },
        pdf_res: 64,
        pdf_size: if q { 64 } else { 96 },
    })
}

/// A file-name-safe version of a material name.
fn slug(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// `neusample demo`.
pub fn run(a: &DemoArgs) -> Result<()> {
    let started = Instant::now();
    let (names, neural_defaults): (Vec<String>, bool) = if a.materials.is_empty() {
        (
            DEFAULT_MATERIALS.iter().map(|s| s.to_string()).collect(),
            !a.procedural,
        )
    } else {
        anyhow::ensure!(
            !a.procedural,
            "--procedural selects the procedural default materials; with --materials name them directly"
        );
        (a.materials.clone(), false)
    };
    let p = preset(a)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create output folder {}", a.out.display()))?;
    let out = a.out.canonicalize()?;
    eprintln!("neusample demo: writing to {}", out.display());

    let techniques = Method::ALL.len() + 2; // + cosine + oracle
    let per_material = techniques
        + if a.no_render {
            0
        } else {
            1 + 3 * techniques + 2
        };
    let pb = bar((names.len() * per_material) as u64, "demo");
    let mut report = Report {
        schema: REPORT_SCHEMA,
        quick: a.quick,
        fixtures: a.use_fixtures,
        seed: a.seed,
        steps_scale: (!a.quick && !a.use_fixtures).then_some(a.steps_scale),
        eval_conditions: p.eval_conditions,
        eval_res: p.eval_res,
        render: (!a.no_render).then(|| RenderSetup {
            width: p.scene.width,
            height: p.scene.height,
            sun_radiance: p.scene.sun_radiance,
            sun_radius_deg: p.scene.sun_radius_deg,
            env_map: a.envmap.as_ref().map(|e| e.display().to_string()),
            uniform_light: a.uniform_light,
            settings: p.settings.clone(),
        }),
        seconds: 0.0,
        materials: Vec::new(),
    };
    for name in &names {
        let DemoMaterial {
            material: m,
            source,
        } = resolve_demo_material(name, neural_defaults)?;
        let mname = m.name().to_string();
        let neural = source.as_ref().map(|src| {
            pb.set_message(format!("{mname}: fit to {}", src.name()));
            NeuralReport {
                source: src.name().to_string(),
                fit: crate::neural::train::fit_report(
                    src.as_ref(),
                    m.as_ref(),
                    if a.quick { 2000 } else { 20000 },
                    p.eval_conditions,
                    p.eval_res,
                    crate::neural::train::NeuralTrainConfig::default_run().epsilon,
                    a.seed + 100,
                ),
                cost: crate::neural::eval_cost(m.as_ref(), p.cost_n, p.cost_passes),
                source_cost: crate::neural::eval_cost(src.as_ref(), p.cost_n, p.cost_passes),
            }
        });
        let src = source.as_deref();
        let mut methods = Vec::new();
        let mut blobs: Vec<(String, Vec<u8>)> = Vec::new();

        pb.set_message(format!("{mname}/cosine"));
        let (fit, kl_src) = fits(&CosineSampler, m.as_ref(), src, &p, a.seed);
        let cost = eval::cost(&CosineSampler, m.as_ref(), p.cost_n, p.cost_passes);
        methods.push(method_report("cosine", 0.0, None, 0, None, fit, cost));
        methods.last_mut().expect("pushed").kl_vs_source = kl_src;
        pb.inc(1);

        for method in Method::ALL {
            pb.set_message(format!("{mname}/{method}"));
            let (bytes, secs, loss, check) = if a.use_fixtures {
                let path = fixture_path(&fixtures_dir(), &slug(&mname), method.name());
                (io::read_blob(&path)?, 0.0, None, None)
            } else {
                let mut cfg = if a.quick {
                    TrainConfig::quick()
                } else {
                    let mut c = TrainConfig::default_for(method);
                    c.steps = ((c.steps as f64 * a.steps_scale).round() as usize).max(1);
                    c
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
                &out.join("blobs")
                    .join(slug(&mname))
                    .join(format!("{method}.nsb")),
                &bytes,
            )?;
            let blob = Blob::open(&bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
            let sampler = blob.sampler().map_err(|e| anyhow::anyhow!("{e}"))?;
            let (fit, kl_src) = fits(&sampler, m.as_ref(), src, &p, a.seed);
            let cost = eval::cost(&sampler, m.as_ref(), p.cost_n, p.cost_passes);
            methods.push(method_report(
                method.name(),
                secs,
                loss,
                bytes.len(),
                check,
                fit,
                cost,
            ));
            methods.last_mut().expect("pushed").kl_vs_source = kl_src;
            blobs.push((method.name().to_string(), bytes));
            pb.inc(1);
        }

        pb.set_message(format!("{mname}/{ORACLE}"));
        let oracle = OracleSampler::new(m.as_ref(), p.settings.oracle_res);
        let (fit, kl_src) = fits(&oracle, m.as_ref(), src, &p, a.seed);
        let cost = eval::cost(&oracle, m.as_ref(), p.oracle_cost_n, p.cost_passes.min(3));
        methods.push(method_report(ORACLE, 0.0, None, 0, None, fit, cost));
        methods.last_mut().expect("pushed").kl_vs_source = kl_src;
        pb.inc(1);

        let (reference, figures, budget) = if a.no_render {
            (None, None, None)
        } else {
            let (r, f, b) = render_material(&out, m.as_ref(), &blobs, &p, &pb, &mut methods)?;
            (Some(r), Some(f), Some(b))
        };
        report.materials.push(MaterialReport {
            material: mname,
            neural,
            methods,
            reference,
            figures,
            equal_time_budget_seconds: budget,
        });
    }
    pb.finish_with_message("done");
    report.seconds = started.elapsed().as_secs_f64();

    let json = serde_json::to_string_pretty(&report)?;
    io::atomic_write(&out.join("report.json"), json.as_bytes())?;
    io::atomic_write(&out.join("report.md"), markdown(&report).as_bytes())?;
    eprintln!(
        "neusample demo finished in {:.0} s: {}",
        report.seconds,
        out.join("report.md").display()
    );
    eprintln!("output folder: {}", out.display());
    Ok(())
}

/// Renders one material with every technique, writes its images and plots, and fills the
/// `render` part of its method reports.
fn render_material(
    out: &Path,
    m: &dyn Material,
    blobs: &[(String, Vec<u8>)],
    p: &Preset,
    pb: &ProgressBar,
    methods: &mut [MethodReport],
) -> Result<(ReferenceReport, FigureReport, f64)> {
    let mname = m.name().to_string();
    let dir = format!("images/{}", slug(&mname));
    let opened = blobs
        .iter()
        .map(|(n, b)| {
            Ok((
                n.clone(),
                Blob::open(b).map_err(|e| anyhow::anyhow!("{e}"))?,
            ))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut techniques: Vec<(String, Technique<'_>)> = vec![(
        "cosine".to_string(),
        Technique::Blob(AnySampler::Cosine(CosineSampler)),
    )];
    for (n, blob) in &opened {
        let s = blob.sampler().map_err(|e| anyhow::anyhow!("{e}"))?;
        techniques.push((n.clone(), Technique::Blob(s)));
    }
    techniques.push((
        ORACLE.to_string(),
        Technique::Oracle(OracleSampler::new(m, p.settings.oracle_res)),
    ));

    let scene = render::demo_scene(&p.scene);
    pb.set_message(format!("{mname}/reference"));
    let reference = metrics::reference(&scene, m, &p.settings);
    pb.inc(1);
    let evals = metrics::evaluate(
        &scene,
        m,
        &techniques,
        &reference,
        BASELINE,
        &p.settings,
        &|msg| {
            pb.set_message(format!("{mname}/{msg}"));
            pb.inc(1);
        },
    )?;

    // Images.
    pb.set_message(format!("{mname}/figures"));
    let rr = &reference.render;
    let exposure = figures::auto_exposure(&rr.image, &rr.mask);
    let ref_png = format!("{dir}/reference.png");
    let ref_exr = format!("{dir}/reference.exr");
    let ref_tm = figures::tonemap(&rr.image, exposure);
    figures::write_png(&out.join(&ref_png), &ref_tm)?;
    figures::write_exr(&out.join(&ref_exr), &rr.image)?;
    let ref_caption = [
        "reference".to_string(),
        format!("oracle + MIS, {} spp", rr.spp),
    ];
    let mut time_tiles: Vec<(Rgb8, [String; 2])> = vec![(ref_tm.clone(), ref_caption.clone())];
    let mut spp_tiles: Vec<(Rgb8, [String; 2])> = vec![(ref_tm, ref_caption)];
    let base = evals
        .iter()
        .position(|e| e.name == BASELINE)
        .context("no baseline technique")?;
    let cosine_ns = evals
        .iter()
        .find(|e| e.name == "cosine")
        .map_or(f64::NAN, |e| e.ns_per_sample);
    for e in &evals {
        let stem = format!("{dir}/{}", e.name);
        let et_png = format!("{stem}.equal_time.png");
        let et_exr = format!("{stem}.equal_time.exr");
        let es_png = format!("{stem}.equal_spp.png");
        let t_img = figures::tonemap(&e.equal_time.image, exposure);
        let s_img = figures::tonemap(&e.equal_spp.image, exposure);
        figures::write_png(&out.join(&et_png), &t_img)?;
        figures::write_exr(&out.join(&et_exr), &e.equal_time.image)?;
        figures::write_png(&out.join(&es_png), &s_img)?;
        time_tiles.push((
            t_img,
            [
                e.name.clone(),
                format!("{} spp · MSE {:.2e}", e.equal_time_spp, e.mse_equal_time),
            ],
        ));
        spp_tiles.push((
            s_img,
            [
                e.name.clone(),
                format!("{} spp · MSE {:.2e}", e.equal_spp.spp, e.mse_equal_spp),
            ],
        ));
        let r = RenderReport {
            ns_per_sample: e.ns_per_sample,
            time_vs_cosine: e.ns_per_sample / cosine_ns,
            equal_spp: e.equal_spp.spp,
            mse_equal_spp: e.mse_equal_spp,
            equal_time_spp: e.equal_time_spp,
            mse_equal_time: e.mse_equal_time,
            speedup_vs_baseline: metrics::speedup(e, &evals[base]),
            speedup_measured_mse: metrics::speedup_measured(e, &evals[base]),
            mse_expected_equal_spp: e.mse_expected_equal_spp,
            mse_ratio_equal_spp: metrics::variance_ratio(e, &evals[base]),
            convergence: e.convergence.clone(),
            equal_time_exr: et_exr,
            equal_time_png: et_png,
            equal_spp_png: es_png,
        };
        if let Some(mr) = methods.iter_mut().find(|x| x.method == e.name) {
            mr.speedup_vs_baseline = Some(r.speedup_vs_baseline);
            mr.mse_equal_spp = Some(r.mse_equal_spp);
            mr.mse_equal_time = Some(r.mse_equal_time);
            mr.render = Some(r);
        }
    }
    let budget = evals[base].ns_per_sample
        * f64::from(p.settings.max_spp)
        * (scene.camera.width * scene.camera.height) as f64
        * 1e-9;
    let est = match p.settings.estimator {
        Estimator::Bsdf => "BSDF sampling",
        Estimator::Mis => "MIS",
    };
    let eq_time = format!("{dir}/equal_time.png");
    figures::write_png(
        &out.join(&eq_time),
        &figures::labelled_grid(
            &time_tiles,
            3,
            &format!(
                "{mname}: equal time ({:.0} ms single-thread per image), {est}",
                budget * 1e3
            ),
        )?,
    )?;
    let eq_spp = format!("{dir}/equal_spp.png");
    figures::write_png(
        &out.join(&eq_spp),
        &figures::labelled_grid(
            &spp_tiles,
            3,
            &format!("{mname}: equal spp ({}), {est}", p.settings.max_spp),
        )?,
    )?;
    pb.inc(1);

    // Convergence plot (Fig. 8).
    let by_spp: Vec<figures::Series> = evals
        .iter()
        .map(|e| figures::Series {
            name: e.name.clone(),
            points: e
                .convergence
                .iter()
                .map(|c| (f64::from(c.spp), c.mse))
                .collect(),
        })
        .collect();
    let by_time: Vec<figures::Series> = evals
        .iter()
        .filter(|e| e.name != ORACLE)
        .map(|e| figures::Series {
            name: e.name.clone(),
            points: e
                .convergence
                .iter()
                .map(|c| (c.seconds * 1e3, c.mse))
                .collect(),
        })
        .collect();
    let conv = format!("plots/{}_convergence.png", slug(&mname));
    figures::write_png(
        &out.join(&conv),
        &figures::convergence_plot(
            &format!("{mname}: convergence ({est})"),
            &by_spp,
            &by_time,
            "single-thread time per image (ms)",
        )?,
    )?;

    // pdf grid (Fig. 7).
    let pdfs = format!("{dir}/pdfs.png");
    figures::write_png(
        &out.join(&pdfs),
        &pdf_figure(m, &techniques, p, p.settings.seed + 500)?,
    )?;
    pb.inc(1);

    let pixels = rr.mask.iter().filter(|&&b| b).count();
    Ok((
        ReferenceReport {
            spp: rr.spp,
            res: p.settings.ref_res,
            estimator: Estimator::Mis,
            noise: reference.noise,
            pixels,
            seconds: rr.seconds,
            exr: ref_exr,
            png: ref_png,
        },
        FigureReport {
            equal_time: eq_time,
            equal_spp: eq_spp,
            convergence: conv,
            pdfs,
        },
        budget,
    ))
}

/// Fig. 7: for a few random conditions, the ground truth p* (tabulated at `pdf_res`) beside
/// every runtime sampler's disk density, false colour `viridis(√(p / max p*))`, with
/// KL(p* ‖ p) under each.
fn pdf_figure(
    m: &dyn Material,
    techniques: &[(String, Technique<'_>)],
    p: &Preset,
    seed: u64,
) -> Result<Rgb8> {
    let conds = groundtruth::conditions(m, p.pdf_conditions, seed);
    let samplers: Vec<(&String, &AnySampler<'_>)> = techniques
        .iter()
        .filter_map(|(n, t)| match t {
            Technique::Blob(s) => Some((n, s)),
            Technique::Oracle(_) => None,
        })
        .collect();
    let size = p.pdf_size;
    let mut tiles = Vec::new();
    for c in &conds {
        let target = TargetPdf::new(m, c, p.pdf_res);
        let vmax = target.density().iter().copied().fold(0.0f32, f32::max);
        let theta = c.wi.z.clamp(-1.0, 1.0).acos().to_degrees();
        tiles.push((
            figures::disk_image(size, vmax, |q| target.pdf(q)),
            [
                "p* (ground truth)".to_string(),
                format!("θi {theta:.0}° uv {:.2},{:.2}", c.uv.x, c.uv.y),
            ],
        ));
        for (name, s) in &samplers {
            let (img, kl) = match s.prepare(&c.phi, c.wi) {
                Some(prep) => (
                    figures::disk_image(size, vmax, |q| prep.pdf_disk(q)),
                    target.kl_from(|q| prep.pdf_disk(q)),
                ),
                None => (Rgb8::filled(size, size, [40, 40, 40]), f64::INFINITY),
            };
            tiles.push((img, [(*name).clone(), format!("KL {kl:.3}")]));
        }
    }
    figures::labelled_grid(
        &tiles,
        samplers.len() + 1,
        &format!(
            "{}: pdfs on the projected disk, viridis(sqrt(p / max p*)), one row per condition",
            m.name()
        ),
    )
}

/// The fit of a sampler to the material's ground truth and, when a source is given, the mean
/// KL against the source's ground truth (same conditions).
fn fits<S: Sampler + Sync>(
    sampler: &S,
    m: &dyn Material,
    source: Option<&dyn Material>,
    p: &Preset,
    seed: u64,
) -> (Fit, Option<f64>) {
    let fit = eval::fit(sampler, m, p.eval_conditions, p.eval_res, seed + 100);
    let kl_src = source.map(|src| {
        eval::fit_to(
            sampler,
            m,
            Some(src),
            p.eval_conditions,
            p.eval_res,
            seed + 100,
        )
        .kl_divergence
    });
    (fit, kl_src)
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
        kl_vs_source: None,
        ns_per_sample: cost.total_ns,
        cost_vs_material_eval: cost.total_ns / cost.material_eval_ns.max(1e-9),
        cost,
        speedup_vs_baseline: None,
        mse_equal_spp: None,
        mse_equal_time: None,
        render: None,
    }
}

fn fmt_x(v: Option<f64>) -> String {
    match v {
        Some(x) if x.is_finite() => {
            if x >= 10.0 {
                format!("{x:.1}×")
            } else {
                format!("{x:.2}×")
            }
        }
        _ => "—".to_string(),
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
        "{} run, {}, seed {}, {:.0} s. Fit: mean over {} random conditions (φ, wi), ground truth on a {}² grid. \
         Cost: single thread, ns per call (median of passes).\n",
        if r.quick { "Quick" } else { "Full" },
        match (r.fixtures, r.steps_scale) {
            (true, _) => "committed fixture blobs".to_string(),
            (false, Some(f)) => format!("freshly trained samplers ({f}× the default training steps)"),
            (false, None) => "freshly trained samplers (quick training)".to_string(),
        },
        r.seed,
        r.seconds,
        r.eval_conditions,
        r.eval_res
    );
    if let Some(rs) = &r.render {
        let st = &rs.settings;
        let _ = writeln!(
            s,
            "Rendering: a {}×{} image of a textured patch and a sphere under {} (sun radiance {}, \
             radius {}°), direct lighting by {}. Reference: the tabulated oracle ({}² cells) with MIS at {} spp; \
             MSE over the pixels that hit an object, minus the reference's own noise. \
             Time per sample: single-thread wall time of the whole render loop per pixel sample \
             (oracle: per-pixel table build excluded — it is a limit, not a method). \
             Speed-up (Table 2): (MSE·time of the improved baseline) / (MSE·time of the method) at N = {} spp, \
             i.e. the relative time the baseline needs for the same quality, with the expected MSE σ²/N from the \
             per-pixel sample variances (the speed-up from the measured MSE against the reference is shown beside it). Equal time: every method gets \
             the baseline's time for {} spp.\n",
            rs.width,
            rs.height,
            match (&rs.env_map, rs.uniform_light) {
                (Some(e), _) => format!("the map {e}"),
                (None, true) => "uniform white light".to_string(),
                (None, false) => "a procedural sky".to_string(),
            },
            rs.sun_radiance,
            rs.sun_radius_deg,
            match st.estimator {
                Estimator::Bsdf => "BSDF sampling (the paper's main mode)",
                Estimator::Mis => "MIS of BSDF and environment sampling (power heuristic)",
            },
            st.ref_res,
            st.ref_spp,
            st.max_spp,
            st.max_spp,
        );
        // Table 2.
        let methods: Vec<String> = r
            .materials
            .first()
            .map(|m| m.methods.iter().map(|x| x.method.clone()).collect())
            .unwrap_or_default();
        let _ = writeln!(s, "## Speed-up over the improved baseline (Table 2)\n");
        let _ = writeln!(
            s,
            "Paper: best method per material 1.28×–6.78×, mean 2.58×; flow 1.17–6.78×, histogram mixture 1.07–6.12×, cosine 0.05–0.88×. \
             The best practical method (oracle excluded) is in bold.\n"
        );
        let _ = writeln!(s, "| material | {} |", methods.join(" | "));
        let _ = writeln!(s, "|---|{}", "---:|".repeat(methods.len()));
        for m in &r.materials {
            let best = m
                .methods
                .iter()
                .filter(|x| x.method != ORACLE)
                .filter_map(|x| x.speedup_vs_baseline.filter(|v| v.is_finite()))
                .fold(f64::NEG_INFINITY, f64::max);
            let cells: Vec<String> = m
                .methods
                .iter()
                .map(|x| {
                    let t = fmt_x(x.speedup_vs_baseline);
                    if x.method != ORACLE && x.speedup_vs_baseline == Some(best) {
                        format!("**{t}**")
                    } else {
                        t
                    }
                })
                .collect();
            let _ = writeln!(s, "| {} | {} |", m.material, cells.join(" | "));
        }
        let _ = writeln!(s);
    }
    for m in &r.materials {
        let _ = writeln!(s, "## {}\n", m.material);
        if let Some(n) = &m.neural {
            let _ = writeln!(
                s,
                "Neural material (feature texture + decoder, NEURAL.md) fitted to `{}`: relative RGB error {:.1} % \
                 (wo on the disk), {:.1} % (around the mirror direction), albedo error {:.1} %, \
                 KL(p*_source ‖ p*_neural) = {:.4} nats (cosine sampling: {:.4}). Evaluation cost: {:.0} ns \
                 (source {:.0} ns), feature lookup {:.0} ns (source {:.0} ns). The samplers are trained on the \
                 neural material (φ = learned features, p* from the decoder); `KL(p*_src‖p)` measures them \
                 against the source material.\n",
                n.source,
                100.0 * n.fit.relative_rgb_error,
                100.0 * n.fit.relative_rgb_error_lobe,
                100.0 * n.fit.albedo_relative_error,
                n.fit.kl_pstar,
                n.fit.kl_pstar_vs_cosine,
                n.cost.eval_ns,
                n.source_cost.eval_ns,
                n.cost.features_ns,
                n.source_cost.features_ns,
            );
        }
        let _ = writeln!(
            s,
            "### pdf fit and cost (Table 1 ratio: sampling cost / material evaluation)\n"
        );
        let _ = writeln!(
            s,
            "| method | KL(p*‖p) | KL(p*_src‖p) | pdf MSE | mass in disk | prepare ns | sample ns | pdf ns | prepare+sample+pdf ns | material eval ns | ×material eval | train s | blob bytes |"
        );
        let _ = writeln!(
            s,
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
        );
        for x in &m.methods {
            let _ = writeln!(
                s,
                "| {} | {:.4} | {} | {:.3e} | {:.4} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.2} | {:.1} | {} |",
                x.method,
                x.kl_divergence,
                x.kl_vs_source
                    .map_or_else(|| "—".to_string(), |k| format!("{k:.4}")),
                x.pdf_mse,
                x.mass_in_disk,
                x.cost.prepare_ns,
                x.cost.sample_ns,
                x.cost.pdf_ns,
                x.cost.total_ns,
                x.cost.material_eval_ns,
                x.cost_vs_material_eval,
                x.train_seconds,
                x.blob_bytes
            );
        }
        let _ = writeln!(s);
        if let (Some(rf), Some(fg)) = (&m.reference, &m.figures) {
            let _ = writeln!(s, "### Rendering\n");
            let _ = writeln!(
                s,
                "| method | render ns/sample | ×cosine time | MSE @ N spp | expected MSE @ N spp | MSE ratio vs baseline (N spp) | equal-time spp | MSE @ equal time | speed-up vs baseline | speed-up (measured MSE) |"
            );
            let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
            for x in &m.methods {
                if let Some(rr) = &x.render {
                    let _ = writeln!(
                        s,
                        "| {} | {:.0} | {:.2} | {:.3e} | {:.3e} | {} | {} | {:.3e} | {} | {} |",
                        x.method,
                        rr.ns_per_sample,
                        rr.time_vs_cosine,
                        rr.mse_equal_spp,
                        rr.mse_expected_equal_spp,
                        fmt_x(Some(rr.mse_ratio_equal_spp)),
                        rr.equal_time_spp,
                        rr.mse_equal_time,
                        fmt_x(Some(rr.speedup_vs_baseline)),
                        fmt_x(Some(rr.speedup_measured_mse)),
                    );
                }
            }
            let _ = writeln!(
                s,
                "\nReference: {} spp, oracle {}², {} pixels on objects, its noise {:.2e} (subtracted). \
                 Equal-time budget: {:.0} ms single-thread per image. Linear EXRs beside the PNGs.\n",
                rf.spp,
                rf.res,
                rf.pixels,
                rf.noise,
                m.equal_time_budget_seconds.unwrap_or(f64::NAN) * 1e3
            );
            let _ = writeln!(s, "![equal time]({})\n", fg.equal_time);
            let _ = writeln!(s, "![convergence]({})\n", fg.convergence);
            let _ = writeln!(s, "![pdfs]({})\n", fg.pdfs);
            let _ = writeln!(s, "![equal spp]({})\n", fg.equal_spp);
        }
    }
    s
}
