//! `neusample demo` and `neusample fixtures`.

use std::path::PathBuf;

use anyhow::Result;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::Args;
use neusample_precompute::demo::{self, DemoConfig, FixtureSet};

/// Options of `neusample demo`.
#[derive(Args, Clone, Debug)]
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
    /// An equirectangular OpenEXR environment map (z-up, see `neusample_render::EnvMap`)
    /// instead of the procedural sky; the sun is added unless --sun-radiance is 0.
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

impl From<DemoArgs> for DemoConfig {
    fn from(a: DemoArgs) -> Self {
        DemoConfig {
            quick: a.quick,
            out: a.out,
            use_fixtures: a.use_fixtures,
            materials: a.materials,
            procedural: a.procedural,
            seed: a.seed,
            steps_scale: a.steps_scale,
            width: a.width,
            spp: a.spp,
            sun_radiance: a.sun_radiance,
            sun_size: a.sun_size,
            envmap: a.envmap,
            uniform_light: a.uniform_light,
            mis: a.mis,
            no_render: a.no_render,
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
    /// Quick training (for tests of the command itself).
    #[arg(long)]
    pub quick: bool,
}

/// The names of [`FixtureSet::NAMES`], listed in `--help`.
fn fixture_set_parser() -> impl TypedValueParser<Value = FixtureSet> {
    PossibleValuesParser::new(FixtureSet::NAMES.map(|(n, _)| n))
        .map(|s| s.parse::<FixtureSet>().expect("a listed fixture set"))
}

/// `neusample fixtures`.
pub fn fixtures(a: &FixturesArgs) -> Result<()> {
    demo::regenerate_fixtures(&a.out, &a.materials_out, a.set, a.quick)
}
