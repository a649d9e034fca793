//! What the renderer needs of a material, and a material paired with its sampler.

use glam::{Vec2, Vec3};
use neusample::wavefront::{Features, FeaturesMut, RgbMut, Vec2s, Vec3s};
use neusample::{NeuralMaterial, Weights, FEATURE_DIM};

/// A spatially varying BRDF as the renderer sees it: per-texel features φ(uv) and the BRDF
/// `f(φ, wi, wo)`, which depends on uv only through φ (the shape of a neural material: a
/// feature texture and a decoder). The samplers are conditioned on the same φ.
///
/// Directions are in the local shading frame (z = normal), both pointing away from the
/// surface; `f` is linear RGB **without** the cosine, 0 when either direction is at or below
/// the horizon, never NaN.
pub trait Material {
    /// φ(uv); `uv` in `[0, 1)²`.
    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM];

    /// `f(φ, wi, wo)` in linear RGB, without the cosine.
    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3];

    /// [`Material::features`] of every `uv[i]` (structure of arrays), the wavefront
    /// integrator's call. The default loops over [`Material::features`]; a material with a
    /// batched path (core's [`NeuralMaterial`]) overrides it. Every slice has the same
    /// length (the integrator guarantees it).
    fn features_batch(&self, uv: Vec2s<'_>, phi: FeaturesMut<'_>) {
        features_per_lane(|uv| self.features(uv), uv, phi);
    }

    /// [`Material::eval`] of every `(phi[i], wi[i], wo[i])` (structure of arrays); as
    /// [`Material::features_batch`], the default loops over the scalar call.
    fn eval_batch(&self, phi: Features<'_>, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>) {
        eval_per_lane(|phi, wi, wo| self.eval(phi, wi, wo), phi, wi, wo, out);
    }
}

/// A batched `features` by a scalar one, lane by lane (the default of
/// [`Material::features_batch`], for materials without a batched path).
pub fn features_per_lane(
    features: impl Fn(Vec2) -> [f32; FEATURE_DIM],
    uv: Vec2s<'_>,
    phi: FeaturesMut<'_>,
) {
    let FeaturesMut { channels } = phi;
    for i in 0..uv.len() {
        for (c, x) in features(uv.at(i)).into_iter().enumerate() {
            channels[c][i] = x;
        }
    }
}

/// A batched `eval` by a scalar one, lane by lane (the default of [`Material::eval_batch`]).
pub fn eval_per_lane(
    eval: impl Fn(&[f32; FEATURE_DIM], Vec3, Vec3) -> [f32; 3],
    phi: Features<'_>,
    wi: Vec3s<'_>,
    wo: Vec3s<'_>,
    out: RgbMut<'_>,
) {
    for i in 0..wi.len() {
        let [r, g, b] = eval(&phi.at(i), wi.at(i), wo.at(i));
        out.r[i] = r;
        out.g[i] = g;
        out.b[i] = b;
    }
}

/// Core's neural material: the bilinear feature lookup and the decoder.
impl<W: Weights> Material for NeuralMaterial<W> {
    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        NeuralMaterial::features(self, uv)
    }

    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3] {
        NeuralMaterial::eval(self, phi, wi, wo)
    }

    fn features_batch(&self, uv: Vec2s<'_>, phi: FeaturesMut<'_>) {
        // Lengths agree by the trait's contract; a mismatch would leave `phi` as it was.
        let _ = NeuralMaterial::features_batch(self, uv, phi);
    }

    fn eval_batch(&self, phi: Features<'_>, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>) {
        let _ = NeuralMaterial::eval_batch(self, phi, wi, wo, out);
    }
}

/// A material with the sampler used for it (any [`neusample::Sampler`]: a blob's
/// `AnySampler`, cosine sampling, or a sampler of your own).
pub struct Surface<'a, M: ?Sized, S> {
    /// The material (features and BRDF).
    pub material: &'a M,
    /// Its sampler.
    pub sampler: S,
}

impl<'a, M: ?Sized, S> Surface<'a, M, S> {
    /// `material` sampled by `sampler`.
    #[must_use]
    pub fn new(material: &'a M, sampler: S) -> Self {
        Surface { material, sampler }
    }
}

impl<M: ?Sized, S: Clone> Clone for Surface<'_, M, S> {
    fn clone(&self) -> Self {
        Surface {
            material: self.material,
            sampler: self.sampler.clone(),
        }
    }
}

impl<M: ?Sized, S: Copy> Copy for Surface<'_, M, S> {}

/// Rec. 709 luminance `Y = 0.2126 R + 0.7152 G + 0.0722 B` of linear RGB (the quantity the
/// target pdf and the environment-sampling table are proportional to).
#[inline]
#[must_use]
pub fn luminance(rgb: [f32; 3]) -> f32 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}
