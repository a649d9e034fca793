//! `model = "marble"`: polished stone with spatially varying roughness (paper: Giallo Antico
//! Marble). Veins from a turbulence-distorted sine are rougher, hazier and differently
//! coloured than the polished body; chips and polishing ripples tilt the normal slightly.
//!
//! The specular part mixes a main GGX lobe (roughness `r`) with a broader haze lobe
//! (`α_h = min(1, 4 α)`), weight `w_h` (two-scale roughness of polished stone).
//!
//! # φ layout
//!
//! | index | meaning                                  | range    |
//! |-------|------------------------------------------|----------|
//! | 0     | perceptual roughness `r`                  | `[0, 1]` |
//! | 1–3   | diffuse albedo (RGB)                      | `[0, 1]` |
//! | 4     | specular level `s` (`F0 = 0.08 s`)        | `[0, 1]` |
//! | 5, 6  | shading normal `n.x`, `n.y`               | `|(n.x, n.y)| ≤ 0.9` |
//! | 7     | haze weight `w_h`                         | `[0, 1]` |

use glam::{Vec2, Vec3};

use super::check::params;
use super::microfacet::{alpha_from_roughness, clamp_tilt, ShadingFrame};
use super::model::FEATURE_DIM;
use super::noise::{fbm, gradient_of, smoothstep, turbulence};
use super::surface::{lerp, lerp3, signed, unit, unit3, Surface, SurfaceModel};

params! {
    /// `[params]` of a `marble` material.
    pub struct Params {
        /// Noise seed.
        pub seed: u32,
        /// Vein frequency (periods per uv unit).
        pub vein_freq: u32 => count(1..=64),
        /// Turbulence frequency (lattice cells per uv unit).
        pub turbulence_freq: u32 => count(1..=64),
        /// Turbulence strength (phase distortion in periods).
        pub turbulence: f32 => range(0.0..=8.0),
        /// Vein sharpness (power applied to the vein profile).
        pub vein_sharpness: f32 => range(0.5..=32.0),
        /// Body albedo.
        pub color_body: [f32; 3] => range_n(0.0..=1.0),
        /// Vein albedo.
        pub color_vein: [f32; 3] => range_n(0.0..=1.0),
        /// Perceptual roughness of the polished body.
        pub roughness_body: f32 => range(0.0..=1.0),
        /// Perceptual roughness in the veins.
        pub roughness_vein: f32 => range(0.0..=1.0),
        /// Haze weight of the body.
        pub haze_body: f32 => range(0.0..=1.0),
        /// Haze weight in the veins.
        pub haze_vein: f32 => range(0.0..=1.0),
        /// Specular level `s` (`F0 = 0.08 s`).
        pub specular: f32 => range(0.0..=1.0),
        /// Bump strength of polishing ripples (slope scale).
        pub bump: f32 => range(0.0..=1.0),
    }
}

/// A `marble` material.
#[derive(Clone, Debug)]
pub struct Marble {
    p: Params,
}

impl Marble {
    fn vein(&self, uv: Vec2) -> f32 {
        let p = &self.p;
        let t = turbulence(uv, p.turbulence_freq, 5, 0.55, p.seed);
        // A diagonal sine, periodic in uv: phase (u + v)·freq plus turbulence.
        let phase = (uv.x + uv.y) * p.vein_freq as f32 + p.turbulence * t;
        let s = 1.0 - (std::f32::consts::PI * phase).sin().abs();
        s.powf(p.vein_sharpness)
    }
}

impl SurfaceModel for Marble {
    type Params = Params;

    fn from_params(p: Params) -> anyhow::Result<Self> {
        p.check()?;
        Ok(Marble { p })
    }

    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        let p = &self.p;
        let v = self.vein(uv);
        let mottle = fbm(uv, p.turbulence_freq * 4, 3, 0.5, p.seed ^ 0x5eed);
        let vein = smoothstep(0.05, 0.6, v + 0.15 * mottle);
        let albedo = lerp3(p.color_body, p.color_vein, vein)
            .map(|c| (c * (1.0 + 0.25 * mottle)).clamp(0.0, 1.0));
        let r = lerp(p.roughness_body, p.roughness_vein, vein);
        let haze = lerp(p.haze_body, p.haze_vein, vein);
        let f = (p.turbulence_freq * 8) as f32;
        let g = gradient_of(
            |q| fbm(q, p.turbulence_freq * 8, 2, 0.5, p.seed ^ 0xb0b) / f + 0.5 * v / f,
            uv,
            0.01 / f,
        );
        let n = Vec3::new(-p.bump * g.x, -p.bump * g.y, 1.0).normalize();
        let (nx, ny) = clamp_tilt(n.x, n.y);
        [r, albedo[0], albedo[1], albedo[2], p.specular, nx, ny, haze]
    }

    fn decode(&self, phi: &[f32; FEATURE_DIM]) -> Surface {
        let a = alpha_from_roughness(unit(phi[0]));
        let mut s = Surface::dielectric(a, unit(phi[4]), unit3(phi, 1));
        s.frame = ShadingFrame::new(signed(phi[5]), signed(phi[6]), 1.0, 0.0);
        s.haze = unit(phi[7]);
        s.haze_alpha = (4.0 * a).min(1.0);
        s
    }
}
