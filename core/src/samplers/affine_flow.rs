//! The affine-coupling flow baseline of Xie et al. 2019 ([`AffineFlowSampler`],
//! `core/ARCHITECTURES.md` §4): a standard-normal base and four conditional affine
//! couplings on the projected unit disk. Densities follow Eq. 3 of the paper, as the spline
//! flow's do ([`super::spline_flow`]); the pdf a sample reports is bit for bit
//! [`Prepared::pdf_disk`] at its point.

use glam::{Vec2, Vec3};

use crate::distrib::gaussian;
use crate::math;
use crate::nn::{self, Activation};
use crate::warp::{self, inside_disk};
use crate::weights::Weights;

use super::coupling::{all_finite, condition_share, density_from_log, first_layer};
pub use super::coupling::{encode_other, COUPLING_INPUTS, HIDDEN, OTHER_BANDS, OTHER_DIM};

use super::{LanePrepared, Prepared, Sample};

#[cfg(not(target_arch = "spirv"))]
mod batch;

/// Coupling layers of [`AffineFlowSampler`]; layer `l` transforms coordinate `l mod 2`.
pub const AFFINE_LAYERS: usize = 4;
/// Bound of the affine log-scale: `s = AFFINE_SCALE_BOUND · tanh(s_raw / AFFINE_SCALE_BOUND)`.
pub const AFFINE_SCALE_BOUND: f32 = 4.0;
/// Outputs of an affine coupling network: `[s_raw, t]`.
pub const AFFINE_OUTPUTS: usize = 2;
/// Offset of an affine coupling network's `dense(39, 32)` (ReLU), relative to the network.
pub const AFFINE_NET_L0: usize = 0;
/// Offset of an affine coupling network's `dense(32, 32)` (ReLU), relative to the network.
pub const AFFINE_NET_L1: usize = AFFINE_NET_L0 + nn::dense_len(COUPLING_INPUTS, HIDDEN);
/// Offset of an affine coupling network's `dense(32, 2)`, relative to the network.
pub const AFFINE_NET_L2: usize = AFFINE_NET_L1 + nn::dense_len(HIDDEN, HIDDEN);
/// Parameters of one affine coupling network (2402); network `l` starts at `l·AFFINE_NET_LEN`.
pub const AFFINE_NET_LEN: usize = AFFINE_NET_L2 + nn::dense_len(HIDDEN, AFFINE_OUTPUTS);
/// Parameters of [`AffineFlowSampler`] (9608).
pub const AFFINE_PARAM_COUNT: usize = AFFINE_LAYERS * AFFINE_NET_LEN;

/// `(s, t)` of affine coupling network `l` for the other coordinate `v`.
#[inline(always)]
fn affine_params<W: Weights>(w: &W, l: usize, share: &[f32; HIDDEN], v: f32) -> (f32, f32) {
    let offset = (l * AFFINE_NET_LEN) as u32;
    let mut h = first_layer(w, offset + AFFINE_NET_L0 as u32, share, v);
    Activation::Relu.apply_all(&mut h);
    let h = nn::dense::<W, HIDDEN, HIDDEN>(w, offset + AFFINE_NET_L1 as u32, &h, Activation::Relu);
    let o = nn::linear::<W, HIDDEN, AFFINE_OUTPUTS>(w, offset + AFFINE_NET_L2 as u32, &h);
    scale_shift(&o)
}

/// `(s, t)` from a coupling network's outputs `[s_raw, t]`: `s = 4·tanh(s_raw / 4)`.
#[inline(always)]
fn scale_shift(o: &[f32; AFFINE_OUTPUTS]) -> (f32, f32) {
    let s = AFFINE_SCALE_BOUND * math::tanh(o[0] / AFFINE_SCALE_BOUND);
    (s, o[1])
}

/// Per layer `l` of an affine flow: the input its network saw in the sampling direction and
/// the `(s, t)` it returned, `[v, s, t]` (row 0 unused).
type AffineSeen = [[f32; 3]; AFFINE_LAYERS];

/// The affine-coupling flow baseline (Xie et al. 2019): a standard-normal base and four
/// conditional affine couplings (`core/ARCHITECTURES.md` §4). Densities are on the
/// projected disk (area measure).
#[derive(Copy, Clone, Debug)]
pub struct AffineFlowSampler<W> {
    params: W,
}

super::traits::flat_params_sampler!(
    AffineFlowSampler,
    AffineFlow,
    AFFINE_PARAM_COUNT,
    "Length of the flat parameter array: four coupling networks (9608)."
);

/// The affine flow at one shading point without its weights handle (the lane of the batched
/// API): the condition's share of every coupling network's first layer.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct AffineFlowLane {
    share: [[f32; HIDDEN]; AFFINE_LAYERS],
}

impl AffineFlowLane {
    /// The state from the couplings' condition shares; `None` when any is not finite.
    #[inline(always)]
    fn new(share: [[f32; HIDDEN]; AFFINE_LAYERS]) -> Option<AffineFlowLane> {
        let mut l = 0;
        while l < AFFINE_LAYERS {
            if !all_finite(&share[l]) {
                return None;
            }
            l += 1;
        }
        Some(AffineFlowLane { share })
    }
}

/// [`AffineFlowSampler`] prepared for one condition: its [`AffineFlowLane`] and a copy of the
/// weights handle.
pub type AffineFlowPrepared<'s, W> = LanePrepared<'s, W, AffineFlowLane>;

super::traits::lane_sampler!(AffineFlowSampler => AffineFlowPrepared, |w, c| {
    let mut share = [[0.0f32; HIDDEN]; AFFINE_LAYERS];
    let mut l = 0;
    while l < AFFINE_LAYERS {
        share[l] = condition_share(w, (l * AFFINE_NET_LEN + AFFINE_NET_L0) as u32, &c);
        l += 1;
    }
    AffineFlowLane::new(share)
});

impl<W: Weights + Copy> AffineFlowPrepared<'_, W> {
    /// Density direction: the latent point `z` of disk point `p` and `ln |det ∂z/∂p|`, or
    /// `None` when `p` is not strictly inside the unit disk. Layers `l = 0..3` in order:
    /// `v_d ← v_d · exp(s) + t` with `d = l mod 2`.
    #[inline]
    #[must_use]
    pub fn to_latent(&self, p: Vec2) -> Option<(Vec2, f32)> {
        if !inside_disk(p) {
            return None;
        }
        let st0 = affine_params(&self.params(), 0, &self.lane_ref().share[0], p.y);
        let unused = [[0.0f32; 3]; AFFINE_LAYERS];
        Some(self.latent_with_layer0(p, st0, &unused, false))
    }

    /// [`AffineFlowPrepared::to_latent`] given layer 0's `(s, t)` at `y = p.y`. With
    /// `reuse`, a layer whose input is bit for bit the one recorded in `seen` (by
    /// [`Self::point_and_layer0`]) takes the recorded `(s, t)` instead of running its network
    /// again: the same function of the same input, so the same numbers.
    #[inline(always)]
    fn latent_with_layer0(
        &self,
        p: Vec2,
        st0: (f32, f32),
        seen: &AffineSeen,
        reuse: bool,
    ) -> (Vec2, f32) {
        let (s0, t0) = st0;
        let mut x = p.x * math::exp(s0) + t0;
        let mut y = p.y;
        let mut ld = s0;
        let mut l = 1;
        while l < AFFINE_LAYERS {
            let v = if l % 2 == 0 { y } else { x };
            let (s, t) = if reuse && v.to_bits() == seen[l][0].to_bits() {
                (seen[l][1], seen[l][2])
            } else {
                affine_params(&self.params(), l, &self.lane_ref().share[l], v)
            };
            if l % 2 == 0 {
                x = x * math::exp(s) + t;
            } else {
                y = y * math::exp(s) + t;
            }
            ld += s;
            l += 1;
        }
        (Vec2::new(x, y), ld)
    }

    /// Sampling direction: the disk-plane point of latent point `z` (not necessarily inside
    /// the disk) and `ln |det ∂p/∂z|`. Layers `l = 3..0`: `v_d ← (v_d − t) · exp(−s)`.
    #[inline]
    #[must_use]
    pub fn from_latent(&self, z: Vec2) -> (Vec2, f32) {
        let (p, ld, _, _) = self.point_and_layer0(z);
        (p, ld)
    }

    /// [`AffineFlowPrepared::from_latent`], also returning layer 0's `(s, t)` (computed at the
    /// final `y`) and, for layers 1‥3, the input each network saw with its `(s, t)`.
    #[inline(always)]
    fn point_and_layer0(&self, z: Vec2) -> (Vec2, f32, (f32, f32), AffineSeen) {
        let (mut x, mut y) = (z.x, z.y);
        let mut ld = 0.0f32;
        let mut seen = [[0.0f32; 3]; AFFINE_LAYERS];
        let mut l = AFFINE_LAYERS - 1;
        while l > 0 {
            let v = if l.is_multiple_of(2) { y } else { x };
            let (s, t) = affine_params(&self.params(), l, &self.lane_ref().share[l], v);
            seen[l] = [v, s, t];
            if l.is_multiple_of(2) {
                x = (x - t) * math::exp(-s);
            } else {
                y = (y - t) * math::exp(-s);
            }
            ld -= s;
            l -= 1;
        }
        let (s0, t0) = affine_params(&self.params(), 0, &self.lane_ref().share[0], y);
        x = (x - t0) * math::exp(-s0);
        ld -= s0;
        (Vec2::new(x, y), ld, (s0, t0), seen)
    }

    /// `ln N(z; 0, I) + ld`, NaN → −∞.
    #[inline(always)]
    fn log_density(z: Vec2, ld: f32) -> f32 {
        let l = gaussian::log_normal_pdf(z, Vec2::ZERO, Vec2::ONE) + ld;
        if l.is_nan() {
            f32::NEG_INFINITY
        } else {
            l
        }
    }

    /// `ln p(p)` on the projected disk (area measure): `ln N(z; 0, I) + ln |det ∂z/∂p|`.
    /// `−∞` outside the open unit disk; never NaN.
    #[inline]
    #[must_use]
    pub fn log_pdf_disk(&self, p: Vec2) -> f32 {
        match self.to_latent(p) {
            Some((z, ld)) => Self::log_density(z, ld),
            None => f32::NEG_INFINITY,
        }
    }
}

impl<W: Weights + Copy> Prepared for AffineFlowPrepared<'_, W> {
    /// Box–Muller from `u` (standard normal `z`), then the inverse couplings. The reported
    /// pdf is the density direction's at the sampled point (reusing layer 0, whose input
    /// `y` is the same in both directions, and any later layer whose input the round trip
    /// reproduced bit for bit), so it equals [`Prepared::pdf_disk`] bit for bit.
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let u = math::sanitize_u2(u)?;
        let (p, _, st0, seen) = self.point_and_layer0(gaussian::box_muller(u));
        if !inside_disk(p) {
            return None;
        }
        let (z, ld) = self.latent_with_layer0(p, st0, &seen, true);
        Sample::from_disk(p, density_from_log(Self::log_density(z, ld)))
    }

    /// Density on the projected disk (area measure); 0 outside the open unit disk.
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        density_from_log(self.log_pdf_disk(p))
    }

    /// The density direction, then the exact inverse of Box–Muller.
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        let w = warp::upper_hemisphere(wo)?;
        let (z, _) = self.to_latent(warp::to_disk(w))?;
        if !math::is_finite(z.x) || !math::is_finite(z.y) {
            return None;
        }
        Some(gaussian::invert_box_muller(z))
    }
}
