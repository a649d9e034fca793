//! Fast single-precision approximations for the batched path: branch-free (selects only, no
//! calls, no tables), so that a loop of them over lanes vectorises, with a bounded error
//! against the exact result (tested below) instead of libm's bits. The scalar path keeps
//! libm ([`super::exp`], [`super::ln`], …); the batched path agrees with it within the
//! tolerances the `wavefront` docs state.
//!
//! `exp` and `ln` are Cephes' `expf` and `logf` (Moshier): Cody–Waite reduction and the
//! same polynomials, with the exponent handled through float bits; `sin_cos_pi` reduces
//! exactly to `|r| ≤ 1/2` and evaluates near-minimax polynomials in `r²` (Chebyshev fits).

use super::branch_free::SHIFT;

/// log₂ e.
const LOG2E: f32 = core::f32::consts::LOG2_E;
/// ln 2 split so that `n·LN2_HI` is exact for `|n| ≤ 2⁹` (Cephes).
const LN2_HI: f32 = 0.693_359_4;
/// The rest of ln 2 (Cephes).
const LN2_LO: f32 = -2.121_944_4e-4;
/// Cephes `expf` polynomial: `e^r ≈ 1 + r + r²·P(r)` on `|r| ≤ ln 2 / 2`.
const EXP_P: [f32; 6] = [
    1.987_569_1e-4,
    1.398_199_9e-3,
    8.333_452e-3,
    4.166_579_6e-2,
    1.666_666_5e-1,
    0.5,
];
/// Cephes `logf` polynomial: `ln(1 + m) ≈ m − m²/2 + m³·P(m)` on `√½ − 1 ≤ m < √2 − 1`.
const LOG_P: [f32; 9] = [
    7.037_683_6e-2,
    -1.151_461e-1,
    1.167_699_9e-1,
    -1.242_014_1e-1,
    1.424_932_3e-1,
    -1.666_805_8e-1,
    2.000_071_4e-1,
    -2.499_999_4e-1,
    3.333_333e-1,
];
/// `sin(πr)/r` as a polynomial in `r²` on `r² ≤ 1/4` (absolute error 5·10⁻¹¹ before rounding).
const SIN_PI_P: [f32; 6] = [
    -7.028_304e-3,
    8.205_035e-2,
    -5.992_521_6e-1,
    2.550_163_3,
    -5.167_712_7,
    core::f32::consts::PI,
];
/// `cos(πr)` as a polynomial in `r²` on `r² ≤ 1/4` (absolute error 2·10⁻¹⁰ before rounding).
const COS_PI_P: [f32; 6] = [
    -2.439_593_2e-2,
    2.349_370_7e-1,
    -1.335_212,
    4.058_709,
    -4.934_802,
    1.0,
];

/// Horner's scheme with separate multiplies and adds (the same bits on every target).
#[inline(always)]
fn horner<const N: usize>(c: &[f32; N], x: f32) -> f32 {
    let mut p = c[0];
    let mut i = 1;
    while i < N {
        p = p * x + c[i];
        i += 1;
    }
    p
}

/// 2ᵏ for an integer-valued `k ∈ [−126, 127]`.
#[inline(always)]
fn pow2(k: f32) -> f32 {
    f32::from_bits(((k + SHIFT).to_bits().wrapping_sub(0x4b40_0000 - 127)) << 23)
}

/// `round(x)` (ties to even) for `|x| < 2²²`.
#[inline(always)]
fn round_small(x: f32) -> f32 {
    (x + SHIFT) - SHIFT
}

/// `e^r` for the reduced argument, before scaling by 2ⁿ.
#[inline(always)]
fn exp_reduced(x: f32, n: f32) -> f32 {
    let r = (x - n * LN2_HI) - n * LN2_LO;
    (horner(&EXP_P, r) * (r * r) + r) + 1.0
}

/// eˣ within 2 ulp of the exact value for every `x` (subnormal results included);
/// `+∞` above ln(f32::MAX), 0 below −104, NaN for NaN.
#[inline(always)]
#[must_use]
pub(crate) fn exp(x: f32) -> f32 {
    // NaN stays NaN.
    let xc = x.clamp(-105.0, 89.0);
    let n = round_small(xc * LOG2E);
    let y = exp_reduced(xc, n);
    // 2ⁿ in two factors, each a normal number, so that the product rounds to a subnormal
    // or overflows to ∞ as the exact value does.
    let h = round_small(n * 0.5);
    y * pow2(h) * pow2(n - h)
}

/// eˣ for `x ∈ [−87, 0]` (within 2 ulp): [`exp`] without its range handling. Other
/// arguments give meaningless (finite or not, never panicking) results: callers select them
/// away, as the softmaxes do for inputs far below the maximum.
#[inline(always)]
#[must_use]
pub(crate) fn exp_nonpositive(x: f32) -> f32 {
    let n = round_small(x * LOG2E);
    exp_reduced(x, n) * pow2(n)
}

/// ln x within 2 ulp (absolute 2⁻²⁴ near 1) for every positive `x`, subnormals included;
/// −∞ at ±0, NaN for negative `x` and NaN, `+∞` at `+∞`.
#[inline(always)]
#[must_use]
pub(crate) fn ln(x: f32) -> f32 {
    let tiny = x < f32::MIN_POSITIVE;
    let xs = if tiny { x * 33_554_432.0 } else { x };
    let bits = xs.to_bits();
    // x = m·2^(e) with m ∈ [½, 1).
    let e = ((bits >> 23) & 0xff) as i32 - 126 - if tiny { 25 } else { 0 };
    let m = f32::from_bits((bits & 0x007f_ffff) | 0x3f00_0000);
    let below = m < core::f32::consts::FRAC_1_SQRT_2;
    let e = (if below { e - 1 } else { e }) as f32;
    let m = if below { m + m - 1.0 } else { m - 1.0 };
    let z = m * m;
    let y = horner(&LOG_P, m) * m * z + e * LN2_LO - 0.5 * z;
    let r = (m + y) + e * LN2_HI;
    if x > 0.0 {
        if x < f32::INFINITY {
            r
        } else {
            f32::INFINITY
        }
    } else if x == 0.0 {
        f32::NEG_INFINITY
    } else {
        f32::NAN
    }
}

/// ln(1 + t) for `t > −1` within 3 ulp: `ln(u) + (t − (u − 1))/u` with `u = 1 + t` (the
/// rounding of `u` corrected to first order; `t` itself where `u` rounds to 1).
#[inline(always)]
#[must_use]
pub(crate) fn ln_1p(t: f32) -> f32 {
    let u = 1.0 + t;
    ln(u) + (t - (u - 1.0)) / u
}

/// Softplus ln(1 + eˣ) = max(x, 0) + ln(1 + e^−|x|), within 4 ulp for every `x`; `+∞` at
/// `+∞`, 0 at −∞, NaN for NaN.
#[inline(always)]
#[must_use]
pub(crate) fn softplus(x: f32) -> f32 {
    let neg_abs = f32::from_bits(x.to_bits() | 0x8000_0000);
    let pos = if x > 0.0 { x } else { 0.0 };
    pos + ln_1p(exp(neg_abs))
}

/// The logistic function 1/(1 + e⁻ˣ) from `e^−|x|` (no overflow, no cancellation):
/// within 3 ulp for `x ≥ −87`; below, a value under 2·10⁻³⁸ (absolute error, the exponent
/// clamped at −87 keeps [`exp_nonpositive`] in range); NaN for NaN.
#[inline(always)]
#[must_use]
pub(crate) fn sigmoid(x: f32) -> f32 {
    let neg_abs = f32::from_bits(x.to_bits() | 0x8000_0000);
    // NaN fails the comparison and stays NaN.
    let e = exp_nonpositive(if neg_abs < -87.0 { -87.0 } else { neg_abs });
    let r = 1.0 / (1.0 + e);
    if x >= 0.0 {
        r
    } else {
        e * r
    }
}

/// [`sigmoid`] of the first `N` elements of `x` (fewer if `x` is shorter), bit for bit, one step at a time across the whole
/// row: the elements' dependency chains then interleave instead of running one vector after
/// another (a sigmoid is some thirty dependent operations).
#[inline(always)]
pub(crate) fn sigmoid_row<const N: usize>(x: &[f32], out: &mut [f32; N]) {
    let mut t = [0.0f32; N];
    for (t, x) in t.iter_mut().zip(x) {
        let neg_abs = f32::from_bits(x.to_bits() | 0x8000_0000);
        *t = if neg_abs < -87.0 { -87.0 } else { neg_abs };
    }
    let mut n = [0.0f32; N];
    for (n, t) in n.iter_mut().zip(&t) {
        *n = round_small(*t * LOG2E);
    }
    let mut r = [0.0f32; N];
    for ((r, t), n) in r.iter_mut().zip(&t).zip(&n) {
        *r = (*t - *n * LN2_HI) - *n * LN2_LO;
    }
    let mut p = [EXP_P[0]; N];
    for c in &EXP_P[1..] {
        for (p, r) in p.iter_mut().zip(&r) {
            *p = *p * *r + *c;
        }
    }
    for (((o, x), (p, r)), n) in out.iter_mut().zip(x).zip(p.iter().zip(&r)).zip(&n) {
        let e = ((*p * (*r * *r) + *r) + 1.0) * pow2(*n);
        let q = 1.0 / (1.0 + e);
        *o = if *x >= 0.0 { q } else { e * q };
    }
}

/// (sin πx, cos πx) within 3·10⁻⁷ for `|x| < 2²²`. Beyond, `x` is within 1 of an integer
/// and the result is that of `x − round(x)`'s sign-less reduction; NaN and ±∞ give NaN.
#[inline(always)]
#[must_use]
pub(crate) fn sin_cos_pi(x: f32) -> (f32, f32) {
    let small = super::abs(x) < 4_194_304.0;
    let k = if small { round_small(x) } else { x };
    // Exact: |r| ≤ 1/2 (0 for large x, NaN for NaN and ±∞).
    let r = x - k;
    let r2 = r * r;
    let s = r * horner(&SIN_PI_P, r2);
    let c = horner(&COS_PI_P, r2);
    // sin(π(k + r)) = (−1)ᵏ sin(πr), likewise cos.
    let odd = small && ((k + SHIFT).to_bits() & 1) == 1;
    if odd {
        (-s, -c)
    } else {
        (s, c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The distance in units in the last place of the exact value `want` (f64) to `got`.
    fn ulps(got: f32, want: f64) -> f64 {
        if want.is_nan() {
            return if got.is_nan() { 0.0 } else { f64::INFINITY };
        }
        if (want as f32).is_infinite() || got.is_infinite() {
            return if got == want as f32 {
                0.0
            } else {
                f64::INFINITY
            };
        }
        // The ulp of the f32 nearest to `want` (subnormal spacing below the normals).
        let w = want as f32;
        let e = if w == 0.0 {
            f32::from_bits(1)
        } else {
            let b = w.abs().to_bits();
            f32::from_bits(b + 1) - f32::from_bits(b)
        };
        (f64::from(got) - want).abs() / f64::from(e)
    }

    /// Every `step`-th f32 bit pattern in `[lo, hi]` and both ends.
    fn sweep(lo: f32, hi: f32, step: u32, mut f: impl FnMut(f32)) {
        let mut b = 0u32;
        loop {
            let x = f32::from_bits(b);
            if x >= lo && x <= hi {
                f(x);
            }
            match b.checked_add(step) {
                Some(n) => b = n,
                None => break,
            }
        }
        f(lo);
        f(hi);
    }

    #[test]
    fn exp_within_2_ulp() {
        let mut worst = 0.0f64;
        sweep(-104.0, 89.0, 97, |x| {
            let u = ulps(exp(x), f64::from(x).exp());
            assert!(u <= 2.0, "exp({x:e}) = {:e}: {u} ulp", exp(x));
            worst = worst.max(u);
        });
        assert!(worst > 0.5, "the sweep compared nothing: {worst}");
        assert_eq!(exp(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp(-200.0), 0.0);
        assert_eq!(exp(f32::INFINITY), f32::INFINITY);
        assert_eq!(exp(89.0), f32::INFINITY);
        assert!(exp(f32::NAN).is_nan());
        assert_eq!(exp(0.0), 1.0);
    }

    #[test]
    fn exp_nonpositive_is_exp() {
        sweep(-87.0, 0.0, 53, |x| {
            assert_eq!(exp_nonpositive(x).to_bits(), exp(x).to_bits(), "x = {x:e}");
        });
    }

    #[test]
    fn ln_within_2_ulp() {
        sweep(0.0, f32::MAX, 89, |x| {
            let want = f64::from(x).ln();
            let got = ln(x);
            // Near 1 the result is tiny: bound the absolute error there.
            let ok = ulps(got, want) <= 2.0 || (f64::from(got) - want).abs() <= 6e-8;
            assert!(ok, "ln({x:e}) = {got:e}, want {want:e}");
        });
        assert_eq!(ln(0.0), f32::NEG_INFINITY);
        assert_eq!(ln(-0.0), f32::NEG_INFINITY);
        assert_eq!(ln(f32::INFINITY), f32::INFINITY);
        assert!(ln(-1.0).is_nan() && ln(f32::NAN).is_nan() && ln(f32::NEG_INFINITY).is_nan());
        assert_eq!(ln(1.0), 0.0);
    }

    #[test]
    fn ln_1p_within_3_ulp() {
        sweep(-0.999_999_9, 1e6, 71, |t| {
            let want = f64::from(t).ln_1p();
            let got = ln_1p(t);
            let ok = ulps(got, want) <= 3.0
                || (f64::from(got) - want).abs() <= 1e-7 * want.abs().max(1e-30);
            assert!(ok, "ln_1p({t:e}) = {got:e}, want {want:e}");
        });
        for t in [1e-30f32, -1e-30, 1e-10, -3e-9, 0.0] {
            assert_eq!(ln_1p(t), t);
        }
        assert!(ln_1p(-0.999_999_94).is_finite());
    }

    #[test]
    fn softplus_within_4_ulp() {
        sweep(-1e6, 1e6, 67, |x| {
            let xd = f64::from(x);
            let want = xd.max(0.0) + (-xd.abs()).exp().ln_1p();
            let got = softplus(x);
            assert!(
                ulps(got, want) <= 4.0,
                "softplus({x:e}) = {got:e}, want {want:e}"
            );
        });
        assert_eq!(softplus(f32::INFINITY), f32::INFINITY);
        assert_eq!(softplus(f32::NEG_INFINITY), 0.0);
        assert!(softplus(f32::NAN).is_nan());
    }

    #[test]
    fn sigmoid_within_3_ulp() {
        let mut worst = 0.0f64;
        sweep(-87.0, 1e6, 61, |x| {
            let want = 1.0 / (1.0 + (-f64::from(x)).exp());
            let u = ulps(sigmoid(x), want);
            assert!(u <= 3.0, "sigmoid({x:e}) = {:e}: {u} ulp", sigmoid(x));
            worst = worst.max(u);
        });
        for x in [-87.5f32, -100.0, -1e6, f32::MIN] {
            assert!((0.0..2e-38).contains(&sigmoid(x)), "sigmoid({x:e})");
        }
        assert!(worst > 0.5, "the sweep compared nothing: {worst}");
        assert_eq!(sigmoid(0.0), 0.5);
        assert_eq!(sigmoid(f32::INFINITY), 1.0);
        assert!(sigmoid(f32::NEG_INFINITY) < 2e-38);
        assert!(sigmoid(f32::NAN).is_nan());
    }

    #[test]
    fn sigmoid_row_is_sigmoid_bit_for_bit() {
        let mut xs = vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0, -0.0];
        sweep(f32::MIN, f32::MAX, 4_099, |x| xs.push(x));
        assert!(xs.len() > 1_000_000);
        let mut out = [0.0f32; 32];
        for row in xs.chunks(32) {
            sigmoid_row(row, &mut out);
            for (x, got) in row.iter().zip(&out) {
                let want = sigmoid(*x);
                assert!(
                    got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                    "sigmoid_row({x:e}) = {got:e}, sigmoid = {want:e}"
                );
            }
        }
    }

    #[test]
    fn sin_cos_pi_within_3e7() {
        sweep(-4_194_303.0, 4_194_303.0, 41, |x| {
            let (s, c) = sin_cos_pi(x);
            // The exact reduction in f64: x − round(x) is exact in f32 too.
            let r = f64::from(x) - f64::from(x).round();
            let k = f64::from(x).round();
            let sign = if k.rem_euclid(2.0) == 1.0 { -1.0 } else { 1.0 };
            let (ws, wc) = (
                (std::f64::consts::PI * r).sin(),
                (std::f64::consts::PI * r).cos(),
            );
            assert!(
                (f64::from(s) - sign * ws).abs() <= 3e-7
                    && (f64::from(c) - sign * wc).abs() <= 3e-7,
                "sin_cos_pi({x:e}) = ({s:e}, {c:e})"
            );
        });
        let (s, c) = sin_cos_pi(f32::NAN);
        assert!(s.is_nan() && c.is_nan());
        let (s, c) = sin_cos_pi(f32::INFINITY);
        assert!(s.is_nan() && c.is_nan());
        assert!(sin_cos_pi(1e30).0.is_finite() && sin_cos_pi(1e30).1.is_finite());
        assert_eq!(sin_cos_pi(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_pi(1.0).1, -1.0);
    }
}
