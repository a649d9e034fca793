//! What the renderer needs of a material, and a material paired with its sampler.

use glam::{Vec2, Vec3};
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
}

/// Core's neural material: the bilinear feature lookup and the decoder.
impl<W: Weights> Material for NeuralMaterial<W> {
    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        NeuralMaterial::features(self, uv)
    }

    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3] {
        NeuralMaterial::eval(self, phi, wi, wo)
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
