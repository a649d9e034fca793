//! The only module that calls transcendental functions.
//!
//! Everything is `libm`'s single-precision functions (FreeBSD msun), which compile for every
//! target this crate supports (x86-64, aarch64, thumbv7em, wasm32 and SPIR-V through
//! rust-gpu). Only functions that rust-gpu accepts are used: no `erf`, `hypot`, `lgamma`,
//! `tgamma`, `scalbn` or `nextafter`.
//!
//! On SIMD CPU targets ([`BRANCH_FREE`]; not SPIR-V, where the compiler maps libm's calls to
//! GLSL.std.450 instructions) the hot path's functions (`exp`, `ln`, `ln_1p`, `sin_cos`,
//! `tanh`, `atan2`, `floor` and those built on them) run [`branch_free`] rewrites that give
//! libm's results bit for bit without branches or calls, so that a loop of them over lanes
//! vectorises and a batched path gives exactly the scalar path's numbers. Elsewhere they call
//! libm: the same numbers in less code. The measured material's angles ([`poly`]) are Cephes'
//! polynomials in f32 on every target, as Dr.Jit computes Mitsuba's.

// The batched path's fast approximations (not on GPUs, which have no batched path).
#[cfg(not(target_arch = "spirv"))]
pub(crate) mod approx;
mod branch_free;
pub(crate) mod lane;
pub(crate) mod poly;

pub use branch_free::SIN_COS_FAST_MAX;

/// π.
pub const PI: f32 = core::f32::consts::PI;
/// 1/π.
pub const INV_PI: f32 = core::f32::consts::FRAC_1_PI;
/// 2π.
pub const TWO_PI: f32 = 2.0 * core::f32::consts::PI;
/// 1/(2π).
pub const INV_TWO_PI: f32 = 0.5 * core::f32::consts::FRAC_1_PI;
/// ln(π).
pub const LN_PI: f32 = 1.144_729_9;
/// ln(2π).
pub const LN_TWO_PI: f32 = 1.837_877_1;
/// The largest f32 below 1 (pbrt's `OneMinusEpsilon`): uniform variates are clamped to it.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// √x, correctly rounded (IEEE 754). With `std`, `f32::sqrt`: an LLVM intrinsic, so loops of
/// it vectorise. Without, libm's `sqrtf`, the same numbers (on x86-64 an opaque `sqrtss`, which
/// keeps loops scalar).
#[inline(always)]
#[must_use]
pub fn sqrt(x: f32) -> f32 {
    #[cfg(feature = "std")]
    {
        x.sqrt()
    }
    #[cfg(not(feature = "std"))]
    {
        libm::sqrtf(x)
    }
}

/// √max(x, 0): never NaN for finite or infinite input (NaN stays NaN).
#[inline(always)]
#[must_use]
pub fn safe_sqrt(x: f32) -> f32 {
    sqrt(if x > 0.0 { x } else { 0.0 })
}

/// Whether the functions below use [`branch_free`]'s arithmetic: where loops of them
/// vectorise (SIMD targets); elsewhere (thumbv7em, plain wasm32) libm itself, which gives the
/// same numbers in less code.
// rust-gpu: never on SPIR-V. The compiler turns these libm calls into GLSL.std.450
// instructions, and `sin_cos_fast`'s f64 kernels would need the Float64 capability.
const BRANCH_FREE: bool = cfg!(all(
    any(
        target_feature = "sse2",
        target_feature = "neon",
        target_feature = "simd128"
    ),
    not(target_arch = "spirv")
));

/// `fn $name(x: f32) -> f32` (inlined, `#[must_use]`): [`branch_free`]'s `$name` where
/// [`BRANCH_FREE`], else libm's `$libm`.
macro_rules! libm_or_branch_free {
    ($(#[$attr:meta])* $vis:vis fn $name:ident => $libm:ident) => {
        $(#[$attr])*
        #[inline(always)]
        #[must_use]
        $vis fn $name(x: f32) -> f32 {
            if BRANCH_FREE {
                branch_free::$name(x)
            } else {
                libm::$libm(x)
            }
        }
    };
}

libm_or_branch_free! {
    /// eˣ: libm's `expf`, branch-free where [`BRANCH_FREE`].
    pub fn exp => expf
}

/// Lower clamp of [`exp_in_range`]'s argument (e⁻⁸⁷ ≈ 1.6·10⁻³⁸: the result stays a
/// normal f32).
pub const EXP_IN_RANGE_MIN: f32 = -87.0;
/// Upper clamp of [`exp_in_range`]'s argument (e⁸⁸ ≈ 1.7·10³⁸).
pub const EXP_IN_RANGE_MAX: f32 = 88.0;

/// eˣ for `x ∈ [EXP_IN_RANGE_MIN, EXP_IN_RANGE_MAX]`, **bit for bit** libm's `expf`, where
/// [`BRANCH_FREE`] with less work than [`exp`] (no subnormal scaling, no special cases), so
/// that a loop of them vectorises. Arguments outside the range are clamped into it (NaN → the
/// lower end), so the result is always finite and positive.
#[inline(always)]
#[must_use]
pub fn exp_in_range(x: f32) -> f32 {
    let x = clamp(x, EXP_IN_RANGE_MIN, EXP_IN_RANGE_MAX);
    if BRANCH_FREE {
        branch_free::exp_in_range(x)
    } else {
        libm::expf(x)
    }
}

libm_or_branch_free! {
    /// ln x: libm's `logf`, branch-free where [`BRANCH_FREE`].
    pub fn ln => logf
}

libm_or_branch_free! {
    /// ln(1 + x): libm's `log1pf`, branch-free where [`BRANCH_FREE`].
    pub fn ln_1p => log1pf
}

/// (sin x, cos x): libm's `sincosf`, through [`sin_cos_fast`] where it applies.
#[inline(always)]
#[must_use]
pub fn sin_cos(x: f32) -> (f32, f32) {
    if BRANCH_FREE && sin_cos_fast_covers(x) {
        sin_cos_fast(x)
    } else {
        libm::sincosf(x)
    }
}

/// (sin x, cos x) for `|x| ≤ SIN_COS_FAST_MAX` (≈ 9π/4), **bit for bit** libm's `sincosf`,
/// branch-free where [`BRANCH_FREE`]; other `x` give meaningless values. A batch computes every
/// lane with it, then redoes the lanes that [`sin_cos_fast_covers`] refuses:
///
/// ```text
/// for i in 0..N { (s[i], c[i]) = sin_cos_fast(x[i]); }      // vectorises
/// for i in 0..N { if !sin_cos_fast_covers(x[i]) { (s[i], c[i]) = sin_cos(x[i]); } }
/// ```
#[inline(always)]
#[must_use]
pub fn sin_cos_fast(x: f32) -> (f32, f32) {
    if BRANCH_FREE {
        branch_free::sin_cos_fast(x)
    } else {
        libm::sincosf(x)
    }
}

/// Whether [`sin_cos_fast`] is libm's `sincosf` at `x`: `|x| ≤ SIN_COS_FAST_MAX` (false for
/// NaN and ±∞).
#[inline(always)]
#[must_use]
pub fn sin_cos_fast_covers(x: f32) -> bool {
    abs(x) <= SIN_COS_FAST_MAX
}

/// atan2(y, x) in (−π, π].
#[inline(always)]
#[must_use]
pub fn atan2(y: f32, x: f32) -> f32 {
    if BRANCH_FREE {
        branch_free::atan2(y, x)
    } else {
        libm::atan2f(y, x)
    }
}

/// x rounded to the nearest integer, ties to even.
#[inline(always)]
#[must_use]
pub fn round(x: f32) -> f32 {
    libm::rintf(x)
}

libm_or_branch_free! {
    /// tanh x: libm's `tanhf`, branch-free where [`BRANCH_FREE`].
    pub fn tanh => tanhf
}

/// |x|.
#[inline(always)]
#[must_use]
pub fn abs(x: f32) -> f32 {
    libm::fabsf(x)
}

libm_or_branch_free! {
    /// ⌊x⌋.
    pub fn floor => floorf
}

/// Softplus ln(1 + eˣ), computed without overflow for large x: `x` above 20, else
/// `ln_1p(exp(x))`. Branch-free where [`BRANCH_FREE`].
#[inline(always)]
#[must_use]
pub fn softplus(x: f32) -> f32 {
    if BRANCH_FREE {
        branch_free::softplus(x)
    } else if x > 20.0 {
        x
    } else {
        libm::log1pf(libm::expf(x))
    }
}

/// Logistic sigmoid 1/(1 + e⁻ˣ), computed without overflow: `1/(1 + exp(−x))` for `x ≥ 0`,
/// else `e/(1 + e)` with `e = exp(x)`. Branch-free where [`BRANCH_FREE`].
#[inline(always)]
#[must_use]
pub fn sigmoid(x: f32) -> f32 {
    if BRANCH_FREE {
        branch_free::sigmoid(x)
    } else if x >= 0.0 {
        1.0 / (1.0 + libm::expf(-x))
    } else {
        let e = libm::expf(x);
        e / (1.0 + e)
    }
}

libm_or_branch_free! {
    /// [`exp_in_range`] for `x ∈ [EXP_IN_RANGE_MIN, 0]` only (bit for bit libm's `expf` there),
    /// with the work for positive arguments and the clamp left out. Other arguments give
    /// meaningless (but panic-free) results: callers select them away, as
    /// [`crate::distrib::gaussian::softmax`] does for inputs far below the maximum.
    pub(crate) fn exp_nonpositive => expf
}

/// [`sigmoid`] through [`exp_in_range`]: bit for bit [`sigmoid`] for `x ≥ EXP_IN_RANGE_MIN`
/// (and for every `x ≥ 0`), branch-free so that a loop of them vectorises. Below the range
/// (and for NaN) it returns `sigmoid(EXP_IN_RANGE_MIN)`-like tiny values instead of libm's
/// subnormals: callers that need those fall back to [`sigmoid`] there.
#[inline(always)]
#[must_use]
pub fn sigmoid_in_range(x: f32) -> f32 {
    // e^(−|x|): for x > 88 libm's e^(−x) is below 2⁻¹²⁶ and 1/(1 + e) rounds to 1 either way.
    // −|x| by setting the sign bit: LLVM would push a select of −x and x through the
    // exponential (two evaluations per lane).
    let pos = x >= 0.0;
    let e = exp_in_range(f32::from_bits(x.to_bits() | 0x8000_0000));
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
    // Two independent selects (nested branches stay branches in unrolled lane loops); NaN
    // fails both comparisons and ends at `lo`.
    let below_hi = if x <= hi { x } else { hi };
    if x >= lo {
        below_hi
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

/// Clamp a float to an index in `[0, n − 1]` (NaN → 0). `n` must be in `1 ..= 2³¹`.
#[inline(always)]
#[must_use]
pub fn clamp_index(x: f32, n: u32) -> u32 {
    let hi = (n - 1) as f32;
    trunc_index(clamp(x, 0.0, hi))
}

/// `x` truncated toward zero, for `x` in `[0, 2³¹)` (`x as u32` there), with float and
/// integer operations only: Rust's saturating conversions become a scalar loop in an x86
/// vector loop before AVX-512, these become a few vector instructions.
#[inline(always)]
#[must_use]
pub fn trunc_index(x: f32) -> u32 {
    // GPUs convert natively, and their compilers may fold `(x + 2²³) − 2²³` into `x`.
    #[cfg(target_arch = "spirv")]
    {
        x as u32
    }
    #[cfg(not(target_arch = "spirv"))]
    {
        trunc_index_bits(x)
    }
}

/// [`trunc_index`] by float and integer operations.
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
fn trunc_index_bits(x: f32) -> u32 {
    /// 2²³: below it, `x + 2²³` holds `x` rounded to an integer in its mantissa.
    const TWO_23: f32 = 8_388_608.0;
    let r = x + TWO_23;
    let near = r.to_bits().wrapping_sub(TWO_23.to_bits());
    let small = if r - TWO_23 > x {
        near.wrapping_sub(1)
    } else {
        near
    };
    // From 2²³ up, `x` is an integer: its significand shifted by its exponent.
    let b = x.to_bits();
    let big = ((b & 0x007f_ffff) | 0x0080_0000) << ((b >> 23).wrapping_sub(150) & 31);
    if x < TWO_23 {
        small
    } else {
        big
    }
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

    /// `trunc_index` is `x as u32` on every 7th f32 of [0, 2³¹) and around the powers of 2.
    #[test]
    fn trunc_index_is_the_conversion() {
        let mut check = |x: f32| assert_eq!(trunc_index(x), x as u32, "x = {x:e}");
        sweep(0.0, 2_147_483_520.0, 7, &mut check);
        for k in 0..31 {
            let p = (1u32 << k) as f32;
            for d in -3i32..=3 {
                let x = f32::from_bits(p.to_bits().wrapping_add_signed(d));
                if x < 2_147_483_648.0 {
                    check(x);
                }
            }
        }
    }

    #[test]
    fn exp_in_range_is_libm_expf() {
        sweep(EXP_IN_RANGE_MIN, EXP_IN_RANGE_MAX, 211, |x| {
            let want = libm::expf(x);
            assert_eq!(exp_in_range(x).to_bits(), want.to_bits(), "x = {x:e}");
        });
        // Clamped outside, never NaN.
        assert_eq!(exp_in_range(-1e9), libm::expf(EXP_IN_RANGE_MIN));
        assert_eq!(exp_in_range(1e9), libm::expf(EXP_IN_RANGE_MAX));
        assert_eq!(exp_in_range(f32::NAN), libm::expf(EXP_IN_RANGE_MIN));
    }

    #[test]
    fn exp_nonpositive_is_libm_expf() {
        sweep(EXP_IN_RANGE_MIN, 0.0, 101, |x| {
            let want = libm::expf(x);
            assert_eq!(exp_nonpositive(x).to_bits(), want.to_bits(), "x = {x:e}");
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

    #[test]
    fn sqrt_is_libm_sqrtf() {
        use branch_free::tests::{all, check, one};
        check("sqrt", 1, one(sqrt), one(libm::sqrtf), all, &[]);
        let reference = |x: f32| libm::sqrtf(if x > 0.0 { x } else { 0.0 });
        check("safe_sqrt", 16, one(safe_sqrt), one(reference), all, &[]);
    }

    #[test]
    fn sin_cos_is_libm_sincosf() {
        use branch_free::tests::{all, check};
        // Through sin_cos_fast in range and libm beyond, where a lane loop does not vectorise.
        check(
            "sin_cos",
            16,
            sin_cos,
            libm::sincosf,
            all,
            &[SIN_COS_FAST_MAX],
        );
        assert!(sin_cos_fast_covers(-SIN_COS_FAST_MAX));
        assert!(!sin_cos_fast_covers(f32::from_bits(
            SIN_COS_FAST_MAX.to_bits() + 1
        )));
        assert!(!sin_cos_fast_covers(f32::NAN));
        assert!(!sin_cos_fast_covers(f32::NEG_INFINITY));
    }

    #[test]
    fn entry_points_are_libm() {
        use branch_free::tests::{all, check, one};
        let reference_softplus = |x: f32| {
            if x > 20.0 {
                x
            } else {
                libm::log1pf(libm::expf(x))
            }
        };
        check("math::exp", 16, one(exp), one(libm::expf), all, &[]);
        check("math::ln", 16, one(ln), one(libm::logf), all, &[]);
        check("math::ln_1p", 16, one(ln_1p), one(libm::log1pf), all, &[]);
        check("math::tanh", 16, one(tanh), one(libm::tanhf), all, &[]);
        check(
            "math::softplus",
            16,
            one(softplus),
            one(reference_softplus),
            all,
            &[],
        );
    }
}
