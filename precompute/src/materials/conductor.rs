//! `model = "conductor"`: a homogeneous GGX conductor (Schlick Fresnel with an RGB `F0`),
//! isotropic or anisotropic. φ is the same at every texel.
//!
//! # φ layout
//!
//! | index | meaning                                             | range    |
//! |-------|-----------------------------------------------------|----------|
//! | 0     | perceptual roughness along the tangent `r_x`         | `[0, 1]` |
//! | 1     | perceptual roughness along the bitangent `r_y`       | `[0, 1]` |
//! | 2–4   | `F0` (RGB)                                           | `[0, 1]` |
//! | 5, 6  | tangent as doubled angle `(cos 2ψ, sin 2ψ)`          | unit vector |
//! | 7     | unused, 0                                           | `0`      |

use glam::Vec2;

use super::check::params;
use super::microfacet::{alpha_from_roughness, half_angle, ShadingFrame};
use super::model::FEATURE_DIM;
use super::surface::{signed, unit, unit3, Surface, SurfaceModel};

params! {
    /// `[params]` of a `conductor` material.
    pub struct Params {
        /// Perceptual roughness along the tangent.
        pub roughness_x: f32 => range(0.0..=1.0),
        /// Perceptual roughness along the bitangent (defaults to `roughness_x`).
        #[serde(default)]
        pub roughness_y: Option<f32> => range(0.0..=1.0),
        /// Reflectance at normal incidence (RGB).
        pub f0: [f32; 3] => range_n(0.0..=1.0),
        /// Tangent angle ψ from the u axis, degrees.
        #[serde(default)]
        pub tangent_deg: f32 => range(-360.0..=360.0),
    }
}

/// A `conductor` material.
#[derive(Clone, Debug)]
pub struct Conductor {
    phi: [f32; FEATURE_DIM],
}

impl SurfaceModel for Conductor {
    type Params = Params;

    fn from_params(p: Params) -> anyhow::Result<Self> {
        p.check()?;
        let ry = p.roughness_y.unwrap_or(p.roughness_x);
        let (s2, c2) = (2.0 * p.tangent_deg.to_radians()).sin_cos();
        let phi = [p.roughness_x, ry, p.f0[0], p.f0[1], p.f0[2], c2, s2, 0.0];
        Ok(Conductor { phi })
    }

    fn features(&self, _uv: Vec2) -> [f32; FEATURE_DIM] {
        self.phi
    }

    fn decode(&self, phi: &[f32; FEATURE_DIM]) -> Surface {
        let (c, s) = half_angle(signed(phi[5]), signed(phi[6]));
        let mut surf =
            Surface::isotropic(alpha_from_roughness(unit(phi[0])), unit3(phi, 2), [0.0; 3]);
        surf.ay = alpha_from_roughness(unit(phi[1]));
        surf.frame = ShadingFrame::new(0.0, 0.0, c, s);
        surf
    }
}
