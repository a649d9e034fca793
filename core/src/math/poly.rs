//! Cephes' single-precision `asinf` and `atanf` polynomials (Moshier), which Dr.Jit evaluates
//! for Mitsuba's angle functions: f32 operations only, selects instead of branches (a loop of
//! them over lanes vectorises; SPIR-V has no f64 for libm's `asinf`), and the same operations
//! on every target, so a scalar, a batched and a GPU caller get the same bits. Within a few
//! ulp of libm (tested below) instead of libm's bits, at a fraction of its cost.

use super::{abs, sqrt};
use core::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// `asin x ≈ x + x·z·P(z)` with `z = x²` on `|x| ≤ ½` (Cephes `asinf`).
const ASIN_P: [f32; 5] = [
    4.216_32e-2,
    2.418_131_2e-2,
    4.547_002_5e-2,
    7.495_300_5e-2,
    1.666_675_2e-1,
];
/// `atan t ≈ t + t·z·P(z)` with `z = t²` on `|t| ≤ tan(π/8)` (Cephes `atanf`).
const ATAN_P: [f32; 4] = [
    8.053_744_6e-2,
    -1.387_768_5e-1,
    1.997_771_1e-1,
    -3.333_295e-1,
];
/// tan(π/8): above it, `atan r = π/4 + atan((r − 1)/(r + 1))`.
const TAN_PI_8: f32 = 0.414_213_57;

/// `|v|` with the sign of `s`.
#[inline(always)]
fn with_sign_of(v: f32, s: f32) -> f32 {
    f32::from_bits((v.to_bits() & 0x7fff_ffff) | (s.to_bits() & 0x8000_0000))
}

/// asin x in [−π/2, π/2], NaN outside [−1, 1]. Above `|x| = ½`:
/// `π/2 − 2 asin √((1 − |x|)/2)`.
#[inline(always)]
#[must_use]
pub fn asin(x: f32) -> f32 {
    let a = abs(x);
    let big = a > 0.5;
    let z = if big { 0.5 * (1.0 - a) } else { a * a };
    let s = if big { sqrt(z) } else { a };
    let p = (((ASIN_P[0] * z + ASIN_P[1]) * z + ASIN_P[2]) * z + ASIN_P[3]) * z + ASIN_P[4];
    let r = p * z * s + s;
    let r = if big { FRAC_PI_2 - (r + r) } else { r };
    with_sign_of(r, x)
}

/// atan2(y, x) in [−π, π] for finite `(y, x)` other than `(±0, ±0)` (NaN there). The ratio
/// of the smaller to the larger magnitude is reduced to `|t| ≤ tan(π/8)` in one division;
/// the octant's offset and the quadrant are restored by selects.
#[inline(always)]
#[must_use]
pub fn atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (abs(x), abs(y));
    let steep = ay > ax;
    let (lo, hi) = if steep { (ax, ay) } else { (ay, ax) };
    let mid = lo > TAN_PI_8 * hi;
    let t = if mid { (lo - hi) / (lo + hi) } else { lo / hi };
    let z = t * t;
    let p = ((ATAN_P[0] * z + ATAN_P[1]) * z + ATAN_P[2]) * z + ATAN_P[3];
    let r = p * z * t + t;
    let r = if mid { FRAC_PI_4 + r } else { r };
    let r = if steep { FRAC_PI_2 - r } else { r };
    let r = if x.is_sign_negative() { PI - r } else { r };
    with_sign_of(r, y)
}

#[cfg(test)]
mod tests {
    use super::{asin, atan2};

    /// Distance in units in the last place between two finite f32 of the same sign.
    fn ulps(a: f32, b: f32) -> u32 {
        let (a, b) = (a.to_bits() as i64, b.to_bits() as i64);
        (a - b).unsigned_abs() as u32
    }

    /// Within 2 ulp of libm's `asinf` on every 97th f32 of [−1, 1] and every 3rd of ±[½, 1]
    /// (the reduced branch); exact at ±0, ±1 and tiny x; NaN outside [−1, 1].
    #[test]
    fn asin_is_within_two_ulp_of_libm() {
        let mut worst = 0;
        let one = 1.0f32.to_bits();
        for bits in (0..=one)
            .step_by(97)
            .chain((0.5f32.to_bits()..=one).step_by(3))
        {
            let x = f32::from_bits(bits);
            for x in [x, -x] {
                let (got, want) = (asin(x), libm::asinf(x));
                let d = ulps(got, want);
                assert!(d <= 2, "asin({x:e}) = {got:e}, libm {want:e} ({d} ulps)");
                worst = worst.max(d);
            }
        }
        assert!(worst >= 1, "the polynomial is not libm: some ulp apart");
        for x in [0.0, -0.0, 1.0, -1.0, 1e-30, -1e-9, 0.5, -0.5] {
            assert_eq!(asin(x).to_bits(), libm::asinf(x).to_bits(), "x = {x:e}");
        }
        for x in [
            1.0 + f32::EPSILON,
            -1.0 - f32::EPSILON,
            f32::NAN,
            f32::NEG_INFINITY,
        ] {
            assert!(asin(x).is_nan(), "asin({x})");
        }
    }

    /// Within 3 ulp of libm's `atan2f` over directions on the unit circle (every octant, the
    /// axes, the diagonals and the octant's reduction point) and over scaled pairs; NaN at the
    /// origin.
    #[test]
    fn atan2_is_within_three_ulp_of_libm() {
        let check = |y: f32, x: f32| {
            let (got, want) = (atan2(y, x), libm::atan2f(y, x));
            let d = ulps(got, want);
            assert!(
                d <= 3,
                "atan2({y:e}, {x:e}) = {got:e}, libm {want:e} ({d} ulps)"
            );
            d
        };
        let mut worst = 0;
        let n = 1 << 18;
        for k in 0..n {
            let phi = (k as f64 + 0.5) / n as f64 * core::f64::consts::TAU;
            let (s, c) = phi.sin_cos();
            worst = worst.max(check(s as f32, c as f32));
            worst = worst.max(check((s * 1e-20) as f32, (c * 1e-20) as f32));
            worst = worst.max(check((s * 3e15) as f32, (c * 3e15) as f32));
        }
        assert!(worst >= 1, "the polynomial is not libm: some ulp apart");
        let t = super::TAN_PI_8;
        for (y, x) in [
            (0.0, 1.0),
            (-0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1.0, 0.0),
            (-1.0, 0.0),
            (1.0, -0.0),
            (1.0, 1.0),
            (-1.0, -1.0),
            (t, 1.0),
            (1.0, -t),
            (1e-30, -2.0),
            (-7.0, 1e-30),
        ] {
            check(y, x);
        }
        assert_eq!(atan2(0.0, -1.0), core::f32::consts::PI);
        assert_eq!(atan2(-0.0, -1.0), -core::f32::consts::PI);
        assert!(atan2(0.0, 0.0).is_nan());
    }
}
