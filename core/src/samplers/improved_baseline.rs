//! The improved baseline of paper §3.1 (Eq. 1): a Lambertian lobe and one isotropic
//! Gaussian on the **projected unit disk**, predicted by an MLP (`ARCHITECTURES.md` §1). How
//! the lobes are sampled and evaluated: [`super::lobes`].

use glam::Vec2;

use crate::distrib::gaussian;
use crate::math::clamp_logit;
use crate::nn::{ReluMlp, CONDITION_DIM};

use super::lobes::{mean, LobeMixture, HIDDEN};

/// Number of network outputs of the improved baseline: `[μx, μy, log σ, a_L, a_G]`.
pub const BASELINE_OUTPUTS: usize = 5;

type Net = ReluMlp<CONDITION_DIM, HIDDEN, BASELINE_OUTPUTS, 4>;

super::mlp::mlp_sampler! {
    /// The improved baseline of paper §3.1 (Eq. 1): Lambert + one isotropic Gaussian on the
    /// projected disk, predicted by an MLP `30 → 32 → 32 → 32 → 5` (ReLU hidden, identity
    /// output) from `encode_condition(φ, wi)`. See `ARCHITECTURES.md` §1.
    pub struct ImprovedBaselineSampler => ImprovedBaselinePrepared {
        kind: ImprovedBaseline,
        net: Net,
        outputs: BASELINE_OUTPUTS,
        from: ImprovedBaselinePrepared::from_outputs,
        chunk: super::lobes::CHUNK,
        count: "Number of parameters: `dense(30,32) dense(32,32) dense(32,32) dense(32,5)` = 3269.",
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
