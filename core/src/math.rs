//! The only module that calls transcendental functions.
//!
//! Everything goes through `libm`, which compiles for every target this crate supports
//! (x86-64, thumbv7em, wasm32 and SPIR-V through rust-gpu). Only functions that rust-gpu
//! accepts are used: no `erf`, `hypot`, `lgamma`, `tgamma`, `scalbn` or `nextafter`.

/// π.
pub const PI: f32 = core::f32::consts::PI;
/// 1/π.
pub const INV_PI: f32 = core::f32::consts::FRAC_1_PI;
/// 2π.
pub const TWO_PI: f32 = 2.0 * core::f32::consts::PI;
/// 1/(2π).
pub const INV_TWO_PI: f32 = 0.5 * core::f32::consts::FRAC_1_PI;
/// ln(2π).
pub const LN_TWO_PI: f32 = 1.837_877_1;
/// The largest f32 below 1 (pbrt's `OneMinusEpsilon`): uniform variates are clamped to it.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// √x.
#[inline(always)]
#[must_use]
pub fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

/// √max(x, 0): never NaN for finite or infinite input (NaN stays NaN).
#[inline(always)]
#[must_use]
pub fn safe_sqrt(x: f32) -> f32 {
    libm::sqrtf(if x > 0.0 { x } else { 0.0 })
}

/// eˣ.
#[inline(always)]
#[must_use]
pub fn exp(x: f32) -> f32 {
    libm::expf(x)
}

/// Whether [`exp_in_range`] and `exp_nonpositive` use their branch-free arithmetic: where
/// loops of them vectorise (SIMD targets) and on GPUs (no call); elsewhere (thumbv7em,
/// plain wasm32) libm's `expf` itself, which gives the same numbers in less code.
const BRANCH_FREE_EXP: bool = cfg!(any(
    target_feature = "sse2",
    target_feature = "neon",
    target_feature = "simd128",
    target_arch = "spirv"
));

// libm's `expf` constants (FreeBSD e_expf.c), by their bits.
const LN2_HI: f32 = f32::from_bits(0x3f31_7200);
const LN2_LO: f32 = f32::from_bits(0x35bf_be8e);
const INV_LN2: f32 = f32::from_bits(0x3fb8_aa3b);
const P1: f32 = f32::from_bits(0x3e2a_aa8f);
const P2: f32 = f32::from_bits(0xbb35_5215);
/// Adding 1.5·2²³ rounds `|v| < 2²²` to an integer held in the low mantissa bits.
const SHIFT: f32 = 12_582_912.0;

/// Lower clamp of [`exp_in_range`]'s argument (e⁻⁸⁷ ≈ 1.6·10⁻³⁸: the result stays a
/// normal f32).
pub const EXP_IN_RANGE_MIN: f32 = -87.0;
/// Upper clamp of [`exp_in_range`]'s argument (e⁸⁸ ≈ 1.7·10³⁸).
pub const EXP_IN_RANGE_MAX: f32 = 88.0;

/// eˣ for `x ∈ [EXP_IN_RANGE_MIN, EXP_IN_RANGE_MAX]`, **bit for bit** libm's `expf` (the
/// FreeBSD algorithm: `x = k·ln 2 + r`, a rational approximation of `eʳ`, scaling by `2ᵏ`)
/// written without branches or float → int conversions, so that a loop of them vectorises
/// (libm's special-case branches and the call keep [`exp`] scalar). Checked against libm for
/// every f32 of the range. On targets without SIMD registers it simply calls libm (same
/// numbers, less code). Arguments outside the range are clamped into it (NaN → the lower
/// end), so the result is always finite and positive.
#[inline(always)]
#[must_use]
pub fn exp_in_range(x: f32) -> f32 {
    let x = clamp(x, EXP_IN_RANGE_MIN, EXP_IN_RANGE_MAX);
    if !BRANCH_FREE_EXP {
        return exp(x);
    }
    let neg = x < 0.0;
    let ax = if neg { -x } else { x };
    // k as libm computes it: trunc(x/ln 2 ± 1/2) for |x| > 1.5 ln 2, ±1 for
    // 0.5 ln 2 < |x| ≤ 1.5 ln 2, else 0. Truncation = rounding corrected toward zero.
    let v = INV_LN2 * x + if neg { -0.5 } else { 0.5 };
    let r = (v + SHIFT) - SHIFT;
    let t = if neg {
        if r < v {
            r + 1.0
        } else {
            r
        }
    } else if r > v {
        r - 1.0
    } else {
        r
    };
    let kf = if ax > f32::from_bits(0x3f85_1592) {
        t
    } else if ax > f32::from_bits(0x3eb1_7218) {
        if neg {
            -1.0
        } else {
            1.0
        }
    } else {
        0.0
    };
    exp_reduced(x, ax, kf)
}

/// The branch-free exps' common tail: given `x`, `|x|` and libm's `k` (as a float), the
/// reduction `x = k·ln 2 + r`, libm's rational approximation of `eʳ` and the scaling by `2ᵏ`,
/// operation for operation as libm's `expf`.
#[inline(always)]
fn exp_reduced(x: f32, ax: f32, kf: f32) -> f32 {
    // Reduction (k·LN2_HI is exact) and libm's approximation.
    let hi = x - kf * LN2_HI;
    let lo = kf * LN2_LO;
    let xr = hi - lo;
    let xx = xr * xr;
    let c = xr - xx * (P1 + xx * P2);
    let y = 1.0 + (xr * c / (2.0 - c) - lo + hi);
    // |x| ≤ 2⁻¹⁴: libm returns 1 + x.
    let y = if ax > f32::from_bits(0x3900_0000) {
        y
    } else {
        1.0 + x
    };
    // 2ᵏ (k ∈ [−126, 127] here, a normal number): the bits of k + 1.5·2²³ are 0x4B40_0000 + k.
    let two_k = f32::from_bits((kf + SHIFT).to_bits().wrapping_sub(0x4B40_0000 - 127) << 23);
    y * two_k
}

/// ln x.
#[inline(always)]
#[must_use]
pub fn ln(x: f32) -> f32 {
    libm::logf(x)
}

/// ln(1 + x).
#[inline(always)]
#[must_use]
pub fn ln_1p(x: f32) -> f32 {
    libm::log1pf(x)
}

/// (sin x, cos x).
#[inline(always)]
#[must_use]
pub fn sin_cos(x: f32) -> (f32, f32) {
    libm::sincosf(x)
}

/// atan2(y, x) in (−π, π].
#[inline(always)]
#[must_use]
pub fn atan2(y: f32, x: f32) -> f32 {
    libm::atan2f(y, x)
}

/// tanh x.
#[inline(always)]
#[must_use]
pub fn tanh(x: f32) -> f32 {
    libm::tanhf(x)
}

/// |x|.
#[inline(always)]
#[must_use]
pub fn abs(x: f32) -> f32 {
    libm::fabsf(x)
}

/// ⌊x⌋.
#[inline(always)]
#[must_use]
pub fn floor(x: f32) -> f32 {
    libm::floorf(x)
}

/// Softplus ln(1 + eˣ), computed without overflow for large x.
#[inline(always)]
#[must_use]
pub fn softplus(x: f32) -> f32 {
    if x > 20.0 {
        x
    } else {
        ln_1p(exp(x))
    }
}

/// Logistic sigmoid 1/(1 + e⁻ˣ), computed without overflow.
#[inline(always)]
#[must_use]
pub fn sigmoid(x: f32) -> f32 {
    if x >= 0.0 {
        1.0 / (1.0 + exp(-x))
    } else {
        let e = exp(x);
        e / (1.0 + e)
    }
}

/// [`exp_in_range`] for `x ∈ [EXP_IN_RANGE_MIN, 0]` only (bit for bit libm's `expf` there),
/// with the work for positive arguments and the clamp left out. Other arguments give
/// meaningless (but panic-free) results: callers select them away, as
/// [`crate::gaussian::softmax`] does for inputs far below the maximum.
#[inline(always)]
#[must_use]
pub(crate) fn exp_nonpositive(x: f32) -> f32 {
    if !BRANCH_FREE_EXP {
        return exp(x);
    }
    let ax = -x;
    // libm's k for x < 0: trunc(x/ln 2 − 1/2) (rounding corrected toward zero) beyond
    // 1.5 ln 2, −1 beyond 0.5 ln 2, else 0.
    let v = INV_LN2 * x - 0.5;
    let r = (v + SHIFT) - SHIFT;
    let t = if r < v { r + 1.0 } else { r };
    let kf = if ax > f32::from_bits(0x3f85_1592) {
        t
    } else if ax > f32::from_bits(0x3eb1_7218) {
        -1.0
    } else {
        0.0
    };
    exp_reduced(x, ax, kf)
}

/// [`sigmoid`] through [`exp_in_range`]: bit for bit [`sigmoid`] for `x ≥ EXP_IN_RANGE_MIN`
/// (and for every `x ≥ 0`), branch-free so that a loop of them vectorises. Below the range
/// (and for NaN) it returns `sigmoid(EXP_IN_RANGE_MIN)`-like tiny values instead of libm's
/// subnormals: callers that need those fall back to [`sigmoid`] there.
#[inline(always)]
#[must_use]
pub fn sigmoid_in_range(x: f32) -> f32 {
    // e^(−|x|): for x > 88 libm's e^(−x) is below 2⁻¹²⁶ and 1/(1 + e) rounds to 1 either way.
    let pos = x >= 0.0;
    let e = exp_in_range(if pos { -x } else { x });
    if pos {
        1.0 / (1.0 + e)
    } else {
        e / (1.0 + e)
    }
}

/// `x` clamped to `[lo, hi]`; NaN maps to `lo`.
#[inline(always)]
#[must_use]
pub fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    // Written so that NaN fails the first comparison and ends at `lo`.
    if x >= lo {
        if x <= hi {
            x
        } else {
            hi
        }
    } else {
        lo
    }
}

/// `true` when `x` is neither NaN nor ±∞.
#[inline(always)]
#[must_use]
pub fn is_finite(x: f32) -> bool {
    // NaN fails the comparison. rust-gpu: written with `fabs` so shaders need no bit casts.
    libm::fabsf(x) < f32::INFINITY
}

/// A uniform variate checked and made safe: values in `[0, 1)` pass unchanged, exactly 1 becomes
/// [`ONE_MINUS_EPSILON`] (pbrt's convention), and anything else (NaN, negative, > 1, ±∞) is
/// refused with `None`.
#[inline(always)]
#[must_use]
pub fn sanitize_u(u: f32) -> Option<f32> {
    if u >= 0.0 && u <= 1.0 {
        Some(if u < ONE_MINUS_EPSILON {
            u
        } else {
            ONE_MINUS_EPSILON
        })
    } else {
        None
    }
}

/// Checks both components of `u` with [`sanitize_u`].
#[inline(always)]
#[must_use]
pub fn sanitize_u2(u: glam::Vec2) -> Option<glam::Vec2> {
    Some(glam::Vec2::new(sanitize_u(u.x)?, sanitize_u(u.y)?))
}

/// Makes a density safe to return: non-finite or negative values become 0.
#[inline(always)]
#[must_use]
pub fn finite_density(p: f32) -> f32 {
    if p >= 0.0 && is_finite(p) {
        p
    } else {
        0.0
    }
}

/// Bound applied to logits before a softmax (NaN → −bound), so that an infinite or NaN
/// logit cannot turn the weights into NaN.
pub const LOGIT_BOUND: f32 = 1.0e30;

/// A logit clamped to ±[`LOGIT_BOUND`] (NaN → −bound).
#[inline(always)]
#[must_use]
pub fn clamp_logit(x: f32) -> f32 {
    clamp(x, -LOGIT_BOUND, LOGIT_BOUND)
}

/// Clamp a float to an index in `[0, n − 1]` (NaN → 0). `n` must be ≥ 1.
#[inline(always)]
#[must_use]
pub fn clamp_index(x: f32, n: u32) -> u32 {
    let hi = (n - 1) as f32;
    clamp(x, 0.0, hi) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every `step`-th f32 in `[lo, hi]`, and both ends.
    fn sweep(lo: f32, hi: f32, step: u32, mut f: impl FnMut(f32)) {
        let mut bits = 0u32;
        loop {
            let x = f32::from_bits(bits);
            if x >= lo && x <= hi {
                f(x);
            }
            match bits.checked_add(step) {
                Some(b) => bits = b,
                None => break,
            }
        }
        f(lo);
        f(hi);
        f(0.0);
        f(-0.0);
    }

    #[test]
    fn exp_in_range_is_libm_expf() {
        sweep(EXP_IN_RANGE_MIN, EXP_IN_RANGE_MAX, 211, |x| {
            assert_eq!(exp_in_range(x).to_bits(), exp(x).to_bits(), "x = {x:e}");
        });
        // Clamped outside, never NaN.
        assert_eq!(exp_in_range(-1e9), exp(EXP_IN_RANGE_MIN));
        assert_eq!(exp_in_range(1e9), exp(EXP_IN_RANGE_MAX));
        assert_eq!(exp_in_range(f32::NAN), exp(EXP_IN_RANGE_MIN));
    }

    #[test]
    fn exp_nonpositive_is_libm_expf() {
        sweep(EXP_IN_RANGE_MIN, 0.0, 101, |x| {
            assert_eq!(exp_nonpositive(x).to_bits(), exp(x).to_bits(), "x = {x:e}");
        });
    }

    #[test]
    fn sigmoid_in_range_is_sigmoid() {
        sweep(EXP_IN_RANGE_MIN, 1e30, 307, |x| {
            assert_eq!(
                sigmoid_in_range(x).to_bits(),
                sigmoid(x).to_bits(),
                "x = {x:e}"
            );
        });
    }
}
