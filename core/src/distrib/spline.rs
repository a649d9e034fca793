//! Monotonic rational-quadratic splines (Durkan et al. 2019, "Neural Spline Flows"), the
//! element-wise bijection of the flow's coupling layers (paper Eq. 4).
//!
//! A spline with `K` bins maps `[−B, B]` onto itself through `K + 1` increasing knots
//! `(x_k, y_k)` with positive derivatives `d_k`; outside `[−B, B]` it is the identity
//! ("identity tails", log-det 0). Inside bin `k`, with `w = x_{k+1} − x_k`,
//! `h = y_{k+1} − y_k`, `s = h / w` and `ξ = (x − x_k) / w ∈ [0, 1]`:
//!
//! ```text
//! y = y_k + h (s ξ² + d_k ξ(1−ξ)) / (s + (d_{k+1} + d_k − 2s) ξ(1−ξ))             (Eq. 4)
//! dy/dx = s² (d_{k+1} ξ² + 2s ξ(1−ξ) + d_k (1−ξ)²) / (s + (d_{k+1} + d_k − 2s) ξ(1−ξ))²
//! ```
//!
//! The inverse solves `a ξ² + b ξ + c = 0` for the root `ξ = 2c / (−b − √(b² − 4ac))`
//! (nflows' form, stable for `b ≥ 0`), written `(−b + √(b² − 4ac)) / 2a` when `b < 0`.
//!
//! # Constraints (the one place raw network outputs become knots)
//!
//! [`Knots::from_raw`] follows nflows' `unconstrained_rational_quadratic_spline`:
//! `widths = MIN_BIN_WIDTH + (1 − K·MIN_BIN_WIDTH)·softmax(raw_w)`, knots the cumulative sum
//! scaled to `[−B, B]` with both ends set exactly to `±B`; the same for heights;
//! interior derivatives `MIN_DERIVATIVE + softplus(raw_d)`, boundary derivatives 1 (so the
//! identity tails join with a continuous slope).
//!
//! # Numerical policy
//!
//! Every function here is total and returns finite, NaN-free numbers:
//!
//! * raw network outputs are clamped to `±`[`RAW_LIMIT`] before the constraints (NaN counts
//!   as `−RAW_LIMIT`). No trained network comes near the limit, so training code need not
//!   reproduce the clamp; it keeps every intermediate value finite for adversarial inputs;
//! * the discriminant is clamped at 0 and `ξ` to `[0, 1]`; `y = +B` lies in the last bin;
//! * both directions evaluate a bin from its nearer knot (the mirrored spline `ξ → 1 − ξ`
//!   swaps `d_k` and `d_{k+1}`), so knots map exactly onto knots and `±B` onto `±B`; this is
//!   the same function, only rounded differently, so training code need not copy it. In
//!   f32 the spline is monotone up to rounding at the scale of `B` (where the two formulas
//!   meet);
//! * **non-finite input**: the input is first clamped to `[−f32::MAX, f32::MAX]`, NaN going
//!   to `−f32::MAX`. So `±∞` and NaN come out as `±f32::MAX` / `−f32::MAX` with log-det 0
//!   — a finite sentinel far outside any bounded domain. The spline does not report
//!   failure; callers on a bounded domain (the flow samplers, whose points must lie in the
//!   unit disk) refuse such points by their own range test.
//!
//! Bin search is a fixed-count linear scan over the `K − 1` interior knots (no early exit,
//! index provably in `0..K`), which rust-gpu compiles as a plain loop.

use crate::distrib::gaussian;
use crate::math;
use crate::math::lane::Lane;

/// Minimum bin width as a fraction of the interval `2B` (nflows' `DEFAULT_MIN_BIN_WIDTH`).
pub const MIN_BIN_WIDTH: f32 = 1e-3;
/// Minimum bin height as a fraction of the interval `2B` (nflows' `DEFAULT_MIN_BIN_HEIGHT`).
pub const MIN_BIN_HEIGHT: f32 = 1e-3;
/// Minimum knot derivative (nflows' `DEFAULT_MIN_DERIVATIVE`).
pub const MIN_DERIVATIVE: f32 = 1e-3;
/// Raw network outputs are clamped to `[−RAW_LIMIT, RAW_LIMIT]` (NaN → `−RAW_LIMIT`) before
/// the constraints, which keeps every intermediate of [`Knots::forward`] and
/// [`Knots::inverse`] finite (derivatives stay below ~10⁶).
pub const RAW_LIMIT: f32 = 1e6;
/// Smallest tail bound [`Knots::from_raw`] accepts (smaller ones are raised to it).
pub const MIN_TAIL_BOUND: f32 = 1e-3;
/// Largest tail bound [`Knots::from_raw`] accepts (larger ones are lowered to it).
pub const MAX_TAIL_BOUND: f32 = 1e6;

/// The knots of a `K`-bin rational-quadratic spline on `[−bound, bound]`, constrained from
/// raw network outputs by [`Knots::from_raw`].
///
/// Bin `k` spans `[x[k], x[k+1]]` × `[y[k], y[k+1]]`, with the right end of the last bin
/// `x[K] = y[K] = bound` implicit; `x[0] = y[0] = −bound`. The derivative at knot `k` is
/// [`Knots::derivative`]`(k)`: 1 at both ends, `MIN_DERIVATIVE + softplus(raw_d[k])`
/// inside. Derivatives are constrained lazily because a forward or inverse evaluation
/// needs only the two of its bin: 2 softplus instead of `K − 1` (the softmaxes need every
/// raw value anyway), which cuts the cost of building a 20-bin spline by about a third.
///
/// `L` is `f32`; inside the crate the batched path instantiates the same code for several
/// splines at once (one per lane), so both paths share one definition of the spline.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Knots<const K: usize, L = f32> {
    /// Left x-knot of every bin (`x[0] = −bound`), strictly increasing.
    pub x: [L; K],
    /// Left y-knot of every bin (`y[0] = −bound`), strictly increasing.
    pub y: [L; K],
    /// Unnormalised derivative at knot `k` for `0 ≤ k < K`, clamped to `±RAW_LIMIT`
    /// (`raw_d[0]` is used only with [`Knots::free_ends`]; otherwise the boundary derivatives
    /// are 1).
    pub raw_d: [L; K],
    /// Unnormalised derivative at the last knot `K` (used only with [`Knots::free_ends`]).
    pub raw_d_last: L,
    /// Whether the boundary derivatives are learned (`MIN_DERIVATIVE + softplus` of
    /// `raw_d[0]` and `raw_d_last`, [`Knots::from_raw_free`]) instead of 1.
    pub free_ends: bool,
    /// Tail bound `B`: the spline maps `[−B, B]` onto itself, identity outside.
    pub bound: f32,
}

/// `v` clamped to `±RAW_LIMIT`, NaN → `−RAW_LIMIT`.
#[inline(always)]
fn sanitize_raw<L: Lane>(v: L) -> L {
    v.clamp(-RAW_LIMIT, RAW_LIMIT)
}

/// Left x- and y-knots of `K` bins on `[−B, B]` from raw widths `raw[0 .. K]` and heights
/// `raw[K .. 2K]`: `size = min + (1 − K·min)·softmax(raw)`, cumulative sum scaled to
/// `[−B, B]`, left end exactly `−B` (the right end `+B` is implicit in [`Knots`]). Widths and
/// heights are independent; their softmaxes and running sums are interleaved so that the two
/// sequential chains overlap (each computed exactly as on its own). Computed in `x` and `y`
/// (the softmaxes first, then each replaced by its knot), so no temporary is zeroed.
#[inline(always)]
fn cumulative_knots<L: Lane, const K: usize, const N: usize>(
    raw: &[L; N],
    bound: f32,
    x: &mut [L; K],
    y: &mut [L; K],
) {
    let mut k = 0;
    while k < K {
        x[k] = sanitize_raw(raw[k]);
        y[k] = sanitize_raw(raw[K + k]);
        k += 1;
    }
    gaussian::softmax_pair_lanes::<L, K>(x, y);
    let scale_w = L::splat(1.0 - MIN_BIN_WIDTH * K as f32);
    let scale_h = L::splat(1.0 - MIN_BIN_HEIGHT * K as f32);
    let (min_w, min_h) = (L::splat(MIN_BIN_WIDTH), L::splat(MIN_BIN_HEIGHT));
    let (b2, b) = (L::splat(2.0 * bound), L::splat(bound));
    // Bin k − 1's size, read before knot k − 1 replaced it.
    let (mut w, mut h) = (x[0], y[0]);
    x[0] = -b;
    y[0] = -b;
    let mut cum_w = L::splat(0.0);
    let mut cum_h = L::splat(0.0);
    k = 1;
    while k < K {
        cum_w = cum_w + (min_w + scale_w * w);
        w = x[k];
        x[k] = b2 * cum_w - b;
        cum_h = cum_h + (min_h + scale_h * h);
        h = y[k];
        y[k] = b2 * cum_h - b;
        k += 1;
    }
}

impl<const K: usize> Knots<K> {
    /// Number of raw network outputs per spline: `K` widths, `K` heights, `K − 1` interior
    /// derivatives.
    pub const RAW_LEN: usize = 3 * K - 1;
    /// Number of raw network outputs per spline with learned boundary derivatives
    /// ([`Knots::from_raw_free`]): `K` widths, `K` heights, `K + 1` derivatives.
    pub const FREE_RAW_LEN: usize = 3 * K + 1;

    /// Constrains raw network outputs into knots — the only place this happens (with
    /// [`Knots::derivative`] for the derivatives).
    ///
    /// `raw` is laid out `[unnormalised widths (K), unnormalised heights (K), unnormalised
    /// interior derivatives (K − 1)]`; `N` must equal [`Knots::RAW_LEN`] (checked at
    /// compile time). `bound` is the tail bound `B`, clamped to
    /// `[MIN_TAIL_BOUND, MAX_TAIL_BOUND]` (NaN → [`MIN_TAIL_BOUND`]) so that no bin
    /// degenerates.
    #[inline]
    #[must_use]
    pub fn from_raw<const N: usize>(raw: &[f32; N], bound: f32) -> Self {
        Self::from_raw_lanes(raw, bound)
    }

    /// Knots on `[−1, 1]` whose boundary derivatives are learned too (nflows' constrained
    /// spline without tails): `raw` is `[widths (K), heights (K), derivatives (K + 1)]`,
    /// `N` = [`Knots::FREE_RAW_LEN`]; every derivative is `MIN_DERIVATIVE + softplus(raw)`.
    /// Meant for a domain that is exactly `[−1, 1]` (callers keep inputs inside it; outside,
    /// the spline is still the identity with log-det 0).
    #[inline]
    #[must_use]
    pub fn from_raw_free<const N: usize>(raw: &[f32; N]) -> Self {
        Self::from_raw_free_lanes(raw)
    }

    /// The derivative at knot `k ∈ 0..=K`: `MIN_DERIVATIVE + softplus(raw)` at interior knots
    /// (and at the boundary knots with [`Knots::free_ends`]), 1 at the boundary knots `0` and
    /// `K` otherwise (and for `k > K`).
    #[inline(always)]
    #[must_use]
    pub fn derivative(&self, k: usize) -> f32 {
        if k == 0 {
            self.derivative_lanes(0, 0)
        } else {
            self.derivative_lanes(k - 1, 1)
        }
    }

    /// The spline `y = RQ(x)` (paper Eq. 4) and `ln |dy/dx|`.
    ///
    /// Identity with log-det 0 outside `[−B, B]`; see the module docs for non-finite `x`
    /// (NaN → `(−f32::MAX, 0)`, `±∞` → `(±f32::MAX, 0)`).
    #[inline]
    #[must_use]
    pub fn forward(&self, x: f32) -> (f32, f32) {
        self.forward_lanes(x)
    }

    /// The inverse spline `x = RQ⁻¹(y)` and `ln |dx/dy|` (= −`ln |dy/dx|` at `x`).
    ///
    /// Identity with log-det 0 outside `[−B, B]`; `y = +B` is handled by the last bin;
    /// non-finite `y` as in [`Knots::forward`].
    #[inline]
    #[must_use]
    pub fn inverse(&self, y: f32) -> (f32, f32) {
        self.inverse_with::<true>(y)
    }

    /// [`Knots::inverse`] without the log-derivative (its `ln`), for callers that drop it.
    #[inline(always)]
    pub(crate) fn inverse_point(&self, y: f32) -> f32 {
        self.inverse_with::<false>(y).0
    }
}

#[cfg(not(target_arch = "spirv"))]
impl<const K: usize, const N: usize> Knots<K, crate::wavefront::lanes::Lanes<N>> {
    /// All-zero knots of `N` lanes, for buffers that are filled before use.
    pub(crate) const ZERO_LANES: Self = {
        let z = crate::wavefront::lanes::Lanes::splat(0.0);
        Knots {
            x: [z; K],
            y: [z; K],
            raw_d: [z; K],
            raw_d_last: z,
            free_ends: false,
            bound: 0.0,
        }
    };
}

// The generic methods are crate-internal (users only see `L = f32`).
#[allow(private_bounds)]
impl<const K: usize, L: Lane> Knots<K, L> {
    /// Placeholder knots (all zero) for buffers that are filled before use.
    #[inline(always)]
    pub(crate) fn zeroed() -> Self {
        let z = [L::splat(0.0); K];
        Knots {
            x: z,
            y: z,
            raw_d: z,
            raw_d_last: L::splat(0.0),
            free_ends: false,
            bound: 1.0,
        }
    }

    /// [`Knots::from_raw`] for every lane.
    #[inline(always)]
    pub(crate) fn from_raw_lanes<const N: usize>(raw: &[L; N], bound: f32) -> Self {
        let mut k = Self::zeroed();
        k.set_raw_lanes(raw, bound);
        k
    }

    /// [`Knots::from_raw_lanes`] written in place (no copy of the knots).
    #[inline(always)]
    pub(crate) fn set_raw_lanes<const N: usize>(&mut self, raw: &[L; N], bound: f32) {
        const {
            assert!(
                K >= 1 && N == 3 * K - 1,
                "raw spline parameters must be 3K − 1 values"
            );
        }
        let bound = math::clamp(bound, MIN_TAIL_BOUND, MAX_TAIL_BOUND);
        cumulative_knots::<L, K, N>(raw, bound, &mut self.x, &mut self.y);
        self.raw_d[0] = L::splat(0.0);
        let mut k = 1;
        while k < K {
            self.raw_d[k] = sanitize_raw(raw[2 * K + k - 1]);
            k += 1;
        }
        self.raw_d_last = L::splat(0.0);
        self.free_ends = false;
        self.bound = bound;
    }

    /// [`Knots::from_raw_free`] for every lane.
    #[inline(always)]
    pub(crate) fn from_raw_free_lanes<const N: usize>(raw: &[L; N]) -> Self {
        let mut k = Self::zeroed();
        k.set_raw_free_lanes(raw);
        k
    }

    /// [`Knots::from_raw_free_lanes`] written in place (no copy of the knots).
    #[inline(always)]
    pub(crate) fn set_raw_free_lanes<const N: usize>(&mut self, raw: &[L; N]) {
        const {
            assert!(
                K >= 1 && N == 3 * K + 1,
                "raw spline parameters with free ends must be 3K + 1 values"
            );
        }
        cumulative_knots::<L, K, N>(raw, 1.0, &mut self.x, &mut self.y);
        let mut k = 0;
        while k < K {
            self.raw_d[k] = sanitize_raw(raw[2 * K + k]);
            k += 1;
        }
        self.raw_d_last = sanitize_raw(raw[3 * K]);
        self.free_ends = true;
        self.bound = 1.0;
    }

    /// The derivative at knot `k + plus` of every lane (its bin `k`): 1 at the boundary
    /// knots, `MIN_DERIVATIVE + softplus(raw_d)` inside. `math::softplus` is `ln_1p(exp)`
    /// for arguments ≤ 20; below −87 it differs from `ln_1p(exp_in_range)` by far less than
    /// an ulp of `MIN_DERIVATIVE`, so the sum is the same.
    ///
    /// With free ends, knot 0 reads `raw_d[0]` like an interior knot and knot `K` (only
    /// reached as `k = K − 1`, `plus = 1`) reads `raw_d_last`.
    #[inline(always)]
    fn derivative_lanes(&self, k: L::Index, plus: usize) -> L {
        let min = L::splat(MIN_DERIVATIVE);
        let d = min + L::gather(&self.raw_d, k, plus, 0.0).softplus();
        if !self.free_ends {
            return L::select(L::interior::<K>(k, plus), d, L::splat(1.0));
        }
        if plus == 0 {
            d
        } else {
            L::select(
                L::interior::<K>(k, plus),
                d,
                min + self.raw_d_last.softplus(),
            )
        }
    }

    /// The bin whose left knot in `knots` is the last one `≤ v` (0 when `v` is below every
    /// interior knot). Fixed-count scan: the result is always in `0..K`.
    #[inline(always)]
    fn bin(knots: &[L; K], v: L) -> L::Index {
        let mut bin = L::index(0);
        let mut k = 1;
        while k < K {
            bin = L::select_index(v.ge(knots[k]), k, bin);
            k += 1;
        }
        bin
    }

    /// `(x_k, x_{k+1}, y_k, y_{k+1}, d_k, d_{k+1})` of bin `k < K`.
    #[inline(always)]
    fn bin_params(&self, k: L::Index) -> (L, L, L, L, L, L) {
        let b = self.bound;
        let x0 = L::gather(&self.x, k, 0, b);
        let x1 = L::gather(&self.x, k, 1, b);
        let y0 = L::gather(&self.y, k, 0, b);
        let y1 = L::gather(&self.y, k, 1, b);
        (
            x0,
            x1,
            y0,
            y1,
            self.derivative_lanes(k, 0),
            self.derivative_lanes(k, 1),
        )
    }

    /// `ln(dy/dx)` inside a bin at `ξ`, with `s = h/w` and the bin's end derivatives.
    #[inline(always)]
    fn log_derivative(xi: L, s: L, d0: L, d1: L) -> L {
        let one = L::splat(1.0);
        let two = L::splat(2.0);
        let t = xi * (one - xi);
        let om = one - xi;
        let den = s + (d1 + d0 - two * s) * t;
        let num = s * s * (d1 * xi * xi + two * s * t + d0 * om * om);
        (num / (den * den)).ln()
    }

    /// `x` clamped to `[−f32::MAX, f32::MAX]` (NaN → `−f32::MAX`) and whether it lies in
    /// `[−B, B]` (outside, the spline is the identity with log-det 0).
    #[inline(always)]
    fn in_bounds(&self, x: L) -> (L, L::Mask) {
        let x = x.clamp(-f32::MAX, f32::MAX);
        let b = L::splat(self.bound);
        (x, L::and(x.ge(-b), x.le(b)))
    }

    /// [`Knots::forward`] for every lane.
    #[inline(always)]
    pub(crate) fn forward_lanes(&self, x: L) -> (L, L) {
        let (y, ld, _, _) = self.forward_margins_lanes(x);
        (y, ld)
    }

    /// [`Knots::forward_lanes`] with the distances of `y` to both ends, `y + B` and `B − y`,
    /// computed from the nearer knot so that they keep their relative precision where `y` is
    /// within rounding of an end (where `1 ± y` itself would cancel). Inside `[−B, B]` only;
    /// outside they are those of the identity.
    #[inline(always)]
    pub(crate) fn forward_margins_lanes(&self, x: L) -> (L, L, L, L) {
        let (x, inside) = self.in_bounds(x);
        let (one, two, half) = (L::splat(1.0), L::splat(2.0), L::splat(0.5));
        let k = Self::bin(&self.x, x);
        let (x0, x1, y0, y1, d0, d1) = self.bin_params(k);
        let (w, h) = (x1 - x0, y1 - y0);
        let s = h / w;
        let xi = ((x - x0) / w).clamp(0.0, 1.0);
        let t = xi * (one - xi);
        let den = s + (d1 + d0 - two * s) * t;
        // Eq. 4 measured from the nearer knot, so that both knots are hit exactly:
        //   y − y_k     = h (s ξ² + d_k ξ(1−ξ)) / den,
        //   y_{k+1} − y = h (s (1−ξ)² + d_{k+1} ξ(1−ξ)) / den.
        let om = one - xi;
        let (dl, dr) = (
            h * (s * xi * xi + d0 * t) / den,
            h * (s * om * om + d1 * t) / den,
        );
        let left = xi.le(half);
        let y = L::select(left, y0 + dl, y1 - dr).clamp_to(y0, y1);
        let ld = Self::log_derivative(xi, s, d0, d1);
        // y0 + B is exactly 0 in the first bin, B − y1 exactly 0 in the last.
        let b = L::splat(self.bound);
        let lo = L::select(left, (y0 + b) + dl, (y1 + b) - dr);
        let hi = L::select(left, (b - y0) - dl, (b - y1) + dr);
        (
            L::select(inside, y, x),
            L::select(inside, ld, L::splat(0.0)),
            L::select(inside, lo, x + b),
            L::select(inside, hi, b - x),
        )
    }

    /// [`Knots::inverse`] for every lane; the log-derivative only when `LOG_DET` (0
    /// otherwise).
    #[inline(always)]
    pub(crate) fn inverse_with<const LOG_DET: bool>(&self, y: L) -> (L, L) {
        let (y, inside) = self.in_bounds(y);
        let (zero, one, two, four) = (L::splat(0.0), L::splat(1.0), L::splat(2.0), L::splat(4.0));
        let k = Self::bin(&self.y, y);
        let (x0, x1, y0, y1, d0, d1) = self.bin_params(k);
        let (w, h) = (x1 - x0, y1 - y0);
        let s = h / w;
        let e = d1 + d0 - two * s;
        // Solve from the nearer knot (the mirrored spline swaps d_k and d_{k+1}): the
        // knots are hit exactly and the root keeps its relative precision.
        let lower = (y - y0).le(y1 - y);
        let dy = L::select(lower, y - y0, y1 - y);
        let da = L::select(lower, d0, d1);
        let a = h * (s - da) + dy * e;
        let b = h * da - dy * e;
        let c = -s * dy;
        let root = (b * b - four * a * c).safe_sqrt();
        // The root 2c / (−b − √(b² − 4ac)) of a ξ² + b ξ + c = 0 (nflows). It cancels
        // catastrophically when b < 0 (steep bins); there the same root is written
        // (−b + √(b² − 4ac)) / 2a, a sum of positive terms. A zero denominator or rounding
        // outside [0, 1] is clamped (NaN → 0).
        let eta = L::select(b.ge(zero), two * c / (-b - root), (root - b) / (two * a));
        let eta = eta.clamp(0.0, 1.0);
        let x = L::select(lower, x0 + eta * w, x1 - eta * w);
        let xi = L::select(lower, eta, one - eta);
        let log_det = if LOG_DET {
            -Self::log_derivative(xi, s, d0, d1)
        } else {
            zero
        };
        (
            L::select(inside, x.clamp_to(x0, x1), y),
            L::select(inside, log_det, zero),
        )
    }
}
