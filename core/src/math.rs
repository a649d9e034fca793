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

/// sin x.
#[inline(always)]
#[must_use]
pub fn sin(x: f32) -> f32 {
    libm::sinf(x)
}

/// cos x.
#[inline(always)]
#[must_use]
pub fn cos(x: f32) -> f32 {
    libm::cosf(x)
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
    // NaN fails the comparison; written with `fabs` so shader targets need no bit casts.
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

/// Clamp a float to an index in `[0, n − 1]` (NaN → 0). `n` must be ≥ 1.
#[inline(always)]
#[must_use]
pub fn clamp_index(x: f32, n: u32) -> u32 {
    let hi = (n - 1) as f32;
    clamp(x, 0.0, hi) as u32
}
