//! Gaussians on the plane and mixture-component selection, shared by the lobe mixtures
//! (paper Eq. 1–2) and the flows' base distributions (Eq. 3).

use glam::Vec2;

use crate::math;
use crate::math::lane::Lane;

/// Lower clamp of every predicted `log σ` (σ ≥ e⁻⁷ ≈ 9·10⁻⁴).
pub const LOG_SIGMA_MIN: f32 = -7.0;
/// Upper clamp of every predicted `log σ` (σ ≤ e ≈ 2.7).
pub const LOG_SIGMA_MAX: f32 = 1.0;

/// σ from a predicted `log σ`, clamped to `[LOG_SIGMA_MIN, LOG_SIGMA_MAX]` (NaN → min).
#[inline(always)]
#[must_use]
pub fn sigma_from_log(log_sigma: f32) -> f32 {
    math::exp(math::clamp(log_sigma, LOG_SIGMA_MIN, LOG_SIGMA_MAX))
}

/// A standard normal pair from `u ∈ [0, 1)²` (Box–Muller): `r = √(−2 ln(1 − u0))`,
/// `θ = 2π u1`. Finite for every `u` in `[0, 1)²`.
#[inline]
#[must_use]
pub fn box_muller(u: Vec2) -> Vec2 {
    let r = math::safe_sqrt(-2.0 * math::ln_1p(-u.x));
    let (s, c) = math::sin_cos(math::TWO_PI * u.y);
    Vec2::new(r * c, r * s)
}

/// Inverse of [`box_muller`]: the `u ∈ [0, 1)²` that maps to the standard normal pair `n`.
#[inline]
#[must_use]
pub fn invert_box_muller(n: Vec2) -> Vec2 {
    let r2 = n.x * n.x + n.y * n.y;
    // u0 = 1 − exp(−r²/2), written with expm1 semantics to keep precision near 0.
    let u0 = -libm::expm1f(-0.5 * r2);
    let mut u1 = math::atan2(n.y, n.x) * math::INV_TWO_PI;
    if u1 < 0.0 {
        u1 += 1.0;
    }
    Vec2::new(
        math::clamp(u0, 0.0, math::ONE_MINUS_EPSILON),
        math::clamp(u1, 0.0, math::ONE_MINUS_EPSILON),
    )
}

/// Density of the axis-aligned normal `N(μ, diag σ²)` at `p` (area measure on the plane).
#[inline]
#[must_use]
pub fn normal_pdf(p: Vec2, mu: Vec2, sigma: Vec2) -> f32 {
    let dx = (p.x - mu.x) / sigma.x;
    let dy = (p.y - mu.y) / sigma.y;
    math::exp(-0.5 * (dx * dx + dy * dy)) * (math::INV_TWO_PI / (sigma.x * sigma.y))
}

/// ln of [`normal_pdf`].
#[inline]
#[must_use]
pub fn log_normal_pdf(p: Vec2, mu: Vec2, sigma: Vec2) -> f32 {
    let dx = (p.x - mu.x) / sigma.x;
    let dy = (p.y - mu.y) / sigma.y;
    -0.5 * (dx * dx + dy * dy) - math::LN_TWO_PI - math::ln(sigma.x * sigma.y)
}

/// Magnitude to which [`softmax`] clamps its inputs (so that ±∞ cannot produce ∞ − ∞).
pub const SOFTMAX_INPUT_BOUND: f32 = 1e30;

/// `softmax(x)` in place, stable for large inputs. Inputs are clamped to
/// ±[`SOFTMAX_INPUT_BOUND`] and NaN counts as −bound; if nothing remains, weights are uniform.
///
/// Inputs more than 80 below the maximum get weight exactly 0. The exponentials are bit for
/// bit libm's `expf` but computed without branches (`math::exp_in_range`), so the loop
/// vectorises; the normalising sum runs in index order.
#[inline]
pub fn softmax<const N: usize>(x: &mut [f32; N]) {
    let m = clamp_and_max(x);
    exp_shifted(x, m);
    let mut sum = 0.0;
    let mut i = 0;
    while i < N {
        sum += x[i];
        i += 1;
    }
    normalize(x, sum);
}

/// Two [`softmax`]es, each bit for bit a call of [`softmax`], with their sequential sums
/// interleaved so that the two dependency chains overlap (the spline's widths and heights);
/// for one point (`L = f32`) or several lanes at once.
#[inline(always)]
pub(crate) fn softmax_pair_lanes<L: Lane, const N: usize>(a: &mut [L; N], b: &mut [L; N]) {
    let ma = clamp_and_max_lanes(a);
    let mb = clamp_and_max_lanes(b);
    let floor_a = ma - L::splat(80.0);
    let floor_b = mb - L::splat(80.0);
    let zero = L::splat(0.0);
    let mut i = 0;
    while i < N {
        // `exp_shifted`, per lane.
        a[i] = L::select(a[i].ge(floor_a), (a[i] - ma).exp_nonpositive(), zero);
        b[i] = L::select(b[i].ge(floor_b), (b[i] - mb).exp_nonpositive(), zero);
        i += 1;
    }
    let mut sa = zero;
    let mut sb = zero;
    i = 0;
    while i < N {
        sa = sa + a[i];
        sb = sb + b[i];
        i += 1;
    }
    // `normalize`, per lane.
    let uniform = L::splat(1.0 / N as f32);
    let (pos_a, pos_b) = (sa.gt(zero), sb.gt(zero));
    i = 0;
    while i < N {
        a[i] = L::select(pos_a, a[i] / sa, uniform);
        b[i] = L::select(pos_b, b[i] / sb, uniform);
        i += 1;
    }
}

/// [`softmax`] over lanes (the batched path's: within the error bound of their
/// `exp_nonpositive`, bit for bit [`softmax`] for `L = f32`).
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
pub(crate) fn softmax_lanes<L: Lane, const N: usize>(x: &mut [L; N]) {
    let m = clamp_and_max_lanes(x);
    let floor = m - L::splat(80.0);
    let zero = L::splat(0.0);
    let mut i = 0;
    while i < N {
        x[i] = L::select(x[i].ge(floor), (x[i] - m).exp_nonpositive(), zero);
        i += 1;
    }
    let mut sum = zero;
    i = 0;
    while i < N {
        sum = sum + x[i];
        i += 1;
    }
    let uniform = L::splat(1.0 / N as f32);
    let pos = sum.gt(zero);
    i = 0;
    while i < N {
        x[i] = L::select(pos, x[i] / sum, uniform);
        i += 1;
    }
}

/// [`clamp_and_max`] for one point or several lanes.
#[inline(always)]
fn clamp_and_max_lanes<L: Lane, const N: usize>(x: &mut [L; N]) -> L {
    let mut lanes = [L::splat(f32::NEG_INFINITY); 4];
    let mut i = 0;
    while i + 4 <= N {
        let mut l = 0;
        while l < 4 {
            let v = x[i + l].clamp(-SOFTMAX_INPUT_BOUND, SOFTMAX_INPUT_BOUND);
            x[i + l] = v;
            lanes[l] = L::select(v.gt(lanes[l]), v, lanes[l]);
            l += 1;
        }
        i += 4;
    }
    while i < N {
        let v = x[i].clamp(-SOFTMAX_INPUT_BOUND, SOFTMAX_INPUT_BOUND);
        x[i] = v;
        lanes[0] = L::select(v.gt(lanes[0]), v, lanes[0]);
        i += 1;
    }
    let m01 = L::select(lanes[1].gt(lanes[0]), lanes[1], lanes[0]);
    let m23 = L::select(lanes[3].gt(lanes[2]), lanes[3], lanes[2]);
    L::select(m23.gt(m01), m23, m01)
}

/// [`softmax`]'s first step: clamps every input to ±[`SOFTMAX_INPUT_BOUND`] (NaN → −bound)
/// and returns the maximum, found in 4 interleaved lanes (exact in any order: no NaN is
/// left, and ±0 give the same differences in [`exp_shifted`]).
#[inline(always)]
fn clamp_and_max<const N: usize>(x: &mut [f32; N]) -> f32 {
    let mut lanes = [f32::NEG_INFINITY; 4];
    let mut i = 0;
    while i + 4 <= N {
        let mut l = 0;
        while l < 4 {
            let v = math::clamp(x[i + l], -SOFTMAX_INPUT_BOUND, SOFTMAX_INPUT_BOUND);
            x[i + l] = v;
            lanes[l] = if v > lanes[l] { v } else { lanes[l] };
            l += 1;
        }
        i += 4;
    }
    while i < N {
        let v = math::clamp(x[i], -SOFTMAX_INPUT_BOUND, SOFTMAX_INPUT_BOUND);
        x[i] = v;
        lanes[0] = if v > lanes[0] { v } else { lanes[0] };
        i += 1;
    }
    let m01 = if lanes[1] > lanes[0] {
        lanes[1]
    } else {
        lanes[0]
    };
    let m23 = if lanes[3] > lanes[2] {
        lanes[3]
    } else {
        lanes[2]
    };
    if m23 > m01 {
        m23
    } else {
        m01
    }
}

/// `x ← e^(x − m)`, 0 for inputs more than 80 below the maximum `m`.
#[inline(always)]
fn exp_shifted<const N: usize>(x: &mut [f32; N], m: f32) {
    // x − m ≤ 0, and ≥ −80 for the kept inputs: where exp_nonpositive is libm's expf.
    let floor = m - 80.0;
    let mut i = 0;
    while i < N {
        let e = math::exp_nonpositive(x[i] - m);
        x[i] = if x[i] >= floor { e } else { 0.0 };
        i += 1;
    }
}

/// `x ← x / sum`, or uniform when the sum is not positive.
#[inline(always)]
fn normalize<const N: usize>(x: &mut [f32; N], sum: f32) {
    let mut i = 0;
    while i < N {
        x[i] = if sum > 0.0 {
            x[i] / sum
        } else {
            1.0 / N as f32
        };
        i += 1;
    }
}

/// Chooses a mixture component from weights `w` (summing to 1) with `u ∈ [0, 1)`, pbrt
/// style: the first component whose running sum exceeds `u`. Returns the index and `u`
/// remapped to `[0, 1)` within that component. Zero-weight components are never chosen.
#[inline]
#[must_use]
pub fn select_component<const N: usize>(w: &[f32; N], u: f32) -> (usize, f32) {
    let mut lo = 0.0;
    let mut i = 0;
    let mut last = 0;
    while i < N {
        if w[i] > 0.0 {
            last = i;
            let hi = lo + w[i];
            if u < hi {
                let r = (u - lo) / w[i];
                return (i, math::clamp(r, 0.0, math::ONE_MINUS_EPSILON));
            }
            lo = hi;
        }
        i += 1;
    }
    // Rounding left u above the last running sum: take the last non-zero component.
    (last, math::ONE_MINUS_EPSILON)
}
