//! The disk flow ([`DiskFlowSampler`], `core/ARCHITECTURES.md` §9): the paper's two RQ-spline
//! couplings (Eq. 3–4), rebuilt so that the whole probability mass lies inside the unit disk
//! and no region is tied to a Gaussian tail.
//!
//! The paper's flow pushes a Gaussian base through splines on `[−1, 1]` that are the
//! identity outside: its density near the rim of the disk is the base's tail unless the
//! splines learn otherwise, and the mass outside the disk is lost. Here the base is the
//! **uniform density on the disk** (the concentric map of `u`), and each coupling is a
//! spline on the **chord** through the point: coordinate `x` is rescaled by
//! `C(y) = √(1 − y²)`, transformed by a spline mapping `[−1, 1]` onto itself (every knot
//! derivative learned, no tails), and scaled back. A coupling therefore maps the disk onto
//! itself, and the density on the **projected disk** (area measure) is
//!
//! ```text
//! p(ω⊥) = (1/π) · |det ∂b/∂ω⊥| = (1/π) · S₁′(ω⊥.y / C(ω⊥.x)) · S₀′(ω⊥.x / C(b.y))
//! ```
//!
//! with the base point `b` from the *density direction* ([`DiskFlowPrepared::to_base`]):
//!
//! ```text
//! b.y = C(x)·S₁(y / C(x)),      S₁ = spline of coupling1(c, enc4(x))
//! b.x = C(b.y)·S₀(x / C(b.y)),  S₀ = spline of coupling0(c, enc4(b.y))
//! ```
//!
//! (the rescaling cancels in each derivative). Sampling runs the inverse of both couplings
//! from `b = concentric(u)`, then evaluates the density direction at the sampled point,
//! reusing the splines the two directions share, so that the pdf a sample reports is bit for
//! bit [`Prepared::pdf_disk`] at its point (as the paper's flow does). `invert` is exact: the
//! density direction, then the inverse concentric map. No Box–Muller, no base network.

use glam::{Vec2, Vec3};

use crate::distrib::spline::Knots;
use crate::math;
use crate::math::lane::Lane;
use crate::nn;
use crate::warp::{self, inside_disk};
use crate::weights::Weights;

use super::coupling::HIDDEN;
use super::coupling::{all_finite, condition_share, coupling_raw, density_from_log};
use super::coupling::{COUPLING_L0, COUPLING_L1, COUPLING_L2};

use super::{LanePrepared, Prepared, Sample};

#[cfg(not(target_arch = "spirv"))]
mod batch;

/// Bins of every spline of [`DiskFlowSampler`] (as the paper's flow).
pub const DISK_FLOW_BINS: usize = 20;
/// Raw outputs of a coupling network: 20 widths, 20 heights, 21 knot derivatives.
pub const DISK_SPLINE_RAW_LEN: usize = Knots::<DISK_FLOW_BINS>::FREE_RAW_LEN;

/// Offset of a coupling network's `dense(39, 32)` (LeakyReLU), relative to the network.
pub const DISK_NET_L0: usize = COUPLING_L0;
/// Offset of a coupling network's `dense(32, 32)` (LeakyReLU), relative to the network.
pub const DISK_NET_L1: usize = COUPLING_L1;
/// Offset of a coupling network's `dense(32, 61)`, relative to the network.
pub const DISK_NET_L2: usize = COUPLING_L2;
/// Parameters of one coupling network (4349).
pub const DISK_NET_LEN: usize = DISK_NET_L2 + nn::dense_len(HIDDEN, DISK_SPLINE_RAW_LEN);
/// Offset of coupling network 0 (transforms x, conditioned on the base point's y).
pub const DISK_FLOW_COUPLING0: usize = 0;
/// Offset of coupling network 1 (transforms y, conditioned on x).
pub const DISK_FLOW_COUPLING1: usize = DISK_FLOW_COUPLING0 + DISK_NET_LEN;
/// Parameters of [`DiskFlowSampler`] (8698).
pub const DISK_FLOW_PARAM_COUNT: usize = DISK_FLOW_COUPLING1 + DISK_NET_LEN;

/// Half the chord of the unit disk at coordinate `v`: `√(1 − v²)` (0 for `|v| ≥ 1`;
/// computed as `√((1 − v)(1 + v))`).
#[inline(always)]
#[must_use]
pub fn chord(v: f32) -> f32 {
    chord_lanes(v)
}

/// `a / c` clamped to `[−1, 1]`: a coordinate in units of the half chord `c` (0 when `c` is
/// not positive; NaN → −1).
#[inline(always)]
#[must_use]
pub fn in_chord(a: f32, c: f32) -> f32 {
    in_chord_lanes(a, c)
}

/// [`chord`] per lane (the scalar and batched paths share it). `(1 − v)(1 + v)` rather than
/// `1 − v²`: `1 − v` is exact for `|v| ≥ ½`, so the chord keeps its relative precision at the
/// rim, where `1 − v²` would lose it to cancellation.
#[inline(always)]
fn chord_lanes<L: Lane>(v: L) -> L {
    let one = L::splat(1.0);
    ((one - v) * (one + v)).safe_sqrt()
}

/// [`in_chord`] per lane.
#[inline(always)]
fn in_chord_lanes<L: Lane>(a: L, c: L) -> L {
    let zero = L::splat(0.0);
    L::select(c.gt(zero), (a / c).clamp(-1.0, 1.0), zero)
}

/// `C(o)·S(a / C(o))` (a forward coupling of coordinate `a` on the chord at the other
/// coordinate `o`), `ln S′`, and the half chord `C(a′)` at its result, computed as
/// `√((1 − s)(1 + s) + s²o²)` (`1 − C(o)²s²` with `s = S(a / C(o))`) from the spline's own
/// distances to the ends, so that it keeps its relative precision where `a′` is within
/// rounding of ±1 (the poles of the disk).
#[inline(always)]
fn chord_forward_next<L: Lane>(k: &Knots<DISK_FLOW_BINS, L>, a: L, o: L) -> (L, L, L) {
    let c = chord_lanes(o);
    let (s, ld, lo, hi) = k.forward_margins_lanes(in_chord_lanes(a, c));
    let next = (lo * hi + s * s * (o * o)).safe_sqrt();
    (c * s, ld, next)
}

/// `S(a / c)`'s log-derivative for a coupling whose half chord `c` is already known.
#[inline(always)]
fn chord_log_derivative<L: Lane>(k: &Knots<DISK_FLOW_BINS, L>, a: L, c: L) -> L {
    k.forward_lanes(in_chord_lanes(a, c)).1
}

/// `C(o)·S⁻¹(a / C(o))`: an inverse coupling of coordinate `a` on the chord at `o`.
#[inline(always)]
fn chord_inverse<L: Lane>(k: &Knots<DISK_FLOW_BINS, L>, a: L, o: L) -> L {
    let c = chord_lanes(o);
    c * k.inverse_with::<false>(in_chord_lanes(a, c)).0
}

/// The spline of a coupling network at `offset`, for the other coordinate `v`.
#[inline]
fn spline_knots<W: Weights>(
    w: &W,
    offset: u32,
    share: &[f32; HIDDEN],
    v: f32,
) -> Knots<DISK_FLOW_BINS> {
    Knots::from_raw_free(&coupling_raw::<W, DISK_SPLINE_RAW_LEN>(w, offset, share, v))
}

/// The disk flow: a uniform base on the disk and two RQ-spline couplings on chords, every
/// mass inside the disk (module docs, `core/ARCHITECTURES.md` §9). Densities are on the
/// projected disk (area measure).
#[derive(Copy, Clone, Debug)]
pub struct DiskFlowSampler<W> {
    params: W,
}

super::traits::flat_params_sampler!(
    DiskFlowSampler,
    DiskFlow,
    DISK_FLOW_PARAM_COUNT,
    "Length of the flat parameter array: coupling 0, coupling 1 (8698)."
);

/// The disk flow at one shading point without its weights handle (the lane of the batched
/// API): the condition's share of both coupling networks' first layers.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DiskFlowLane {
    /// Condition's share (bias included) of coupling network 0's and 1's first layer.
    share: [[f32; HIDDEN]; 2],
}

impl DiskFlowLane {
    /// The state from the couplings' condition shares; `None` when one is not finite.
    #[inline(always)]
    fn new(share: [[f32; HIDDEN]; 2]) -> Option<DiskFlowLane> {
        if !all_finite(&share[0]) || !all_finite(&share[1]) {
            return None;
        }
        Some(DiskFlowLane { share })
    }
}

/// [`DiskFlowSampler`] prepared for one condition: its [`DiskFlowLane`] and a copy of the
/// weights handle.
pub type DiskFlowPrepared<'s, W> = LanePrepared<'s, W, DiskFlowLane>;

super::traits::lane_sampler!(DiskFlowSampler => DiskFlowPrepared, |w, c| {
    let share = [
        condition_share(w, DISK_FLOW_COUPLING0 as u32, &c),
        condition_share(w, DISK_FLOW_COUPLING1 as u32, &c),
    ];
    DiskFlowLane::new(share)
});

impl<W: Weights + Copy> DiskFlowPrepared<'_, W> {
    /// The spline of coupling network `net` (0 or 1) at other coordinate `v`.
    #[inline(always)]
    fn knots(&self, net: usize, v: f32) -> Knots<DISK_FLOW_BINS> {
        let offset = if net == 0 {
            DISK_FLOW_COUPLING0
        } else {
            DISK_FLOW_COUPLING1
        };
        spline_knots(
            &self.params(),
            offset as u32,
            &self.lane_ref().share[net],
            v,
        )
    }

    /// Density direction: the base point `b` of disk point `p` and `ln |det ∂b/∂p|`, or
    /// `None` when `p` is not strictly inside the unit disk.
    #[inline]
    #[must_use]
    pub fn to_base(&self, p: Vec2) -> Option<(Vec2, f32)> {
        if !inside_disk(p) {
            return None;
        }
        let k1 = self.knots(1, p.x);
        Some(self.base_with_k1(p, &k1))
    }

    /// [`DiskFlowPrepared::to_base`] given coupling 1's spline `k1` at `x = p.x`.
    #[inline(always)]
    fn base_with_k1(&self, p: Vec2, k1: &Knots<DISK_FLOW_BINS>) -> (Vec2, f32) {
        let (by, ld1, cb) = chord_forward_next(k1, p.y, p.x);
        let k0 = self.knots(0, by);
        let (s0, ld0) = k0.forward(in_chord(p.x, cb));
        (Vec2::new(cb * s0, by), ld0 + ld1)
    }

    /// Sampling direction: the disk point of base point `b` (inside the closed disk), with
    /// the splines it built: coupling 0's at `b.y` and coupling 1's at `x`.
    #[inline(always)]
    fn point_and_knots(&self, b: Vec2) -> (Vec2, Knots<DISK_FLOW_BINS>, Knots<DISK_FLOW_BINS>) {
        let k0 = self.knots(0, b.y);
        let x = chord_inverse(&k0, b.x, b.y);
        let k1 = self.knots(1, x);
        let y = chord_inverse(&k1, b.y, x);
        (Vec2::new(x, y), k0, k1)
    }

    /// The disk point of base point `b` (sampling direction).
    #[inline]
    #[must_use]
    pub fn from_base(&self, b: Vec2) -> Vec2 {
        self.point_and_knots(b).0
    }

    /// `ln p(p)` on the projected disk (area measure): `−ln π + ln |det ∂b/∂p|`. `−∞`
    /// outside the open unit disk; never NaN.
    #[inline]
    #[must_use]
    pub fn log_pdf_disk(&self, p: Vec2) -> f32 {
        match self.to_base(p) {
            Some((_, ld)) => log_density(ld),
            None => f32::NEG_INFINITY,
        }
    }
}

/// The `u` whose concentric map is the base point `b` (clamped below 1, as `sample` clamps
/// it), or `None` when it is not finite.
#[inline(always)]
fn invert_base(b: Vec2) -> Option<Vec2> {
    let u = warp::invert_uniform_disk_concentric(b);
    if math::is_finite(u.x) && math::is_finite(u.y) {
        let c = |v: f32| math::clamp(v, 0.0, math::ONE_MINUS_EPSILON);
        Some(Vec2::new(c(u.x), c(u.y)))
    } else {
        None
    }
}

/// `−ln π + ld` (NaN → −∞).
#[inline(always)]
fn log_density(ld: f32) -> f32 {
    let l = ld - math::LN_PI;
    if l.is_nan() {
        f32::NEG_INFINITY
    } else {
        l
    }
}

impl<W: Weights + Copy> Prepared for DiskFlowPrepared<'_, W> {
    /// `b` = the concentric map of `u`, then the inverse couplings.
    ///
    /// The reported pdf (solid angle; disk area in [`Sample::pdf_disk`]) is the density
    /// direction's at the sampled point, reusing coupling 1's spline (its input `x` is the
    /// same in both directions) and coupling 0's when the round trip gives back `b.y` bit for
    /// bit, so it equals [`Prepared::pdf_disk`] bit for bit.
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let u = math::sanitize_u2(u)?;
        let b = warp::sample_uniform_disk_concentric(u);
        let (p, k0, k1) = self.point_and_knots(b);
        if !inside_disk(p) {
            return None;
        }
        // `base_with_k1`, with coupling 0's spline reused when its input is unchanged.
        let (by, ld1, cb) = chord_forward_next(&k1, p.y, p.x);
        let k0 = if by.to_bits() == b.y.to_bits() {
            k0
        } else {
            self.knots(0, by)
        };
        let ld0 = chord_log_derivative(&k0, p.x, cb);
        Sample::from_disk(p, density_from_log(log_density(ld0 + ld1)))
    }

    /// Density on the projected disk (area measure); 0 outside the open unit disk.
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        density_from_log(self.log_pdf_disk(p))
    }

    /// The density direction, then the inverse concentric map.
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        let w = warp::upper_hemisphere(wo)?;
        let (b, _) = self.to_base(warp::to_disk(w))?;
        invert_base(b)
    }
}
