//! The demo run (`neusample demo`): every method trained on the demo materials (or loaded
//! from the fixtures), baked, verified, and evaluated through the runtime's public API — pdf
//! fit, cost, and rendering with the tabulated oracle beside them — into `report.json`,
//! `report.md`, images and plots.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use glam::Vec2;
use indicatif::ProgressBar;
use neusample::samplers::CosineSampler;
use neusample::{Blob, BlobSampler};
use neusample::{DType, Prepared, Sampler, SamplerKind};
use neusample_render::{demo_scene, Estimator};

use super::config::{
    preset, resolve_demo_material, DemoConfig, DemoMaterial, Preset, BASELINE, COSINE,
    DEFAULT_MATERIALS, MEASURED_DATA, ORACLE,
};
use super::figures::{self, Rgb8};
use super::fixtures::fixture_path;
use super::markdown::{fmt_chi2, markdown};
use super::report::{
    method_report, FigureReport, MaterialReport, MethodReport, NeuralReport, ReferenceReport,
    RenderReport, RenderSetup, Report, Training, REPORT_SCHEMA,
};
use crate::bake;
use crate::defend;
use crate::eval::measured_data::MeasuredDataSampler;
use crate::eval::metrics::{self, Technique};
use crate::eval::{self, Fit, OracleSampler};
use crate::groundtruth::{self, TargetPdf};
use crate::materials::Material;
use crate::train::neural_material::NeuralTrainConfig;
use crate::train::{self, has_integrand, needs_integrand, TrainConfig};
use crate::util::io::{self, slug};
use crate::util::progress::stages_bar;
use crate::util::rng::Stream;

/// A sampler trained by the demo: the checked blob and what the report says of its training.
pub(crate) struct TrainedBlob {
    /// The blob (f32, baked, checked, with its defensive weight).
    pub(crate) bytes: Vec<u8>,
    /// Training time.
    pub(crate) seconds: f64,
    /// The last training loss.
    pub(crate) loss: Option<f32>,
    /// The bake check's largest relative pdf error.
    pub(crate) max_relative: f64,
}

impl TrainedBlob {
    /// What its method's report says of its training.
    pub(crate) fn training(&self) -> Training {
        Training {
            seconds: self.seconds,
            final_loss: self.loss,
            blob_bytes: self.bytes.len(),
            blob_vs_model: Some(self.max_relative),
        }
    }
}

/// The training settings of `neusample demo --train`: the quick schedule with `a.quick`,
/// else the defaults scaled by `a.steps_scale`; seed `a.seed`.
pub(crate) fn demo_train_config(a: &DemoConfig) -> TrainConfig {
    let mut cfg = if a.quick {
        TrainConfig::quick()
    } else {
        TrainConfig::default().with_steps_scaled(a.steps_scale)
    };
    cfg.common.seed = a.seed;
    cfg
}

/// The label [`train_blob`] gives the blob of `method` trained on the material `mname` with
/// `cfg`: it ends with a fingerprint of every training setting, so that a run which finds
/// the blob on disk can tell whether it was trained as that run would train it (the
/// fingerprint is the standard library's hash of the settings' `Debug` text: another
/// toolchain may change it, which costs a retraining, never a stale blob).
pub(crate) fn demo_blob_label(mname: &str, method: SamplerKind, cfg: &TrainConfig) -> String {
    use std::hash::{DefaultHasher, Hash, Hasher};
    let mut h = DefaultHasher::new();
    format!("{cfg:?}").hash(&mut h);
    format!(
        "demo material={mname} method={} steps={} settings={:016x}",
        method.name(),
        cfg.schedule(method).map_or(0, |s| s.steps),
        h.finish()
    )
}

/// `method` trained on `m` as `neusample demo --train` trains it: the quick schedule with
/// `a.quick`, else the defaults scaled by `a.steps_scale`; seed `a.seed`; baked to f32,
/// checked and given its defensive weight.
pub(crate) fn train_blob(
    m: &dyn Material,
    method: SamplerKind,
    a: &DemoConfig,
) -> Result<TrainedBlob> {
    let (mname, method_name) = (m.name(), method.name());
    let cfg = demo_train_config(a);
    let trained = train::train(m, method, &cfg)
        .with_context(|| format!("training {method_name} on {mname}"))?;
    let label = demo_blob_label(mname, method, &cfg);
    let (bytes, v) = bake::checked_blob_bytes(
        &trained,
        DType::F32,
        &label,
        m,
        8,
        Stream::DemoBlobCheck.of(a.seed),
    )
    .with_context(|| format!("baking {method_name} on {mname}"))?;
    let (bytes, _) = defend::defend_baked(bytes, m, Stream::Defend.of(a.seed))?;
    Ok(TrainedBlob {
        bytes,
        seconds: trained.seconds,
        loss: trained.loss_history.last().copied(),
        max_relative: v.max_relative,
    })
}

/// `neusample demo`.
pub fn run(a: &DemoConfig) -> Result<()> {
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

    let method_list = a.method_list();
    let techniques = method_list.len() + 2; // + cosine + oracle
    let per_material = techniques
        + if a.no_render {
            0
        } else {
            1 + 3 * techniques + 2
        };
    let pb = stages_bar((names.len() * per_material) as u64, "demo");
    let mut report = new_report(a, &p);
    for name in &names {
        let material_started = Instant::now();
        let DemoMaterial {
            material: m,
            source,
        } = resolve_demo_material(name, neural_defaults)?;
        let mname = m.name().to_string();
        let neural = source
            .as_ref()
            .map(|src| neural_report(src.as_ref(), m.as_ref(), a, &p, &pb));
        let src = source.as_deref();
        let (mut methods, blobs) = fit_and_cost(m.as_ref(), src, a, &p, &out, &pb)?;
        let fit_seconds = material_started.elapsed().as_secs_f64();
        let (reference, figures, budget) = if a.no_render {
            (None, None, None)
        } else {
            let (r, f, b) = render_material(&out, m.as_ref(), &blobs, &p, &pb, &mut methods)?;
            (Some(r), Some(f), Some(b))
        };
        eprintln!(
            "{mname}: {:.0} s training, fits and costs, {:.0} s rendering",
            fit_seconds,
            material_started.elapsed().as_secs_f64() - fit_seconds
        );
        report.materials.push(MaterialReport {
            material: mname,
            neural,
            methods,
            reference,
            figures,
            equal_time_budget_seconds: budget,
            verdict: None,
        });
        let last = report.materials.last_mut().expect("pushed");
        last.verdict = metrics::verdict(
            &last
                .methods
                .iter()
                .filter(|x| x.method != ORACLE)
                .filter_map(|x| Some((x.method.clone(), x.render.as_ref()?.speedup)))
                .collect::<Vec<_>>(),
        );
    }
    pb.finish_with_message("done");
    report.seconds = started.elapsed().as_secs_f64();

    let json = serde_json::to_string_pretty(&report)?;
    io::atomic_write(&out.join("report.json"), json.as_bytes())?;
    io::atomic_write(&out.join("report.md"), markdown(&report).as_bytes())?;
    if a.quick {
        eprintln!("{}", super::markdown::SMOKE_LINE.replace("**", ""));
    }
    eprintln!(
        "neusample demo finished in {:.0} s: {}",
        report.seconds,
        out.join("report.md").display()
    );
    eprintln!("output folder: {}", out.display());
    Ok(())
}

/// The report before any material: the run's settings.
fn new_report(a: &DemoConfig, p: &Preset) -> Report {
    Report {
        schema: REPORT_SCHEMA,
        quick: a.quick,
        fixtures: a.use_fixtures,
        blobs: a
            .blobs
            .as_ref()
            .filter(|_| a.use_fixtures)
            .map(|b| b.display().to_string()),
        seed: a.seed,
        steps_scale: (!a.quick && !a.use_fixtures).then_some(a.steps_scale),
        eval_conditions: p.eval_conditions,
        eval_res: p.eval_res,
        render: (!a.no_render).then(|| RenderSetup {
            width: p.scene.width,
            height: p.scene.height,
            sun_radiance: p.scene.sun_radiance,
            sun_radius_deg: p.scene.sun_radius_deg,
            env_map: a.sky.env_map_name(),
            uniform_light: p.scene.uniform_light,
            settings: p.settings.clone(),
        }),
        seconds: 0.0,
        materials: Vec::new(),
    }
}

/// A neural material's fit to its source (RGB error, KL) and both materials' costs.
fn neural_report(
    src: &dyn Material,
    m: &dyn Material,
    a: &DemoConfig,
    p: &Preset,
    pb: &ProgressBar,
) -> NeuralReport {
    pb.set_message(format!("{}: fit to {}", m.name(), src.name()));
    NeuralReport {
        source: src.name().to_string(),
        fit: eval::fit_report(
            src,
            m,
            if a.quick { 2000 } else { 20000 },
            p.eval_conditions,
            p.eval_res,
            NeuralTrainConfig::default_run().epsilon,
            Stream::Fit.of(a.seed),
        ),
        cost: eval::eval_cost(m, p.cost_n, p.cost_passes),
        source_cost: eval::eval_cost(src, p.cost_n, p.cost_passes),
    }
}

/// Every technique's fit and cost on `m` (cosine, each method of `a` from its fixture or
/// trained now, the oracle and a measured material's own sampler), with the learned blobs,
/// which are also written under `out/blobs/`.
#[allow(clippy::type_complexity)]
fn fit_and_cost(
    m: &dyn Material,
    src: Option<&dyn Material>,
    a: &DemoConfig,
    p: &Preset,
    out: &Path,
    pb: &ProgressBar,
) -> Result<(Vec<MethodReport>, Vec<(String, Vec<u8>)>)> {
    let mname = m.name().to_string();
    let method_list = a.method_list();
    let mut methods = Vec::new();
    let mut blobs: Vec<(String, Vec<u8>)> = Vec::new();

    pb.set_message(format!("{mname}/{COSINE}"));
    let fit = fits(&CosineSampler, m, src, p, a.seed);
    let cost = eval::cost(&CosineSampler, m, p.cost_n, p.cost_passes);
    methods.push(method_report(COSINE, Training::NONE, fit, cost));
    pb.inc(1);

    for &method in &method_list {
        let method_name = method.name();
        if needs_integrand(method) && !has_integrand(m) {
            // Trained on the integrand itself: neural and measured materials have one.
            pb.inc(if a.no_render { 1 } else { 4 });
            continue;
        }
        pb.set_message(format!("{mname}/{method_name}"));
        let (bytes, training) = if a.use_fixtures {
            let path = fixture_path(&a.blob_dir(&mname), &slug(&mname), method_name);
            let bytes = io::read_blob(&path)?;
            let training = Training {
                blob_bytes: bytes.len(),
                ..Training::NONE
            };
            (bytes, training)
        } else {
            let t = train_blob(m, method, a)?;
            let training = t.training();
            (t.bytes, training)
        };
        io::atomic_write(
            &out.join("blobs")
                .join(slug(&mname))
                .join(format!("{method_name}.nsb")),
            &bytes,
        )?;
        let blob = Blob::open(&bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
        let sampler = blob.sampler().map_err(|e| anyhow::anyhow!("{e}"))?;
        let fit = fits(&sampler, m, src, p, a.seed);
        let cost = eval::cost_any(&sampler, m, p.cost_n, p.cost_passes);
        methods.push(method_report(method_name, training, fit, cost));
        blobs.push((method_name.to_string(), bytes));
        pb.inc(1);
    }

    pb.set_message(format!("{mname}/{ORACLE}"));
    let oracle = OracleSampler::new(m, p.settings.oracle_res);
    let fit = fits(&oracle, m, src, p, a.seed);
    let cost = eval::cost_scalar(&oracle, m, p.oracle_cost_n, p.cost_passes.min(3));
    methods.push(method_report(ORACLE, Training::NONE, fit, cost));
    pb.inc(1);

    // A measured material's own sampler: the peer a user of the data would pick.
    if let Some(data) = m.measured() {
        pb.set_message(format!("{mname}/{MEASURED_DATA}"));
        let s = MeasuredDataSampler(data.material().borrowed());
        let fit = fits(&s, m, src, p, a.seed);
        let cost = eval::cost(&s, m, p.cost_n, p.cost_passes);
        methods.push(method_report(MEASURED_DATA, Training::NONE, fit, cost));
    }
    Ok((methods, blobs))
}

/// The techniques a material is rendered with: cosine, the learned blobs, a measured
/// material's own sampler and the tabulated oracle.
fn techniques<'m>(
    m: &'m dyn Material,
    blobs: &'m [(String, Vec<u8>)],
    p: &Preset,
) -> Result<Vec<(String, Technique<'m>)>> {
    let mut techniques: Vec<(String, Technique<'_>)> =
        vec![(COSINE.to_string(), Technique::Blob(BlobSampler::cosine()))];
    for (n, bytes) in blobs {
        let blob = Blob::open(bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
        let s = blob.sampler().map_err(|e| anyhow::anyhow!("{e}"))?;
        techniques.push((n.clone(), Technique::Blob(s)));
    }
    if let Some(data) = m.measured() {
        techniques.push((
            MEASURED_DATA.to_string(),
            Technique::Measured(data.material().borrowed()),
        ));
    }
    techniques.push((
        ORACLE.to_string(),
        Technique::Oracle(OracleSampler::new(m, p.settings.oracle_res)),
    ));
    Ok(techniques)
}

/// One technique's rendering figures against the baseline `base`: the intervals come from
/// the method's own resampling stream. `paths`: its equal-time EXR and PNG, its equal-spp PNG.
fn render_report(
    e: &metrics::TechniqueEval,
    base: &metrics::TechniqueEval,
    cosine_ns: f64,
    seed: u64,
    paths: [String; 3],
) -> RenderReport {
    let [equal_time_exr, equal_time_png, equal_spp_png] = paths;
    // The resampling stream of this method: the seed mixed with the method's name.
    let name_key = e.name.bytes().fold(0xCBF2_9CE4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x100_0000_01B3)
    });
    let seed = crate::util::rng::mix_seed(Stream::Bootstrap.of(seed), name_key);
    let speedup = metrics::speedup(e, base, seed);
    let mse_ratio = metrics::variance_ratio(e, base, seed);
    RenderReport {
        blocks: e.equal_spp.blocks.len() as u32,
        variance: e.variance,
        mse_equal_spp_interval: e.mse_at(e.equal_spp.spp),
        mse_equal_time_interval: e.mse_equal_time_estimate(seed),
        speedup,
        mse_ratio,
        ns_per_sample: e.ns_per_sample,
        time_vs_cosine: e.ns_per_sample / cosine_ns,
        equal_spp: e.equal_spp.spp,
        mse_equal_spp: e.mse_equal_spp,
        equal_time_spp: e.equal_time_spp,
        mse_equal_time: e.mse_equal_time,
        speedup_measured_mse: metrics::speedup_measured(e, base),
        mse_expected_equal_spp: e.mse_expected_equal_spp,
        convergence: e.convergence.clone(),
        equal_time_exr,
        equal_time_png,
        equal_spp_png,
    }
}

/// The convergence plot (Fig. 8): MSE against spp and against time; its path under `out`.
fn convergence_figure(
    out: &Path,
    mname: &str,
    evals: &[metrics::TechniqueEval],
    est: &str,
) -> Result<String> {
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
    let conv = format!("plots/{}_convergence.png", slug(mname));
    figures::write_png(
        &out.join(&conv),
        &figures::convergence_plot(
            &format!("{mname}: convergence ({est})"),
            &by_spp,
            &by_time,
            "single-thread time per image (ms)",
        )?,
    )?;
    Ok(conv)
}

/// One technique's equal-time (PNG and EXR) and equal-spp (PNG) images under `out/dir`:
/// their paths, and the two tone-mapped images with their captions for the grids.
#[allow(clippy::type_complexity)]
fn technique_images(
    out: &Path,
    dir: &str,
    e: &metrics::TechniqueEval,
    exposure: f32,
) -> Result<([String; 3], (Rgb8, [String; 2]), (Rgb8, [String; 2]))> {
    let stem = format!("{dir}/{}", e.name);
    let et_png = format!("{stem}.equal_time.png");
    let et_exr = format!("{stem}.equal_time.exr");
    let es_png = format!("{stem}.equal_spp.png");
    let t_img = figures::tonemap(&e.equal_time.image, exposure);
    let s_img = figures::tonemap(&e.equal_spp.image, exposure);
    figures::write_png(&out.join(&et_png), &t_img)?;
    figures::write_exr(&out.join(&et_exr), &e.equal_time.image)?;
    figures::write_png(&out.join(&es_png), &s_img)?;
    let caption = |spp: u32, mse: f64| [e.name.clone(), format!("{spp} spp · MSE {mse:.2e}")];
    Ok((
        [et_exr, et_png, es_png],
        (t_img, caption(e.equal_time_spp, e.mse_equal_time)),
        (s_img, caption(e.equal_spp.spp, e.mse_equal_spp)),
    ))
}

/// A labelled grid of tiles, three per row, as a PNG at `path`.
fn write_grid(path: &Path, tiles: &[(Rgb8, [String; 2])], title: &str) -> Result<()> {
    figures::write_png(path, &figures::labelled_grid(tiles, 3, title)?)
}

/// The reference image as a PNG and an EXR under `out/dir`: their paths and the PNG's
/// tone-mapped image.
fn reference_images(
    out: &Path,
    dir: &str,
    rr: &neusample_render::Render,
    exposure: f32,
) -> Result<(String, String, Rgb8)> {
    let ref_png = format!("{dir}/reference.png");
    let ref_exr = format!("{dir}/reference.exr");
    let ref_tm = figures::tonemap(&rr.image, exposure);
    figures::write_png(&out.join(&ref_png), &ref_tm)?;
    figures::write_exr(&out.join(&ref_exr), &rr.image)?;
    Ok((ref_png, ref_exr, ref_tm))
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
    let techniques = techniques(m, blobs, p)?;

    let scene = demo_scene(&p.scene);
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
    let (ref_png, ref_exr, ref_tm) = reference_images(out, &dir, rr, exposure)?;
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
        .find(|e| e.name == COSINE)
        .map_or(f64::NAN, |e| e.ns_per_sample);
    for e in &evals {
        let (paths, time_tile, spp_tile) = technique_images(out, &dir, e, exposure)?;
        time_tiles.push(time_tile);
        spp_tiles.push(spp_tile);
        let r = render_report(e, &evals[base], cosine_ns, p.settings.seed, paths);
        if let Some(mr) = methods.iter_mut().find(|x| x.method == e.name) {
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
    let title = format!(
        "{mname}: equal time ({:.0} ms single-thread per image), {est}",
        budget * 1e3
    );
    write_grid(&out.join(&eq_time), &time_tiles, &title)?;
    let eq_spp = format!("{dir}/equal_spp.png");
    let title = format!("{mname}: equal spp ({}), {est}", p.settings.max_spp);
    write_grid(&out.join(&eq_spp), &spp_tiles, &title)?;
    pb.inc(1);

    let conv = convergence_figure(out, &mname, &evals, est)?;

    // pdf grid (Fig. 7) and the worst conditions' weights.
    let pdfs = format!("{dir}/pdfs.png");
    let seed = p.settings.seed;
    figures::write_png(
        &out.join(&pdfs),
        &pdf_figure(m, &techniques, p, Stream::PdfFigure.of(seed))?,
    )?;
    let weights = format!("{dir}/weights.png");
    figures::write_png(
        &out.join(&weights),
        &weights_figure(m, &techniques, p, Stream::Fit.of(seed))?,
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
            weights,
        },
        budget,
    ))
}

/// Where each learned sampler's sample weights are largest: for every runtime sampler but
/// cosine and the baseline, its two worst conditions by χ²(p* ‖ p) to the horizon among the fit
/// conditions (`seed` is the fit's), as p* (tabulated), p and the weight p*/p on the disk with
/// p* from the material itself (each tile scaled to its own maximum, `viridis(√(w / max w))`),
/// labelled with the condition's χ² and its largest weight on the rim-resolving quadrature
/// (the outermost rings are thinner than a pixel).
fn weights_figure(
    m: &dyn Material,
    techniques: &[(String, Technique<'_>)],
    p: &Preset,
    seed: u64,
) -> Result<Rgb8> {
    use rayon::prelude::*;
    let conds = groundtruth::conditions(m, p.eval_conditions, seed);
    let nodes = groundtruth::rim_quadrature(groundtruth::RIM_RADIAL, groundtruth::RIM_ANGULAR);
    let targets: Vec<TargetPdf> = conds
        .par_iter()
        .map(|c| TargetPdf::new(m, c, p.pdf_res))
        .collect();
    let size = p.pdf_size;
    let mut tiles = Vec::new();
    let mut rows = 0;
    for (name, t) in techniques {
        let Technique::Blob(s) = t else { continue };
        if name == COSINE || name == BASELINE {
            continue;
        }
        // χ² to the horizon, as the fit reports it, and the albedo that normalises p*.
        let mut chi: Vec<(usize, f64, f64)> = conds
            .par_iter()
            .enumerate()
            .map(|(i, c)| {
                let Some(pr) = s.prepare(&c.phi, c.wi) else {
                    return (i, f64::INFINITY, 0.0);
                };
                let (a, m2) = groundtruth::rim_moments(m, c, &nodes, |q| pr.pdf_disk(q));
                let x = if a > 0.0 { m2 / (a * a) - 1.0 } else { 0.0 };
                (i, x, a)
            })
            .collect();
        chi.sort_by(|a, b| b.1.total_cmp(&a.1));
        for &(i, x, albedo) in chi.iter().take(2) {
            let (c, target) = (&conds[i], &targets[i]);
            let vmax = target.density().iter().copied().fold(0.0f32, f32::max);
            let theta = c.wi.z.clamp(-1.0, 1.0).acos().to_degrees();
            let Some(pr) = s.prepare(&c.phi, c.wi) else {
                continue;
            };
            // p* from the material itself (no table cut-off), so the rim shows.
            let weight = |q: Vec2| {
                let d = pr.pdf_disk(q);
                match neusample::warp::from_disk(q) {
                    Some(wo) if d > 0.0 && albedo > 0.0 => {
                        crate::materials::luminance(m.eval(&c.phi, c.wi, wo)) / albedo as f32 / d
                    }
                    _ => 0.0,
                }
            };
            let mut wmax = 0.0f32;
            for &(q, _) in &nodes {
                let w = weight(q);
                if w.is_finite() {
                    wmax = wmax.max(w);
                }
            }
            tiles.push((
                figures::disk_image(size, vmax, |q| target.pdf(q)),
                [
                    format!("{name}: p*"),
                    format!("θi {theta:.0}° uv {:.2},{:.2}", c.uv.x, c.uv.y),
                ],
            ));
            tiles.push((
                figures::disk_image(size, vmax, |q| pr.pdf_disk(q)),
                [
                    format!("{name}: p"),
                    format!("χ² {} (to the horizon)", fmt_chi2(x)),
                ],
            ));
            tiles.push((
                figures::disk_image(size, wmax, weight),
                [
                    "weight p*/p".to_string(),
                    format!("max {wmax:.3} (to the horizon)"),
                ],
            ));
            rows += 1;
        }
    }
    if rows == 0 {
        tiles.push((
            Rgb8::filled(size, size, [40, 40, 40]),
            ["no learned sampler".to_string(), String::new()],
        ));
    }
    figures::labelled_grid(
        &tiles,
        3,
        &format!(
            "{}: sample weights p*/p at each learned sampler's two worst-χ² conditions",
            m.name()
        ),
    )
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
    let samplers: Vec<(&String, &BlobSampler<'_>)> = techniques
        .iter()
        .filter_map(|(n, t)| match t {
            Technique::Blob(s) => Some((n, s)),
            Technique::Oracle(_) | Technique::Measured(_) => None,
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
    let fit = eval::fit(
        sampler,
        m,
        p.eval_conditions,
        p.eval_res,
        Stream::Fit.of(seed),
    );
    let kl_src = source.map(|src| {
        eval::fit_to(
            sampler,
            m,
            Some(src),
            p.eval_conditions,
            p.eval_res,
            Stream::Fit.of(seed),
        )
        .kl_divergence
    });
    (fit, kl_src)
}
