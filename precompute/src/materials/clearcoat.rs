//! `model = "clearcoat"`: a smooth-to-glossy dielectric coat over a rough, normal-mapped base
//! (car paint with metallic flakes, lacquered leather, varnished metal).
//!
//! ```text
//! f = F_c(wi·h) · D_c G2_c / (4 cos θi cos θo)                        (coat, geometric frame)
//!   + (1 − F(θi)) (1 − F(θo)) · A · f_base(wi_t, wo_t) / η²          (base, seen through it)
//! ```
//!
//! `F` is the exact dielectric Fresnel of index η, `wi_t`, `wo_t` are the refracted directions
//! (mirrored up), `A = exp(−σ τ (1/cos θi_t + 1/cos θo_t))` is the absorption of the coat
//! (σ = `params.absorption`, τ the thickness from φ) and `f_base` is a
//! [`super::surface::Surface`]. The `1/η²` accounts for the solid-angle compression under
//! refraction (`cos θo dωo = η² cos θo_t dωo_t`), so the base term reflects at most
//! `(1 − F(θi))` times the base albedo. Every term is symmetric in `wi`, `wo`.
//!
//! # φ layout
//!
//! | index | meaning                                           | range    |
//! |-------|---------------------------------------------------|----------|
//! | 0     | coat perceptual roughness `r_c`                   | `[0, 1]` |
//! | 1     | coat thickness τ (optical depth = σ τ)            | `[0, 1]` |
//! | 2     | base perceptual roughness `r_b`                   | `[0, 1]` |
//! | 3–5   | base colour (RGB)                                 | `[0, 1]` |
//! | 6, 7  | base shading normal `n.x`, `n.y` (flakes)          | `|(n.x, n.y)| ≤ 0.9` |

use glam::{Vec2, Vec3};

use super::check::params;
use super::format::File;
use super::microfacet::{
    alpha_from_roughness, clamp_tilt, fresnel_dielectric, ggx_dg, normalize_pair, refract_up,
    ShadingFrame,
};
use super::model::{Material, FEATURE_DIM};
use super::noise::{fbm, hash, unit as hunit, worley, wrap_uv};
use super::surface::{lerp, lerp3, sanitize, signed, unit, unit3, Surface};

params! {
    /// `[params]` of a `clearcoat` material.
    pub struct Params {
        /// Noise seed.
        pub seed: u32,
        /// Coat index of refraction.
        pub coat_ior: f32 => range(1.01..=2.5),
        /// Coat perceptual roughness (orange peel / wear varies it).
        pub coat_roughness: [f32; 2] => interval(0.0..=1.0),
        /// Absorption coefficient σ of the coat per unit thickness (RGB).
        pub absorption: [f32; 3] => range_n(0.0..=8.0),
        /// Coat thickness.
        pub thickness: [f32; 2] => interval(0.0..=1.0),
        /// Base colours blended by a low-frequency pattern.
        pub base_color_a: [f32; 3] => range_n(0.0..=1.0),
        /// Second base colour.
        pub base_color_b: [f32; 3] => range_n(0.0..=1.0),
        /// Base metallic (constant).
        pub base_metallic: f32 => range(0.0..=1.0),
        /// Base perceptual roughness.
        pub base_roughness: [f32; 2] => interval(0.0..=1.0),
        /// Flakes per uv unit (Worley cells).
        pub flakes: u32 => count(1..=512),
        /// Flake normal tilt `|(n.x, n.y)|` (max).
        pub flake_tilt: f32 => range(0.0..=0.9),
        /// Pattern frequency of colour/roughness variation.
        pub pattern_freq: u32 => count(1..=64),
    }
}

/// A `clearcoat` material.
#[derive(Clone, Debug)]
pub struct ClearCoat {
    name: String,
    p: Params,
}

impl ClearCoat {
    /// Validates a parsed file.
    pub fn new(file: File<Params>) -> anyhow::Result<Self> {
        file.params.check()?;
        Ok(ClearCoat {
            name: file.name,
            p: file.params,
        })
    }
}

impl Material for ClearCoat {
    fn name(&self) -> &str {
        &self.name
    }

    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        let p = &self.p;
        let uv = wrap_uv(uv);
        let pat = (0.5 + 1.2 * fbm(uv, p.pattern_freq, 3, 0.5, p.seed)).clamp(0.0, 1.0);
        let wear =
            (0.5 + 1.5 * fbm(uv, p.pattern_freq * 2, 2, 0.5, p.seed ^ 0xc0a7)).clamp(0.0, 1.0);
        let w = worley(uv, p.flakes, 1.0, p.seed ^ 0xf1a4);
        let a = hunit(w.id) * std::f32::consts::TAU;
        let t = p.flake_tilt * hunit(hash(w.id, 1, p.seed)).sqrt();
        let (nx, ny) = clamp_tilt(t * a.cos(), t * a.sin());
        let color = lerp3(p.base_color_a, p.base_color_b, pat);
        let rc = lerp(p.coat_roughness[0], p.coat_roughness[1], wear);
        let tau = lerp(p.thickness[1], p.thickness[0], wear);
        let rb = lerp(p.base_roughness[0], p.base_roughness[1], pat);
        [rc, tau, rb, color[0], color[1], color[2], nx, ny]
    }

    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3] {
        let Some((wi, wo)) = normalize_pair(wi, wo) else {
            return [0.0; 3];
        };
        let eta = self.p.coat_ior;
        let ac = alpha_from_roughness(unit(phi[0]));
        let (dg, cos_d) = ggx_dg(wi, wo, ac, ac);
        let coat = fresnel_dielectric(cos_d, eta).0 * dg * 0.25 / (wi.z * wo.z);
        let (fi, cti) = fresnel_dielectric(wi.z, eta);
        let (fo, cto) = fresnel_dielectric(wo.z, eta);
        let wi_t = refract_up(wi, eta, cti);
        let wo_t = refract_up(wo, eta, cto);
        let mut base = Surface::metallic(
            alpha_from_roughness(unit(phi[2])),
            unit3(phi, 3),
            self.p.base_metallic,
        );
        base.frame = ShadingFrame::new(signed(phi[6]), signed(phi[7]), 1.0, 0.0);
        let fb = base.eval_unit(wi_t, wo_t);
        let path = unit(phi[1]) * (1.0 / cti + 1.0 / cto);
        let k = (1.0 - fi) * (1.0 - fo) / (eta * eta);
        let s = &self.p.absorption;
        sanitize([
            coat + k * (-s[0] * path).exp() * fb[0],
            coat + k * (-s[1] * path).exp() * fb[1],
            coat + k * (-s[2] * path).exp() * fb[2],
        ])
    }
}
