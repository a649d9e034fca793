//! `model = "normal_mapped"`: leather-like isotropic GGX + diffuse under strong normal mapping
//! (paper: Goat Leather, Cowhide Leather, Sheep Leather — one isotropic highlight that the
//! normal map moves around).
//!
//! Texture: a cellular "grain" (periodic Worley cells, pillow-shaped tops, creases where two
//! cells meet) plus fBm wrinkles give a height field `H(uv)`; the shading normal is
//! `normalize(−∂H/∂u, −∂H/∂v, 1)`. Creases are darker, rougher and occluded.
//!
//! # φ layout
//!
//! | index | meaning                                    | range     |
//! |-------|--------------------------------------------|-----------|
//! | 0, 1  | shading normal `n.x`, `n.y`                 | `[−0.9, 0.9]`, `|(n.x, n.y)| ≤ 0.9` |
//! | 2     | perceptual roughness `r` (`α = r²`)         | `[0, 1]`  |
//! | 3–5   | diffuse albedo (RGB)                        | `[0, 1]`  |
//! | 6     | specular level `s` (`F0 = 0.08 s`)          | `[0, 1]`  |
//! | 7     | cavity `c` (multiplies f)                   | `[0, 1]`  |

use glam::Vec2;

use super::check::params;
use super::microfacet::{alpha_from_roughness, clamp_tilt, ShadingFrame};
use super::model::FEATURE_DIM;
use super::noise::{fbm, gradient_of, smoothstep, unit as hunit, worley};
use super::surface::{lerp, lerp3, signed, unit, unit3, Surface, SurfaceModel};

params! {
    /// `[params]` of a `normal_mapped` material.
    pub struct Params {
        /// Noise seed.
        pub seed: u32,
        /// Grain cells per uv unit (Worley frequency).
        pub grain_cells: u32 => count(1..=256),
        /// Bump strength of the grain (slope scale).
        pub grain_depth: f32 => range(0.0..=3.0),
        /// Wrinkle fBm base frequency (cells per uv unit).
        pub wrinkle_freq: u32 => count(1..=256),
        /// Wrinkle fBm octaves.
        pub wrinkle_octaves: u32 => count(1..=8),
        /// Bump strength of the wrinkles.
        pub wrinkle_strength: f32 => range(0.0..=3.0),
        /// Albedo of the cell tops.
        pub color_top: [f32; 3] => range_n(0.0..=1.0),
        /// Albedo in the creases.
        pub color_crease: [f32; 3] => range_n(0.0..=1.0),
        /// Extra per-cell albedo variation (relative).
        #[serde(default)]
        pub color_jitter: f32 => range(0.0..=1.0),
        /// Perceptual roughness on the cell tops.
        pub roughness_top: f32 => range(0.0..=1.0),
        /// Perceptual roughness in the creases.
        pub roughness_crease: f32 => range(0.0..=1.0),
        /// Specular level `s` (`F0 = 0.08 s`).
        pub specular: f32 => range(0.0..=1.0),
    }
}

/// A `normal_mapped` material.
#[derive(Clone, Debug)]
pub struct Leather {
    p: Params,
}

impl Leather {
    fn height(&self, uv: Vec2) -> f32 {
        let p = &self.p;
        let w = worley(uv, p.grain_cells, 0.9, p.seed);
        let ridge = smoothstep(0.0, 0.35, w.f2 - w.f1);
        let pillow = ridge * (1.0 - 0.8 * w.f1 * w.f1);
        let wrinkles = fbm(uv, p.wrinkle_freq, p.wrinkle_octaves, 0.5, p.seed ^ 0xa5a5);
        p.grain_depth * pillow / p.grain_cells as f32
            + p.wrinkle_strength * wrinkles / p.wrinkle_freq as f32
    }
}

impl SurfaceModel for Leather {
    type Params = Params;

    fn from_params(p: Params) -> anyhow::Result<Self> {
        p.check()?;
        Ok(Leather { p })
    }

    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        let p = &self.p;
        let h = 0.05 / (p.grain_cells.max(p.wrinkle_freq << (p.wrinkle_octaves - 1)) as f32);
        let g = gradient_of(|q| self.height(q), uv, h);
        let n = glam::Vec3::new(-g.x, -g.y, 1.0).normalize();
        let w = worley(uv, p.grain_cells, 0.9, p.seed);
        let crease = 1.0 - smoothstep(0.0, 0.35, w.f2 - w.f1);
        let jitter = 1.0 + p.color_jitter * (hunit(w.id) - 0.5);
        let albedo =
            lerp3(p.color_top, p.color_crease, crease).map(|c| (c * jitter).clamp(0.0, 1.0));
        let r = lerp(p.roughness_top, p.roughness_crease, crease);
        let cavity = 1.0 - 0.5 * crease;
        let (nx, ny) = clamp_tilt(n.x, n.y);
        [
            nx, ny, r, albedo[0], albedo[1], albedo[2], p.specular, cavity,
        ]
    }

    fn decode(&self, phi: &[f32; FEATURE_DIM]) -> Surface {
        let a = alpha_from_roughness(unit(phi[2]));
        let mut s = Surface::dielectric(a, unit(phi[6]), unit3(phi, 3));
        s.frame = ShadingFrame::new(signed(phi[0]), signed(phi[1]), 1.0, 0.0);
        s.scale = unit(phi[7]);
        s
    }
}
