//! The sun and environment-map options of `neusample demo` and `neusample scene`.

use std::path::PathBuf;

use clap::Args;
use neusample_precompute::demo::Sky;

/// The sun and the environment map.
#[derive(Args, Clone, Debug)]
pub struct SkyArgs {
    /// Radiance of the sun disc (0: sky only); `neusample demo` lights with it only with --sky
    /// or --envmap.
    #[arg(long, default_value_t = 60.0)]
    pub sun_radiance: f32,
    /// Angular radius of the sun, degrees.
    #[arg(long, default_value_t = 4.0)]
    pub sun_size: f32,
    /// An equirectangular OpenEXR environment map (z-up, see `neusample_render::EnvMap`)
    /// instead of the procedural sky; the sun is added unless --sun-radiance is 0.
    #[arg(long)]
    pub envmap: Option<PathBuf>,
}

impl From<SkyArgs> for Sky {
    fn from(a: SkyArgs) -> Self {
        Sky {
            sun_radiance: a.sun_radiance,
            sun_size: a.sun_size,
            envmap: a.envmap,
        }
    }
}
