//! The "standard surface" shared by most analytic models: a normal-mapped, optionally
//! anisotropic GGX specular lobe (Schlick Fresnel, height-correlated Smith), an optional
//! isotropic haze lobe, and a Fresnel-weighted Lambert base.
//!
//! ```text
//! f = s · [ F(wi·h) · ((1 − w_h) DG(α_x, α_y) + w_h DG(α_h)) / (4 M_i M_o)
//!         + ρ_d/π · d(wi) d(wo) · (1 − F̄(M_i))(1 − F̄(M_o)) ]
//!
//! d(w) = β + (1 − β) · max(cos_s θ, 0) / M,   β = DIFFUSE_FLOOR = 0.1
//! ```
//!
//! with `M_i, M_o` the max-cosine normal-mapping denominators of [`super::microfacet`]
//! (the specular lobe is 0 when either direction is below the shading horizon), `F̄` the
//! scalar Schlick Fresnel of the mean `F0`, and `s ∈ [0, 1]` a cavity factor. Every term is
//! symmetric in `wi` and `wo`, so the BRDF is reciprocal; the specular part reflects at most
//! `F`, the diffuse part at most `ρ_d (1 − F̄(M_i))` because `d ≤ 1`, so the white furnace
//! stays ≤ 1 for `ρ_d ≤ 1` (checked numerically in `tests/materials.rs`).
//!
//! A model is a [`SurfaceModel`]: a procedural feature texture plus a decoder from φ to a
//! [`Surface`]; [`Textured`] turns it into a [`Material`].

use glam::{Vec2, Vec3};
use serde::de::DeserializeOwned;

use super::format::File;
use super::microfacet::{
    alpha_from_roughness, ggx_dg, normalize_pair, schlick, schlick1, ShadingFrame, ALPHA_MIN,
    LAMBERT,
};
use super::model::{Material, FEATURE_DIM};
use super::noise::wrap_uv;

/// Floor β of the diffuse normal-mapping factor `d(w) = β + (1 − β)·max(cos_s θ, 0)/M`, so
/// that a texel whose shading normal faces away from `wi` is dark but never black (a
/// normal-mapped texel with `f ≡ 0` would have no target density).
pub const DIFFUSE_FLOOR: f32 = 0.1;

/// A decoded texel of the standard surface.
#[derive(Copy, Clone, Debug)]
pub struct Surface {
    /// Shading frame (normal map and tangent).
    pub frame: ShadingFrame,
    /// GGX α along the tangent.
    pub ax: f32,
    /// GGX α along the bitangent.
    pub ay: f32,
    /// Specular reflectance at normal incidence (Schlick `F0`, RGB).
    pub f0: [f32; 3],
    /// Lambert albedo ρ_d (already without the metallic part).
    pub diffuse: [f32; 3],
    /// Weight of the isotropic haze lobe, `[0, 1]`.
    pub haze: f32,
    /// GGX α of the haze lobe.
    pub haze_alpha: f32,
    /// Cavity factor multiplying the whole BRDF, `[0, 1]`.
    pub scale: f32,
}

impl Surface {
    /// A plain isotropic surface in the geometric frame.
    #[must_use]
    pub fn isotropic(alpha: f32, f0: [f32; 3], diffuse: [f32; 3]) -> Self {
        Surface {
            frame: ShadingFrame::new(0.0, 0.0, 1.0, 0.0),
            ax: alpha,
            ay: alpha,
            f0,
            diffuse,
            haze: 0.0,
            haze_alpha: 1.0,
            scale: 1.0,
        }
    }

    /// An isotropic dielectric of specular level `s` (`F0 = 0.08 s`) and albedo `diffuse`.
    #[must_use]
    pub fn dielectric(alpha: f32, specular: f32, diffuse: [f32; 3]) -> Self {
        Self::isotropic(alpha, [0.08 * specular; 3], diffuse)
    }

    /// An isotropic surface of a base colour and metallic weight `m`:
    /// `F0 = lerp(0.04, colour, m)`, diffuse = colour·(1 − m).
    #[must_use]
    pub fn metallic(alpha: f32, color: [f32; 3], m: f32) -> Self {
        Self::isotropic(
            alpha,
            lerp3([0.04; 3], color, m),
            color.map(|x| x * (1.0 - m)),
        )
    }

    /// Evaluates f (no cosine) for unit directions above the geometric horizon.
    #[inline]
    #[must_use]
    pub fn eval_unit(&self, wi: Vec3, wo: Vec3) -> [f32; 3] {
        let li = self.frame.to_local(wi);
        let lo = self.frame.to_local(wo);
        let mi = li.z.max(wi.z);
        let mo = lo.z.max(wo.z);
        if !(mi > 1e-6 && mo > 1e-6) {
            return [0.0; 3];
        }
        let mut spec = 0.0;
        let mut cos_d = 1.0;
        if li.z > 1e-6 && lo.z > 1e-6 {
            let (dg, cd) = ggx_dg(li, lo, self.ax, self.ay);
            spec = dg;
            cos_d = cd;
            if self.haze > 0.0 {
                let (dgh, _) = ggx_dg(li, lo, self.haze_alpha, self.haze_alpha);
                spec = (1.0 - self.haze) * dg + self.haze * dgh;
            }
            spec *= 0.25 / (mi * mo) * self.scale;
        }
        let fr = schlick(self.f0, cos_d);
        let f0m = (self.f0[0] + self.f0[1] + self.f0[2]) * (1.0 / 3.0);
        // Diffuse shading factor d(w) = β + (1 − β)·max(cos_s, 0)/M ∈ [β, 1].
        let di = DIFFUSE_FLOOR + (1.0 - DIFFUSE_FLOOR) * li.z.max(0.0) / mi;
        let d_o = DIFFUSE_FLOOR + (1.0 - DIFFUSE_FLOOR) * lo.z.max(0.0) / mo;
        let kd =
            LAMBERT * di * d_o * (1.0 - schlick1(f0m, mi)) * (1.0 - schlick1(f0m, mo)) * self.scale;
        [
            fr[0] * spec + self.diffuse[0] * kd,
            fr[1] * spec + self.diffuse[1] * kd,
            fr[2] * spec + self.diffuse[2] * kd,
        ]
    }

    /// Evaluates f (no cosine) for arbitrary directions: normalised here, 0 below the horizon.
    #[inline]
    #[must_use]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> [f32; 3] {
        match normalize_pair(wi, wo) {
            Some((wi, wo)) => self.eval_unit(wi, wo),
            None => [0.0; 3],
        }
    }
}

/// Anisotropic α pair `(α_t, α_b)` from a perceptual roughness and an anisotropy
/// `a ∈ [0, 1]` (Burley 2012's aspect `√(1 − 0.9 a)`): `α_t = r²·aspect` along the tangent
/// (the brushing or fibre direction: smoother) and `α_b = r²/aspect` across it, so the
/// highlight stretches across the tangent.
#[inline]
#[must_use]
pub fn aniso_alphas(roughness: f32, anisotropy: f32) -> (f32, f32) {
    let a = alpha_from_roughness(roughness);
    let aspect = (1.0 - 0.9 * anisotropy.clamp(0.0, 1.0)).sqrt();
    ((a * aspect).max(ALPHA_MIN), (a / aspect).min(1.0))
}

/// `x` clamped to `[0, 1]` (NaN → 0).
#[inline]
#[must_use]
pub fn unit(x: f32) -> f32 {
    if x > 0.0 {
        x.min(1.0)
    } else {
        0.0
    }
}

/// `x` clamped to `[−1, 1]` (NaN → 0).
#[inline]
#[must_use]
pub fn signed(x: f32) -> f32 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(-1.0, 1.0)
    }
}

/// `φ[i..i + 3]` (a colour), each clamped to `[0, 1]`.
#[inline]
#[must_use]
pub fn unit3(phi: &[f32; FEATURE_DIM], i: usize) -> [f32; 3] {
    [unit(phi[i]), unit(phi[i + 1]), unit(phi[i + 2])]
}

/// `a + (b − a) t`.
#[inline]
#[must_use]
pub fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// `a + (b − a) t` per channel.
#[inline]
#[must_use]
pub fn lerp3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [
        lerp(a[0], b[0], t),
        lerp(a[1], b[1], t),
        lerp(a[2], b[2], t),
    ]
}

/// A procedural feature texture plus a decoder from φ to a [`Surface`].
pub trait SurfaceModel: Sized + Send + Sync {
    /// The `[params]` table of the model's material files.
    type Params: DeserializeOwned;
    /// Validates the parameters (errors name `params.<field>`).
    fn from_params(params: Self::Params) -> anyhow::Result<Self>;
    /// φ(uv), `uv` already wrapped into `[0, 1)²`.
    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM];
    /// The surface a φ describes (must accept any finite φ; clamps out-of-range values).
    fn decode(&self, phi: &[f32; FEATURE_DIM]) -> Surface;
}

/// A named [`SurfaceModel`] as a [`Material`].
#[derive(Clone, Debug)]
pub struct Textured<M> {
    name: String,
    model: M,
}

impl<M: SurfaceModel> Textured<M> {
    /// Builds the material from a parsed file.
    pub fn new(file: File<M::Params>) -> anyhow::Result<Self> {
        Ok(Textured {
            name: file.name,
            model: M::from_params(file.params)?,
        })
    }

    /// The model.
    #[must_use]
    pub fn model(&self) -> &M {
        &self.model
    }
}

/// Replaces non-finite channels by 0 and clamps negatives to 0.
#[inline]
#[must_use]
pub fn sanitize(rgb: [f32; 3]) -> [f32; 3] {
    let c = |x: f32| if x > 0.0 && x.is_finite() { x } else { 0.0 };
    [c(rgb[0]), c(rgb[1]), c(rgb[2])]
}

impl<M: SurfaceModel> Material for Textured<M> {
    fn name(&self) -> &str {
        &self.name
    }
    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        self.model.features(wrap_uv(uv))
    }
    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3] {
        sanitize(self.model.decode(phi).eval(wi, wo))
    }
}
