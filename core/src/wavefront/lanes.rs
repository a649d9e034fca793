//! [`V8`]: eight `f32` lanes with element-wise operations written as plain loops over a
//! fixed array, which LLVM turns into one 256-bit operation under AVX2, two 128-bit ones
//! under SSE2 or NEON, and scalar code elsewhere. Only separate multiplies and adds: no
//! fused multiply-add, so every instruction set gives the same bits.

use core::ops::{Add, Mul};

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
