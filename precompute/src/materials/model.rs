//! The material interface: a feature texture φ(uv) and a decoder f(φ, wi, wo).

use glam::{Vec2, Vec3};
use neusample::wavefront::{Features, FeaturesMut, RgbMut, Vec2s, Vec3s};

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

    /// Whether `f(φ, wi, wo)` is unchanged when `wi` and `wo` turn together about the normal,
    /// by construction: samplers are then trained with `wi` at azimuth 0, and the runtime
    /// turns every condition there ([`neusample::samplers::Defensive::with_isotropic`]).
    /// False unless a model knows it (isotropic measured data).
    fn isotropic(&self) -> bool {
        false
    }

    /// The runtime's view of the material when it is a neural material (feature texture +
    /// decoder): the reparameterization sampler trains through its decoder. `None` for every
    /// other model.
    fn neural(&self) -> Option<neusample::NeuralMaterial<&[f32]>> {
        None
    }

    /// The measured data when the material is a measured one: its own sampler is the
    /// reference every learned sampler is compared with. `None` for every other model.
    fn measured(&self) -> Option<&neusample_owned::measured::OwnedMeasured> {
        None
    }

    /// [`Material::features`] of every `uv[i]` (structure of arrays, equal lengths); by
    /// default lane by lane. The neural material runs core's batched path.
    fn features_batch(&self, uv: Vec2s<'_>, phi: FeaturesMut<'_>) {
        neusample_render::features_per_lane(|uv| self.features(uv), uv, phi);
    }

    /// [`Material::eval`] of every `(phi[i], wi[i], wo[i])` (structure of arrays, equal
    /// lengths); by default lane by lane. The neural material runs core's batched path.
    fn eval_batch(&self, phi: Features<'_>, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>) {
        neusample_render::eval_per_lane(|phi, wi, wo| self.eval(phi, wi, wo), phi, wi, wo, out);
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

    fn features_batch(&self, uv: Vec2s<'_>, phi: FeaturesMut<'_>) {
        Material::features_batch(self, uv, phi);
    }

    fn eval_batch(&self, phi: Features<'_>, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>) {
        Material::eval_batch(self, phi, wi, wo, out);
    }
}
