//! The improved baseline of paper §3.1 (Eq. 1): a Lambertian lobe and one isotropic
//! Gaussian on the **projected unit disk**, predicted by an MLP (`ARCHITECTURES.md` §1). How
//! the lobes are sampled and evaluated: [`super::lobes`].

use glam::{Vec2, Vec3};

use crate::distrib::gaussian;
use crate::math::clamp_logit;
use crate::nn::{self, check_condition, encode_condition, Activation, CONDITION_DIM, FEATURE_DIM};
use crate::weights::Weights;

use super::lobes::{mean, LobeMixture, HIDDEN};
use super::Sampler;

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

/// The improved baseline's lobes at one shading point (Eq. 1): the weights `(w_L, w_G)` and
/// one isotropic Gaussian.
pub type ImprovedBaselinePrepared = LobeMixture<2, 1>;

impl LobeMixture<2, 1> {
    /// The lobes from raw network outputs `[μx, μy, log σ, a_L, a_G]`: `(w_L, w_G) =
    /// softmax(a_L, a_G)`, `σ = exp(clamp(log σ, −7, 1))`. Non-finite outputs are clamped
    /// ([`MEAN_BOUND`](super::lobes::MEAN_BOUND), ±10³⁰) so the lobes are always finite.
    #[inline]
    #[must_use]
    pub fn from_outputs(o: &[f32; BASELINE_OUTPUTS]) -> Self {
        let mut weights = [clamp_logit(o[3]), clamp_logit(o[4])];
        gaussian::softmax(&mut weights);
        let sigma = gaussian::sigma_from_log(o[2]);
        let mu = Vec2::new(mean(o[0]), mean(o[1]));
        LobeMixture::new(weights, [(mu, Vec2::splat(sigma))])
    }

    /// Mean of the Gaussian lobe (projected disk coordinates).
    #[must_use]
    pub fn mean(&self) -> Vec2 {
        self.lobes()[0].0
    }

    /// Standard deviation of the (isotropic) Gaussian lobe.
    #[must_use]
    pub fn sigma(&self) -> f32 {
        self.lobes()[0].1.x
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

#[cfg(not(target_arch = "spirv"))]
crate::wavefront::mlp_lane_sampler!(
    ImprovedBaselineSampler => ImprovedBaselinePrepared,
    chunk: crate::samplers::lobes::CHUNK,
    hidden: HIDDEN,
    outputs: BASELINE_OUTPUTS,
    layers: [BASELINE_L0, BASELINE_L1, BASELINE_L2, BASELINE_L3],
);

/// [`ImprovedBaselinePrepared::from_outputs`] over a chunk's rows, with the fast `exp`.
#[cfg(not(target_arch = "spirv"))]
impl crate::wavefront::FromOutputs<BASELINE_OUTPUTS> for ImprovedBaselinePrepared {
    const ROWS: bool = true;

    #[inline(always)]
    fn lanes<const B: usize>(
        o: &crate::wavefront::Soa<BASELINE_OUTPUTS, B>,
        valid: &[bool; B],
        lanes: &mut [Option<Self>],
    ) {
        use super::lobes::batch::{mean_row, sigma_row, weight_rows};
        let w = weight_rows([&o[3], &o[4]]);
        let mu = [&o[0], &o[1]].map(mean_row);
        let s = sigma_row(&o[2]);
        for (l, lane) in lanes.iter_mut().enumerate().take(B) {
            *lane = valid[l].then(|| {
                let mean = Vec2::new(mu[0][l], mu[1][l]);
                LobeMixture::new([w[0][l], w[1][l]], [(mean, Vec2::splat(s[l]))])
            });
        }
    }
}
