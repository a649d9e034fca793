//! The analytic mixture of paper §3.1 (Eq. 2): a Lambertian lobe and two axis-aligned
//! anisotropic Gaussians on the **projected unit disk**, predicted by an MLP
//! (`ARCHITECTURES.md` §2). How the lobes are sampled and evaluated: [`super::lobes`].

use glam::Vec2;

use crate::distrib::gaussian;
use crate::math::clamp_logit;
use crate::nn::{ReluMlp, CONDITION_DIM};

use super::lobes::{mean, LobeMixture, HIDDEN};

/// Number of network outputs of the analytic mixture:
/// `[μ1x, μ1y, μ2x, μ2y, log σ1x, log σ1y, log σ2x, log σ2y, a0, a1, a2]`.
pub const ANALYTIC_OUTPUTS: usize = 11;

type Net = ReluMlp<CONDITION_DIM, HIDDEN, ANALYTIC_OUTPUTS, 2>;

super::mlp::mlp_sampler! {
    /// The analytic mixture of paper §3.1 (Eq. 2): Lambert + two axis-aligned anisotropic
    /// Gaussians on the projected disk, predicted by an MLP `30 → 32 → 11` (ReLU hidden) from
    /// `encode_condition(φ, wi)`. See `ARCHITECTURES.md` §2.
    pub struct AnalyticMixtureSampler => AnalyticMixturePrepared {
        kind: AnalyticMixture,
        net: Net,
        outputs: ANALYTIC_OUTPUTS,
        from: AnalyticMixturePrepared::from_outputs,
        chunk: super::lobes::CHUNK,
        count: "Number of parameters: `dense(30,32) dense(32,11)` = 1355.",
    }
}

/// The analytic mixture's lobes at one shading point (Eq. 2): the weights `(w0, w1, w2)`
/// (Lambert, Gaussian 1, Gaussian 2) and two axis-aligned anisotropic Gaussians.
pub type AnalyticMixturePrepared = LobeMixture<3, 2>;

impl LobeMixture<3, 2> {
    /// The lobes from raw network outputs (see [`ANALYTIC_OUTPUTS`]): `w = softmax(a)`,
    /// `σ = exp(clamp(log σ, −7, 1))` per axis. Non-finite outputs are clamped
    /// ([`MEAN_BOUND`](super::lobes::MEAN_BOUND), ±10³⁰) so the lobes are always finite.
    #[inline]
    #[must_use]
    pub fn from_outputs(o: &[f32; ANALYTIC_OUTPUTS]) -> Self {
        let mut weights = [clamp_logit(o[8]), clamp_logit(o[9]), clamp_logit(o[10])];
        gaussian::softmax(&mut weights);
        let sigma = |i: usize| {
            Vec2::new(
                gaussian::sigma_from_log(o[i]),
                gaussian::sigma_from_log(o[i + 1]),
            )
        };
        let lobes = [
            (Vec2::new(mean(o[0]), mean(o[1])), sigma(4)),
            (Vec2::new(mean(o[2]), mean(o[3])), sigma(6)),
        ];
        LobeMixture::new(weights, lobes)
    }

    /// Means of the two Gaussian lobes.
    #[must_use]
    pub fn means(&self) -> [Vec2; 2] {
        [self.lobes()[0].0, self.lobes()[1].0]
    }

    /// Per-axis standard deviations of the two Gaussian lobes.
    #[must_use]
    pub fn sigmas(&self) -> [Vec2; 2] {
        [self.lobes()[0].1, self.lobes()[1].1]
    }
}

/// [`AnalyticMixturePrepared::from_outputs`] over a chunk's rows, with the fast `exp`.
#[cfg(not(target_arch = "spirv"))]
impl crate::wavefront::FromOutputs<ANALYTIC_OUTPUTS> for AnalyticMixturePrepared {
    const ROWS: bool = true;

    #[inline(always)]
    fn lanes<const B: usize>(
        o: &crate::wavefront::Soa<ANALYTIC_OUTPUTS, B>,
        valid: &[bool; B],
        lanes: &mut [Option<Self>],
    ) {
        use super::lobes::batch::{mean_row, sigma_row, weight_rows};
        let w = weight_rows([&o[8], &o[9], &o[10]]);
        let mu = [&o[0], &o[1], &o[2], &o[3]].map(mean_row);
        let s = [&o[4], &o[5], &o[6], &o[7]].map(sigma_row);
        for (l, lane) in lanes.iter_mut().enumerate().take(B) {
            *lane = valid[l].then(|| {
                let lobe = |g: usize| {
                    (
                        Vec2::new(mu[2 * g][l], mu[2 * g + 1][l]),
                        Vec2::new(s[2 * g][l], s[2 * g + 1][l]),
                    )
                };
                LobeMixture::new([w[0][l], w[1][l], w[2][l]], [lobe(0), lobe(1)])
            });
        }
    }
}
