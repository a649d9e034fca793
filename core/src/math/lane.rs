//! [`Lane`]: the arithmetic that the per-point math shared by the scalar and the batched
//! paths is written in. `f32` is one point (the scalar API, GPU shaders: libm's functions);
//! the batched path implements it for eight points at once (`batch::lanes::V8`), element by
//! element with the scalar arithmetic and the fast approximations of `math::approx` for
//! the transcendental functions, so one definition of the math serves both paths (agreeing
//! within those functions' error bounds) and vectorises across points.

use core::ops::{Add, Div, Mul, Neg, Sub};

use super::{clamp, exp, exp_nonpositive, ln, safe_sqrt, sigmoid, softplus};

/// One point (`f32`) or several, with the scalar semantics per element (NaN included).
pub(crate) trait Lane:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// A comparison's outcome per element.
    type Mask: Copy;
    /// An index per element (a spline bin).
    type Index: Copy;

    /// Every element `x`.
    fn splat(x: f32) -> Self;
    /// `self >= b` per element (false for NaN).
    fn ge(self, b: Self) -> Self::Mask;
    /// `self <= b` per element.
    fn le(self, b: Self) -> Self::Mask;
    /// `self > b` per element.
    fn gt(self, b: Self) -> Self::Mask;
    /// Both masks.
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// `a` where `m`, else `b`.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// [`clamp`] per element with lane bounds.
    fn clamp_to(self, lo: Self, hi: Self) -> Self;
    /// [`exp`] per element (within 2 ulp for lanes).
    fn exp(self) -> Self;
    /// [`exp_nonpositive`] per element (within 2 ulp for lanes).
    fn exp_nonpositive(self) -> Self;
    /// [`sigmoid`] per element (within 3 ulp for lanes).
    fn sigmoid(self) -> Self;
    /// [`ln`] per element (within 2 ulp for lanes).
    fn ln(self) -> Self;
    /// [`softplus`] per element (within 4 ulp for lanes).
    fn softplus(self) -> Self;
    /// [`safe_sqrt`] per element.
    fn safe_sqrt(self) -> Self;
    /// Every element's index `k`.
    fn index(k: usize) -> Self::Index;
    /// `k` where `m`, else `i`.
    fn select_index(m: Self::Mask, k: usize, i: Self::Index) -> Self::Index;
    /// `a[i + plus]` per element, `fallback` where `i + plus ≥ K`.
    fn gather<const K: usize>(a: &[Self; K], i: Self::Index, plus: usize, fallback: f32) -> Self;
    /// `0 < i + plus < K` per element (an interior knot).
    fn interior<const K: usize>(i: Self::Index, plus: usize) -> Self::Mask;

    /// [`clamp`] per element.
    #[inline(always)]
    fn clamp(self, lo: f32, hi: f32) -> Self {
        self.clamp_to(Self::splat(lo), Self::splat(hi))
    }
}

/// The [`Lane`] methods `$name(self) -> f32` of `f32`: the scalar functions of the same name.
macro_rules! scalar_fns {
    ($($name:ident),*) => {
        $(
            #[inline(always)]
            fn $name(self) -> f32 {
                $name(self)
            }
        )*
    };
}

impl Lane for f32 {
    type Mask = bool;
    type Index = usize;

    #[inline(always)]
    fn splat(x: f32) -> f32 {
        x
    }
    #[inline(always)]
    fn ge(self, b: f32) -> bool {
        self >= b
    }
    #[inline(always)]
    fn le(self, b: f32) -> bool {
        self <= b
    }
    #[inline(always)]
    fn gt(self, b: f32) -> bool {
        self > b
    }
    #[inline(always)]
    fn and(a: bool, b: bool) -> bool {
        a && b
    }
    #[inline(always)]
    fn select(m: bool, a: f32, b: f32) -> f32 {
        if m {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn clamp_to(self, lo: f32, hi: f32) -> f32 {
        clamp(self, lo, hi)
    }
    scalar_fns!(exp, exp_nonpositive, sigmoid, ln, softplus, safe_sqrt);
    #[inline(always)]
    fn index(k: usize) -> usize {
        k
    }
    #[inline(always)]
    fn select_index(m: bool, k: usize, i: usize) -> usize {
        if m {
            k
        } else {
            i
        }
    }
    #[inline(always)]
    fn gather<const K: usize>(a: &[f32; K], i: usize, plus: usize, fallback: f32) -> f32 {
        let j = i + plus;
        if j < K {
            a[j]
        } else {
            fallback
        }
    }
    #[inline(always)]
    fn interior<const K: usize>(i: usize, plus: usize) -> bool {
        let j = i + plus;
        j > 0 && j < K
    }
}
