//! Gaussians on the plane and mixture-component selection, shared by the lobe mixtures
//! (paper Eq. 1–2) and the flows' base distributions (Eq. 3).

use glam::Vec2;

use crate::math;

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
#[inline]
pub fn softmax<const N: usize>(x: &mut [f32; N]) {
    let mut m = f32::NEG_INFINITY;
    let mut i = 0;
    while i < N {
        x[i] = math::clamp(x[i], -SOFTMAX_INPUT_BOUND, SOFTMAX_INPUT_BOUND);
        i += 1;
    }
    i = 0;
    while i < N {
        if x[i] > m {
            m = x[i];
        }
        i += 1;
    }
    let mut sum = 0.0;
    i = 0;
    while i < N {
        // NaN compares false: treat it as −∞ (weight 0).
        let e = if x[i] >= m - 80.0 {
            math::exp(x[i] - m)
        } else {
            0.0
        };
        x[i] = e;
        sum += e;
        i += 1;
    }
    i = 0;
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
