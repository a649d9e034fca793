//! The demo's settings: the default materials and report names, the typed configuration,
//! the sizes of a run (`Preset`), and the materials it evaluates.

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use anyhow::Result;
use neusample::SamplerKind;
use neusample_render::{EnvMap, Estimator, SceneParams};

use crate::eval::metrics::{self, RenderSettings};
use crate::materials::neural::{is_blob_file, label_field, NeuralParts};
use crate::materials::{self, Material};
use crate::train::METHODS;
use crate::util::io;

/// The built-in materials the demo and the fixtures use: an isotropic highlight under strong
/// normal mapping, an anisotropic highlight with varying tangents, and a multi-lobe fabric.
pub const DEFAULT_MATERIALS: [&str; 3] = ["goat_leather", "brushed_metal", "victorian_fabric"];

/// Suffix of a neural material's name: `goat_leather_neural` is the neural version of
/// `goat_leather` (`fixtures/materials/neural/goat_leather_neural.nsb`).
pub const NEURAL_SUFFIX: &str = "_neural";

/// Name of cosine sampling in reports.
pub const COSINE: &str = SamplerKind::Cosine.name();

/// Name of the improved baseline in reports (the reference of the speed-ups).
pub const BASELINE: &str = SamplerKind::ImprovedBaseline.name();

/// Name of the tabulated oracle in reports.
pub const ORACLE: &str = "oracle";

/// Name of a measured material's own sampler (VNDF and luminance warps) in reports.
pub const MEASURED_DATA: &str = "measured-data";

/// What `neusample demo` runs (the command line's options, typed).
#[derive(Clone, Debug, PartialEq)]
pub struct DemoConfig {
    /// CI-sized smoke test (`--smoke`): a small image, few samples and conditions, short
    /// training; the report's first line says its numbers are not results.
    pub quick: bool,
    /// Output folder (created; files are replaced atomically).
    pub out: PathBuf,
    /// Use the committed pretrained blobs (`fixtures/`, the default) instead of training.
    pub use_fixtures: bool,
    /// With `use_fixtures`: read `<blobs>/<material>/<method>.nsb` from this folder instead of
    /// the committed `fixtures/blobs/`.
    pub blobs: Option<PathBuf>,
    /// With `use_fixtures`: per material (its name in reports), a folder to read
    /// `<folder>/<material>/<method>.nsb` from instead of `blobs` (`neusample table` points
    /// the materials whose samplers it trained at them).
    pub material_blobs: Vec<(String, PathBuf)>,
    /// Materials (built-in names or files, `.nsb` neural materials included); default: the
    /// neural versions of the three demo materials (or the procedural ones with
    /// `procedural`).
    pub materials: Vec<String>,
    /// Use the procedural source materials of the defaults instead of their neural versions
    /// (the paper's setting is neural materials).
    pub procedural: bool,
    /// Seed of training and evaluation.
    pub seed: u64,
    /// Multiplies every method's default training steps (1 = the defaults of `neusample
    /// train`; the demo's 0.5 keeps the full run within ten minutes on 2 cores, at some cost in
    /// fit: 1 gives the better samplers of `neusample train`). Not used with `quick` or
    /// `use_fixtures`.
    pub steps_scale: f64,
    /// Image width in pixels (height = 3/4 of it); default 112, 64 with `quick`.
    pub width: Option<usize>,
    /// Equal-spp sample count N (convergence up to it; the baseline's equal-time budget);
    /// default 32, 8 with `quick`.
    pub spp: Option<u32>,
    /// The sun and the environment map, with `uniform_light` off.
    pub sky: Sky,
    /// Uniform white lighting (the default) instead of the sky with its sun: the render
    /// variance then measures the BSDF sampler alone (the paper's uniformly lit scenes).
    /// Ignored with `envmap`.
    pub uniform_light: bool,
    /// Combine BSDF sampling with environment sampling (MIS, power heuristic) instead of
    /// BSDF sampling alone.
    pub mis: bool,
    /// Skip the rendering evaluation (fit and cost only).
    pub no_render: bool,
    /// The trained methods to evaluate besides cosine and the oracle (the improved baseline,
    /// every speed-up's reference, is always added); empty: every trainable method.
    pub methods: Vec<SamplerKind>,
    /// Random conditions of the fit measures; default 64, 24 with `quick`.
    pub eval_conditions: Option<usize>,
    /// Interleaved single-thread timing passes per method; default 11, 5 with `quick`.
    pub timing_passes: Option<usize>,
}

impl DemoConfig {
    /// The defaults of the command line, writing to `out`.
    #[must_use]
    pub fn new(out: impl Into<PathBuf>) -> Self {
        DemoConfig {
            quick: false,
            out: out.into(),
            use_fixtures: true,
            blobs: None,
            material_blobs: Vec::new(),
            materials: Vec::new(),
            procedural: false,
            seed: 1,
            steps_scale: 0.5,
            width: None,
            spp: None,
            sky: Sky::default(),
            uniform_light: true,
            mis: false,
            no_render: false,
            methods: Vec::new(),
            eval_conditions: None,
            timing_passes: None,
        }
    }
}

/// The sun and the environment map of `neusample demo` and `neusample scene`.
#[derive(Clone, Debug, PartialEq)]
pub struct Sky {
    /// Radiance of the sun disc (0: sky only).
    pub sun_radiance: f32,
    /// Angular radius of the sun, degrees.
    pub sun_size: f32,
    /// An equirectangular OpenEXR environment map (z-up, see `render::EnvMap`) instead of the
    /// procedural sky; the sun is added unless `sun_radiance` is 0.
    pub envmap: Option<PathBuf>,
}

impl Default for Sky {
    /// The command line's defaults: a sun of radiance 60 and radius 4°, the procedural sky.
    fn default() -> Self {
        Sky {
            sun_radiance: 60.0,
            sun_size: 4.0,
            envmap: None,
        }
    }
}

impl Sky {
    /// Refuses a sun radiance that is not finite and ≥ 0 and a radius outside (0, 90)
    /// degrees (in the words of the command line's options).
    pub fn validate(&self) -> Result<()> {
        anyhow::ensure!(
            self.sun_radiance.is_finite() && self.sun_radiance >= 0.0,
            "--sun-radiance must be finite and ≥ 0"
        );
        anyhow::ensure!(
            self.sun_size.is_finite() && self.sun_size > 0.0 && self.sun_size < 90.0,
            "--sun-size must be in (0, 90) degrees"
        );
        Ok(())
    }

    /// The environment map, read from its file; `None` without one.
    pub fn load_env_map(&self) -> Result<Option<EnvMap>> {
        Ok(match &self.envmap {
            Some(p) => Some(EnvMap::load_exr(p)?),
            None => None,
        })
    }

    /// The environment map's file name for reports.
    #[must_use]
    pub fn env_map_name(&self) -> Option<String> {
        self.envmap.as_ref().map(|e| e.display().to_string())
    }
}

/// Refuses a command-line `option` whose value `v` lies outside `range`
/// (`--width must be in 8..=4096, got 4`).
pub(crate) fn ensure_in<T>(option: &str, v: T, range: RangeInclusive<T>) -> Result<()>
where
    T: PartialOrd + std::fmt::Display,
{
    anyhow::ensure!(
        range.contains(&v),
        "{option} must be in {}..={}, got {v}",
        range.start(),
        range.end()
    );
    Ok(())
}

/// The folder of the committed fixture blobs.
#[must_use]
pub fn fixtures_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/blobs")
}

impl DemoConfig {
    /// The folder holding `<material>/<method>.nsb` for `material` (with `use_fixtures`): its
    /// entry of `material_blobs`, else `blobs`, else the committed fixtures.
    #[must_use]
    pub fn blob_dir(&self, material: &str) -> PathBuf {
        self.material_blobs
            .iter()
            .find(|(name, _)| name == material)
            .map(|(_, dir)| dir.clone())
            .or_else(|| self.blobs.clone())
            .unwrap_or_else(fixtures_dir)
    }

    /// The trained methods evaluated, in [`METHODS`] order: `methods` (every method when
    /// empty) with the improved baseline.
    #[must_use]
    pub fn method_list(&self) -> Vec<SamplerKind> {
        METHODS
            .into_iter()
            .filter(|m| {
                self.methods.is_empty()
                    || *m == SamplerKind::ImprovedBaseline
                    || self.methods.contains(m)
            })
            .collect()
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
/// reference of its fit, found by [`resolve_source`]).
pub struct DemoMaterial {
    /// What is rendered and sampled.
    pub material: Box<dyn Material>,
    /// The source of a neural material, when it is known (its label's `source=` field: a
    /// built-in name or a file, [`resolve_source`]).
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
    let material = materials::resolve(spec)?;
    let p = Path::new(spec);
    let source = if p.exists() && is_blob_file(p) {
        let bytes = io::read_blob(p)?;
        let (_, label) = NeuralParts::from_blob(&bytes)?;
        match label_field(&label, "source") {
            Some(src) => match resolve_source(p, src) {
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

/// The extensions of a material file that [`resolve_source`] tries after the name itself.
const SOURCE_EXTENSIONS: [&str; 3] = ["toml", "json", "bsdf"];

/// The source material `source` (from its label) of the neural-material blob at `blob`: a
/// built-in name or a path, as [`materials::resolve`] reads them; otherwise the first file
/// of `<source>`, `<source>.toml`, `.json`, `.bsdf` beside the blob, then in the folder
/// above it. `train-material` labels a material file's fit with the
/// material's name, so `fixtures/measured/neural/chm_mint_neural.nsb` (source `chm_mint`)
/// finds `fixtures/measured/chm_mint.toml`.
///
/// # Errors
/// No such built-in or file: the message lists where it looked; or the file found does not
/// load.
pub fn resolve_source(blob: &Path, source: &str) -> Result<Box<dyn Material>> {
    let direct = match materials::resolve(source) {
        Ok(m) => return Ok(m),
        Err(e) => e,
    };
    let candidates = source_candidates(blob, source);
    match candidates.iter().find(|c| c.is_file()) {
        Some(file) => materials::load(file),
        None => {
            let tried: Vec<String> = candidates.iter().map(|c| c.display().to_string()).collect();
            Err(direct.context(format!("nor any of {}", tried.join(", "))))
        }
    }
}

/// Where [`resolve_source`] looks for the source `source` of the blob at `blob`, in order:
/// `<source>`, then `<source>.toml`, `.json` and `.bsdf`, in the blob's folder and then in
/// the folder above it.
fn source_candidates(blob: &Path, source: &str) -> Vec<PathBuf> {
    let here = blob.parent().unwrap_or_else(|| Path::new(""));
    [Some(here), here.parent()]
        .into_iter()
        .flatten()
        .flat_map(|dir| {
            std::iter::once(dir.join(source)).chain(
                SOURCE_EXTENSIONS
                    .iter()
                    .map(move |ext| dir.join(format!("{source}.{ext}"))),
            )
        })
        .collect()
}

/// Sizes of a demo run.
pub(crate) struct Preset {
    pub(crate) eval_conditions: usize,
    pub(crate) eval_res: usize,
    pub(crate) cost_n: usize,
    pub(crate) cost_passes: usize,
    /// The oracle's `prepare` tabulates the material: measured on far fewer conditions.
    pub(crate) oracle_cost_n: usize,
    pub(crate) scene: SceneParams,
    pub(crate) settings: RenderSettings,
    pub(crate) pdf_conditions: usize,
    pub(crate) pdf_res: usize,
    pub(crate) pdf_size: usize,
}

pub(crate) fn preset(a: &DemoConfig) -> Result<Preset> {
    let width = a.width.unwrap_or(if a.quick { 64 } else { 112 });
    ensure_in("--width", width, 8..=4096)?;
    anyhow::ensure!(
        a.steps_scale > 0.0 && a.steps_scale.is_finite(),
        "--steps-scale must be positive, got {}",
        a.steps_scale
    );
    let spp = a.spp.unwrap_or(if a.quick { 8 } else { 32 });
    anyhow::ensure!((1..=65536).contains(&spp), "--spp must be in 1..=65536");
    a.sky.validate()?;
    let env_map = a.sky.load_env_map()?;
    let q = a.quick;
    Ok(Preset {
        eval_conditions: a.eval_conditions.unwrap_or(if q { 24 } else { 64 }),
        eval_res: if q { 64 } else { 96 },
        cost_n: if q { 2000 } else { 10000 },
        cost_passes: if q { 3 } else { 5 },
        oracle_cost_n: if q { 20 } else { 100 },
        scene: SceneParams {
            width,
            height: (width * 3 / 4).max(1),
            sun_radiance: a.sky.sun_radiance,
            sun_radius_deg: a.sky.sun_size,
            env_map,
            uniform_light: a.uniform_light && a.sky.envmap.is_none(),
            ..SceneParams::default()
        },
        settings: RenderSettings {
            max_spp: spp,
            ref_spp: if q { 128 } else { 256 },
            ref_res: if q { 32 } else { 40 },
            oracle_res: if q { 24 } else { 32 },
            timing_spp: 1,
            timing_passes: a.timing_passes.unwrap_or(if q { 5 } else { 11 }),
            max_equal_time_spp: 64 * spp,
            estimator: if a.mis {
                Estimator::Mis
            } else {
                Estimator::Bsdf
            },
            seed: a.seed,
            blocks: metrics::DEFAULT_BLOCKS,
        },
        pdf_conditions: if q { 2 } else { 4 },
        pdf_res: 64,
        pdf_size: if q { 64 } else { 96 },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixtures() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures")
    }

    /// A material file named `name` (gold's model) at `path`.
    fn write_material(path: &Path, name: &str) {
        let text = std::fs::read_to_string(fixtures().join("materials/gold.toml"))
            .unwrap()
            .replace("name = \"gold\"", &format!("name = \"{name}\""));
        std::fs::write(path, text).unwrap();
    }

    /// The committed neural fit of the mint finds its material file one folder up, and the
    /// demo resolves it as the fit's source.
    #[test]
    fn a_measured_fit_finds_its_material_file() {
        let blob = fixtures().join("measured/neural/chm_mint_neural.nsb");
        let src = resolve_source(&blob, "chm_mint").unwrap();
        assert_eq!(src.name(), "chm_mint");
        assert!(src.measured().is_some());
        let d = resolve_demo_material(blob.to_str().unwrap(), false).unwrap();
        assert_eq!(d.material.name(), "chm_mint_neural");
        assert_eq!(
            d.source.map(|s| s.name().to_string()).as_deref(),
            Some("chm_mint")
        );
    }

    /// A built-in source resolves by name wherever the blob is.
    #[test]
    fn a_builtin_source_resolves_by_name() {
        let src = resolve_source(Path::new("/nonexistent/x.nsb"), "goat_leather").unwrap();
        assert_eq!(src.name(), "goat_leather");
    }

    /// The blob's folder comes before the folder above it, `.toml` before `.json` and
    /// `.bsdf`; a source found nowhere names where it was looked for.
    #[test]
    fn the_blobs_folder_comes_first() {
        let dir = tempfile::tempdir().unwrap();
        let (up, here) = (dir.path().to_path_buf(), dir.path().join("neural"));
        std::fs::create_dir_all(&here).unwrap();
        let blob = here.join("fit.nsb");
        let c = source_candidates(&blob, "src");
        let want: Vec<PathBuf> = [&here, &up]
            .iter()
            .flat_map(|d| ["src", "src.toml", "src.json", "src.bsdf"].map(|f| d.join(f)))
            .collect();
        assert_eq!(c, want);

        write_material(&up.join("src.toml"), "one_up");
        assert_eq!(resolve_source(&blob, "src").unwrap().name(), "one_up");
        write_material(&here.join("src.toml"), "beside");
        assert_eq!(resolve_source(&blob, "src").unwrap().name(), "beside");
        // A measured file beside the blob.
        std::fs::copy(
            fixtures().join("measured/paper_white_rgb.bsdf"),
            here.join("paper.bsdf"),
        )
        .unwrap();
        let m = resolve_source(&blob, "paper").unwrap();
        assert!(m.measured().is_some());

        let Err(e) = resolve_source(&blob, "nowhere") else {
            panic!("a source that is nowhere resolved");
        };
        let e = format!("{e:#}");
        assert!(
            e.contains("nowhere") && e.contains(&here.join("nowhere.bsdf").display().to_string()),
            "{e}"
        );
    }
}
