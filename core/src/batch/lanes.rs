//! [`V8`]: eight `f32` lanes with element-wise operations written as plain loops over a
//! fixed array, which LLVM turns into one 256-bit operation under AVX2 or AVX-512, two
//! 128-bit ones under SSE2 or NEON, and scalar code elsewhere. Only separate multiplies and
//! adds (no fused multiply-add): every instruction set gives the same bits here (the dense
//! layers are where the paths differ).

use core::ops::{Add, Mul};

use crate::math;
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
    type Index = [u32; 8];

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
    #[inline(always)]
    fn clamp_to(self, lo: V8, hi: V8) -> V8 {
        V8(each(|l| math::clamp(self.0[l], lo.0[l], hi.0[l])))
    }
    #[inline(always)]
    fn exp_nonpositive(self) -> V8 {
        let mut r = self.0;
        for v in &mut r {
            *v = math::exp_nonpositive(*v);
        }
        V8(r)
    }
    #[inline(always)]
    fn ln(self) -> V8 {
        let mut r = self.0;
        for v in &mut r {
            *v = math::ln(*v);
        }
        V8(r)
    }
    #[inline(always)]
    fn softplus(self) -> V8 {
        let mut r = self.0;
        for v in &mut r {
            *v = math::softplus(*v);
        }
        V8(r)
    }
    #[inline(always)]
    fn safe_sqrt(self) -> V8 {
        let mut r = self.0;
        for v in &mut r {
            *v = math::safe_sqrt(*v);
        }
        V8(r)
    }
    #[inline(always)]
    fn index(k: usize) -> [u32; 8] {
        [k as u32; 8]
    }
    #[inline(always)]
    fn select_index(m: [bool; 8], k: usize, i: [u32; 8]) -> [u32; 8] {
        each(|l| if m[l] { k as u32 } else { i[l] })
    }
    #[inline(always)]
    fn gather<const K: usize>(a: &[V8; K], i: [u32; 8], plus: usize, fallback: f32) -> V8 {
        V8(each(|l| match a.get(i[l] as usize + plus) {
            Some(v) => v.0[l],
            None => fallback,
        }))
    }
    #[inline(always)]
    fn interior<const K: usize>(i: [u32; 8], plus: usize) -> [bool; 8] {
        each(|l| {
            let j = i[l] as usize + plus;
            j > 0 && j < K
        })
    }
}
