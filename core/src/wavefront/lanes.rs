//! [`V8`]: eight `f32` lanes with element-wise operations written as plain loops over a
//! fixed array, which LLVM turns into one 256-bit operation under AVX2 or AVX-512, two
//! 128-bit ones under SSE2 or NEON, and scalar code elsewhere. Only separate multiplies and
//! adds (no fused multiply-add): every instruction set gives the same bits here (the dense
//! layers are where the paths differ). The transcendental functions are the fast
//! approximations of `math::approx` (bounded error, not libm's bits).

use core::ops::{Add, Mul};

use crate::math;
use crate::math::approx;
use crate::math::lane::Lane;

/// `[f(0), …, f(7)]` as a plain loop (`core::array::from_fn`'s machinery is not always
/// inlined into the dispatched kernels, and a call there runs without their instruction set).
#[inline(always)]
fn each<T: Copy + Default>(f: impl Fn(usize) -> T) -> [T; 8] {
    let mut r = [T::default(); 8];
    for (l, v) in r.iter_mut().enumerate() {
        *v = f(l);
    }
    r
}

/// `$f` (a scalar `f32` function's path) of each lane of the `V8` `$v`, in one loop over the
/// lanes, which vectorises where `$f` does. A macro, so that `$f` is called directly in the
/// dispatched kernel (no `Fn` shim compiled without its instruction set).
macro_rules! map {
    ($v:expr, $f:path) => {{
        let mut r = $v.0;
        for x in &mut r {
            *x = $f(*x);
        }
        V8(r)
    }};
}

/// The [`Lane`] methods `$name(self) -> V8` that apply the scalar function `$f` lane by lane
/// ([`map!`]).
macro_rules! lane_maps {
    ($($name:ident => $f:path,)*) => {
        $(
            #[inline(always)]
            fn $name(self) -> V8 {
                map!(self, $f)
            }
        )*
    };
}

/// Eight `f32` lanes.
#[derive(Copy, Clone, Debug, PartialEq)]
#[repr(C, align(32))]
pub(crate) struct V8(pub(crate) [f32; 8]);

impl V8 {
    /// Every lane `x`.
    #[inline(always)]
    pub(crate) const fn splat(x: f32) -> V8 {
        V8([x; 8])
    }

    /// Lanes `s[0..8]` (missing elements read 0).
    #[inline(always)]
    pub(crate) fn load(s: &[f32]) -> V8 {
        let mut r = [0.0f32; 8];
        match s.get(..8) {
            Some(h) => r.copy_from_slice(h),
            None => {
                for (d, v) in r.iter_mut().zip(s) {
                    *d = *v;
                }
            }
        }
        V8(r)
    }

    /// Writes the lanes to `s[0..8]` (as many as fit).
    #[inline(always)]
    pub(crate) fn store(self, s: &mut [f32]) {
        match s.get_mut(..8) {
            Some(h) => h.copy_from_slice(&self.0),
            None => {
                for (d, v) in s.iter_mut().zip(self.0) {
                    *d = v;
                }
            }
        }
    }
}

impl Add for V8 {
    type Output = V8;
    #[inline(always)]
    fn add(self, b: V8) -> V8 {
        let mut r = [0.0f32; 8];
        for l in 0..8 {
            r[l] = self.0[l] + b.0[l];
        }
        V8(r)
    }
}

impl Mul for V8 {
    type Output = V8;
    #[inline(always)]
    fn mul(self, b: V8) -> V8 {
        let mut r = [0.0f32; 8];
        for l in 0..8 {
            r[l] = self.0[l] * b.0[l];
        }
        V8(r)
    }
}

impl core::ops::Sub for V8 {
    type Output = V8;
    #[inline(always)]
    fn sub(self, b: V8) -> V8 {
        V8(each(|l| self.0[l] - b.0[l]))
    }
}

impl core::ops::Div for V8 {
    type Output = V8;
    #[inline(always)]
    fn div(self, b: V8) -> V8 {
        V8(each(|l| self.0[l] / b.0[l]))
    }
}

impl core::ops::Neg for V8 {
    type Output = V8;
    #[inline(always)]
    fn neg(self) -> V8 {
        V8(each(|l| -self.0[l]))
    }
}

impl Lane for V8 {
    type Mask = [bool; 8];
    /// Indices as floats (small integers, exact): masks and selects on floats vectorise,
    /// mixing them with integer lanes does not.
    type Index = V8;

    #[inline(always)]
    fn splat(x: f32) -> V8 {
        V8([x; 8])
    }
    #[inline(always)]
    fn ge(self, b: V8) -> [bool; 8] {
        each(|l| self.0[l] >= b.0[l])
    }
    #[inline(always)]
    fn le(self, b: V8) -> [bool; 8] {
        each(|l| self.0[l] <= b.0[l])
    }
    #[inline(always)]
    fn gt(self, b: V8) -> [bool; 8] {
        each(|l| self.0[l] > b.0[l])
    }
    #[inline(always)]
    fn and(a: [bool; 8], b: [bool; 8]) -> [bool; 8] {
        each(|l| a[l] & b[l])
    }
    #[inline(always)]
    fn select(m: [bool; 8], a: V8, b: V8) -> V8 {
        V8(each(|l| if m[l] { a.0[l] } else { b.0[l] }))
    }
    /// `max` then `min` (IEEE maxNum/minNum: a NaN operand gives the other one, so NaN →
    /// `lo` as in [`math::clamp`]), which vectorises where the comparisons of
    /// [`math::clamp`] stay scalar branches; the sign of a zero result may differ.
    #[inline(always)]
    fn clamp_to(self, lo: V8, hi: V8) -> V8 {
        V8(each(|l| self.0[l].max(lo.0[l]).min(hi.0[l])))
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
    fn index(k: usize) -> V8 {
        V8::splat(k as f32)
    }
    #[inline(always)]
    fn select_index(m: [bool; 8], k: usize, i: V8) -> V8 {
        <V8 as Lane>::select(m, V8::splat(k as f32), i)
    }
    /// A scan over the `K` entries with selects (no per-lane loads): the compares of one
    /// index are shared by the gathers of several arrays once inlined.
    #[inline(always)]
    fn gather<const K: usize>(a: &[V8; K], i: V8, plus: usize, fallback: f32) -> V8 {
        let mut r = V8::splat(fallback);
        let mut j = plus;
        while j < K {
            let hit = each(|l| i.0[l] == (j - plus) as f32);
            r = <V8 as Lane>::select(hit, a[j], r);
            j += 1;
        }
        r
    }
    #[inline(always)]
    fn interior<const K: usize>(i: V8, plus: usize) -> [bool; 8] {
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

/// `exp(log_pdf)` as a density (the batched path's
/// [`density_from_log`](crate::samplers::coupling::density_from_log)): 0 for −∞, NaN or an
/// overflow.
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
