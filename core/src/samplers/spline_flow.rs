//! The paper's conditional rational-quadratic spline flow ([`SplineFlowSampler`], Eq. 3–4,
//! `core/ARCHITECTURES.md` §3) on the projected unit disk.
//!
//! A flow is a bijection `T` between the disk point `ω⊥ = (x, y)` and a latent point `z`
//! with a Gaussian base density `p_z`. The density on the **projected disk** (area measure) is
//!
//! ```text
//! p(ω⊥) = p_z(T(ω⊥)) · |det ∂T/∂ω⊥|                                           (Eq. 3)
//! ```
//!
//! computed in the *density direction* `ω⊥ → z` ([`Prepared::pdf_disk`],
//! [`SplineFlowPrepared::to_latent`]). Sampling runs the *sampling direction* `z → ω⊥`
//! (Box–Muller, then the inverse couplings), then evaluates the density direction at the
//! sampled point, reusing the one coupling evaluation both directions share: the pdf a
//! sample reports is bit for bit [`Prepared::pdf_disk`] at its point. Samples that leave the
//! open unit disk are refused (`None`); the density is 0 there, so it integrates over the
//! disk to the probability that a sample lands inside.
//!
//! Per shading point, [`Sampler::prepare`](super::Sampler::prepare) encodes the condition `c`
//! once, runs the base network, and precomputes the condition's share of every coupling
//! network's first layer; per sample only the 9 encoded inputs of the other coordinate and the
//! remaining layers run.

use glam::{Vec2, Vec3};

use crate::distrib::gaussian;
use crate::distrib::spline::Knots;
use crate::math;
use crate::nn::{self, Activation, CONDITION_DIM};
use crate::warp::{self, inside_disk};
use crate::weights::Weights;

use super::coupling::{all_finite, condition_share, coupling_raw, density_from_log};
pub use super::coupling::{encode_other, COUPLING_INPUTS, HIDDEN, OTHER_BANDS, OTHER_DIM};
use super::coupling::{COUPLING_L0, COUPLING_L1, COUPLING_L2};

use super::{LanePrepared, Prepared, Sample};

#[cfg(not(target_arch = "spirv"))]
mod batch;

/// Bins of every spline of [`SplineFlowSampler`] (release: 20).
pub const SPLINE_BINS: usize = 20;
/// Tail bound `B` of every spline of [`SplineFlowSampler`]: splines act on `[−1, 1]`.
pub const TAIL_BOUND: f32 = 1.0;
/// Raw outputs of a spline coupling network: 20 widths, 20 heights, 19 derivatives.
pub const SPLINE_RAW_LEN: usize = Knots::<SPLINE_BINS>::RAW_LEN;
/// Outputs of the base network: `[μx, μy, log σx, log σy]`.
pub const BASE_OUTPUTS: usize = 4;

/// Offset of the base network's `dense(30, 32)` (ReLU).
pub const FLOW_BASE_L0: usize = 0;
/// Offset of the base network's `dense(32, 4)`.
pub const FLOW_BASE_L1: usize = FLOW_BASE_L0 + nn::dense_len(CONDITION_DIM, HIDDEN);
/// Parameters of the base network (1124).
pub const FLOW_BASE_LEN: usize = FLOW_BASE_L1 + nn::dense_len(HIDDEN, BASE_OUTPUTS);
/// Offset of a spline coupling network's `dense(39, 32)` (LeakyReLU), relative to the network.
pub const SPLINE_NET_L0: usize = COUPLING_L0;
/// Offset of a spline coupling network's `dense(32, 32)` (LeakyReLU), relative to the network.
pub const SPLINE_NET_L1: usize = COUPLING_L1;
/// Offset of a spline coupling network's `dense(32, 59)`, relative to the network.
pub const SPLINE_NET_L2: usize = COUPLING_L2;
/// Parameters of one spline coupling network (4283).
pub const SPLINE_NET_LEN: usize = SPLINE_NET_L2 + nn::dense_len(HIDDEN, SPLINE_RAW_LEN);
/// Offset of coupling network 0 (transforms x, conditioned on y').
pub const FLOW_COUPLING0: usize = FLOW_BASE_LEN;
/// Offset of coupling network 1 (transforms y, conditioned on x).
pub const FLOW_COUPLING1: usize = FLOW_COUPLING0 + SPLINE_NET_LEN;
/// Parameters of [`SplineFlowSampler`] (9690).
pub const FLOW_PARAM_COUNT: usize = FLOW_COUPLING1 + SPLINE_NET_LEN;

/// The spline of a coupling network at `offset`, for the other coordinate `v`.
#[inline]
fn spline_knots<W: Weights>(
    w: &W,
    offset: u32,
    share: &[f32; HIDDEN],
    v: f32,
) -> Knots<SPLINE_BINS> {
    Knots::from_raw(
        &coupling_raw::<W, SPLINE_RAW_LEN>(w, offset, share, v),
        TAIL_BOUND,
    )
}

/// The conditional rational-quadratic spline flow of the paper (Eq. 3–4): a diagonal
/// Gaussian base predicted from the condition and two spline coupling layers
/// (`core/ARCHITECTURES.md` §3). Densities are on the projected disk (area measure).
#[derive(Copy, Clone, Debug)]
pub struct SplineFlowSampler<W> {
    params: W,
}

super::traits::flat_params_sampler!(
    SplineFlowSampler,
    SplineFlow,
    FLOW_PARAM_COUNT,
    "Length of the flat parameter array: base, coupling 0, coupling 1 (9690)."
);

/// The flow at one shading point without its weights handle (the lane of the batched API):
/// the base Gaussian and the condition's share of both coupling networks' first layers.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct SplineFlowLane {
    /// Mean of the base Gaussian.
    mu: Vec2,
    /// Standard deviations of the base Gaussian (clamped `exp(log σ)`).
    sigma: Vec2,
    /// `ln(σx·σy)`, the base density's normalisation.
    ln_sigma: f32,
    /// Condition's share (bias included) of coupling network 0's and 1's first layer.
    share: [[f32; HIDDEN]; 2],
}

impl SplineFlowLane {
    /// The state from the base network's outputs `[μx, μy, log σx, log σy]` and the
    /// couplings' condition shares; `None` when any of them is not finite.
    #[inline(always)]
    fn new(o: &[f32; BASE_OUTPUTS], share: [[f32; HIDDEN]; 2]) -> Option<SplineFlowLane> {
        if !all_finite(o) || !all_finite(&share[0]) || !all_finite(&share[1]) {
            return None;
        }
        let sigma = Vec2::new(
            gaussian::sigma_from_log(o[2]),
            gaussian::sigma_from_log(o[3]),
        );
        Some(SplineFlowLane {
            mu: Vec2::new(o[0], o[1]),
            sigma,
            ln_sigma: math::ln(sigma.x * sigma.y),
            share,
        })
    }

    /// Mean of the base Gaussian.
    #[must_use]
    pub fn mean(&self) -> Vec2 {
        self.mu
    }

    /// Standard deviations of the base Gaussian.
    #[must_use]
    pub fn sigma(&self) -> Vec2 {
        self.sigma
    }

    /// The base point `z = μ + σ ⊙ n` of Box–Muller's `n` from `u` (already sanitised).
    #[inline(always)]
    fn base_point(&self, u: Vec2) -> Vec2 {
        self.mu + self.sigma * gaussian::box_muller(u)
    }

    /// `ln N(z; μ, diag σ²) + ld`, NaN → −∞ (`gaussian::log_normal_pdf` with `ln(σx·σy)`
    /// computed once).
    #[inline(always)]
    fn log_density(&self, z: Vec2, ld: f32) -> f32 {
        let dx = (z.x - self.mu.x) / self.sigma.x;
        let dy = (z.y - self.mu.y) / self.sigma.y;
        let l = -0.5 * (dx * dx + dy * dy) - math::LN_TWO_PI - self.ln_sigma + ld;
        if l.is_nan() {
            f32::NEG_INFINITY
        } else {
            l
        }
    }

    /// The `u` whose Box–Muller point under this base Gaussian is `z`.
    #[inline(always)]
    fn invert_base(&self, z: Vec2) -> Option<Vec2> {
        let n = (z - self.mu) / self.sigma;
        if !math::is_finite(n.x) || !math::is_finite(n.y) {
            return None;
        }
        Some(gaussian::invert_box_muller(n))
    }
}

/// [`SplineFlowSampler`] prepared for one condition: its [`SplineFlowLane`] and a copy of the weights
/// handle.
pub type SplineFlowPrepared<'s, W> = LanePrepared<'s, W, SplineFlowLane>;

super::traits::lane_sampler!(SplineFlowSampler => SplineFlowPrepared, |w, c| {
    let h = nn::dense::<W, CONDITION_DIM, HIDDEN>(w, FLOW_BASE_L0 as u32, &c, Activation::Relu);
    let o = nn::linear::<W, HIDDEN, BASE_OUTPUTS>(w, FLOW_BASE_L1 as u32, &h);
    let share = [
        condition_share(w, FLOW_COUPLING0 as u32, &c),
        condition_share(w, FLOW_COUPLING1 as u32, &c),
    ];
    SplineFlowLane::new(&o, share)
});

impl<W: Weights + Copy> SplineFlowPrepared<'_, W> {
    /// Mean of the base Gaussian.
    #[must_use]
    pub fn mean(&self) -> Vec2 {
        self.lane_ref().mu
    }

    /// Standard deviations of the base Gaussian.
    #[must_use]
    pub fn sigma(&self) -> Vec2 {
        self.lane_ref().sigma
    }

    /// Density direction: the latent point `z = (x', y')` of disk point `p` and
    /// `ln |det ∂z/∂p|`, or `None` when `p` is not strictly inside the unit disk.
    ///
    /// ```text
    /// y' = RQ(y; coupling1(c, enc4(x))),  x' = RQ(x; coupling0(c, enc4(y')))
    /// ```
    #[inline]
    #[must_use]
    pub fn to_latent(&self, p: Vec2) -> Option<(Vec2, f32)> {
        if !inside_disk(p) {
            return None;
        }
        let k1 = spline_knots(
            &self.params(),
            FLOW_COUPLING1 as u32,
            &self.lane_ref().share[1],
            p.x,
        );
        Some(self.latent_with_k1(p, &k1))
    }

    /// [`SplineFlowPrepared::to_latent`] given coupling 1's spline `k1` at `x = p.x`.
    #[inline(always)]
    fn latent_with_k1(&self, p: Vec2, k1: &Knots<SPLINE_BINS>) -> (Vec2, f32) {
        let (yl, ld1) = k1.forward(p.y);
        let k0 = spline_knots(
            &self.params(),
            FLOW_COUPLING0 as u32,
            &self.lane_ref().share[0],
            yl,
        );
        let (xl, ld0) = k0.forward(p.x);
        (Vec2::new(xl, yl), ld0 + ld1)
    }

    /// Sampling direction: the disk-plane point `p` of latent point `z` (not necessarily
    /// inside the disk) and `ln |det ∂p/∂z|`.
    ///
    /// ```text
    /// x = RQ⁻¹(x'; coupling0(c, enc4(y'))),  y = RQ⁻¹(y'; coupling1(c, enc4(x)))
    /// ```
    #[inline]
    #[must_use]
    pub fn from_latent(&self, z: Vec2) -> (Vec2, f32) {
        let (p, k0, k1) = self.point_and_knots(z);
        // The log-dets of the same two inverses (not needed by `sample`, so not computed there).
        (p, k0.inverse(z.x).1 + k1.inverse(z.y).1)
    }

    /// [`SplineFlowPrepared::from_latent`]'s point, with the splines it built: coupling 0's at
    /// `y' = z.y` and coupling 1's at `x`.
    #[inline(always)]
    fn point_and_knots(&self, z: Vec2) -> (Vec2, Knots<SPLINE_BINS>, Knots<SPLINE_BINS>) {
        let k0 = spline_knots(
            &self.params(),
            FLOW_COUPLING0 as u32,
            &self.lane_ref().share[0],
            z.y,
        );
        let x = k0.inverse_point(z.x);
        let k1 = spline_knots(
            &self.params(),
            FLOW_COUPLING1 as u32,
            &self.lane_ref().share[1],
            x,
        );
        let y = k1.inverse_point(z.y);
        (Vec2::new(x, y), k0, k1)
    }

    /// `ln p(p)` on the projected disk (area measure): `ln N(z; μ, diag σ²) + ln |det ∂z/∂p|`
    /// (Eq. 3). `−∞` outside the open unit disk; never NaN.
    #[inline]
    #[must_use]
    pub fn log_pdf_disk(&self, p: Vec2) -> f32 {
        match self.to_latent(p) {
            Some((z, ld)) => self.lane_ref().log_density(z, ld),
            None => f32::NEG_INFINITY,
        }
    }
}

impl<W: Weights + Copy> Prepared for SplineFlowPrepared<'_, W> {
    /// Box–Muller from `u`, `z = μ + σ ⊙ n`, then the inverse couplings.
    ///
    /// The reported pdf (solid angle; disk area in [`Sample::pdf_disk`]) is the density
    /// direction's at the sampled point, reusing coupling 1's spline (its input `x` is the
    /// same in both directions), so it equals [`Prepared::pdf_disk`] bit for bit. The
    /// sampling direction's own log-det is the same number only up to f32 rounding, which
    /// steep splines amplify to the percent level: one extra coupling network
    /// per sample buys exact agreement with `pdf` for MIS. That network's input is
    /// `y' = RQ(y)`, and when this round trip gives back `z.y` bit for bit (about half the
    /// samples) its spline is the one the sampling direction already built, so it is reused.
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let u = math::sanitize_u2(u)?;
        let z = self.lane_ref().base_point(u);
        let (p, k0, k1) = self.point_and_knots(z);
        if !inside_disk(p) {
            return None;
        }
        // `latent_with_k1`, with coupling 0's spline reused when its input is unchanged.
        let (yl, ld1) = k1.forward(p.y);
        let k0 = if yl.to_bits() == z.y.to_bits() {
            k0
        } else {
            spline_knots(
                &self.params(),
                FLOW_COUPLING0 as u32,
                &self.lane_ref().share[0],
                yl,
            )
        };
        let (xl, ld0) = k0.forward(p.x);
        let log_p = self.lane_ref().log_density(Vec2::new(xl, yl), ld0 + ld1);
        Sample::from_disk(p, density_from_log(log_p))
    }

    /// Density on the projected disk (area measure), Eq. 3; 0 outside the open unit disk.
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        density_from_log(self.log_pdf_disk(p))
    }

    /// The density direction, then the exact inverse of Box–Muller.
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        let w = warp::upper_hemisphere(wo)?;
        let (z, _) = self.to_latent(warp::to_disk(w))?;
        self.lane_ref().invert_base(z)
    }
}
