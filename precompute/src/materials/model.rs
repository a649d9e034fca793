//! The material interface: a feature texture φ(uv) and a decoder f(φ, wi, wo).

use glam::{Vec2, Vec3};

pub use neusample_render::luminance;

/// Length of the per-texel feature vector φ (the same as the samplers' condition).
pub const FEATURE_DIM: usize = neusample::FEATURE_DIM;

/// A spatially varying BRDF: a feature texture φ(uv) and a decoder f(φ, wi, wo).
pub trait Material: Send + Sync {
    /// The material's name (from its file).
    fn name(&self) -> &str;

    /// Per-texel parameters φ(uv), `uv ∈ [0, 1)²` (wrapping: the texture tiles). φ alone
    /// determines f at that texel. Ranges are documented per model, roughly `[−1, 1]` or
    /// `[0, 1]`.
    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM];

    /// BRDF `f(φ, wi, wo)` in linear RGB, **without** the cosine; local frame (z = geometric
    /// normal), both directions pointing away from the surface (they need not be normalised).
    /// 0 when either direction is at or below the horizon; never NaN.
    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3];

    /// Whether `f(φ, wi, wo) = f(φ, wo, wi)` holds by construction (true for the analytic
    /// models; tables need not be reciprocal).
    fn reciprocal(&self) -> bool {
        true
    }
}

/// Every material renders: the renderer's view is `features` and `eval`.
impl neusample_render::Material for dyn Material + '_ {
    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        Material::features(self, uv)
    }

    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3] {
        Material::eval(self, phi, wi, wo)
    }
}
