//! [`Lanes`] (and [`V8`], eight of them): `f32` lanes with element-wise operations written as
//! plain loops over a fixed array, which LLVM turns into one 256-bit operation per eight
//! lanes under AVX2 or AVX-512, two 128-bit ones under SSE2 or NEON, and scalar code
//! elsewhere. More than eight lanes run each step on several independent vectors side by
//! side, which hides the latency of long dependency chains (the transcendental functions). Only separate multiplies and
//! adds (no fused multiply-add): every instruction set gives the same bits here (the dense
//! layers are where the paths differ). The transcendental functions are the fast
//! approximations of `math::approx` (bounded error, not libm's bits).

use core::ops::{Add, Mul};

use crate::math;
use crate::math::approx;
use crate::math::lane::Lane;

/// `[f(0), …, f(N − 1)]` as a plain loop (`core::array::from_fn`'s machinery is not always
/// inlined into the dispatched kernels, and a call there runs without their instruction set).
#[inline(always)]
fn each<T: Copy + Default, const N: usize>(f: impl Fn(usize) -> T) -> [T; N] {
    let mut r = [T::default(); N];
    for (l, v) in r.iter_mut().enumerate() {
        *v = f(l);
    }
    r
}

/// `$f` (a scalar `f32` function's path) of each lane of the [`Lanes`] `$v`, in one loop over the
/// lanes, which vectorises where `$f` does. A macro, so that `$f` is called directly in the
/// dispatched kernel (no `Fn` shim compiled without its instruction set).
macro_rules! map {
    ($v:expr, $f:path) => {{
        let mut r = $v.0;
        for x in &mut r {
            *x = $f(*x);
        }
        Lanes(r)
    }};
}

/// The [`Lane`] methods `$name(self) -> Lanes<N>` that apply the scalar function `$f` lane by lane
/// ([`map!`]).
macro_rules! lane_maps {
    ($($name:ident => $f:path,)*) => {
        $(
            #[inline(always)]
            fn $name(self) -> Lanes<N> {
                map!(self, $f)
            }
        )*
    };
}

/// The width of a small batch's element-wise steps: a chunk of at most `NARROW` lanes runs
/// them on `NARROW` lanes instead of the chunk's full width (the steps are element-wise, so
/// a lane's result does not depend on the width).
pub(crate) const NARROW: usize = 8;

/// The first `B` columns of `rows` (`B ≤ C`; zeros past `C`).
#[inline(always)]
pub(crate) fn head<T: Copy + Default, const N: usize, const B: usize, const C: usize>(
    rows: &[[T; C]; N],
) -> [[T; B]; N] {
    let mut r = [[T::default(); B]; N];
    for (r, row) in r.iter_mut().zip(rows) {
        for (d, v) in r.iter_mut().zip(row) {
            *d = *v;
        }
    }
    r
}

/// `N` `f32` lanes.
#[derive(Copy, Clone, Debug, PartialEq)]
#[repr(C, align(32))]
pub(crate) struct Lanes<const N: usize>(pub(crate) [f32; N]);

/// Eight `f32` lanes: one 256-bit vector.
pub(crate) type V8 = Lanes<8>;

impl<const N: usize> Lanes<N> {
    /// Every lane `x`.
    #[inline(always)]
    pub(crate) const fn splat(x: f32) -> Self {
        Lanes([x; N])
    }

    /// Lanes `s[0..N]` (missing elements read 0).
    #[inline(always)]
    pub(crate) fn load(s: &[f32]) -> Self {
        let mut r = [0.0f32; N];
        match s.get(..N) {
            Some(h) => r.copy_from_slice(h),
            None => {
                for (d, v) in r.iter_mut().zip(s) {
                    *d = *v;
                }
            }
        }
        Lanes(r)
    }

    /// Writes the lanes to `s[0..N]` (as many as fit).
    #[inline(always)]
    pub(crate) fn store(self, s: &mut [f32]) {
        match s.get_mut(..N) {
            Some(h) => h.copy_from_slice(&self.0),
            None => {
                for (d, v) in s.iter_mut().zip(self.0) {
                    *d = v;
                }
            }
        }
    }
}

impl<const N: usize> Add for Lanes<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        let mut r = [0.0f32; N];
        for l in 0..N {
            r[l] = self.0[l] + b.0[l];
        }
        Lanes(r)
    }
}

impl<const N: usize> Mul for Lanes<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        let mut r = [0.0f32; N];
        for l in 0..N {
            r[l] = self.0[l] * b.0[l];
        }
        Lanes(r)
    }
}

impl<const N: usize> core::ops::Sub for Lanes<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, b: Self) -> Self {
        Lanes(each(|l| self.0[l] - b.0[l]))
    }
}

impl<const N: usize> core::ops::Div for Lanes<N> {
    type Output = Self;
    #[inline(always)]
    fn div(self, b: Self) -> Self {
        Lanes(each(|l| self.0[l] / b.0[l]))
    }
}

impl<const N: usize> core::ops::Neg for Lanes<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Lanes(each(|l| -self.0[l]))
    }
}

impl<const N: usize> Lane for Lanes<N> {
    type Mask = [bool; N];
    /// Indices as floats (small integers, exact): masks and selects on floats vectorise,
    /// mixing them with integer lanes does not.
    type Index = Self;

    #[inline(always)]
    fn splat(x: f32) -> Self {
        Lanes([x; N])
    }
    #[inline(always)]
    fn ge(self, b: Self) -> [bool; N] {
        each(|l| self.0[l] >= b.0[l])
    }
    #[inline(always)]
    fn le(self, b: Self) -> [bool; N] {
        each(|l| self.0[l] <= b.0[l])
    }
    #[inline(always)]
    fn gt(self, b: Self) -> [bool; N] {
        each(|l| self.0[l] > b.0[l])
    }
    #[inline(always)]
    fn and(a: [bool; N], b: [bool; N]) -> [bool; N] {
        each(|l| a[l] & b[l])
    }
    #[inline(always)]
    fn select(m: [bool; N], a: Self, b: Self) -> Self {
        Lanes(each(|l| if m[l] { a.0[l] } else { b.0[l] }))
    }
    /// `max` then `min` (IEEE maxNum/minNum: a NaN operand gives the other one, so NaN →
    /// `lo` as in [`math::clamp`]), which vectorises where the comparisons of
    /// [`math::clamp`] stay scalar branches; the sign of a zero result may differ.
    #[inline(always)]
    fn clamp_to(self, lo: Self, hi: Self) -> Self {
        Lanes(each(|l| self.0[l].max(lo.0[l]).min(hi.0[l])))
    }
    lane_maps!(
        exp => approx::exp,
        exp_nonpositive => approx::exp_nonpositive,
        sigmoid => approx::sigmoid,
        ln => approx::ln,
        softplus => approx::softplus,
        safe_sqrt => math::safe_sqrt,
    );
    #[inline(always)]
    fn index(k: usize) -> Self {
        Lanes::splat(k as f32)
    }
    #[inline(always)]
    fn select_index(m: [bool; N], k: usize, i: Self) -> Self {
        <Self as Lane>::select(m, Lanes::splat(k as f32), i)
    }
    /// A scan over the `K` entries with selects (no per-lane loads): the compares of one
    /// index are shared by the gathers of several arrays once inlined.
    #[inline(always)]
    fn gather<const K: usize>(a: &[Self; K], i: Self, plus: usize, fallback: f32) -> Self {
        let mut r = Lanes::splat(fallback);
        let mut j = plus;
        while j < K {
            let hit = each(|l| i.0[l] == (j - plus) as f32);
            r = <Self as Lane>::select(hit, a[j], r);
            j += 1;
        }
        r
    }
    #[inline(always)]
    fn interior<const K: usize>(i: Self, plus: usize) -> [bool; N] {
        each(|l| {
            let j = i.0[l] + plus as f32;
            j > 0.0 && j < K as f32
        })
    }
}

/// [`nn::encode_scalar`](crate::nn::encode_scalar)`::<BANDS>` of every lane of `v`, written
/// to rows `at .. at + 1 + 2·BANDS` of `out`: `v`, then `sin(2ᵏπv), cos(2ᵏπv)` from one
/// [`approx::sin_cos_pi`] and the double-angle recurrences, over all `C` lanes at once.
#[inline(always)]
pub(crate) fn encode_rows<const BANDS: usize, const N: usize, const C: usize>(
    v: &[f32; C],
    out: &mut [[f32; C]; N],
    at: usize,
) {
    let mut s = [0.0f32; C];
    let mut c = [0.0f32; C];
    for l in 0..C {
        (s[l], c[l]) = approx::sin_cos_pi(v[l]);
    }
    if let Some(row) = out.get_mut(at) {
        *row = *v;
    }
    for k in 0..BANDS {
        if let Some(row) = out.get_mut(at + 1 + 2 * k) {
            *row = s;
        }
        if let Some(row) = out.get_mut(at + 2 + 2 * k) {
            *row = c;
        }
        for l in 0..C {
            let (a, b) = (s[l], c[l]);
            s[l] = 2.0 * a * b;
            c[l] = b * b - a * a;
        }
    }
}

/// [`gaussian::box_muller`](crate::distrib::gaussian::box_muller) of every lane
/// (`u ∈ [0, 1)²`): `r = √(−2 ln(1 − u0))`, `θ = 2π u1`, with the fast approximations.
#[inline(always)]
pub(crate) fn box_muller_rows<const C: usize>(
    u0: &[f32; C],
    u1: &[f32; C],
    nx: &mut [f32; C],
    ny: &mut [f32; C],
) {
    for l in 0..C {
        let r = math::safe_sqrt(-2.0 * approx::ln_1p(-u0[l]));
        let (s, c) = approx::sin_cos_pi(2.0 * u1[l]);
        nx[l] = r * c;
        ny[l] = r * s;
    }
}

/// `exp(log_pdf)` as a density with the fast `exp` (the scalar flows' `density_from_log`
/// over lanes): 0 for −∞, NaN or an overflow.
#[inline(always)]
pub(crate) fn density_from_log(log_pdf: f32) -> f32 {
    let p = approx::exp(log_pdf);
    if p > 0.0 && p < f32::INFINITY {
        p
    } else {
        0.0
    }
}

/// [`density_from_log`] of every lane, in place.
#[inline(always)]
pub(crate) fn densities_from_log<const C: usize>(log_pdf: &mut [f32; C]) {
    for v in log_pdf.iter_mut() {
        *v = density_from_log(*v);
    }
}
