//! Transcendental functions in single precision only, for targets whose own ones are too
//! coarse (SPIR-V) and which have no f64 to run libm's (libm's `asinf` takes one branch in
//! f64).
//!
//! `asinf` is fdlibm's single-precision `e_asinf.c` (Sun Microsystems 1993, conversion to
//! float by Ian Lance Taylor, Cygnus Support; "Permission to use, copy, modify, and
//! distribute this software is freely granted, provided that this notice is preserved."),
//! ported operation for operation (one constant corrected, see `PIO4_HI`): a rational
//! approximation of `asin x − x` in `x²` below ½, and `π/2 − 2 asin √((1 − |x|)/2)` above,
//! with `√` split into a 12-bit head and a tail so that `π/4` absorbs the rounding. Its error
//! is below one ulp (tested against libm).

// fdlibm's constants, by their bits.
/// π/2, head.
const PIO2_HI: f32 = f32::from_bits(0x3fc9_0fda);
/// π/2 − `PIO2_HI`.
const PIO2_LO: f32 = f32::from_bits(0x33a2_2168);
/// π/4, head: half of `PIO2_HI`, so that `2·PIO4_HI + PIO2_LO = π/2`. (fdlibm's float
/// conversion rounds π/4 up on its own, `0x3f490fdb`, which breaks that identity by one ulp
/// of π/2 and puts its results more than one ulp off just above ½.)
const PIO4_HI: f32 = PIO2_HI * 0.5;
/// Numerator of the rational approximation `R(t) = P(t)/Q(t)`.
const PS: [f32; 6] = [
    f32::from_bits(0x3e2a_aaab),
    f32::from_bits(0xbea6_b090),
    f32::from_bits(0x3e4e_0aa8),
    f32::from_bits(0xbd24_1146),
    f32::from_bits(0x3a4f_7f04),
    f32::from_bits(0x3811_ef08),
];
/// Denominator (after its leading 1).
const QS: [f32; 4] = [
    f32::from_bits(0xc019_d139),
    f32::from_bits(0x4001_572d),
    f32::from_bits(0xbf30_3361),
    f32::from_bits(0x3d9d_c62e),
];
/// 2⁻²⁷: below it, `asin x = x` in f32.
const TINY: f32 = f32::from_bits(0x3200_0000);
/// 0.975 (fdlibm's threshold `0x3F79999A`): above it the tail of `√` is not needed.
const NEAR_ONE: f32 = f32::from_bits(0x3f79_999a);

/// `(P(t), Q(t))` of fdlibm's rational approximation, in its order of operations.
#[inline(always)]
fn pq(t: f32) -> (f32, f32) {
    let p = t * (PS[0] + t * (PS[1] + t * (PS[2] + t * (PS[3] + t * (PS[4] + t * PS[5])))));
    let q = 1.0 + t * (QS[0] + t * (QS[1] + t * (QS[2] + t * QS[3])));
    (p, q)
}

/// asin x in [−π/2, π/2], NaN outside [−1, 1] (fdlibm's `asinf`, f32 only).
#[must_use]
pub(crate) fn asinf(x: f32) -> f32 {
    let a = libm::fabsf(x);
    if a == 1.0 {
        return x * PIO2_HI + x * PIO2_LO;
    }
    if !(a < 1.0) {
        // |x| > 1 or NaN.
        return f32::NAN;
    }
    if a < 0.5 {
        if a < TINY {
            return x;
        }
        let t = x * x;
        let (p, q) = pq(t);
        return x + x * (p / q);
    }
    // ½ ≤ |x| < 1.
    let t = (1.0 - a) * 0.5;
    let (p, q) = pq(t);
    let s = libm::sqrtf(t);
    let r = if a >= NEAR_ONE {
        PIO2_HI - (2.0 * (s + s * (p / q)) - PIO2_LO)
    } else {
        // s = w + c exactly enough: w keeps the upper 12 bits of s's significand.
        let w = f32::from_bits(s.to_bits() & 0xffff_f000);
        let c = (t - w * w) / (s + w);
        let p = 2.0 * s * (p / q) - (PIO2_LO - 2.0 * c);
        let q = PIO4_HI - 2.0 * w;
        PIO4_HI - (p - q)
    };
    if x > 0.0 {
        r
    } else {
        -r
    }
}

#[cfg(test)]
mod tests {
    use super::asinf;

    /// Distance in units in the last place between two finite f32 of the same sign.
    fn ulps(a: f32, b: f32) -> u32 {
        let (a, b) = (a.to_bits() as i64, b.to_bits() as i64);
        (a - b).unsigned_abs() as u32
    }

    /// Within one ulp of libm's `asinf` on every 97th f32 of [−1, 1] and every 3rd of
    /// ±[½, 1] (the branch that libm computes in f64); exact at ±0, ±1 and tiny x; NaN
    /// outside [−1, 1].
    #[test]
    fn asinf_is_within_one_ulp_of_libm() {
        let mut count = 0u64;
        let mut check = |x: f32| {
            let (got, want) = (asinf(x), libm::asinf(x));
            let d = ulps(got, want);
            assert!(d <= 1, "asinf({x:e}) = {got:e}, libm {want:e} ({d} ulps)");
            count += 1;
        };
        let one = 1.0f32.to_bits();
        for bits in (0..=one)
            .step_by(97)
            .chain((0.5f32.to_bits()..=one).step_by(3))
        {
            let x = f32::from_bits(bits);
            check(x);
            check(-x);
        }
        for x in [
            0.5,
            f32::from_bits(0x3f79_999a),
            f32::from_bits(0x3f79_9999),
        ] {
            check(x);
        }
        assert!(count > 1 << 23, "{count} points");
        for x in [0.0, -0.0, 1.0, -1.0, 1e-30, -1e-9] {
            assert_eq!(asinf(x).to_bits(), libm::asinf(x).to_bits(), "x = {x:e}");
        }
        assert!(asinf(1.0 + f32::EPSILON).is_nan());
        assert!(asinf(-1.0 - f32::EPSILON).is_nan());
        assert!(asinf(f32::NAN).is_nan());
        assert!(asinf(f32::NEG_INFINITY).is_nan());
    }
}
