//! Equirectangular environment maps (z-up lat-long images).

use glam::Vec3;

#[cfg(feature = "exr")]
use crate::error::Error;
use crate::image::Image;

/// An equirectangular environment map, **z-up**: row 0 is the zenith (+z), the last row the
/// nadir; column 0 is azimuth −π (the −x direction) and the azimuth `atan2(y, x)` increases
/// with the column. Looked up with nearest-pixel filtering.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvMap {
    /// The image (linear RGB).
    pub image: Image,
    /// Multiplier applied to every texel.
    pub scale: f32,
}

impl EnvMap {
    /// Loads the first RGB(A) layer of an OpenEXR file (non-finite and negative values
    /// become 0).
    #[cfg(feature = "exr")]
    pub fn load_exr(path: &std::path::Path) -> Result<EnvMap, Error> {
        use exr::prelude::{read_first_rgba_layer_from_file, Vec2 as ExrVec2};
        let img = read_first_rgba_layer_from_file(
            path,
            |res: ExrVec2<usize>, _| Image::new(res.width(), res.height()),
            |im: &mut Image, pos: ExrVec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
                let w = im.width;
                let clean = |v: f32| if v.is_finite() && v > 0.0 { v } else { 0.0 };
                im.data[pos.y() * w + pos.x()] = [clean(r), clean(g), clean(b)];
            },
        )
        .map_err(|e| Error::EnvMap {
            path: path.to_path_buf(),
            reason: format!("cannot read environment map {}: {e}", path.display()),
        })?;
        let image = img.layer_data.channel_data.pixels;
        if image.width == 0 || image.height == 0 {
            return Err(Error::EnvMap {
                path: path.to_path_buf(),
                reason: format!("environment map {} is empty", path.display()),
            });
        }
        Ok(EnvMap { image, scale: 1.0 })
    }

    /// Radiance towards `d`.
    #[must_use]
    pub fn lookup(&self, d: Vec3) -> [f32; 3] {
        let (u, v) = dir_to_latlong(d);
        let x = ((u * self.image.width as f32) as usize).min(self.image.width - 1);
        let y = ((v * self.image.height as f32) as usize).min(self.image.height - 1);
        let c = self.image.at(x, y);
        [c[0] * self.scale, c[1] * self.scale, c[2] * self.scale]
    }
}

/// Lat-long coordinates `(u, v) ∈ [0, 1]²` of a unit direction (see [`EnvMap`]).
pub(crate) fn dir_to_latlong(d: Vec3) -> (f32, f32) {
    let phi = d.y.atan2(d.x);
    let theta = d.z.clamp(-1.0, 1.0).acos();
    (
        (phi + std::f32::consts::PI) * (0.5 * std::f32::consts::FRAC_1_PI),
        theta * std::f32::consts::FRAC_1_PI,
    )
}
