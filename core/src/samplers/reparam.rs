//! The reparameterization sampler ([`ReparamSampler`], `core/ARCHITECTURES.md` §8; after Wu
//! et al., SIGGRAPH 2025): a small MLP warp `T(z; c)` from a standard-normal `z` to the
//! projected unit disk, the exact density of its samples from the 2 × 2 Jacobian, and a second
//! small MLP that approximates that density anywhere, for MIS.
//!
//! ```text
//! (a, b, w) = warp(c, z)                   dense(32,16) SiLU, dense(16,16) SiLU, dense(16,3)
//! v = (a, b, softplus(w)) / |(a, b, softplus(w))|        ω⊥ = T(z) = (v.x, v.y), wo = v
//! q(T(z)) = N(z; 0, I) / |det ∂T/∂z|                     (projected-disk area measure)
//! p̂(ω⊥) = exp(clamp(pdf_net(c, ω⊥), −16, 16))            dense(32,16) ReLU, dense(16,1)
//! ```
//!
//! Two densities, two roles, both on every [`Sample`]:
//!
//! * [`Sample::pdf`] is `q·cos θo`, the density the warp drew the sample with (forward-mode
//!   Jacobian alongside the forward pass): `f·cos θo / Sample::pdf` is the sample's exact
//!   weight wherever the warp is injective. A sample whose Jacobian is degenerate or
//!   orientation-reversing (`det ≤ 0`: the warp folds there) is refused, so no weight is
//!   infinite.
//! * [`Prepared::pdf`] is `p̂·cos θo`, the pdf network, which MIS weights must use for every
//!   strategy (light samples cannot know `q`); a sample carries it as [`Sample::mis_pdf`]
//!   (one evaluation of the pdf network per sample).
//!   MIS stays unbiased with an approximate `p̂` because the strategies' weights still sum
//!   to one; a poor `p̂` costs variance only.

use glam::{Vec2, Vec3};

use crate::distrib::gaussian;
use crate::math;
use crate::math::lane::Lane;
use crate::nn::{self, CONDITION_DIM};
use crate::warp::inside_disk;
use crate::weights::Weights;

use super::coupling::all_finite;

use super::{LanePrepared, Prepared, Sample};

#[cfg(not(target_arch = "spirv"))]
mod batch;

/// Width of the hidden layers of both networks.
pub const REPARAM_HIDDEN: usize = 16;
/// Inputs of both networks: the encoded condition, then a 2-D point (`z` for the warp,
/// `ω⊥` for the pdf network): 30 + 2 = 32.
pub const REPARAM_INPUTS: usize = CONDITION_DIM + 2;
/// Outputs of the warp: `(a, b, w)`.
pub const WARP_OUTPUTS: usize = 3;
/// Offset of the warp's `dense(32, 16)` (SiLU).
pub const WARP_L0: usize = 0;
/// Offset of the warp's `dense(16, 16)` (SiLU).
pub const WARP_L1: usize = WARP_L0 + nn::dense_len(REPARAM_INPUTS, REPARAM_HIDDEN);
/// Offset of the warp's `dense(16, 3)`.
pub const WARP_L2: usize = WARP_L1 + nn::dense_len(REPARAM_HIDDEN, REPARAM_HIDDEN);
/// Offset of the pdf network's `dense(32, 16)` (ReLU); the warp's parameters end here (851).
pub const DENSITY_L0: usize = WARP_L2 + nn::dense_len(REPARAM_HIDDEN, WARP_OUTPUTS);
/// Offset of the pdf network's `dense(16, 1)`.
pub const DENSITY_L1: usize = DENSITY_L0 + nn::dense_len(REPARAM_INPUTS, REPARAM_HIDDEN);
/// Parameters of [`ReparamSampler`]: the warp (851), then the pdf network (545): 1396.
pub const REPARAM_PARAM_COUNT: usize = DENSITY_L1 + nn::dense_len(REPARAM_HIDDEN, 1);

/// Clamp of the pdf network's log-density before `exp` (disk measure): `p̂ ∈ [e⁻¹⁶, e¹⁶]`.
pub const LOG_DENSITY_MIN: f32 = -16.0;
/// Upper clamp of the pdf network's log-density (see [`LOG_DENSITY_MIN`]).
pub const LOG_DENSITY_MAX: f32 = 16.0;

/// `(silu(a), silu'(a))` from `a` and `s = σ(a)`: `silu(a) = a·s`,
/// `silu'(a) = s·(1 + a·(1 − s))`. Both paths call it, each with its own sigmoid.
#[inline(always)]
pub(crate) fn silu_from_sigmoid(a: f32, s: f32) -> (f32, f32) {
    (a * s, s * (1.0 + a * (1.0 - s)))
}

/// `(silu(a), silu'(a))` with [`math::sigmoid`].
#[inline(always)]
fn silu_slope(a: f32) -> (f32, f32) {
    silu_from_sigmoid(a, math::sigmoid(a))
}

/// The warp at one latent point: where it lands and how it stretches area there.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Warped {
    /// `T(z)` on the projected disk (`|point| < 1` whenever `softplus(w) > 0`).
    pub point: Vec2,
    /// The direction `v = (a, b, softplus(w)) / |·|` above `point` (`v.z = cos θo`).
    pub wo: Vec3,
    /// `det ∂T/∂z` (signed: negative where the warp reverses orientation).
    pub det: f32,
}

/// The warp's last step, shared by the scalar and batched paths: from the output `o =
/// (a, b, w)` and its derivatives `d0 = ∂o/∂z.x`, `d1 = ∂o/∂z.y` to the direction `v` above
/// the point and `det ∂T/∂z` (`ARCHITECTURES.md` §8).
#[inline(always)]
pub(crate) fn finish_warp<L: Lane>(
    o: [L; WARP_OUTPUTS],
    d0: [L; WARP_OUTPUTS],
    d1: [L; WARP_OUTPUTS],
) -> ([L; 3], L) {
    let s = o[2].softplus();
    let ds = o[2].sigmoid();
    let inv = L::splat(1.0) / (o[0] * o[0] + o[1] * o[1] + s * s).safe_sqrt();
    let v = [o[0] * inv, o[1] * inv, s * inv];
    // d(u/|u|) = (du − v (v·du)) / |u|, for u = (a, b, s) along each latent axis.
    let t0 = v[0] * d0[0] + v[1] * d0[1] + v[2] * (ds * d0[2]);
    let t1 = v[0] * d1[0] + v[1] * d1[1] + v[2] * (ds * d1[2]);
    let x0 = (d0[0] - v[0] * t0) * inv;
    let y0 = (d0[1] - v[1] * t0) * inv;
    let x1 = (d1[0] - v[0] * t1) * inv;
    let y1 = (d1[1] - v[1] * t1) * inv;
    (v, x0 * y1 - x1 * y0)
}

/// The density `N(z; 0, I) / det` on the projected disk of a warp sample at `z = (zx, zy)`,
/// or 0 unless `det > 0` and the result is finite (a folded or degenerate Jacobian refuses
/// the sample).
#[inline(always)]
pub(crate) fn sample_density<L: Lane>(zx: L, zy: L, det: L) -> L {
    let zero = L::splat(0.0);
    let log = L::splat(-0.5) * (zx * zx + zy * zy) - L::splat(math::LN_TWO_PI) - det.ln();
    let p = log.exp();
    let det_ok = L::and(det.gt(zero), det.le(L::splat(f32::MAX)));
    let p_ok = L::and(p.gt(zero), p.le(L::splat(f32::MAX)));
    L::select(L::and(det_ok, p_ok), p, zero)
}

/// The sample at disk point `point` below the direction with `cos θo = cos` and disk
/// density `q` (0: refused).
#[inline(always)]
pub(crate) fn warp_sample(point: Vec2, cos: f32, q: f32) -> Option<Sample> {
    if !(q > 0.0) || !(cos > 0.0) {
        return None;
    }
    Sample::from_disk(point, q)
}

/// The pdf network's log-density to density step (the scalar path's; the batched path
/// takes the fast `exp` of the same clamp).
#[inline(always)]
pub(crate) fn density_from_output(o: f32) -> f32 {
    math::exp(math::clamp(o, LOG_DENSITY_MIN, LOG_DENSITY_MAX))
}

/// The reparameterization sampler (module docs; `core/ARCHITECTURES.md` §8).
#[derive(Copy, Clone, Debug)]
pub struct ReparamSampler<W> {
    params: W,
}

super::traits::flat_params_sampler!(
    ReparamSampler,
    Reparam,
    REPARAM_PARAM_COUNT,
    "Number of parameters: [`REPARAM_PARAM_COUNT`] (1396)."
);

/// The reparameterization sampler at one shading point without its weights handle (the lane
/// of the batched API): the condition's share of both networks' first layers.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ReparamLane {
    warp: [f32; REPARAM_HIDDEN],
    density: [f32; REPARAM_HIDDEN],
}

impl ReparamLane {
    /// The state from both shares; `None` when any value is not finite.
    #[inline(always)]
    fn new(warp: [f32; REPARAM_HIDDEN], density: [f32; REPARAM_HIDDEN]) -> Option<ReparamLane> {
        if all_finite(&warp) && all_finite(&density) {
            Some(ReparamLane { warp, density })
        } else {
            None
        }
    }
}

/// The condition's share of the first layer at `offset` (`dense(32, 16)`): bias plus the
/// product with inputs `0 .. 30`.
#[inline(always)]
fn share<W: Weights>(w: &W, offset: u32, c: &[f32; CONDITION_DIM]) -> [f32; REPARAM_HIDDEN] {
    let mut acc = nn::bias::<W, REPARAM_INPUTS, REPARAM_HIDDEN>(w, offset);
    nn::accumulate_inputs::<W, CONDITION_DIM, REPARAM_HIDDEN>(w, offset, 0, c, &mut acc);
    acc
}

/// The first layer at `offset` from its condition share and the point inputs 30, 31
/// (before the activation).
#[inline(always)]
fn first_layer<W: Weights>(
    w: &W,
    offset: u32,
    share: &[f32; REPARAM_HIDDEN],
    p: Vec2,
) -> [f32; REPARAM_HIDDEN] {
    let mut acc = *share;
    let x = [p.x, p.y];
    nn::accumulate_inputs::<W, 2, REPARAM_HIDDEN>(w, offset, CONDITION_DIM as u32, &x, &mut acc);
    acc
}

/// `Σ_i x_i W[i]` of the dense layer at `offset` without its bias: how a tangent passes a
/// linear layer.
#[inline(always)]
fn tangent<W: Weights, const I: usize, const O: usize>(
    w: &W,
    offset: u32,
    x: &[f32; I],
) -> [f32; O] {
    let mut acc = [0.0f32; O];
    nn::accumulate_inputs::<W, I, O>(w, offset, 0, x, &mut acc);
    acc
}

/// The warp of a lane at latent point `z`, with its Jacobian by forward-mode differentiation.
#[inline(always)]
fn warp_lane<W: Weights>(w: &W, lane: &ReparamLane, z: Vec2) -> Warped {
    const H: usize = REPARAM_HIDDEN;
    let l0 = WARP_L0 as u32;
    let a1 = first_layer(w, l0, &lane.warp, z);
    // ∂a1/∂z.k is row 30 + k of the first layer's matrix.
    let r0: [f32; H] = w.read(l0 + (CONDITION_DIM * H) as u32);
    let r1: [f32; H] = w.read(l0 + ((CONDITION_DIM + 1) * H) as u32);
    let mut h1 = [0.0f32; H];
    let mut t0 = [0.0f32; H];
    let mut t1 = [0.0f32; H];
    let mut j = 0;
    while j < H {
        let (y, d) = silu_slope(a1[j]);
        h1[j] = y;
        t0[j] = d * r0[j];
        t1[j] = d * r1[j];
        j += 1;
    }
    let l1 = WARP_L1 as u32;
    let a2 = nn::linear::<W, H, H>(w, l1, &h1);
    let u0: [f32; H] = tangent::<W, H, H>(w, l1, &t0);
    let u1: [f32; H] = tangent::<W, H, H>(w, l1, &t1);
    let mut h2 = [0.0f32; H];
    let mut j = 0;
    while j < H {
        let (y, d) = silu_slope(a2[j]);
        h2[j] = y;
        t0[j] = d * u0[j];
        t1[j] = d * u1[j];
        j += 1;
    }
    let l2 = WARP_L2 as u32;
    let o = nn::linear::<W, H, WARP_OUTPUTS>(w, l2, &h2);
    let d0 = tangent::<W, H, WARP_OUTPUTS>(w, l2, &t0);
    let d1 = tangent::<W, H, WARP_OUTPUTS>(w, l2, &t1);
    let (v, det) = finish_warp(o, d0, d1);
    Warped {
        point: Vec2::new(v[0], v[1]),
        wo: Vec3::from_array(v),
        det,
    }
}

/// The pdf network of a lane at disk point `p` (inside the disk): `p̂(p)`.
#[inline(always)]
fn density_lane<W: Weights>(w: &W, lane: &ReparamLane, p: Vec2) -> f32 {
    let mut g = first_layer(w, DENSITY_L0 as u32, &lane.density, p);
    nn::Activation::Relu.apply_all(&mut g);
    let o = nn::linear::<W, REPARAM_HIDDEN, 1>(w, DENSITY_L1 as u32, &g);
    density_from_output(o[0])
}

/// [`ReparamSampler`] prepared for one condition: its [`ReparamLane`] and a copy of the
/// weights handle.
pub type ReparamPrepared<'s, W> = LanePrepared<'s, W, ReparamLane>;

super::traits::lane_sampler!(ReparamSampler => ReparamPrepared, |w, c| {
    ReparamLane::new(
        share(w, WARP_L0 as u32, &c),
        share(w, DENSITY_L0 as u32, &c),
    )
});

impl<W: Weights + Copy> ReparamPrepared<'_, W> {
    /// The warp at latent point `z` (not necessarily a Box–Muller output) with its Jacobian
    /// determinant. For tests and training checks; [`Prepared::sample`] is `warp` at
    /// `box_muller(u)`.
    #[inline]
    #[must_use]
    pub fn warp(&self, z: Vec2) -> Warped {
        warp_lane(&self.params(), self.lane_ref(), z)
    }
}

impl<W: Weights + Copy> Prepared for ReparamPrepared<'_, W> {
    /// `z` by Box–Muller from `u`, then the warp; [`Sample::pdf`] is the warp's own density,
    /// `N(z)/det ∂T/∂z` times `cos θo`, and [`Sample::mis_pdf`] the pdf network's there.
    /// `None` where `det ≤ 0` (a fold) or the density is not finite and positive.
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let u = math::sanitize_u2(u)?;
        let z = gaussian::box_muller(u);
        let t = self.warp(z);
        let s = warp_sample(t.point, t.wo.z, sample_density(z.x, z.y, t.det))?;
        Some(s.with_mis_pdf(self.pdf(s.wo)))
    }

    /// The pdf network `p̂` on the projected disk (area measure); 0 outside the open disk.
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        if !inside_disk(p) {
            return 0.0;
        }
        density_lane(&self.params(), self.lane_ref(), p)
    }
}
