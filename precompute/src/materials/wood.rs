//! `model = "wood"`: diffuse-dominant wood with a weak anisotropic varnish lobe along the grain
//! (paper: Wagon Fine Wood Panelling). Growth rings (a distorted ring field around a far-away
//! pith, so the rings appear as wavy bands), early/late wood colours, pores; the grain
//! direction follows the ring bands.
//!
//! # φ layout
//!
//! | index | meaning                                               | range    |
//! |-------|-------------------------------------------------------|----------|
//! | 0–2   | diffuse albedo (RGB)                                  | `[0, 1]` |
//! | 3     | perceptual roughness `r`                              | `[0, 1]` |
//! | 4, 5  | grain direction as doubled angle `(cos 2ψ, sin 2ψ)`   | unit vector |
//! | 6     | anisotropy `a`: `(α_t, α_b)` from [`aniso_alphas`], tangent = grain (smoother along the fibres, highlight stretched across them) | `[0, 1]` |
//! | 7     | specular level `s` (`F0 = 0.08 s`)                    | `[0, 1]` |

use glam::Vec2;

use super::check::params;
use super::microfacet::{half_angle, ShadingFrame};
use super::model::FEATURE_DIM;
use super::noise::{fbm, gradient, gradient_of, smoothstep};
use super::surface::{aniso_alphas, lerp, lerp3, signed, unit, unit3, Surface, SurfaceModel};

params! {
    /// `[params]` of a `wood` material.
    pub struct Params {
        /// Noise seed.
        pub seed: u32,
        /// Growth rings per uv unit across the grain.
        pub rings: u32 => count(1..=128),
        /// Ring distortion (in ring periods).
        pub distortion: f32 => range(0.0..=8.0),
        /// Early-wood albedo (light).
        pub color_early: [f32; 3] => range_n(0.0..=1.0),
        /// Late-wood albedo (dark).
        pub color_late: [f32; 3] => range_n(0.0..=1.0),
        /// Perceptual roughness: late wood is smoother.
        pub roughness: [f32; 2] => interval(0.0..=1.0),
        /// Anisotropy along the grain.
        pub anisotropy: f32 => range(0.0..=1.0),
        /// Specular level `s` (`F0 = 0.08 s`).
        pub specular: f32 => range(0.0..=1.0),
    }
}

/// A `wood` material.
#[derive(Clone, Debug)]
pub struct Wood {
    p: Params,
}

impl Wood {
    fn ring_phase(&self, uv: Vec2) -> f32 {
        let p = &self.p;
        // Grain runs along u; rings are bands in v, distorted by low-frequency noise.
        let d = fbm(uv, 3, 3, 0.5, p.seed);
        uv.y * p.rings as f32 + p.distortion * d
    }
}

impl SurfaceModel for Wood {
    type Params = Params;

    fn from_params(p: Params) -> anyhow::Result<Self> {
        p.check()?;
        Ok(Wood { p })
    }

    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        let p = &self.p;
        let ph = self.ring_phase(uv);
        let frac = ph - ph.floor();
        // Early wood grows fast (light, wide), late wood is a narrow dark band.
        let late = smoothstep(0.65, 0.85, frac) * (1.0 - smoothstep(0.92, 1.0, frac));
        let pores = smoothstep(
            0.35,
            0.6,
            gradient(uv * Vec2::new(1.0, 8.0), 64, p.seed ^ 0x9),
        ) * (1.0 - late);
        let streak = fbm(Vec2::new(uv.x, uv.y), 2, 2, 0.5, p.seed ^ 0x3) * 0.3;
        let albedo = lerp3(p.color_early, p.color_late, (late + 0.5 * pores).min(1.0))
            .map(|c| (c * (1.0 + streak)).clamp(0.0, 1.0));
        // Grain direction: along the iso-lines of the ring phase (mostly u).
        let g = gradient_of(|q| self.ring_phase(q), uv, 1e-3);
        let t = Vec2::new(g.y, -g.x);
        let t = if t.length_squared() > 1e-12 {
            t.normalize()
        } else {
            Vec2::X
        };
        let t = if t.x < 0.0 { -t } else { t };
        let r = lerp(p.roughness[1], p.roughness[0], late);
        [
            albedo[0],
            albedo[1],
            albedo[2],
            r,
            t.x * t.x - t.y * t.y,
            2.0 * t.x * t.y,
            p.anisotropy * (1.0 - 0.5 * pores),
            p.specular,
        ]
    }

    fn decode(&self, phi: &[f32; FEATURE_DIM]) -> Surface {
        let (c, s) = half_angle(signed(phi[4]), signed(phi[5]));
        let (ax, ay) = aniso_alphas(unit(phi[3]), unit(phi[6])); // x = grain
        let mut surf = Surface::dielectric(ax, unit(phi[7]), unit3(phi, 0));
        surf.ay = ay;
        surf.frame = ShadingFrame::new(0.0, 0.0, c, s);
        surf
    }
}
