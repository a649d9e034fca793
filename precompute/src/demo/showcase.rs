//! `neusample scene`: a Fig. 11-style scene — several materials in one image, lit by
//! the daylight sky with MIS and multi-bounce global illumination, rendered once with the
//! improved baseline on every object and once with the best sampler per material, at equal
//! single-thread time, both against a high-sample reference.
//!
//! # Procedure
//!
//! 1. Each material is the committed neural version of a built-in one
//!    (`fixtures/materials/neural/<name>_neural.nsb`, [`neural_fixture`]) or a material file
//!    (a measured `.bsdf` or its `.toml`, a neural `.nsb`, any material file) rendered as
//!    itself. Its samplers are the first `<dir>/<name>/<method>.nsb` of `--blobs`,
//!    `fixtures/blobs/` and `fixtures/measured/blobs/` ([`measured_blobs_dir`]). The first
//!    material is the floor, the others the spheres of [`showcase_scene`].
//! 2. A method per material: an explicit `name=method` entry, else the verdict of a demo
//!    report (`table`, or `<table>/sky-sun/report.json`: its `verdict.best`), else `flow`
//!    (with a note).
//! 3. The **reference**: the baseline on every object, MIS, `ref_factor · N` samples per
//!    pixel, all threads, seeded apart from the compared renders.
//! 4. **Time per sample** of both configurations, single thread, the median of interleaved
//!    passes ([`time_per_sample_wavefront`], as [`crate::eval::metrics`] times techniques);
//!    the best-per-material configuration gets `round(N · t_baseline / t_best)` samples per
//!    pixel (at least 1), the time the baseline takes for `N`.
//! 5. **MSE** of both renders against the reference over the pixels that hit an object, the
//!    reference's own noise subtracted ([`metrics::mse`], [`metrics::Reference::noise`]), per
//!    image and per material (pixels whose primary ray through the pixel centre hits that
//!    material's objects). Intervals: the per-sample variance of the render's sample blocks
//!    ([`metrics::block_variances`], median of means, 95 % bootstrap) divided by its spp, and
//!    for the ratio baseline / best the bootstrap of the quotient, both block sets resampled.
//!
//! Every render uses MIS (BSDF sampling with pdfs in solid angle, plus environment
//! sampling, power heuristic), pixel jitter and `bounces` surface interactions per path.
//!
//! It writes `showcase.png` (reference | baseline | best per material, labelled),
//! `reference.exr`, `baseline.exr`, `best.exr`, `showcase.md` and `showcase.json`
//! ([`ShowcaseReport`]) into the output folder, each file atomically.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use neusample::{Blob, BlobSampler, SamplerKind};
use neusample_render::{
    render_wavefront, showcase_scene, time_per_sample_wavefront, EnvMap, Estimator, Render,
    RenderOptions, Scene, SceneParams, ShowcaseParams, Surface, SHOWCASE_OBJECTS,
};
use serde::{Deserialize, Serialize};

use super::config::{
    ensure_in, neural_fixture, resolve_demo_material, Sky, BASELINE, COSINE, MEASURED_DATA,
    NEURAL_SUFFIX,
};
use super::figures;
use super::fixtures::{fixture_path, fixtures_dir};
use super::markdown::{fmt_e_interval, fmt_x_interval};
use super::report::{MaterialReport, Report};
use crate::eval::metrics::{self, Reference};
use crate::materials::Material;
use crate::util::io;
use crate::util::json::f64_or_nan;
use crate::util::rng::{mix_seed, Stream};
use crate::util::stats::{bootstrap, ratio, Estimate};
use crate::util::timing::median;

/// Schema version of `showcase.json` ([`ShowcaseReport`]).
pub const SHOWCASE_SCHEMA: u32 = 1;

/// The default materials: a wooden floor, then a gold, a brushed-metal (anisotropic), a
/// fabric and a clear-coated sphere.
pub const SHOWCASE_MATERIALS: [&str; 5] = [
    "wagon_wood",
    "gold",
    "brushed_metal",
    "victorian_fabric",
    "car_paint",
];

/// The method of a material that neither `--methods` nor the table names.
pub const FALLBACK_METHOD: &str = "flow";

/// Where the table's demo report lies below `--table`.
pub const TABLE_REPORT: &str = "sky-sun/report.json";

/// What `neusample scene` runs (the command line's options, typed).
#[derive(Clone, Debug, PartialEq)]
pub struct ShowcaseConfig {
    /// Output folder (created; files are replaced atomically).
    pub out: PathBuf,
    /// Materials, the floor first, then the spheres; 1 to 5: built-in names with a committed
    /// neural version (`_neural` optional), or material files (`.toml`, `.json`, a measured
    /// `.bsdf`, a neural `.nsb`) rendered as themselves. Empty: [`SHOWCASE_MATERIALS`].
    pub materials: Vec<String>,
    /// A demo report whose verdicts give each material's best method: a `report.json`, or a
    /// folder of reports whose `sky-sun/report.json` is used.
    pub table: Option<PathBuf>,
    /// `(material, method)` choices, before the table's.
    pub methods: Vec<(String, String)>,
    /// Seed of every render.
    pub seed: u64,
    /// Image width in pixels (height = 9/16 of it).
    pub width: usize,
    /// The baseline's samples per pixel N (and so the equal-time budget).
    pub spp: u32,
    /// The reference has `ref_factor · N` samples per pixel.
    pub ref_factor: u32,
    /// Surface interactions per path (1 = direct lighting only).
    pub bounces: u32,
    /// Interleaved single-thread timing passes per configuration.
    pub timing_passes: usize,
    /// The sun and the environment map.
    pub sky: Sky,
    /// A folder of samplers, `<blobs>/<material>/<method>.nsb`, searched before the
    /// committed fixtures.
    pub blobs: Option<PathBuf>,
}

impl ShowcaseConfig {
    /// The defaults of the command line, writing to `out`.
    #[must_use]
    pub fn new(out: impl Into<PathBuf>) -> Self {
        ShowcaseConfig {
            out: out.into(),
            materials: Vec::new(),
            table: None,
            methods: Vec::new(),
            seed: 1,
            width: 256,
            spp: 16,
            ref_factor: 16,
            bounces: 3,
            timing_passes: 5,
            sky: Sky::default(),
            blobs: None,
        }
    }
}

/// Parses a `material=method` entry of `--methods`.
pub fn parse_method_choice(s: &str) -> Result<(String, String)> {
    let (m, k) = s
        .split_once('=')
        .with_context(|| format!("`{s}`: expected material=method, e.g. gold=flow"))?;
    let (m, k) = (m.trim(), k.trim());
    anyhow::ensure!(
        !m.is_empty() && !k.is_empty(),
        "`{s}`: expected material=method, e.g. gold=flow"
    );
    Ok((m.to_string(), k.to_string()))
}

/// A material name without its `_neural` suffix.
fn base_name(name: &str) -> &str {
    name.strip_suffix(NEURAL_SUFFIX).unwrap_or(name)
}

/// Where a material's method came from.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MethodSource {
    /// `--methods`.
    Given,
    /// The table's verdict.
    Table,
    /// Neither named it: [`FALLBACK_METHOD`].
    Fallback,
}

/// An MSE against the reference (reference noise subtracted) with its interval.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MseReport {
    /// MSE of the image, `mean (L − L_ref)² − noise` (at least [`metrics::MSE_FLOOR`]).
    #[serde(deserialize_with = "f64_or_nan")]
    pub mse: f64,
    /// The per-sample variance of the blocks over spp, with its 95 % interval (null
    /// bounds with fewer than two blocks).
    pub estimate: Estimate,
}

/// One material of the scene.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ShowcaseMaterial {
    /// Material name (`gold_neural`).
    pub material: String,
    /// Which objects use it (`floor`, `sphere 1`, …).
    pub objects: Vec<String>,
    /// The sampler of the best-per-material render.
    pub method: String,
    /// Where the method came from.
    pub method_source: MethodSource,
    /// Pixels whose primary ray through the pixel centre hits this material.
    pub pixels: usize,
    /// The baseline's MSE over those pixels.
    pub baseline: MseReport,
    /// The best-per-material render's MSE over those pixels.
    pub best: MseReport,
    /// Baseline MSE / best MSE at equal time, with its interval.
    pub mse_ratio: Estimate,
}

/// One of the two compared renders.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ShowcaseRender {
    /// Samples per pixel.
    pub spp: u32,
    /// Independent sample blocks (the units the intervals resample).
    pub blocks: u32,
    /// Single-thread render time per pixel sample, ns (median of the passes).
    #[serde(deserialize_with = "f64_or_nan")]
    pub ns_per_sample: f64,
    /// The time per sample of each timing pass, ns.
    pub ns_passes: Vec<f64>,
    /// Single-thread time of the whole image, `spp · pixels · ns_per_sample`, seconds.
    #[serde(deserialize_with = "f64_or_nan")]
    pub single_thread_seconds: f64,
    /// Wall time of the render (all threads), seconds.
    #[serde(deserialize_with = "f64_or_nan")]
    pub seconds: f64,
    /// MSE over every pixel that hits an object.
    pub mse: MseReport,
    /// The linear image (relative to the output folder).
    pub exr: String,
}

/// `showcase.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ShowcaseReport {
    /// [`SHOWCASE_SCHEMA`].
    pub schema: u32,
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Surface interactions per path.
    pub bounces: u32,
    /// Always `mis`.
    pub estimator: Estimator,
    /// Pixel jitter (always on).
    pub jitter: bool,
    /// Seed.
    pub seed: u64,
    /// Sun radiance.
    pub sun_radiance: f32,
    /// Sun angular radius, degrees.
    pub sun_radius_deg: f32,
    /// Environment map file, if any.
    pub env_map: Option<String>,
    /// The demo report the methods were read from, if any.
    pub table: Option<String>,
    /// Interleaved single-thread timing passes per configuration.
    pub timing_passes: usize,
    /// The reference: baseline, MIS, this many samples per pixel.
    pub reference_spp: u32,
    /// The reference's expected contribution to a measured MSE (subtracted).
    #[serde(deserialize_with = "f64_or_nan")]
    pub reference_noise: f64,
    /// Wall time of the reference render, seconds.
    #[serde(deserialize_with = "f64_or_nan")]
    pub reference_seconds: f64,
    /// Pixels hitting an object (where the image MSE is measured).
    pub pixels: usize,
    /// The baseline on every object.
    pub baseline: ShowcaseRender,
    /// The best method per material, at the baseline's single-thread time.
    pub best: ShowcaseRender,
    /// Baseline MSE / best MSE over the image, with its interval.
    pub mse_ratio: Estimate,
    /// Per material.
    pub materials: Vec<ShowcaseMaterial>,
    /// The figure (relative to the output folder).
    pub png: String,
    /// The reference image.
    pub reference_exr: String,
    /// Wall time of the whole run, seconds.
    #[serde(deserialize_with = "f64_or_nan")]
    pub seconds: f64,
}

/// A material with the blobs of its two samplers.
struct Loaded {
    name: String,
    material: Box<dyn Material>,
    method: String,
    method_source: MethodSource,
    baseline: Vec<u8>,
    /// `None` for cosine sampling (no blob).
    best: Option<Vec<u8>>,
}

/// The folder of the samplers committed for the measured fixtures
/// (`fixtures/measured/blobs/<material>/<method>.nsb`).
#[must_use]
pub fn measured_blobs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/measured/blobs")
}

/// Where the samplers of the scene's materials are looked for, in order: `--blobs`, the
/// committed fixtures, the committed measured fixtures.
fn blob_dirs(c: &ShowcaseConfig) -> Vec<PathBuf> {
    c.blobs
        .iter()
        .cloned()
        .chain([fixtures_dir(), measured_blobs_dir()])
        .collect()
}

/// The blob of `method` for the material `name` (`gold_neural`, `chm_mint`): the first
/// `<dir>/<slug of name>/<method>.nsb` of `dirs`.
fn load_blob(dirs: &[PathBuf], name: &str, spec: &str, method: &str) -> Result<Vec<u8>> {
    let candidates: Vec<PathBuf> = dirs
        .iter()
        .map(|d| fixture_path(d, &io::slug(name), method))
        .collect();
    let Some(path) = candidates.iter().find(|p| p.is_file()) else {
        let tried: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
        anyhow::bail!(
            "no `{method}` sampler for {name}: none of {}; train one with `neusample train \
             --material {spec} --method {method} --out <dir>/{}/{method}.nsb` and pass \
             `--blobs <dir>` (or `neusample demo --train --materials {spec} --out X` and \
             `--blobs X/blobs`)",
            tried.join(", "),
            io::slug(name)
        );
    };
    io::read_blob(path).with_context(|| format!("sampler `{method}` of {name}"))
}

/// The sampler of a loaded blob (cosine sampling without one).
fn sampler_of(bytes: Option<&[u8]>) -> Result<BlobSampler<'_>> {
    match bytes {
        None => Ok(BlobSampler::cosine()),
        Some(b) => Blob::open(b)
            .and_then(|blob| blob.sampler())
            .map_err(|e| anyhow::anyhow!("{e}")),
    }
}

/// Checks a method name: a trained method or cosine sampling.
fn check_method(material: &str, method: &str) -> Result<()> {
    match SamplerKind::from_name(method) {
        Some(_) => Ok(()),
        _ if method == MEASURED_DATA => anyhow::bail!(
            "{material}: the data's own sampler (`{MEASURED_DATA}`) is not one of the \
             scene's runtime samplers; `neusample demo` renders it"
        ),
        _ => {
            let names: Vec<&str> = SamplerKind::ALL.iter().map(|k| k.name()).collect();
            anyhow::bail!(
                "unknown method `{method}` for {material}; expected one of {}",
                names.join(", ")
            )
        }
    }
}

/// The demo report `table` names: the file itself, or `<table>/`[`TABLE_REPORT`].
#[must_use]
pub fn table_report(table: &Path) -> PathBuf {
    if table.is_file() {
        table.to_path_buf()
    } else {
        table.join(TABLE_REPORT)
    }
}

/// The best method of every material in the table's report.
fn table_methods(table: &Path) -> Result<Vec<(String, String)>> {
    let path = table_report(table);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read the table's report {}", path.display()))?;
    let report: Report = serde_json::from_str(&text)
        .with_context(|| format!("{} is not a demo report", path.display()))?;
    Ok(report
        .materials
        .iter()
        .filter_map(|m| Some((base_name(&m.material).to_string(), table_method(m)?)))
        .collect())
}

/// Whether the scene can render `method`: a runtime sampler (a blob, or cosine sampling).
fn is_runtime_sampler(method: &str) -> bool {
    SamplerKind::from_name(method).is_some()
}

/// The method the table gives a material: its verdict, or, when the verdict is a technique
/// the scene does not render (the oracle, a measured material's own sampler), the runtime
/// sampler with the largest equal-time speed-up in the report (with a note).
fn table_method(m: &MaterialReport) -> Option<String> {
    let best = &m.verdict.as_ref()?.best;
    if is_runtime_sampler(best) {
        return Some(best.clone());
    }
    let fallback = m
        .methods
        .iter()
        .filter(|x| is_runtime_sampler(&x.method))
        .filter_map(|x| Some((&x.method, x.render.as_ref()?.speedup.value)))
        .filter(|(_, v)| v.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1))?
        .0;
    eprintln!(
        "note: the table's best for {} is `{best}`, which the scene does not render; \
         using `{fallback}`, its best runtime sampler",
        m.material
    );
    Some(fallback.clone())
}

fn validate(c: &ShowcaseConfig) -> Result<()> {
    ensure_in("--width", c.width, 8..=4096)?;
    ensure_in("--spp", c.spp, 1..=65536)?;
    ensure_in("--ref-factor", c.ref_factor, 1..=1024)?;
    ensure_in("--bounces", c.bounces, 1..=16)?;
    ensure_in("--timing-passes", c.timing_passes, 1..=100)?;
    c.sky.validate()?;
    anyhow::ensure!(
        c.materials.len() <= SHOWCASE_OBJECTS,
        "at most {SHOWCASE_OBJECTS} materials (a floor and four spheres), got {}",
        c.materials.len()
    );
    Ok(())
}

/// Whether a `--materials` entry names a file rather than a built-in material.
fn is_file_spec(spec: &str) -> bool {
    let p = Path::new(spec);
    p.is_file() || spec.contains(['/', '\\', '.'])
}

/// A `--materials` entry resolved: its name, the material and the spec that loads it.
fn resolve_entry(spec: &str) -> Result<(String, Box<dyn Material>, String)> {
    if is_file_spec(spec) {
        let material = resolve_demo_material(spec, false)
            .with_context(|| format!("material `{spec}`"))?
            .material;
        return Ok((material.name().to_string(), material, spec.to_string()));
    }
    let base = base_name(spec);
    let path = neural_fixture(base);
    anyhow::ensure!(
        path.exists(),
        "unknown material `{spec}`: neither a material file nor a built-in name with a \
         committed neural version {}",
        path.display()
    );
    let material = resolve_demo_material(base, true)
        .with_context(|| format!("material `{spec}`"))?
        .material;
    Ok((
        format!("{base}{NEURAL_SUFFIX}"),
        material,
        path.display().to_string(),
    ))
}

/// Resolves every material, its method and its blobs.
fn load(c: &ShowcaseConfig, specs: &[String]) -> Result<Vec<Loaded>> {
    let entries = specs
        .iter()
        .map(|spec| resolve_entry(spec))
        .collect::<Result<Vec<_>>>()?;
    let names: Vec<&str> = entries.iter().map(|(n, _, _)| n.as_str()).collect();
    for (m, _) in &c.methods {
        anyhow::ensure!(
            names.iter().any(|n| base_name(n) == base_name(m)),
            "--methods names `{m}`, which is not one of the materials ({})",
            names.join(", ")
        );
    }
    let table = match &c.table {
        Some(dir) => table_methods(dir)?,
        None => Vec::new(),
    };
    let dirs = blob_dirs(c);
    entries
        .into_iter()
        .map(|(name, material, spec)| {
            let base = base_name(&name);
            let given = c.methods.iter().find(|(m, _)| base_name(m) == base);
            let from_table = table.iter().find(|(m, _)| m == base);
            let (method, method_source) = match (given, from_table) {
                (Some((_, k)), _) => (k.clone(), MethodSource::Given),
                (None, Some((_, k))) => (k.clone(), MethodSource::Table),
                (None, None) => {
                    eprintln!("note: no method given for {name}; using {FALLBACK_METHOD}");
                    (FALLBACK_METHOD.to_string(), MethodSource::Fallback)
                }
            };
            check_method(&name, &method)?;
            let baseline = load_blob(&dirs, &name, &spec, BASELINE)?;
            let best = if method == COSINE {
                None
            } else {
                Some(load_blob(&dirs, &name, &spec, &method)?)
            };
            Ok(Loaded {
                name,
                material,
                method,
                method_source,
                baseline,
                best,
            })
        })
        .collect()
}

/// Each material with its sampler.
fn surfaces<'a, 's>(
    loaded: &'a [Loaded],
    samplers: &[BlobSampler<'s>],
) -> Vec<Surface<'a, dyn Material, BlobSampler<'s>>> {
    loaded
        .iter()
        .zip(samplers)
        .map(|(l, s)| Surface::new(l.material.as_ref(), *s))
        .collect()
}

/// Points per character of the header's text, about (for wrapping).
const HEADER_CHAR_WIDTH: usize = 6;

/// `grid` under a header: the first line in a larger font, the others wrapped at words to
/// the grid's width.
fn with_header(grid: &figures::Rgb8, lines: &[String]) -> Result<figures::Rgb8> {
    let pad = 6;
    let per_line = ((grid.width - 2 * pad) / HEADER_CHAR_WIDTH).max(20);
    let mut rows: Vec<(String, u32)> = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let size = if i == 0 { 15 } else { 13 };
        // Wrap between the items of a `·`-separated list, else between words.
        let sep = if line.contains(" · ") { " · " } else { " " };
        let mut cur = String::new();
        for item in line.split(sep) {
            if !cur.is_empty() && cur.chars().count() + sep.len() + item.chars().count() > per_line
            {
                rows.push((std::mem::take(&mut cur), size));
            }
            if !cur.is_empty() {
                cur.push_str(sep);
            }
            cur.push_str(item);
        }
        rows.push((cur, size));
    }
    let line_h = 18;
    let head = pad + rows.len() * line_h;
    let mut out = figures::Rgb8::filled(grid.width, grid.height + head, [255, 255, 255]);
    out.blit(grid, 0, head);
    let texts: Vec<_> = rows
        .into_iter()
        .enumerate()
        .map(|(k, (text, size))| {
            (
                text,
                (pad as i32, (pad + k * line_h) as i32),
                size,
                plotters::style::RGBColor(0, 0, 0),
            )
        })
        .collect();
    figures::draw_text(&mut out, &texts)?;
    Ok(out)
}

/// The object names of each surface of [`showcase_scene`].
fn object_names(scene: &Scene, surfaces: usize) -> Vec<Vec<String>> {
    let mut names = vec![Vec::new(); surfaces];
    for (k, o) in scene.objects.iter().enumerate() {
        if let Some(v) = names.get_mut(o.surface) {
            v.push(if k == 0 {
                "floor".to_string()
            } else {
                format!("sphere {k}")
            });
        }
    }
    names
}

/// Per pixel, the surface its primary ray through the pixel centre hits.
fn surface_map(scene: &Scene) -> Vec<Option<usize>> {
    let (w, h) = (scene.camera.width, scene.camera.height);
    (0..w * h)
        .map(|i| {
            let r = scene.camera.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            scene.intersect(&r).map(|hit| hit.surface)
        })
        .collect()
}

/// The reference restricted to `mask` (its noise recomputed over it).
fn masked_reference(reference: &Render, mask: Vec<bool>) -> Reference {
    let noise = metrics::mean_variance_of_mean(reference, &mask);
    let mut render = reference.clone();
    render.mask = mask;
    Reference { render, noise }
}

/// The MSE of `r` against `reference` over its mask, with the block interval.
fn mse_of(r: &Render, reference: &Reference, seed: u64) -> (MseReport, Vec<f64>) {
    let mask = &reference.render.mask;
    let mse = (metrics::mse(&r.image, &reference.render.image, mask) - reference.noise)
        .max(metrics::MSE_FLOOR);
    let blocks = metrics::block_variances(r, reference);
    let mut estimate = metrics::variance(&blocks, seed).scaled(1.0 / f64::from(r.spp.max(1)));
    if blocks.len() < 2 {
        (estimate.lo, estimate.hi) = (f64::NAN, f64::NAN);
    }
    (MseReport { mse, estimate }, blocks)
}

/// Baseline MSE / best MSE from the block variances of both renders, with the bootstrap
/// interval (both block sets resampled independently).
fn mse_ratio(base: (&[f64], u32), best: (&[f64], u32), seed: u64) -> Estimate {
    let (sb, sm) = (f64::from(base.1.max(1)), f64::from(best.1.max(1)));
    bootstrap([base.0, best.0], seed, |[vb, vm]| {
        ratio(
            metrics::robust_variance(vb) / sb,
            metrics::robust_variance(vm) / sm,
        )
    })
}

/// `neusample scene`.
pub fn run(c: &ShowcaseConfig) -> Result<()> {
    let started = Instant::now();
    validate(c)?;
    let names: Vec<String> = if c.materials.is_empty() {
        SHOWCASE_MATERIALS.iter().map(|s| s.to_string()).collect()
    } else {
        c.materials.clone()
    };
    anyhow::ensure!(!names.is_empty(), "no materials");
    let env_map = c.sky.load_env_map()?;
    let loaded = load(c, &names)?;
    std::fs::create_dir_all(&c.out)
        .with_context(|| format!("cannot create output folder {}", c.out.display()))?;
    let out = c.out.canonicalize()?;
    eprintln!("neusample scene: writing to {}", out.display());

    let (width, height) = (c.width, (c.width * 9 / 16).max(1));
    let scene = scene_of(c, width, height, env_map, loaded.len());
    let base_samplers = loaded
        .iter()
        .map(|l| sampler_of(Some(&l.baseline)).with_context(|| format!("{} baseline", l.name)))
        .collect::<Result<Vec<_>>>()?;
    let best_samplers = loaded
        .iter()
        .map(|l| sampler_of(l.best.as_deref()).with_context(|| format!("{} {}", l.name, l.method)))
        .collect::<Result<Vec<_>>>()?;
    let (base_surfaces, best_surfaces) = (
        surfaces(&loaded, &base_samplers),
        surfaces(&loaded, &best_samplers),
    );

    let opts = render_options(c);

    let full = reference_render(c, &scene, &base_surfaces, &opts);
    let (reference, ref_spp) = (&full.render, full.render.spp);

    let (base_ns, best_ns) = timings(c, &scene, [&base_surfaces, &best_surfaces], &opts)?;
    let (tb, tm) = (median(base_ns.clone()), median(best_ns.clone()));
    let [base_render, best_render] =
        equal_time_renders(c, &scene, [&base_surfaces, &best_surfaces], &opts, tb / tm);

    // MSE over the image and per material.
    let seed = mix_seed(c.seed, 0x5C3E);
    let (base_mse, base_blocks) = mse_of(&base_render, &full, seed);
    let (best_mse, best_blocks) = mse_of(&best_render, &full, seed + 1);
    let ratio_all = mse_ratio(
        (&base_blocks, base_render.spp),
        (&best_blocks, best_render.spp),
        seed + 2,
    );
    let objects = object_names(&scene, loaded.len());
    let renders = [&base_render, &best_render];
    let materials = per_material(&loaded, &scene, &objects, reference, renders, seed);

    let mses = [base_mse.mse, best_mse.mse];
    write_images(
        &out, c, &loaded, &objects, reference, ref_spp, renders, mses,
    )?;

    let pixels = (width * height) as f64;
    let side = |r: &Render, ns: f64, passes: Vec<f64>, mse: MseReport, exr: &str| ShowcaseRender {
        spp: r.spp,
        blocks: r.blocks.len() as u32,
        ns_per_sample: ns,
        ns_passes: passes,
        single_thread_seconds: f64::from(r.spp) * pixels * ns * 1e-9,
        seconds: r.seconds,
        mse,
        exr: exr.to_string(),
    };
    let report = ShowcaseReport {
        schema: SHOWCASE_SCHEMA,
        width,
        height,
        bounces: c.bounces,
        estimator: Estimator::Mis,
        jitter: true,
        seed: c.seed,
        sun_radiance: c.sky.sun_radiance,
        sun_radius_deg: c.sky.sun_size,
        env_map: c.sky.env_map_name(),
        table: c
            .table
            .as_ref()
            .map(|t| table_report(t).display().to_string()),
        timing_passes: c.timing_passes,
        reference_spp: ref_spp,
        reference_noise: full.noise,
        reference_seconds: reference.seconds,
        pixels: reference.mask.iter().filter(|&&b| b).count(),
        baseline: side(&base_render, tb, base_ns, base_mse, "baseline.exr"),
        best: side(&best_render, tm, best_ns, best_mse, "best.exr"),
        mse_ratio: ratio_all,
        materials,
        png: "showcase.png".to_string(),
        reference_exr: "reference.exr".to_string(),
        seconds: started.elapsed().as_secs_f64(),
    };
    io::atomic_write(
        &out.join("showcase.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    io::atomic_write(&out.join("showcase.md"), markdown(&report).as_bytes())?;
    eprintln!(
        "neusample scene finished in {:.0} s: {}",
        report.seconds,
        out.join("showcase.md").display()
    );
    Ok(())
}

/// The reference: the baseline with `c.ref_factor` times the samples, seeded apart, and its
/// own noise.
fn reference_render(
    c: &ShowcaseConfig,
    scene: &Scene,
    base_surfaces: &[Surface<'_, dyn Material, BlobSampler<'_>>],
    opts: &RenderOptions,
) -> Reference {
    let ref_spp = c.spp.saturating_mul(c.ref_factor).max(2);
    eprintln!("reference: baseline, {ref_spp} spp");
    let mut o = opts.clone();
    o.spp = ref_spp;
    o.seed = Stream::Reference.of(c.seed);
    let reference = render_wavefront(scene, base_surfaces, &o);
    Reference {
        noise: metrics::mean_variance_of_mean(&reference, &reference.mask),
        render: reference,
    }
}

/// The baseline at `c.spp` and the best samplers at the spp of the same single-thread time
/// (`speed`: the baseline's time per sample over theirs; NaN or ∞ give 1 spp).
fn equal_time_renders(
    c: &ShowcaseConfig,
    scene: &Scene,
    surfaces: [&[Surface<'_, dyn Material, BlobSampler<'_>>]; 2],
    opts: &RenderOptions,
    speed: f64,
) -> [Render; 2] {
    let best_spp = if speed.is_finite() && speed > 0.0 {
        (f64::from(c.spp) * speed)
            .round()
            .clamp(1.0, f64::from(c.spp.saturating_mul(64))) as u32
    } else {
        1
    };
    eprintln!("baseline: {} spp; best per material: {best_spp} spp", c.spp);
    let mut o = opts.clone();
    o.blocks = metrics::DEFAULT_BLOCKS;
    let base_render = render_wavefront(scene, surfaces[0], &o);
    let mut o = opts.clone();
    o.spp = best_spp;
    o.seed = Stream::EqualTime.of(c.seed);
    o.blocks = metrics::DEFAULT_BLOCKS;
    [base_render, render_wavefront(scene, surfaces[1], &o)]
}

/// The render settings every showcase render shares: MIS, jittered pixels, `c.bounces`.
fn render_options(c: &ShowcaseConfig) -> RenderOptions {
    let mut opts = RenderOptions::new(c.spp, c.seed);
    opts.checkpoints.clear();
    opts.estimator = Estimator::Mis;
    opts.jitter = true;
    opts.max_bounces = c.bounces;
    opts
}

/// Single-thread time per sample of the baseline's and the best samplers' scenes, in
/// `c.timing_passes` interleaved passes each.
fn timings(
    c: &ShowcaseConfig,
    scene: &Scene,
    surfaces: [&[Surface<'_, dyn Material, BlobSampler<'_>>]; 2],
    opts: &RenderOptions,
) -> Result<(Vec<f64>, Vec<f64>)> {
    eprintln!("timing: {} passes per configuration", c.timing_passes);
    let mut t = opts.clone();
    t.spp = 1;
    let (mut base_ns, mut best_ns) = (Vec::new(), Vec::new());
    for _ in 0..c.timing_passes {
        base_ns.push(time_per_sample_wavefront(scene, surfaces[0], &t, 1)?);
        best_ns.push(time_per_sample_wavefront(scene, surfaces[1], &t, 1)?);
    }
    Ok((base_ns, best_ns))
}

/// The showcase scene for `surfaces` materials at `width × height`.
fn scene_of(
    c: &ShowcaseConfig,
    width: usize,
    height: usize,
    env_map: Option<EnvMap>,
    surfaces: usize,
) -> Scene {
    showcase_scene(&ShowcaseParams {
        scene: SceneParams {
            width,
            height,
            sun_radiance: c.sky.sun_radiance,
            sun_radius_deg: c.sky.sun_size,
            env_map,
            ..ShowcaseParams::default().scene
        },
        surfaces,
    })
}

/// The MSE of the baseline and of the best render (`renders`) over each material's
/// pixels, and their ratio.
fn per_material(
    loaded: &[Loaded],
    scene: &Scene,
    objects: &[Vec<String>],
    reference: &Render,
    renders: [&Render; 2],
    seed: u64,
) -> Vec<ShowcaseMaterial> {
    let [base_render, best_render] = renders;
    let hits = surface_map(scene);
    let mut materials = Vec::new();
    for (k, l) in loaded.iter().enumerate() {
        let mask: Vec<bool> = hits
            .iter()
            .zip(&reference.mask)
            .map(|(h, &m)| m && *h == Some(k))
            .collect();
        let pixels = mask.iter().filter(|&&b| b).count();
        let r = masked_reference(reference, mask);
        let s = mix_seed(seed, 16 + k as u64);
        let (b, bb) = mse_of(base_render, &r, s);
        let (m, mb) = mse_of(best_render, &r, s + 1);
        materials.push(ShowcaseMaterial {
            material: l.name.clone(),
            objects: objects[k].clone(),
            method: l.method.clone(),
            method_source: l.method_source,
            pixels,
            mse_ratio: mse_ratio((&bb, base_render.spp), (&mb, best_render.spp), s + 2),
            baseline: b,
            best: m,
        });
    }
    materials
}

/// The reference, baseline and best renders as EXRs, and the labelled comparison PNG.
#[allow(clippy::too_many_arguments)]
fn write_images(
    out: &Path,
    c: &ShowcaseConfig,
    loaded: &[Loaded],
    objects: &[Vec<String>],
    reference: &Render,
    ref_spp: u32,
    renders: [&Render; 2],
    mses: [f64; 2],
) -> Result<()> {
    let [base_render, best_render] = renders;
    let [base_mse, best_mse] = mses;
    let exposure = figures::auto_exposure(&reference.image, &reference.mask);
    figures::write_exr(&out.join("reference.exr"), &reference.image)?;
    figures::write_exr(&out.join("baseline.exr"), &base_render.image)?;
    figures::write_exr(&out.join("best.exr"), &best_render.image)?;
    let tiles = [
        (
            figures::tonemap(&reference.image, exposure),
            ["reference".to_string(), format!("baseline, {ref_spp} spp")],
        ),
        (
            figures::tonemap(&base_render.image, exposure),
            [
                "baseline, equal time".to_string(),
                format!("{} spp · MSE {:.2e}", base_render.spp, base_mse),
            ],
        ),
        (
            figures::tonemap(&best_render.image, exposure),
            [
                "best per material, equal time".to_string(),
                format!("{} spp · MSE {:.2e}", best_render.spp, best_mse),
            ],
        ),
    ];
    let grid = figures::labelled_grid(&tiles, 3, "")?;
    let methods: Vec<String> = loaded
        .iter()
        .zip(objects)
        .map(|(l, o)| format!("{} ({}): {}", base_name(&l.name), o.join(", "), l.method))
        .collect();
    let header = [
        format!(
            "Equal single-thread time, MIS, {} bounces: the baseline on every object against \
             the best sampler per material",
            c.bounces
        ),
        methods.join(" · "),
    ];
    figures::write_png(&out.join("showcase.png"), &with_header(&grid, &header)?)?;
    Ok(())
}

/// `showcase.md`: the settings, the figure and the MSE tables.
#[must_use]
pub fn markdown(r: &ShowcaseReport) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Showcase: several materials in one scene\n");
    let _ = writeln!(
        s,
        "{}×{} px, daylight sky (sun radiance {}, radius {}°{}), MIS (BSDF sampling and \
         environment sampling, power heuristic), {} surface interactions per path, pixel \
         jitter, seed {}. Reference: the improved baseline with {} spp. MSE over the {} pixels \
         that hit an object, linear radiance, reference noise ({:.2e}) subtracted; intervals \
         are 95 % bootstrap intervals over {} sample blocks per render. Equal time: the \
         best-per-material render gets the single-thread time the baseline takes for its {} \
         spp (median of {} interleaved passes each).\n",
        r.width,
        r.height,
        r.sun_radiance,
        r.sun_radius_deg,
        r.env_map
            .as_ref()
            .map(|e| format!(", environment map {e}"))
            .unwrap_or_default(),
        r.bounces,
        r.seed,
        r.reference_spp,
        r.pixels,
        r.reference_noise,
        r.baseline.blocks,
        r.baseline.spp,
        r.timing_passes,
    );
    let _ = writeln!(s, "![showcase]({})\n", r.png);
    let _ = writeln!(
        s,
        "| render | spp | ns / sample (1 thread) | image time (1 thread) | MSE | MSE from blocks [95 %] |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---|");
    for (name, x) in [("baseline", &r.baseline), ("best per material", &r.best)] {
        let _ = writeln!(
            s,
            "| {name} | {} | {:.0} | {:.2} s | {:.3e} | {} |",
            x.spp,
            x.ns_per_sample,
            x.single_thread_seconds,
            x.mse.mse,
            fmt_e_interval(&x.mse.estimate)
        );
    }
    let _ = writeln!(
        s,
        "\nMSE ratio baseline / best per material at equal time: **{}**.\n",
        fmt_x_interval(&r.mse_ratio)
    );
    let _ = writeln!(
        s,
        "| material | objects | method (from) | pixels | baseline MSE | best MSE | ratio |"
    );
    let _ = writeln!(s, "|---|---|---|---:|---|---|---|");
    for m in &r.materials {
        let from = match m.method_source {
            MethodSource::Given => "--methods",
            MethodSource::Table => "table",
            MethodSource::Fallback => "default",
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} ({from}) | {} | {} | {} | {} |",
            m.material,
            m.objects.join(", "),
            m.method,
            m.pixels,
            fmt_e_interval(&m.baseline.estimate),
            fmt_e_interval(&m.best.estimate),
            fmt_x_interval(&m.mse_ratio)
        );
    }
    let _ = writeln!(
        s,
        "\nTimes are single-thread medians; the run took {:.0} s of wall time in all.",
        r.seconds
    );
    s
}
