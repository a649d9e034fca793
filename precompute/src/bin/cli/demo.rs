//! `neusample demo` and `neusample fixtures`.

use std::path::PathBuf;

use anyhow::Result;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::Args;
use neusample::SamplerKind;
use neusample_precompute::demo::{
    self, DemoConfig, FixtureSet, Lighting, TableConfig, DEFAULT_MATERIALS,
};
use neusample_precompute::train::{parse_method, METHODS};

use crate::sky::SkyArgs;

/// Options of `neusample demo`.
#[derive(Args, Clone, Debug)]
pub struct DemoArgs {
    /// CI-sized smoke test: a small image, few samples and conditions (and, with --train,
    /// short training); its report says in its first line that its numbers are not results.
    #[arg(long, alias = "quick")]
    pub smoke: bool,
    /// Output folder (created; files are replaced atomically).
    #[arg(long, default_value = "neusample-report")]
    pub out: PathBuf,
    /// Train every sampler instead of using the committed pretrained blobs (`fixtures/`).
    #[arg(long)]
    pub train: bool,
    /// Pretrained blobs from this folder (`<material>/<method>.nsb`) instead of the committed
    /// `fixtures/blobs/`.
    #[arg(long, conflicts_with = "train")]
    pub blobs: Option<PathBuf>,
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
    /// fit: 1 gives the better samplers of `neusample train`). Used with --train only, and
    /// not with --smoke.
    #[arg(long, default_value_t = 0.5)]
    pub steps_scale: f64,
    /// Image width in pixels (height = 3/4 of it); default 112, 64 with --smoke.
    #[arg(long)]
    pub width: Option<usize>,
    /// Equal-spp sample count N (convergence up to it; the baseline's equal-time budget);
    /// default 32, 8 with --smoke.
    #[arg(long)]
    pub spp: Option<u32>,
    #[command(flatten)]
    pub sky_light: SkyArgs,
    /// Light the scene with the procedural sky and its small bright sun instead of uniform
    /// white light (the default, under which the render variance measures the BSDF sampler
    /// alone, as in the paper's uniformly lit scenes). Under the sun, BSDF sampling must also
    /// find the light, which no sampler does well for broad lobes.
    #[arg(long)]
    pub sky: bool,
    /// Combine BSDF sampling with environment sampling (MIS, power heuristic) instead of
    /// BSDF sampling alone.
    #[arg(long)]
    pub mis: bool,
    /// Skip the rendering evaluation (fit and cost only).
    #[arg(long)]
    pub no_render: bool,
    /// Trained methods to evaluate, comma-separated, of the names listed below (cosine, the
    /// improved baseline and the oracle are always evaluated); default: all.
    #[arg(long, value_delimiter = ',', value_parser = method_parser())]
    pub methods: Vec<SamplerKind>,
}

/// A trainable method's name (`neusample train --method`'s names).
fn method_parser() -> impl TypedValueParser<Value = SamplerKind> {
    PossibleValuesParser::new(METHODS.map(|m| m.name()))
        .map(|s| parse_method(&s).expect("a listed method"))
}

impl From<DemoArgs> for DemoConfig {
    fn from(a: DemoArgs) -> Self {
        DemoConfig {
            quick: a.smoke,
            out: a.out,
            use_fixtures: !a.train,
            blobs: a.blobs,
            material_blobs: Vec::new(),
            materials: a.materials,
            procedural: a.procedural,
            seed: a.seed,
            steps_scale: a.steps_scale,
            width: a.width,
            spp: a.spp,
            sky: a.sky_light.into(),
            uniform_light: !a.sky,
            mis: a.mis,
            no_render: a.no_render,
            methods: a.methods,
            eval_conditions: None,
            timing_passes: None,
        }
    }
}

/// Options of `neusample fixtures`.
#[derive(Args, Clone, Debug)]
pub struct FixturesArgs {
    /// Output folder of the sampler blobs.
    #[arg(long, default_value = "fixtures/blobs")]
    pub out: PathBuf,
    /// Output folder of the neural materials.
    #[arg(long, default_value = "fixtures/materials/neural")]
    pub materials_out: PathBuf,
    /// Which fixtures: samplers on the procedural materials, the neural materials and
    /// their samplers, or all.
    #[arg(long, default_value = "all", value_parser = fixture_set_parser())]
    pub set: FixtureSet,
    /// Built-in materials (default: the three demo materials).
    #[arg(long, value_delimiter = ',', default_values_t = DEFAULT_MATERIALS.map(String::from))]
    pub materials: Vec<String>,
    /// Quick training (for tests of the command itself).
    #[arg(long)]
    pub quick: bool,
    /// Trained methods to (re)train (as `demo --methods`); default: all.
    #[arg(long, value_delimiter = ',', value_parser = method_parser())]
    pub methods: Vec<SamplerKind>,
}

/// The names of [`FixtureSet::NAMES`], listed in `--help`.
fn fixture_set_parser() -> impl TypedValueParser<Value = FixtureSet> {
    PossibleValuesParser::new(FixtureSet::NAMES.map(|(n, _)| n))
        .map(|s| s.parse::<FixtureSet>().expect("a listed fixture set"))
}

/// `neusample fixtures`.
pub fn fixtures(a: &FixturesArgs) -> Result<()> {
    let names: Vec<&str> = a.materials.iter().map(String::as_str).collect();
    demo::regenerate_fixtures(&a.out, &a.materials_out, a.set, &names, &a.methods, a.quick)
}

/// Options of `neusample table`.
#[derive(Args, Clone, Debug)]
pub struct TableArgs {
    /// Output folder: one demo report per lighting and `table.md`.
    #[arg(long, default_value = "neusample-table")]
    pub out: PathBuf,
    /// Materials (default: all thirteen built-ins), built-in names and material files mixed
    /// (`.toml`, `.json`, `.bsdf`, `.nsb`). A built-in's neural version is evaluated (trained
    /// into `fixtures/` first where it is not committed); a file's samplers are read from
    /// `fixtures/blobs/<name>/` when it holds every method evaluated, else trained once into
    /// `<out>/blobs/<name>/` (as `demo --train` trains them; a later run reuses them).
    #[arg(long, value_delimiter = ',')]
    pub materials: Vec<String>,
    /// Seed of the evaluation (and of the training of a file's samplers).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Image width in pixels (height = 3/4 of it).
    #[arg(long, default_value_t = 128)]
    pub width: usize,
    /// Equal-spp sample count N.
    #[arg(long, default_value_t = 32)]
    pub spp: u32,
    /// Only rewrite `table.md` from the reports already in the output folder.
    #[arg(long)]
    pub markdown_only: bool,
    /// The demo's CI-sized smoke test per lighting (numbers are not results).
    #[arg(long)]
    pub smoke: bool,
    /// Trained methods to evaluate (as `demo --methods`); default: all.
    #[arg(long, value_delimiter = ',', value_parser = method_parser())]
    pub methods: Vec<SamplerKind>,
    /// Lightings to run, comma-separated (`uniform`, `sky-sun`); default: both. A lighting
    /// not run stays in `table.md` when its report is already in the output folder.
    #[arg(long, value_delimiter = ',', value_parser = lighting_parser())]
    pub lightings: Vec<Lighting>,
}

/// `uniform` or `sky-sun`.
fn lighting_parser() -> impl clap::builder::TypedValueParser<Value = Lighting> {
    clap::builder::PossibleValuesParser::new(Lighting::ALL.map(Lighting::name)).map(|s| {
        Lighting::ALL
            .into_iter()
            .find(|l| l.name() == s)
            .expect("a listed lighting")
    })
}

impl From<TableArgs> for TableConfig {
    fn from(a: TableArgs) -> Self {
        let mut c = TableConfig::new(a.out);
        c.materials = a.materials;
        c.seed = a.seed;
        c.width = a.width;
        c.spp = a.spp;
        c.markdown_only = a.markdown_only;
        c.smoke = a.smoke;
        c.methods = a.methods;
        c.lightings = a.lightings;
        c
    }
}
