//! `neusample scene`.

use std::path::PathBuf;

use clap::Args;
use neusample_precompute::demo::showcase::{parse_method_choice, ShowcaseConfig};

use crate::sky::SkyArgs;

/// Options of `neusample scene`.
#[derive(Args, Clone, Debug)]
pub struct SceneArgs {
    /// Output folder (created; files are replaced atomically).
    #[arg(long, default_value = "neusample-scene")]
    pub out: PathBuf,
    /// Materials, the floor first, then up to four spheres: built-in names with a committed
    /// neural version, or material files (.toml, .json, measured .bsdf, neural .nsb) rendered
    /// as themselves; default wagon_wood,gold,brushed_metal,victorian_fabric,car_paint.
    #[arg(long, value_delimiter = ',')]
    pub materials: Vec<String>,
    /// A demo report whose verdicts give each material's method: a report.json, or a folder
    /// of reports whose sky-sun/report.json is used.
    #[arg(long, value_name = "FILE|DIR")]
    pub table: Option<PathBuf>,
    /// Methods per material, before the table's: material=method,… (a sampler kind's name;
    /// an unknown name is answered with the list of names); a material named by neither
    /// gets flow.
    #[arg(long, value_delimiter = ',', value_parser = parse_choice)]
    pub methods: Vec<(String, String)>,
    /// Seed of every render.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Image width in pixels (height = 9/16 of it).
    #[arg(long, default_value_t = 256)]
    pub width: usize,
    /// The baseline's samples per pixel N (the equal-time budget).
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// The reference (baseline, MIS) has this many times N samples per pixel.
    #[arg(long, default_value_t = 16)]
    pub ref_factor: u32,
    /// Surface interactions per path (1 = direct lighting only).
    #[arg(long, default_value_t = 3)]
    pub bounces: u32,
    /// Interleaved single-thread timing passes per configuration.
    #[arg(long, default_value_t = 5)]
    pub timing_passes: usize,
    #[command(flatten)]
    pub sky: SkyArgs,
    /// A folder of samplers, <DIR>/<material>/<method>.nsb (what `neusample demo --train
    /// --out X` writes under X/blobs), searched before fixtures/blobs and
    /// fixtures/measured/blobs.
    #[arg(long, value_name = "DIR")]
    pub blobs: Option<PathBuf>,
}

fn parse_choice(s: &str) -> Result<(String, String), String> {
    parse_method_choice(s).map_err(|e| format!("{e:#}"))
}

impl From<SceneArgs> for ShowcaseConfig {
    fn from(a: SceneArgs) -> Self {
        ShowcaseConfig {
            out: a.out,
            materials: a.materials,
            table: a.table,
            methods: a.methods,
            seed: a.seed,
            width: a.width,
            spp: a.spp,
            ref_factor: a.ref_factor,
            bounces: a.bounces,
            timing_passes: a.timing_passes,
            sky: a.sky.into(),
            blobs: a.blobs,
        }
    }
}
