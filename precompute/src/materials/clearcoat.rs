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
use serde::Deserialize;

use super::check;
use super::format::File;
use super::microfacet::{
    alpha_from_roughness, clamp_tilt, fresnel_dielectric, ggx_dg, normalize_pair, refract_up,
    ShadingFrame,
};
use super::model::{Material, FEATURE_DIM};
use super::noise::{fbm, hash, unit as hunit, worley, wrap_uv};
use super::surface::{lerp3, sanitize, signed, unit, Surface};

/// `[params]` of a `clearcoat` material.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// Noise seed.
    pub seed: u32,
    /// Coat index of refraction, 1.01..=2.5.
    pub coat_ior: f32,
    /// Coat perceptual roughness `[min, max]` (orange peel / wear varies it).
    pub coat_roughness: [f32; 2],
    /// Absorption coefficient σ of the coat per unit thickness (RGB), 0..=8.
    pub absorption: [f32; 3],
    /// Coat thickness `[min, max]` in `[0, 1]`.
    pub thickness: [f32; 2],
    /// Base colours blended by a low-frequency pattern.
    pub base_color_a: [f32; 3],
    /// Second base colour.
    pub base_color_b: [f32; 3],
    /// Base metallic, 0..=1 (constant).
    pub base_metallic: f32,
    /// Base perceptual roughness `[min, max]`.
    pub base_roughness: [f32; 2],
    /// Flakes per uv unit (Worley cells), 1..=512.
    pub flakes: u32,
    /// Flake normal tilt `|(n.x, n.y)|` (max), 0..=0.9.
    pub flake_tilt: f32,
    /// Pattern frequency of colour/roughness variation, 1..=64.
    pub pattern_freq: u32,
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
        let p = &file.params;
        check::range("coat_ior", p.coat_ior, 1.01, 2.5)?;
        check::interval("coat_roughness", p.coat_roughness, 0.0, 1.0)?;
        check::range_n("absorption", &p.absorption, 0.0, 8.0)?;
        check::interval("thickness", p.thickness, 0.0, 1.0)?;
        check::range_n("base_color_a", &p.base_color_a, 0.0, 1.0)?;
        check::range_n("base_color_b", &p.base_color_b, 0.0, 1.0)?;
        check::range("base_metallic", p.base_metallic, 0.0, 1.0)?;
        check::interval("base_roughness", p.base_roughness, 0.0, 1.0)?;
        check::count("flakes", p.flakes, 1, 512)?;
        check::range("flake_tilt", p.flake_tilt, 0.0, 0.9)?;
        check::count("pattern_freq", p.pattern_freq, 1, 64)?;
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
        let rc = p.coat_roughness[0] + (p.coat_roughness[1] - p.coat_roughness[0]) * wear;
        let tau = p.thickness[1] + (p.thickness[0] - p.thickness[1]) * wear;
        let rb = p.base_roughness[0] + (p.base_roughness[1] - p.base_roughness[0]) * pat;
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
        let color = [unit(phi[3]), unit(phi[4]), unit(phi[5])];
        let m = self.p.base_metallic;
        let mut base = Surface::isotropic(
            alpha_from_roughness(unit(phi[2])),
            lerp3([0.04; 3], color, m),
            color.map(|x| x * (1.0 - m)),
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
