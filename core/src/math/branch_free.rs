//! libm's single-precision functions rewritten without branches.
//!
//! Each function is **bit for bit** the function of the `libm` crate (0.2.16, a port of
//! FreeBSD's msun) that it names, over its stated domain: the same operations in the same
//! order, with every branch of the original computed as a candidate and chosen by comparisons
//! (selects), integers taken from float bits instead of float → int conversions, and no calls.
//! A `for` loop of them over lanes therefore vectorises, and gives exactly the numbers of a
//! loop of libm calls. NaN results are NaN; their sign and payload are not promised (Rust
//! leaves them unspecified).
//!
//! Plain arithmetic on `f32`, `u32`, `i32` and `bool`, no `u64`; [`sin_cos_fast`] keeps
//! libm's `f64` kernels, which exactness needs, so SPIR-V builds use libm (see `BRANCH_FREE`).

/// Adding 1.5·2²³ rounds `|v| < 2²²` to an integer held in the low mantissa bits.
pub(super) const SHIFT: f32 = 12_582_912.0;
/// The bits of [`SHIFT`]: those of `k + SHIFT` are `SHIFT_BITS + k` for an integer `|k| < 2²²`.
const SHIFT_BITS: u32 = 0x4b40_0000;

/// 2¹²⁷.
const X1P127: f32 = f32::from_bits(0x7f00_0000);
/// 2⁻¹⁰² (libm `scalbnf`'s pre-scale toward the subnormals: 2⁻¹²⁶·2²⁴).
const X1P_102: f32 = f32::from_bits(0x0c80_0000);

// FreeBSD e_expf.c: ln 2 split so that k·LN2_HI is exact, 1/ln 2, the rational approximation.
const EXPF_LN2_HI: f32 = f32::from_bits(0x3f31_7200);
const EXPF_LN2_LO: f32 = f32::from_bits(0x35bf_be8e);
const INV_LN2: f32 = f32::from_bits(0x3fb8_aa3b);
const EXPF_P1: f32 = f32::from_bits(0x3e2a_aa8f);
const EXPF_P2: f32 = f32::from_bits(0xbb35_5215);

// FreeBSD e_logf.c / s_log1pf.c / s_expm1f.c: their ln 2 split, log's polynomial, expm1's.
const LN2_HI: f32 = f32::from_bits(0x3f31_7180);
const LN2_LO: f32 = f32::from_bits(0x3717_f7d1);
const LG1: f32 = f32::from_bits(0x3f2a_aaaa);
const LG2: f32 = f32::from_bits(0x3ecc_ce13);
const LG3: f32 = f32::from_bits(0x3e91_e9ee);
const LG4: f32 = f32::from_bits(0x3e78_9e26);
const EXPM1_Q1: f32 = f32::from_bits(0xbd08_8868);
const EXPM1_Q2: f32 = f32::from_bits(0x3acf_3010);

// FreeBSD k_sinf.c / k_cosf.c (double precision).
const S1: f64 = -0.166_666_666_416_265_24;
const S2: f64 = 0.008_333_329_385_889_463;
const S3: f64 = -0.000_198_393_348_360_966_32;
const S4: f64 = 2.718_311_493_989_822e-6;
const C0: f64 = -0.499_999_997_251_031;
const C1: f64 = 0.041_666_623_323_739_06;
const C2: f64 = -0.001_388_676_377_460_993;
const C3: f64 = 2.439_044_879_627_741e-5;

/// `|x|`, by clearing the sign bit as libm does.
#[inline(always)]
fn abs(x: f32) -> f32 {
    f32::from_bits(x.to_bits() & 0x7fff_ffff)
}

/// `trunc(v)` for `|v| < 2²²`: the conversion `v as i32` libm uses for its `k`, as a float.
/// Rounds to nearest with [`SHIFT`], then corrects toward zero.
#[inline(always)]
fn trunc_small(v: f32) -> f32 {
    let r = (v + SHIFT) - SHIFT;
    if v < 0.0 {
        if r < v {
            r + 1.0
        } else {
            r
        }
    } else if r > v {
        r - 1.0
    } else {
        r
    }
}

/// 2ᵏ for an integer-valued `kf ∈ [−126, 127]`.
#[inline(always)]
fn pow2(kf: f32) -> f32 {
    f32::from_bits((kf + SHIFT).to_bits().wrapping_sub(SHIFT_BITS - 127) << 23)
}

/// libm `expf`'s `k` (as a float) for `|x| < 2²²·ln 2`: `trunc(x/ln 2 ± 1/2)` for
/// `|x| > 1.5 ln 2`, ±1 for `0.5 ln 2 < |x| ≤ 1.5 ln 2`, else 0. With `FROM_1_5`, `expm1f`'s
/// `k`: the same, but `|x|` equal to the bound 1.5 ln 2 (as an f32) takes the first case.
#[inline(always)]
fn expf_k<const FROM_1_5: bool>(x: f32, ax: f32) -> f32 {
    let neg = x < 0.0;
    let t = trunc_small(INV_LN2 * x + if neg { -0.5 } else { 0.5 });
    let bound = f32::from_bits(0x3f85_1592);
    let above = if FROM_1_5 { ax >= bound } else { ax > bound };
    if above {
        t
    } else if ax > f32::from_bits(0x3eb1_7218) {
        if neg {
            -1.0
        } else {
            1.0
        }
    } else {
        0.0
    }
}

/// libm `expf` before its final scaling by 2ᵏ: given `x`, `|x|` and `k` (as a float), the
/// reduction `x = k·ln 2 + r` (for `k = 0` it leaves `x` unchanged), the rational approximation
/// of `eʳ`, and `1 + x` for `|x| ≤ 2⁻¹⁴`.
#[inline(always)]
fn expf_reduced(x: f32, ax: f32, kf: f32) -> f32 {
    // Where libm returns 1 + x the approximation runs on 0: tiny x would make subnormal
    // intermediates, which are slow. (Compared as bits: with the float comparison used at the
    // end, LLVM proves this select redundant under that one and drops it.)
    let tiny = ax <= f32::from_bits(0x3900_0000);
    let x1 = if ax.to_bits() <= 0x3900_0000 { 0.0 } else { x };
    let hi = x1 - kf * EXPF_LN2_HI;
    let lo = kf * EXPF_LN2_LO;
    let xr = hi - lo;
    let xx = xr * xr;
    let c = xr - xx * (EXPF_P1 + xx * EXPF_P2);
    let y = 1.0 + (xr * c / (2.0 - c) - lo + hi);
    if tiny {
        1.0 + x
    } else {
        y
    }
}

/// eˣ, libm's `expf` (FreeBSD e_expf.c) for `x ∈ [−87, 88]`, where `2ᵏ` is a normal number.
/// Other arguments give meaningless (finite or NaN) values.
#[inline(always)]
#[must_use]
pub fn exp_in_range(x: f32) -> f32 {
    let ax = abs(x);
    let kf = expf_k::<false>(x, ax);
    expf_reduced(x, ax, kf) * pow2(kf)
}

/// [`exp_in_range`] for `x ∈ [−87, 0]` only, with the work for positive arguments left out.
/// Other arguments give meaningless (finite or NaN) values.
#[inline(always)]
#[must_use]
pub fn exp_nonpositive(x: f32) -> f32 {
    let ax = -x;
    // expf_k for x < 0.
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
    expf_reduced(x, ax, kf) * pow2(kf)
}

/// eˣ, libm's `expf` (FreeBSD e_expf.c) for every `x`: also the subnormal results down to
/// `x ≈ −103.97` (libm's `scalbnf`, which pre-scales so that the result rounds once), 0 below,
/// +∞ from `x ≈ 88.72` on, NaN for NaN.
#[inline(always)]
#[must_use]
pub fn exp(x: f32) -> f32 {
    let ax = abs(x);
    let kf = expf_k::<false>(x, ax);
    let y = expf_reduced(x, ax, kf);
    // scalbnf(y, k) for k ∈ [−150, 128]: by 2¹²⁷ first above 127, by 2⁻¹⁰² first below −126.
    let big = kf > 127.0;
    let small = kf < -126.0;
    let y = y * if big {
        X1P127
    } else if small {
        X1P_102
    } else {
        1.0
    };
    let kf = if big {
        kf - 127.0
    } else if small {
        kf + 102.0
    } else {
        kf
    };
    let y = y * pow2(kf);
    // Overflow (x·2¹²⁷ as libm, +∞ for +∞) and underflow to 0; NaN has stayed NaN.
    if x >= f32::from_bits(0x42b1_7218) {
        x * X1P127
    } else if x <= -f32::from_bits(0x42cf_f1b5) {
        0.0
    } else {
        y
    }
}

/// The tail libm's `logf` and `log1pf` share: `ln(1 + f)` for `1 + f ∈ [√2/2, √2]` through
/// `s = f/(2 + f)` and a polynomial in `s²`, returned as `(s, hfsq, r)` for the caller's sum.
#[inline(always)]
fn log_kernel(f: f32) -> (f32, f32, f32) {
    let s = f / (2.0 + f);
    let z = s * s;
    let w = z * z;
    let t1 = w * (LG2 + w * LG4);
    let t2 = z * (LG1 + w * LG3);
    let r = t2 + t1;
    let hfsq = 0.5 * f * f;
    (s, hfsq, r)
}

/// ln x, libm's `logf` (FreeBSD e_logf.c) for every `x`: −∞ for ±0, NaN below 0, +∞ for +∞,
/// NaN for NaN.
#[inline(always)]
#[must_use]
pub fn ln(x: f32) -> f32 {
    // Subnormals are scaled by 2²⁵ first.
    let sub = x < f32::MIN_POSITIVE;
    let xs = if sub {
        x * f32::from_bits(0x4c00_0000)
    } else {
        x
    };
    // Reduce x into [√2/2, √2]: x = 2ᵏ·(1 + f).
    let ix = xs.to_bits().wrapping_add(0x3f80_0000 - 0x3f35_04f3);
    let k = (ix >> 23) as i32 - 0x7f - if sub { 25 } else { 0 };
    let f = f32::from_bits((ix & 0x007f_ffff) + 0x3f35_04f3) - 1.0;
    let (s, hfsq, r) = log_kernel(f);
    let dk = k as f32;
    let y = s * (hfsq + r) + dk * LN2_LO - hfsq + f + dk * LN2_HI;
    if (x > 0.0) & (x < f32::INFINITY) {
        y
    } else if x == 0.0 {
        f32::NEG_INFINITY
    } else if x < 0.0 {
        f32::NAN
    } else {
        // +∞ and NaN.
        x
    }
}

/// ln(1 + x), libm's `log1pf` (FreeBSD s_log1pf.c) for every `x`: −∞ for −1, NaN below −1,
/// +∞ for +∞, NaN for NaN.
#[inline(always)]
#[must_use]
pub fn ln_1p(x: f32) -> f32 {
    // √2/2 − 1 ≤ x < √2 − 1: the kernel takes f = x directly (k = 0, no correction).
    let near_zero = (x >= f32::from_bits(0xbe95_f619)) & (x < f32::from_bits(0x3ed4_13d0));
    // Elsewhere u = 1 + x = 2ᵏ·(1 + f), with c ≈ ln(1 + x) − ln u correcting the rounding of u.
    let u = 1.0 + x;
    let iu = u.to_bits().wrapping_add(0x3f80_0000 - 0x3f35_04f3);
    let ku = (iu >> 23) as i32 - 0x7f;
    let cu = if ku >= 2 {
        1.0 - (u - x)
    } else {
        x - (u - 1.0)
    };
    let cu = if ku < 25 { cu / u } else { 0.0 };
    let fu = f32::from_bits((iu & 0x007f_ffff) + 0x3f35_04f3) - 1.0;
    // |x| < 2⁻²⁴ (±0 and subnormals included): libm returns x; the kernel runs on 0 there
    // (tiny f would make subnormal intermediates, which are slow).
    let tiny = abs(x) < f32::from_bits(0x3380_0000);
    let k = if near_zero { 0 } else { ku };
    let c = if near_zero { 0.0 } else { cu };
    let f = if tiny {
        0.0
    } else if near_zero {
        x
    } else {
        fu
    };
    let (s, hfsq, r) = log_kernel(f);
    let dk = k as f32;
    let y = s * (hfsq + r) + (dk * LN2_LO + c) - hfsq + f + dk * LN2_HI;
    let y = if tiny { x } else { y };
    if (x > -1.0) & (x < f32::INFINITY) {
        y
    } else if x == -1.0 {
        f32::NEG_INFINITY
    } else if x < -1.0 {
        f32::NAN
    } else {
        // +∞ and NaN.
        x
    }
}

/// eˣ − 1, libm's `expm1f` (FreeBSD s_expm1f.c) for `−27 ln 2 < x ≤ ln(f32::MAX)` and NaN,
/// the arguments it does not send to a special case. Others give meaningless values.
#[inline(always)]
#[must_use]
fn exp_m1_in_range(x: f32) -> f32 {
    let ax = abs(x);
    // libm's k: trunc(x/ln 2 ± 1/2) from 1.5 ln 2 on, ±1 above 0.5 ln 2, else 0 (x unreduced).
    let kf = expf_k::<true>(x, ax);
    // Where libm returns x the rest runs on 0 (no subnormal intermediates, see `expf_reduced`).
    let tiny = !(ax >= f32::from_bits(0x3300_0000));
    let x1 = if tiny { 0.0 } else { x };
    // Reduction x = k·ln 2 + (xr + c) (k·LN2_HI is exact); for k = 0 xr = x, c = 0.
    let hi = x1 - kf * LN2_HI;
    let lo = kf * LN2_LO;
    let xr = hi - lo;
    let c = (hi - xr) - lo;
    // The rational approximation.
    let hfx = 0.5 * xr;
    let hxs = xr * hfx;
    let r1 = 1.0 + hxs * (EXPM1_Q1 + hxs * EXPM1_Q2);
    let t = 3.0 - r1 * hfx;
    let e = hxs * ((r1 - t) / (6.0 - xr * t));
    let y0 = xr - (xr * e - hxs);
    let e = xr * (e - c) - c;
    let e = e - hxs;
    // Reconstruction, by libm's cases of k.
    let y_m1 = 0.5 * (xr - e) - 0.5;
    let y_1 = if xr < -0.25 {
        -2.0 * (e - (xr + 0.5))
    } else {
        1.0 + 2.0 * (xr - e)
    };
    let two_k = pow2(kf);
    let y_wide = xr - e + 1.0;
    let y_wide = if kf == 128.0 {
        y_wide * 2.0 * X1P127
    } else {
        y_wide * two_k
    };
    let y_wide = y_wide - 1.0;
    let two_mk = pow2(-kf);
    let y_lo = (xr - e + (1.0 - two_mk)) * two_k;
    let y_hi = (xr - (e + two_mk) + 1.0) * two_k;
    let y = if kf == 0.0 {
        y0
    } else if kf == -1.0 {
        y_m1
    } else if kf == 1.0 {
        y_1
    } else if (kf < 0.0) | (kf > 56.0) {
        y_wide
    } else if kf < 23.0 {
        y_lo
    } else {
        y_hi
    };
    // |x| < 2⁻²⁵ (NaN included): x itself.
    if tiny {
        x
    } else {
        y
    }
}

/// tanh x, libm's `tanhf` (after FreeBSD s_tanhf.c, through `expm1f`) for every `x`.
#[inline(always)]
#[must_use]
pub fn tanh(x: f32) -> f32 {
    let ax = abs(x);
    // libm's three formulas by |x|: above ln 3 / 2, above ln(5/3) / 2, and below; they share
    // one expm1 and one division here.
    let upper = ax > f32::from_bits(0x3f0c_9f54);
    let mid = ax > f32::from_bits(0x3e82_c578);
    // expm1(2|x|), or expm1(−2|x|) below ln(5/3)/2: the sign set by bits, not by a select,
    // which LLVM would push through expm1 (two evaluations per lane).
    let t = exp_m1_in_range(f32::from_bits(
        (2.0 * ax).to_bits() | (u32::from(!mid) << 31),
    ));
    let q = (if upper { 2.0 } else { t }) / (t + 2.0);
    let tt = if upper {
        1.0 - q
    } else if mid {
        q
    } else {
        -q
    };
    // 1 above 10; |x| itself below 2⁻¹²⁶ (±0, subnormals) and for NaN.
    let tt = if ax > 10.0 { 1.0 } else { tt };
    let tt = if ax >= f32::MIN_POSITIVE { tt } else { ax };
    // The sign of x, as libm's final negation.
    f32::from_bits(tt.to_bits() ^ (x.to_bits() & 0x8000_0000))
}

/// libm's `k_sinf` (FreeBSD k_sinf.c): sin y for `|y| ≲ π/4`, in double precision.
#[inline(always)]
fn k_sinf(x: f64) -> f32 {
    let z = x * x;
    let w = z * z;
    let r = S3 + z * S4;
    let s = z * x;
    ((x + s * (S1 + z * S2)) + s * w * r) as f32
}

/// libm's `k_cosf` (FreeBSD k_cosf.c): cos y for `|y| ≲ π/4`, in double precision.
#[inline(always)]
fn k_cosf(x: f64) -> f32 {
    let z = x * x;
    let w = z * z;
    let r = C2 + z * C3;
    (((1.0 + z * C0) + w * C1) + (w * z) * r) as f32
}

/// The largest `|x|` for which [`sin_cos_fast`] is libm (≈ 9π/4, the end of `sincosf`'s
/// small-argument cases; beyond it libm reduces modulo π/2 with more bits of π).
pub const SIN_COS_FAST_MAX: f32 = f32::from_bits(0x40e2_31d5);

/// (sin x, cos x), libm's `sincosf` (FreeBSD s_sincosf.c) for `|x| ≤ SIN_COS_FAST_MAX`
/// (NaN for NaN). Larger `|x|` give meaningless values.
#[inline(always)]
#[must_use]
pub fn sin_cos_fast(x: f32) -> (f32, f32) {
    let ax = abs(x);
    let neg = x < 0.0;
    // libm's cases |x| ≲ π/4, 3π/4, 5π/4, 7π/4, 9π/4 reduce to y = x − n·π/2 in double
    // precision (n ∈ −4..=4 of the sign of x), with n·π/2 rounded as libm's S1PIO2 … S4PIO2
    // (n = 0: y = x).
    let n: i32 = if ax > f32::from_bits(0x40af_eddf) {
        4
    } else if ax > f32::from_bits(0x407b_53d1) {
        3
    } else if ax > f32::from_bits(0x4016_cbe3) {
        2
    } else if ax > f32::from_bits(0x3f49_0fda) {
        1
    } else {
        0
    };
    let n = if neg { -n } else { n };
    let y = x as f64 - n as f64 * core::f64::consts::FRAC_PI_2;
    let s = k_sinf(y);
    let c = k_cosf(y);
    // By the quadrant n mod 4. libm's case |x| ≲ 3π/4, x > 0 takes π/2 − x, the negation of
    // y here: the kernels are odd and even bit for bit.
    let q = n & 3;
    let (a, b) = if q & 1 != 0 { (c, s) } else { (s, c) };
    let sin = if q & 2 != 0 { -a } else { a };
    let cos = if (q + 1) & 2 != 0 { -b } else { b };
    // |x| < 2⁻¹²: (x, 1).
    if ax < f32::from_bits(0x3980_0000) {
        (x, 1.0)
    } else {
        (sin, cos)
    }
}

// FreeBSD s_atanf.c: atan of the reduction points (high and low parts) and the polynomial.
const ATAN_HI: [f32; 4] = [
    f32::from_bits(0x3eed_6338),
    f32::from_bits(0x3f49_0fda),
    f32::from_bits(0x3f7b_985e),
    f32::from_bits(0x3fc9_0fda),
];
const ATAN_LO: [f32; 4] = [
    f32::from_bits(0x31ac_3769),
    f32::from_bits(0x3322_2168),
    f32::from_bits(0x3314_0fb4),
    f32::from_bits(0x33a2_2168),
];
const ATAN_T: [f32; 5] = [
    f32::from_bits(0x3eaa_aaa9),
    f32::from_bits(0xbe4c_ca98),
    f32::from_bits(0x3e11_f50d),
    f32::from_bits(0xbdda_1247),
    f32::from_bits(0x3d7c_ac25),
];

/// atan x: libm's `atanf` (FreeBSD s_atanf.c) bit for bit, for every `x`.
#[inline(always)]
#[must_use]
pub fn atan(x: f32) -> f32 {
    let ix = x.to_bits() & 0x7fff_ffff;
    let neg = x.to_bits() >> 31 != 0;
    let ax = abs(x);
    // The argument reductions of |x| ≥ 7/16, (a·|x| + b) / (c + d·|x|) with the interval's
    // coefficients chosen first, so one division per lane: libm's (2|x| − 1)/(2 + |x|),
    // (|x| − 1)/(|x| + 1), (|x| − 1.5)/(1 + 1.5|x|) and −1/|x|, bit for bit (a product by 1
    // and a sum with 0 are exact; 0·|x| is NaN only for |x| = ∞, where `huge` is chosen).
    let (a, b, c, d, hi, lo) = if ix < 0x3f30_0000 {
        (2.0, -1.0, 2.0, 1.0, ATAN_HI[0], ATAN_LO[0])
    } else if ix < 0x3f98_0000 {
        (1.0, -1.0, 1.0, 1.0, ATAN_HI[1], ATAN_LO[1])
    } else if ix < 0x401c_0000 {
        (1.0, -1.5, 1.0, 1.5, ATAN_HI[2], ATAN_LO[2])
    } else {
        (0.0, -1.0, 0.0, 1.0, ATAN_HI[3], ATAN_LO[3])
    };
    let r = (a * ax + b) / (c + d * ax);
    let reduced = ix >= 0x3ee0_0000;
    let v = if reduced { r } else { x };
    let z = v * v;
    let w = z * z;
    let s1 = z * (ATAN_T[0] + w * (ATAN_T[2] + w * ATAN_T[4]));
    let s2 = w * (ATAN_T[1] + w * ATAN_T[3]);
    let plain = v - v * (s1 + s2);
    let shifted = hi - ((v * (s1 + s2) - lo) - v);
    let shifted = if neg { -shifted } else { shifted };
    // |x| ≥ 2²⁶: ±(π/2 + 2⁻¹²⁰) rounded, NaN stays NaN.
    let huge = ATAN_HI[3] + f32::from_bits(0x0380_0000);
    let huge = if neg { -huge } else { huge };
    if ix < 0x3980_0000 {
        x
    } else if !reduced {
        plain
    } else if ix < 0x4c80_0000 {
        shifted
    } else if ix > 0x7f80_0000 {
        x
    } else {
        huge
    }
}

/// atan2(y, x): libm's `atan2f` (FreeBSD e_atan2f.c) bit for bit, for every `(y, x)`.
#[inline(always)]
#[must_use]
pub fn atan2(y: f32, x: f32) -> f32 {
    const PI: f32 = f32::from_bits(0x4049_0fdb);
    const PI_LO: f32 = f32::from_bits(0xb3bb_bd2e);
    let (hx, hy) = (x.to_bits(), y.to_bits());
    let m = ((hy >> 31) & 1) | ((hx >> 30) & 2);
    let (ix, iy) = (hx & 0x7fff_ffff, hy & 0x7fff_ffff);
    let half_pi = if m & 1 != 0 { -PI / 2.0 } else { PI / 2.0 };
    // atan(|y/x|), 0 where |y/x| < 2⁻²⁶ and x < 0.
    let z = atan(abs(y / x));
    let z = if m & 2 != 0 && iy.wrapping_add(26 << 23) < ix {
        0.0
    } else {
        z
    };
    // By the quadrant m = 2·sign(x) + sign(y), with selects (no switch: loops of this
    // vectorise). Negating a difference is the reversed difference, bit for bit.
    let neg_y = m & 1 != 0;
    let neg_x = m & 2 != 0;
    let sign = |v: f32| if neg_y { -v } else { v };
    let general = sign(if neg_x { PI - (z - PI_LO) } else { z });
    // y = 0 and x = ±∞ by the quadrant; both infinite: ±π/4, ±3π/4.
    let on_axis = if neg_x { sign(PI) } else { y };
    let x_inf = sign(if neg_x { PI } else { 0.0 });
    let both_inf = sign(if neg_x { 3.0 * PI / 4.0 } else { PI / 4.0 });
    if ix > 0x7f80_0000 || iy > 0x7f80_0000 {
        x + y
    } else if hx == 0x3f80_0000 {
        // x = 1: libm's atan(y), which is z with y's sign (atan is odd bit for bit).
        sign(z)
    } else if iy == 0 {
        on_axis
    } else if ix == 0 {
        half_pi
    } else if ix == 0x7f80_0000 {
        if iy == 0x7f80_0000 {
            both_inf
        } else {
            x_inf
        }
    } else if ix.wrapping_add(26 << 23) < iy || iy == 0x7f80_0000 {
        half_pi
    } else {
        general
    }
}

/// ⌊x⌋: libm's `floorf` for every `x` (−0 stays −0).
#[inline(always)]
#[must_use]
pub fn floor(x: f32) -> f32 {
    // Below 2²³ in magnitude: truncate through an integer and step down below a negative x.
    let t = (x as i32) as f32;
    let f = if t > x { t - 1.0 } else { t };
    // Keep the sign of zero (−0.5 → −1, −0 → −0).
    let f = if f == 0.0 {
        f32::from_bits(x.to_bits() & 0x8000_0000)
    } else {
        f
    };
    if abs(x) < 8_388_608.0 {
        f
    } else {
        x
    }
}

/// Softplus ln(1 + eˣ), [`super::softplus`]'s formula (`x` above 20, else
/// `log1pf(expf(x))`) bit for bit, for every `x`.
#[inline(always)]
#[must_use]
pub fn softplus(x: f32) -> f32 {
    let y = ln_1p(exp(x));
    if x > 20.0 {
        x
    } else {
        y
    }
}

/// Logistic sigmoid, [`super::sigmoid`]'s formula (`1/(1 + e⁻ˣ)` for `x ≥ 0`, else
/// `eˣ/(1 + eˣ)`, through libm's `expf`) bit for bit, for every `x`.
#[inline(always)]
#[must_use]
pub fn sigmoid(x: f32) -> f32 {
    let pos = x >= 0.0;
    // e^(−|x|), −|x| by setting the sign bit (see `tanh`).
    let e = exp(f32::from_bits(x.to_bits() | 0x8000_0000));
    (if pos { 1.0 } else { e }) / (1.0 + e)
}

#[cfg(test)]
pub(super) mod tests {
    //! Every function against libm for every `STEP`-th f32 bit pattern (every f32 with
    //! `NEUSAMPLE_FULL_TESTS=1`), every pattern within `WINDOW` of each of libm's thresholds,
    //! and the special values.

    extern crate std;

    use super::*;
    use std::{format, string::String, vec::Vec};

    /// The CI sweep's stride through the 2³² bit patterns (a prime: every exponent, varied
    /// mantissas).
    const STEP: u64 = 509;
    /// Bit patterns checked either side of each threshold.
    const WINDOW: u32 = 2048;
    /// Lanes per evaluation: the functions run in a loop over an array, as batches run them.
    const LANES: usize = 8;

    /// Whether every f32 is checked (`NEUSAMPLE_FULL_TESTS=1`).
    fn full() -> bool {
        std::env::var("NEUSAMPLE_FULL_TESTS").is_ok_and(|v| v == "1")
    }

    /// Equal bits, or both NaN.
    fn same(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    /// Values every sweep visits.
    const SPECIALS: [f32; 12] = [
        0.0,
        f32::from_bits(1),
        f32::from_bits(0x007f_ffff),
        f32::MIN_POSITIVE,
        1.0,
        -1.0,
        f32::MAX,
        f32::INFINITY,
        f32::NAN,
        f32::from_bits(0x7fa0_0000),
        f32::from_bits(0xffc0_0001),
        core::f32::consts::PI,
    ];

    struct Sweep<F, G, D> {
        ours: F,
        reference: G,
        domain: D,
        lanes: [f32; LANES],
        n: usize,
        checked: u64,
        bad: Vec<String>,
    }

    impl<F, G, D> Sweep<F, G, D>
    where
        F: Fn(f32) -> (f32, f32),
        G: Fn(f32) -> (f32, f32),
        D: Fn(f32) -> bool,
    {
        fn visit(&mut self, x: f32) {
            if (self.domain)(x) {
                self.lanes[self.n] = x;
                self.n += 1;
                if self.n == LANES {
                    self.flush();
                }
            }
        }

        /// Checks the lanes gathered so far, both as a lane loop and one call at a time.
        fn flush(&mut self) {
            let mut out = [(0.0f32, 0.0f32); LANES];
            for i in 0..LANES {
                out[i] = (self.ours)(self.lanes[i]);
            }
            for i in 0..self.n {
                let x = self.lanes[i];
                let want = (self.reference)(x);
                let one = (self.ours)(core::hint::black_box(x));
                for got in [out[i], one] {
                    if !(same(got.0, want.0) && same(got.1, want.1)) && self.bad.len() < 10 {
                        self.bad.push(format!(
                            "x = {x:e} ({:#010x}): got {got:?}, libm {want:?}",
                            x.to_bits()
                        ));
                    }
                }
            }
            self.checked += self.n as u64;
            self.n = 0;
        }
    }

    /// Checks `ours` against `reference` (bit for bit, or both NaN) on `domain`: every
    /// `coarse·STEP`-th bit pattern (every `coarse`-th when [`full`]), ±[`WINDOW`] bit patterns
    /// around ±each of `edges`, and [`SPECIALS`].
    pub(in crate::math) fn check(
        name: &str,
        coarse: u64,
        ours: impl Fn(f32) -> (f32, f32),
        reference: impl Fn(f32) -> (f32, f32),
        domain: impl Fn(f32) -> bool,
        edges: &[f32],
    ) {
        let mut s = Sweep {
            ours,
            reference,
            domain,
            lanes: [0.0; LANES],
            n: 0,
            checked: 0,
            bad: Vec::new(),
        };
        let step = if full() { coarse } else { coarse * STEP };
        let start = std::time::Instant::now();
        let mut bits = 0u64;
        while bits <= u64::from(u32::MAX) {
            s.visit(f32::from_bits(bits as u32));
            bits += step;
        }
        for &e in edges.iter().chain(SPECIALS.iter()) {
            for sign in [0, 0x8000_0000] {
                let centre = (e.to_bits() & 0x7fff_ffff) | sign;
                for d in 0..=2 * WINDOW {
                    s.visit(f32::from_bits(centre.wrapping_add(d).wrapping_sub(WINDOW)));
                }
            }
        }
        s.flush();
        std::eprintln!(
            "{name}: {} values checked in {:.2?}",
            s.checked,
            start.elapsed()
        );
        assert!(
            s.bad.is_empty(),
            "{name} differs from libm:\n{}",
            s.bad.join("\n")
        );
    }

    pub(in crate::math) fn one(f: impl Fn(f32) -> f32) -> impl Fn(f32) -> (f32, f32) {
        move |x| (f(x), 0.0)
    }

    pub(in crate::math) fn all(_: f32) -> bool {
        true
    }

    /// libm expf's thresholds (the ends of its cases and of k ∈ [−126, 127]).
    fn exp_edges() -> [f32; 8] {
        [
            f32::from_bits(0x3900_0000),
            f32::from_bits(0x3eb1_7218),
            f32::from_bits(0x3f85_1592),
            f32::from_bits(0x42ae_ac50),
            f32::from_bits(0x42b1_7218),
            f32::from_bits(0x42cf_f1b5),
            126.5 * core::f32::consts::LN_2,
            127.5 * core::f32::consts::LN_2,
        ]
    }

    #[test]
    fn exp_is_libm_expf() {
        check("exp", 1, one(exp), one(libm::expf), all, &exp_edges());
    }

    #[test]
    fn exp_in_range_is_libm_expf() {
        let domain = |x: f32| x >= -87.0 && x <= 88.0;
        let mut edges = exp_edges().to_vec();
        edges.extend([87.0, 88.0]);
        check(
            "exp_in_range",
            1,
            one(exp_in_range),
            one(libm::expf),
            domain,
            &edges,
        );
    }

    #[test]
    fn exp_nonpositive_is_libm_expf() {
        let domain = |x: f32| x >= -87.0 && x <= 0.0;
        let mut edges = exp_edges().to_vec();
        edges.push(87.0);
        check(
            "exp_nonpositive",
            1,
            one(exp_nonpositive),
            one(libm::expf),
            domain,
            &edges,
        );
    }

    #[test]
    fn ln_is_libm_logf() {
        let edges = [
            f32::from_bits(0x3f35_04f3),
            core::f32::consts::SQRT_2,
            2.0,
            0.5,
        ];
        check("ln", 1, one(ln), one(libm::logf), all, &edges);
    }

    #[test]
    fn ln_1p_is_libm_log1pf() {
        let edges = [
            f32::from_bits(0x3380_0000),
            f32::from_bits(0x3e95_f619),
            f32::from_bits(0x3ed4_13d0),
            core::f32::consts::SQRT_2 - 1.0,
            2.0 * core::f32::consts::SQRT_2 - 1.0,
            // u = 1 + x reaches 2²⁵·√2/2 (the end of the correction term).
            2.372_224e7,
        ];
        check("ln_1p", 1, one(ln_1p), one(libm::log1pf), all, &edges);
    }

    /// libm expm1f's thresholds and ends of its cases of k.
    fn exp_m1_edges() -> [f32; 8] {
        let ln2 = core::f32::consts::LN_2;
        [
            f32::from_bits(0x3300_0000),
            f32::from_bits(0x3eb1_7218),
            f32::from_bits(0x3f85_1592),
            f32::from_bits(0x4195_b844),
            f32::from_bits(0x42b1_7217),
            22.5 * ln2,
            56.5 * ln2,
            127.5 * ln2,
        ]
    }

    #[test]
    fn exp_m1_in_range_is_libm_expm1f() {
        let domain = |x: f32| {
            (x.is_nan() || x > -f32::from_bits(0x4195_b844)) && x <= f32::from_bits(0x42b1_7217)
        };
        check(
            "exp_m1_in_range",
            1,
            one(exp_m1_in_range),
            one(libm::expm1f),
            domain,
            &exp_m1_edges(),
        );
    }

    #[test]
    fn tanh_is_libm_tanhf() {
        let mut edges: Vec<f32> = exp_m1_edges().iter().map(|e| 0.5 * e).collect();
        edges.extend([
            f32::from_bits(0x3e82_c578),
            f32::from_bits(0x3f0c_9f54),
            10.0,
        ]);
        check("tanh", 1, one(tanh), one(libm::tanhf), all, &edges);
    }

    #[test]
    fn sin_cos_fast_is_libm_sincosf() {
        let pi = core::f32::consts::PI;
        let edges = [
            f32::from_bits(0x3980_0000),
            f32::from_bits(0x3f49_0fda),
            f32::from_bits(0x4016_cbe3),
            f32::from_bits(0x407b_53d1),
            f32::from_bits(0x40af_eddf),
            SIN_COS_FAST_MAX,
            0.5 * pi,
            pi,
            1.5 * pi,
            2.0 * pi,
        ];
        let domain = |x: f32| x.is_nan() || abs(x) <= SIN_COS_FAST_MAX;
        check(
            "sin_cos_fast",
            1,
            sin_cos_fast,
            libm::sincosf,
            domain,
            &edges,
        );
    }

    #[test]
    fn atan_is_libm_atanf() {
        let edges = [
            0.4375,
            0.6875,
            1.1875,
            2.4375,
            67_108_864.0,
            f32::from_bits(0x3980_0000),
        ];
        check("atan", 1, one(atan), one(libm::atanf), all, &edges);
    }

    #[test]
    fn floor_is_libm_floorf() {
        let edges = [0.5, 1.0, 8_388_608.0, 2_147_483_648.0];
        check("floor", 1, one(floor), one(libm::floorf), all, &edges);
    }

    #[test]
    fn atan2_is_libm_atan2f() {
        // y over the sweep, x over special values and a spread of magnitudes and signs (and
        // the reverse), so every case of e_atan2f.c is reached.
        let mut xs: Vec<f32> = SPECIALS.to_vec();
        xs.extend([2.0, 0.3, 1e-20, 1e20, 3e-39, 7.5, 1e30, 1.0e-8]);
        let negs: Vec<f32> = xs.iter().map(|v| -v).collect();
        xs.extend(negs);
        for &x in &xs {
            check(
                "atan2(y, x)",
                7,
                |y| (atan2(y, x), 0.0),
                |y| (libm::atan2f(y, x), 0.0),
                all,
                &[1.0],
            );
            check(
                "atan2(x, y)",
                7,
                |y| (atan2(x, y), 0.0),
                |y| (libm::atan2f(x, y), 0.0),
                all,
                &[1.0],
            );
        }
    }

    #[test]
    fn softplus_is_its_libm_formula() {
        let reference = |x: f32| {
            if x > 20.0 {
                x
            } else {
                libm::log1pf(libm::expf(x))
            }
        };
        let mut edges = exp_edges().to_vec();
        // exp(x) = 2⁻²⁴ and √2 − 1: the ends of log1pf's cases.
        edges.extend([
            20.0,
            -libm::logf(f32::from_bits(0x3380_0000)),
            -libm::logf(f32::from_bits(0x3ed4_13d0)),
        ]);
        check("softplus", 1, one(softplus), one(reference), all, &edges);
    }

    #[test]
    fn sigmoid_is_its_libm_formula() {
        let reference = |x: f32| {
            if x >= 0.0 {
                1.0 / (1.0 + libm::expf(-x))
            } else {
                let e = libm::expf(x);
                e / (1.0 + e)
            }
        };
        check(
            "sigmoid",
            1,
            one(sigmoid),
            one(reference),
            all,
            &exp_edges(),
        );
    }
}
