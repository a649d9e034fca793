//! The improved baseline of paper §3.1 (Eq. 1): a Lambertian lobe and one isotropic
//! Gaussian on the **projected unit disk**, predicted by an MLP (`ARCHITECTURES.md` §1). How
//! the lobes are sampled and evaluated: [`super::lobes`].

use glam::{Vec2, Vec3};

use crate::distrib::gaussian;
use crate::math::clamp_logit;
use crate::nn::{self, check_condition, encode_condition, Activation, CONDITION_DIM, FEATURE_DIM};
use crate::weights::Weights;

use super::lobes::{self, mean, Lobe, HIDDEN};
use super::{Prepared, Sample, Sampler};

/// Number of network outputs of the improved baseline: `[μx, μy, log σ, a_L, a_G]`.
pub const BASELINE_OUTPUTS: usize = 5;

const BASELINE_L0: usize = 0;
const BASELINE_L1: usize = BASELINE_L0 + nn::dense_len(CONDITION_DIM, HIDDEN);
const BASELINE_L2: usize = BASELINE_L1 + nn::dense_len(HIDDEN, HIDDEN);
const BASELINE_L3: usize = BASELINE_L2 + nn::dense_len(HIDDEN, HIDDEN);
const BASELINE_END: usize = BASELINE_L3 + nn::dense_len(HIDDEN, BASELINE_OUTPUTS);

/// The improved baseline of paper §3.1 (Eq. 1): Lambert + one isotropic Gaussian on the
/// projected disk, predicted by an MLP `30 → 32 → 32 → 32 → 5` (ReLU hidden, identity
/// output) from `encode_condition(φ, wi)`. See `ARCHITECTURES.md` §1.
#[derive(Copy, Clone, Debug)]
pub struct ImprovedBaselineSampler<W> {
    params: W,
}

super::traits::flat_params_sampler!(
    ImprovedBaselineSampler,
    ImprovedBaseline,
    BASELINE_END,
    "Number of parameters: `dense(30,32) dense(32,32) dense(32,32) dense(32,5)` = 3269."
);

impl<W: Weights> ImprovedBaselineSampler<W> {
    /// The raw network outputs `[μx, μy, log σ, a_L, a_G]` for an encoded condition.
    #[inline]
    #[must_use]
    pub fn forward(&self, c: &[f32; CONDITION_DIM]) -> [f32; BASELINE_OUTPUTS] {
        let w = &self.params;
        let h: [f32; HIDDEN] = nn::dense(w, BASELINE_L0 as u32, c, Activation::Relu);
        let h: [f32; HIDDEN] = nn::dense(w, BASELINE_L1 as u32, &h, Activation::Relu);
        let h: [f32; HIDDEN] = nn::dense(w, BASELINE_L2 as u32, &h, Activation::Relu);
        nn::dense(w, BASELINE_L3 as u32, &h, Activation::Identity)
    }
}

/// The improved baseline's lobes at one shading point (Eq. 1).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ImprovedBaselinePrepared {
    /// `(w_L, w_G)`, summing to 1.
    weights: [f32; 2],
    mu: Vec2,
    sigma: f32,
}

impl ImprovedBaselinePrepared {
    /// The lobes from raw network outputs `[μx, μy, log σ, a_L, a_G]`: `(w_L, w_G) =
    /// softmax(a_L, a_G)`, `σ = exp(clamp(log σ, −7, 1))`. Non-finite outputs are clamped
    /// ([`MEAN_BOUND`](super::lobes::MEAN_BOUND), ±10³⁰) so the lobes are always finite.
    #[inline]
    #[must_use]
    pub fn from_outputs(o: &[f32; BASELINE_OUTPUTS]) -> Self {
        let mut weights = [clamp_logit(o[3]), clamp_logit(o[4])];
        gaussian::softmax(&mut weights);
        ImprovedBaselinePrepared {
            weights,
            mu: Vec2::new(mean(o[0]), mean(o[1])),
            sigma: gaussian::sigma_from_log(o[2]),
        }
    }

    /// The Gaussian lobe (isotropic: one σ on both axes).
    #[inline(always)]
    fn lobes(&self) -> [Lobe; 1] {
        [(self.mu, Vec2::splat(self.sigma))]
    }

    /// Mixture weights `(w_L, w_G)`.
    #[must_use]
    pub fn weights(&self) -> [f32; 2] {
        self.weights
    }

    /// Mean of the Gaussian lobe (projected disk coordinates).
    #[must_use]
    pub fn mean(&self) -> Vec2 {
        self.mu
    }

    /// Standard deviation of the (isotropic) Gaussian lobe.
    #[must_use]
    pub fn sigma(&self) -> f32 {
        self.sigma
    }
}

impl<W: Weights> Sampler for ImprovedBaselineSampler<W> {
    type Prepared<'s>
        = ImprovedBaselinePrepared
    where
        Self: 's;

    #[inline]
    fn prepare(&self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<ImprovedBaselinePrepared> {
        let wi = check_condition(phi, wi)?;
        let o = self.forward(&encode_condition(phi, wi));
        Some(ImprovedBaselinePrepared::from_outputs(&o))
    }
}

impl Prepared for ImprovedBaselinePrepared {
    /// Component 0 (Lambert) by the concentric map, component 1 (Gaussian) by Box–Muller;
    /// the reported density is the full Eq. 1 mixture at the drawn point.
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let p = lobes::draw(&self.weights, &self.lobes(), u)?;
        Sample::from_disk(p, self.pdf_disk(p))
    }

    /// Eq. 1, with respect to area on the projected disk; 0 outside the open unit disk.
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        lobes::density(&self.weights, &self.lobes(), p)
    }
}

#[cfg(not(target_arch = "spirv"))]
mod batch;
