//! `model = "anisotropic"`: anisotropic GGX highlights with a spatially varying tangent field
//! (paper: Stylized Melted Metal, brushed metals, Turtle Shell).
//!
//! Patterns (`params.pattern`):
//!
//! * `"flow"` — melted metal: the tangent follows the iso-lines of a low-frequency fBm
//!   (swirls), roughness and tint vary with a second fBm, blobby fBm bumps tilt the normal.
//! * `"spot"` — engine-turned / spot-brushed metal: one circular brushing per periodic Worley
//!   cell, tangent = circumferential direction around the cell's centre.
//! * `"shell"` — tortoise shell: polygonal plates (Worley cells), growth rings concentric to
//!   each plate's centre give the tangent, a tint that darkens towards the plate seams, and a
//!   bulge per plate.
//!
//! # φ layout
//!
//! | index | meaning                                             | range     |
//! |-------|-----------------------------------------------------|-----------|
//! | 0, 1  | tangent as doubled angle `(cos 2ψ, sin 2ψ)`         | `[−1, 1]` (unit vector) |
//! | 2     | perceptual roughness along the tangent `r_t`        | `[0, 1]`  |
//! | 3     | perceptual roughness across (bitangent) `r_b`       | `[0, 1]`  |
//! | 4, 5  | shading normal `n.x`, `n.y`                          | `|(n.x, n.y)| ≤ 0.9` |
//! | 6     | tint `t`: colour = lerp(`color_a`, `color_b`, t)    | `[0, 1]`  |
//! | 7     | metallic `m`: `F0 = lerp(0.04, colour, m)`, diffuse = colour·(1 − m) | `[0, 1]` |

use glam::{Vec2, Vec3};
use serde::Deserialize;

use super::check::params;
use super::microfacet::{alpha_from_roughness, clamp_tilt, half_angle, ShadingFrame};
use super::model::FEATURE_DIM;
use super::noise::{fbm, gradient_of, smoothstep, unit as hunit, worley};
use super::surface::{lerp, lerp3, signed, unit, Surface, SurfaceModel};

/// Tangent-field pattern.
#[derive(Copy, Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Pattern {
    /// Swirling flow lines (melted metal).
    Flow,
    /// Circular brushing per cell (engine turning).
    Spot,
    /// Plates with concentric growth rings (tortoise shell).
    Shell,
}

params! {
    /// `[params]` of an `anisotropic` material.
    pub struct Params {
        /// Tangent-field pattern.
        pub pattern: Pattern,
        /// Noise seed.
        pub seed: u32,
        /// Pattern frequency (cells or fBm lattice cells per uv unit).
        pub freq: u32 => count(1..=256),
        /// Perceptual roughness along the tangent.
        pub roughness_along: [f32; 2] => interval(0.0..=1.0),
        /// Perceptual roughness across the tangent.
        pub roughness_across: [f32; 2] => interval(0.0..=1.0),
        /// First colour (F0 for metals, albedo for dielectrics).
        pub color_a: [f32; 3] => range_n(0.0..=1.0),
        /// Second colour.
        pub color_b: [f32; 3] => range_n(0.0..=1.0),
        /// Metallic.
        pub metallic: f32 => range(0.0..=1.0),
        /// Bump strength (slope scale).
        pub bump: f32 => range(0.0..=3.0),
    }
}

/// An `anisotropic` material.
#[derive(Clone, Debug)]
pub struct Anisotropic {
    p: Params,
}

impl Anisotropic {
    fn flow_field(&self, uv: Vec2) -> f32 {
        fbm(uv, self.p.freq, 3, 0.5, self.p.seed)
    }
}

impl SurfaceModel for Anisotropic {
    type Params = Params;

    fn from_params(p: Params) -> anyhow::Result<Self> {
        p.check()?;
        Ok(Anisotropic { p })
    }

    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        let p = &self.p;
        let f = p.freq as f32;
        // (tangent direction in uv, roughness blend ∈ [0,1], tint ∈ [0,1], height gradient)
        let (tangent, rb, tint, grad) = match p.pattern {
            Pattern::Flow => {
                let g = gradient_of(|q| self.flow_field(q), uv, 0.02 / f);
                let t = Vec2::new(-g.y, g.x);
                let v = fbm(uv, p.freq * 2, 3, 0.5, p.seed ^ 0x1234) * 1.4 + 0.5;
                let hgrad = gradient_of(
                    |q| fbm(q, p.freq * 2, 2, 0.5, p.seed ^ 0x77) / (2.0 * f),
                    uv,
                    0.01 / f,
                );
                (
                    t,
                    v.clamp(0.0, 1.0),
                    (0.5 + 1.2 * g.length() / f).clamp(0.0, 1.0),
                    hgrad,
                )
            }
            Pattern::Spot | Pattern::Shell => {
                let jitter = if p.pattern == Pattern::Spot { 0.3 } else { 0.9 };
                let w = worley(uv, p.freq, jitter, p.seed);
                // Direction to the nearest feature point, by differencing f1 (∇f1 points away
                // from the centre).
                let g = gradient_of(|q| worley(q, p.freq, jitter, p.seed).f1, uv, 0.002 / f);
                let t = Vec2::new(-g.y, g.x);
                let seam = 1.0 - smoothstep(0.0, 0.25, w.f2 - w.f1);
                let rb = (hunit(w.id) * 0.6 + 0.4 * seam).clamp(0.0, 1.0);
                if p.pattern == Pattern::Spot {
                    (t, rb, hunit(w.id.rotate_left(7)), Vec2::ZERO)
                } else {
                    let rings = 0.5 + 0.5 * (w.f1 * 40.0).sin();
                    let tint = (0.6 * seam + 0.25 * rings + 0.3 * hunit(w.id)).clamp(0.0, 1.0);
                    // A dome per plate: height −f1²/2 → gradient −f1 ∇f1.
                    let hgrad = -g * w.f1 / f;
                    (t, rb, tint, hgrad)
                }
            }
        };
        let (c2, s2) = if tangent.length_squared() > 1e-20 {
            let t = tangent.normalize();
            (t.x * t.x - t.y * t.y, 2.0 * t.x * t.y)
        } else {
            (1.0, 0.0)
        };
        let n = Vec3::new(-p.bump * grad.x, -p.bump * grad.y, 1.0).normalize();
        let (nx, ny) = clamp_tilt(n.x, n.y);
        let ra = lerp(p.roughness_along[0], p.roughness_along[1], rb);
        let rc = lerp(p.roughness_across[0], p.roughness_across[1], rb);
        [c2, s2, ra, rc, nx, ny, tint, p.metallic]
    }

    fn decode(&self, phi: &[f32; FEATURE_DIM]) -> Surface {
        let (c, s) = half_angle(signed(phi[0]), signed(phi[1]));
        let ax = alpha_from_roughness(unit(phi[2]));
        let ay = alpha_from_roughness(unit(phi[3]));
        let color = lerp3(self.p.color_a, self.p.color_b, unit(phi[6]));
        let mut surf = Surface::metallic(ax, color, unit(phi[7]));
        surf.ay = ay;
        surf.frame = ShadingFrame::new(signed(phi[4]), signed(phi[5]), c, s);
        surf
    }
}
