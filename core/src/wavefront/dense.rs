//! Dense layers over a chunk of `B` lanes in structure-of-arrays form: `x[i][b]` is input
//! `i` of lane `b`. The product runs in register tiles of a few outputs × 16 or 32 lanes, so
//! a weight is read once per tile and every multiply-add is a SIMD operation; aligned f32
//! weights are read in place, others (f16, unaligned bytes) widened into a copy once per
//! tile and chunk.
//!
//! Per lane the sum is `bias + x[0]·W[0] + x[1]·W[1] + …` in input order. On x86-64 with
//! AVX-512 (x86-64-v4) or AVX2 + FMA (x86-64-v3) each step is one fused multiply-add
//! (`pulp`'s safe intrinsics; one rounding per step); the portable path multiplies and adds
//! separately, bit for bit the scalar [`nn::dense`](crate::nn::dense). The paths agree to
//! within the rounding of the products (the tolerance is in the `wavefront` docs); each is
//! deterministic.

use super::lanes::{Lanes, V8};
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
use super::simd::{self, Isa};
use crate::nn::{Activation, ReluMlp};
use crate::weights::Weights;

/// Lanes per register tile of the portable path (two [`V8`]); chunks are whole tiles.
pub(crate) const TB: usize = 16;

/// How a product starts: from the bias of the layer (at the weights' `offset + I·O`) or
/// from the values already in the output.
#[derive(Copy, Clone, PartialEq, Eq)]
enum Start {
    Bias,
    Output,
}

/// `y[j][b] = act(b_j + Σ_i x[i][b] · W[i][j])`: the dense layer `dense(I, O)` at `offset`
/// (weights then bias, `core/ARCHITECTURES.md`) for the first `m` lanes (rounded up to a
/// tile; the other lanes of `y` are left as they were or overwritten).
#[inline(always)]
pub(crate) fn dense<W: Weights + ?Sized, const I: usize, const O: usize, const B: usize>(
    w: &W,
    offset: u32,
    x: &[[f32; B]; I],
    act: Activation,
    y: &mut [[f32; B]; O],
    m: usize,
) {
    product::<W, I, O, B>(w, offset, 0, x, y, m, Start::Bias, act);
}

impl<const I: usize, const H: usize, const O: usize, const L: usize> ReluMlp<I, H, O, L> {
    /// [`ReluMlp::forward`] over the first `m` lanes of a chunk, into `y`.
    #[inline(always)]
    pub(crate) fn forward_lanes<W: Weights + ?Sized, const B: usize>(
        w: &W,
        x: &[[f32; B]; I],
        y: &mut [[f32; B]; O],
        m: usize,
    ) {
        Self::forward_lanes_in(w, x, &mut [[[0.0; B]; H]; 2], y, m);
    }

    /// [`ReluMlp::forward_lanes`] with the hidden layers' activations in `h` (working
    /// memory, so that a caller that keeps it across chunks does not zero it again).
    #[inline(always)]
    pub(crate) fn forward_lanes_in<W: Weights + ?Sized, const B: usize>(
        w: &W,
        x: &[[f32; B]; I],
        h: &mut [[[f32; B]; H]; 2],
        y: &mut [[f32; B]; O],
        m: usize,
    ) {
        let offsets = Self::OFFSETS;
        let relu = Activation::Relu;
        dense(w, offsets[0] as u32, x, relu, &mut h[0], m);
        let mut k = 1;
        while k + 1 < L {
            let [a, b] = h;
            let (src, dst) = if k % 2 == 1 { (&*a, b) } else { (&*b, a) };
            dense(w, offsets[k] as u32, src, relu, dst, m);
            k += 1;
        }
        dense(
            w,
            offsets[L - 1] as u32,
            &h[(L - 2) % 2],
            Activation::Identity,
            y,
            m,
        );
    }
}

/// `acc[j][b] += Σ_{i < I} x[i][b] · W[offset + (row0 + i)·O + j]` for `j < O`, `b < B`:
/// rows `row0 .. row0 + I` of the row-major `· × O` matrix at `offset`, as
/// [`Weights::accumulate`] reads them, for the first `m` lanes (rounded up to a tile; `B`
/// must be a multiple of 16).
#[inline(always)]
pub(crate) fn accumulate<W: Weights + ?Sized, const I: usize, const O: usize, const B: usize>(
    w: &W,
    offset: u32,
    row0: u32,
    x: &[[f32; B]; I],
    acc: &mut [[f32; B]; O],
    m: usize,
) {
    product::<W, I, O, B>(
        w,
        offset,
        row0,
        x,
        acc,
        m,
        Start::Output,
        Activation::Identity,
    );
}

/// [`accumulate`] followed by `act` on the first `m` lanes (fused into the product's
/// stores where the activation allows).
#[inline(always)]
pub(crate) fn accumulate_act<
    W: Weights + ?Sized,
    const I: usize,
    const O: usize,
    const B: usize,
>(
    w: &W,
    offset: u32,
    row0: u32,
    x: &[[f32; B]; I],
    acc: &mut [[f32; B]; O],
    m: usize,
    act: Activation,
) {
    product::<W, I, O, B>(w, offset, row0, x, acc, m, Start::Output, act);
}

/// For each offset in `offsets`, the condition's share of the dense layer `dense(I, O)` there,
/// into `shares`: its bias plus its first `C` input rows times `c`, no activation, for the
/// first `m` lanes (the other lanes hold the bias).
#[inline(always)]
pub(crate) fn condition_shares<
    W: Weights + ?Sized,
    const I: usize,
    const C: usize,
    const O: usize,
    const B: usize,
    const N: usize,
>(
    w: &W,
    offsets: [u32; N],
    c: &[[f32; B]; C],
    m: usize,
    shares: &mut [[[f32; B]; O]; N],
) {
    for (y, offset) in shares.iter_mut().zip(offsets) {
        let b: [f32; O] = w.read(offset + (I * O) as u32);
        for (row, v) in y.iter_mut().zip(b) {
            *row = [v; B];
        }
        accumulate::<W, C, O, B>(w, offset, 0, c, y, m);
    }
}

/// The activation applied to the first `m` lanes of every row.
#[inline(always)]
pub(crate) fn activate<const O: usize, const B: usize>(
    act: Activation,
    y: &mut [[f32; B]; O],
    m: usize,
) {
    if act == Activation::Identity {
        return;
    }
    let m = if m < B { m } else { B };
    for row in y.iter_mut() {
        for v in row[..m].iter_mut() {
            *v = act.apply(*v);
        }
    }
}

/// Whether the tiled kernels apply `act` in their stores (the piecewise-linear ones);
/// otherwise [`activate`] runs after the product.
#[inline(always)]
fn fused(act: Activation) -> bool {
    matches!(
        act,
        Activation::Identity | Activation::Relu | Activation::LeakyRelu
    )
}

/// The product behind [`dense`], [`accumulate`] and [`accumulate_act`], on the instruction
/// set the batched kernels run with ([`simd::current`]). Not inlined: a sampler's kernel,
/// compiled once per instruction set, calls the one copy of each layer shape, which holds
/// the tiled kernel of every instruction set.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn product<W: Weights + ?Sized, const I: usize, const O: usize, const B: usize>(
    w: &W,
    offset: u32,
    row0: u32,
    x: &[[f32; B]; I],
    y: &mut [[f32; B]; O],
    m: usize,
    start: Start,
    act: Activation,
) {
    const { assert!(B.is_multiple_of(TB), "lane chunks are whole tiles") };
    let m = if m < B { m } else { B };
    let fuse = fused(act);
    let store_act = if fuse { act } else { Activation::Identity };
    let args = Args {
        w,
        offset,
        row0,
        x,
        m,
        start,
        act: store_act,
    };
    // At most eight lanes fill one AVX2 vector: AVX-512's sixteen would compute as many
    // unused lanes as used ones (the same sums either way: fused multiply-adds in input
    // order).
    #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
    let isa = match simd::current() {
        Isa::X86V4 if m <= 8 => Isa::X86V3,
        isa => isa,
    };
    #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
    let done = match isa {
        Isa::X86V4 => match pulp::x86::V4::try_new() {
            Some(s) => {
                s.vectorize(Tiled::<_, W, I, O, B, 8, 2> {
                    s,
                    args: &args,
                    y: &mut *y,
                });
                true
            }
            None => false,
        },
        Isa::X86V3 => match pulp::x86::V3::try_new() {
            Some(s) => {
                s.vectorize(Tiled::<_, W, I, O, B, 6, 2> {
                    s,
                    args: &args,
                    y: &mut *y,
                });
                true
            }
            None => false,
        },
        Isa::Portable | Isa::Neon => false,
    };
    // 6 outputs × 4 vectors: 24 accumulators, 4 inputs and the weight in NEON's 32 registers.
    #[cfg(target_arch = "aarch64")]
    let done = match (simd::current(), pulp::aarch64::Neon::try_new()) {
        (Isa::Neon, Some(s)) => {
            s.vectorize(Tiled::<_, W, I, O, B, 6, 4> {
                s,
                args: &args,
                y: &mut *y,
            });
            true
        }
        _ => false,
    };
    #[cfg(not(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64")))]
    let done = false;
    if !done {
        // The activation in a pass of its own, not a run-time `match` per value inside the
        // tile's stores.
        let plain = Args {
            act: Activation::Identity,
            ..args
        };
        portable::<W, I, O, B>(&plain, y);
        activate(act, y, m);
    } else if !fuse {
        activate(act, y, m);
    }
}

/// The arguments of one product.
struct Args<'a, W: ?Sized, const I: usize, const B: usize> {
    w: &'a W,
    offset: u32,
    row0: u32,
    x: &'a [[f32; B]; I],
    m: usize,
    start: Start,
    /// Applied in the stores: identity, ReLU or leaky ReLU.
    act: Activation,
}

impl<W: Weights + ?Sized, const I: usize, const B: usize> Args<'_, W, I, B> {
    /// The aligned f32 weights from row `row0` of the `· × O` matrix to the end of the
    /// parameters (the rows, then at least the bias), for [`by_lane`]; `None` for other
    /// storage.
    #[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
    #[inline(always)]
    fn rows_onward<const O: usize>(&self) -> Option<&[f32]> {
        let base = self.offset as usize + self.row0 as usize * O;
        self.w.as_f32_slice()?.get(base..)
    }

    /// Rows `row0 .. row0 + I` of [`Self::rows_onward`] (the tiles then read them without
    /// a copy).
    #[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
    #[inline(always)]
    fn rows<const O: usize>(&self) -> Option<&[[f32; O]; I]> {
        let s = self.rows_onward::<O>()?.get(..I * O)?;
        s.as_chunks::<O>().0.try_into().ok()
    }

    /// Columns `j0 .. j0 + J` of rows `row0 .. row0 + I` of the `· × O` matrix, widened to
    /// f32 (0 past column `O − 1`).
    #[inline(always)]
    fn tile<const O: usize, const J: usize>(&self, j0: usize) -> [[f32; J]; I] {
        let base = self.offset as usize + self.row0 as usize * O;
        let mut tile = [[0.0f32; J]; I];
        let cols = if O - j0 >= J { J } else { O - j0 };
        match self
            .w
            .as_f32_slice()
            .and_then(|s| s.get(base..base + I * O))
        {
            Some(s) => {
                for (t, row) in tile.iter_mut().zip(s.chunks_exact(O)) {
                    // A whole tile row is a copy of known length (moves, not a `memcpy` call).
                    if let Some(r) = row.get(j0..j0 + J) {
                        t.copy_from_slice(r);
                    } else if let Some(r) = row.get(j0..j0 + cols) {
                        t[..cols].copy_from_slice(r);
                    }
                }
            }
            None => {
                for (i, t) in tile.iter_mut().enumerate() {
                    for (c, v) in t.iter_mut().enumerate().take(cols) {
                        *v = self.w.at((base + i * O + j0 + c) as u32);
                    }
                }
            }
        }
        tile
    }

    /// The bias of outputs `j0 .. j0 + J` (0 past column `O − 1`).
    #[inline(always)]
    fn bias<const O: usize, const J: usize>(&self, j0: usize) -> [f32; J] {
        let b: [f32; O] = self.w.read(self.offset + (I * O) as u32);
        let mut out = [0.0f32; J];
        for (c, v) in out.iter_mut().enumerate() {
            if let Some(x) = b.get(j0 + c) {
                *v = *x;
            }
        }
        out
    }
}

/// The portable product: tiles of 2 outputs × 16 lanes ([`V8`] pairs), separate multiplies
/// and adds. Two outputs keep the accumulators, inputs and weight of a tile within SSE2's
/// sixteen registers (four outputs spill).
#[inline(never)]
fn portable<W: Weights + ?Sized, const I: usize, const O: usize, const B: usize>(
    a: &Args<'_, W, I, B>,
    y: &mut [[f32; B]; O],
) {
    const TJ: usize = 2;
    let mut j0 = 0;
    while j0 < O {
        let cols = if O - j0 >= TJ { TJ } else { O - j0 };
        let tile = a.tile::<O, TJ>(j0);
        let bias = a.bias::<O, TJ>(j0);
        let mut b0 = 0;
        while b0 < a.m {
            let mut acc = [[V8::splat(0.0); 2]; TJ];
            for t in 0..cols {
                acc[t] = match a.start {
                    Start::Bias => [V8::splat(bias[t]); 2],
                    Start::Output => [V8::load(&y[j0 + t][b0..]), V8::load(&y[j0 + t][b0 + 8..])],
                };
            }
            for i in 0..I {
                let x0 = V8::load(&a.x[i][b0..]);
                let x1 = V8::load(&a.x[i][b0 + 8..]);
                for t in 0..TJ {
                    let wv = V8::splat(tile[i][t]);
                    acc[t][0] = acc[t][0] + x0 * wv;
                    acc[t][1] = acc[t][1] + x1 * wv;
                }
            }
            for t in 0..cols {
                for (h, v) in acc[t].iter().enumerate() {
                    let mut r = v.0;
                    if a.act != Activation::Identity {
                        for e in r.iter_mut() {
                            *e = a.act.apply(*e);
                        }
                    }
                    Lanes(r).store(&mut y[j0 + t][b0 + 8 * h..]);
                }
            }
            b0 += TB;
        }
        j0 += TJ;
    }
}

/// A vector instruction set's fused multiply-add on `LANES` f32 lanes (a `pulp` token).
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
trait Fma: Copy {
    /// The vector.
    type V: Copy;
    /// Lanes per vector.
    const LANES: usize;
    /// Every lane `x`.
    fn splat(self, x: f32) -> Self::V;
    /// `s[at .. at + LANES]` (zeros if out of range).
    fn load(self, s: &[f32], at: usize) -> Self::V;
    /// Writes `v` to `s[at .. at + LANES]` (nothing if out of range).
    fn store(self, v: Self::V, s: &mut [f32], at: usize);
    /// `a·b + c`, rounded once.
    fn fma(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// `act(v)` for identity, ReLU (`x > 0 ? x : 0`, NaN → 0) and leaky ReLU
    /// (`x ≥ 0 ? x : slope·x`, NaN stays NaN), as [`Activation::apply`].
    fn act(self, act: Activation, v: Self::V) -> Self::V;
}

/// The items of an [`Fma`] impl that differ only by vector type, width and `pulp` method
/// names: `V`, `LANES`, `splat`, `load`, `store` and `fma`.
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
macro_rules! fma_items {
    ($v:ident, $lanes:literal, $splat:ident, $mul_add:ident) => {
        type V = $v;
        const LANES: usize = $lanes;
        #[inline(always)]
        fn splat(self, x: f32) -> $v {
            self.$splat(x)
        }
        #[inline(always)]
        fn load(self, s: &[f32], at: usize) -> $v {
            match s
                .get(at..at + $lanes)
                .and_then(|h| <[f32; $lanes]>::try_from(h).ok())
            {
                Some(a) => pulp::cast(a),
                None => self.$splat(0.0),
            }
        }
        #[inline(always)]
        fn store(self, v: $v, s: &mut [f32], at: usize) {
            if let Some(h) = s.get_mut(at..at + $lanes) {
                h.copy_from_slice(&pulp::cast::<$v, [f32; $lanes]>(v));
            }
        }
        #[inline(always)]
        fn fma(self, a: $v, b: $v, c: $v) -> $v {
            self.$mul_add(a, b, c)
        }
    };
}

#[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
mod x86 {
    use super::Fma;
    use crate::nn::{Activation, LEAKY_RELU_SLOPE};
    use pulp::x86::{V3, V4};
    use pulp::{f32x16, f32x8};

    /// [`fma_items`] and `act` with `maxps`, which returns its second operand when either
    /// is NaN (so ReLU maps NaN to 0 and leaky ReLU keeps it).
    macro_rules! x86_fma {
        ($token:ident, $v:ident, $lanes:literal, $splat:ident, $mul_add:ident, $max:ident, $mul:ident) => {
            impl Fma for $token {
                fma_items!($v, $lanes, $splat, $mul_add);
                #[inline(always)]
                fn act(self, act: Activation, v: $v) -> $v {
                    match act {
                        Activation::Relu => self.$max(v, self.$splat(0.0)),
                        Activation::LeakyRelu => {
                            self.$max(v, self.$mul(v, self.$splat(LEAKY_RELU_SLOPE)))
                        }
                        _ => v,
                    }
                }
            }
        };
    }

    x86_fma!(
        V3,
        f32x8,
        8,
        splat_f32x8,
        mul_add_f32x8,
        max_f32x8,
        mul_f32x8
    );
    x86_fma!(
        V4,
        f32x16,
        16,
        splat_f32x16,
        mul_add_f32x16,
        max_f32x16,
        mul_f32x16
    );
}

#[cfg(target_arch = "aarch64")]
mod neon {
    use super::Fma;
    use crate::nn::Activation;
    use pulp::aarch64::Neon;
    use pulp::f32x4;

    impl Fma for Neon {
        fma_items!(f32x4, 4, splat_f32x4, mul_add_f32x4);
        /// Per lane with [`Activation::apply`]'s comparisons (NEON's `fmax` would keep a
        /// NaN that ReLU maps to 0); the compiler keeps it in vector registers.
        #[inline(always)]
        fn act(self, act: Activation, v: f32x4) -> f32x4 {
            match act {
                Activation::Relu | Activation::LeakyRelu => {
                    pulp::cast(pulp::cast::<f32x4, [f32; 4]>(v).map(|x| act.apply(x)))
                }
                _ => v,
            }
        }
    }
}

/// The product in register tiles of `J` outputs × `NV` vectors of lanes, with fused
/// multiply-adds of the token `S`.
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
struct Tiled<
    'a,
    S,
    W: ?Sized,
    const I: usize,
    const O: usize,
    const B: usize,
    const J: usize,
    const NV: usize,
> {
    s: S,
    args: &'a Args<'a, W, I, B>,
    y: &'a mut [[f32; B]; O],
}

#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
impl<
        S: Fma,
        W: Weights + ?Sized,
        const I: usize,
        const O: usize,
        const B: usize,
        const J: usize,
        const NV: usize,
    > pulp::NullaryFnOnce for Tiled<'_, S, W, I, O, B, J, NV>
{
    type Output = ();

    #[inline(always)]
    fn call(self) {
        let Tiled { s, args, y } = self;
        if args.m <= LANE_BY_LANE {
            if let Some(w) = args.rows_onward::<O>() {
                by_lane::<S, W, I, O, B>(s, args, w, y);
                return;
            }
        }
        let full = O / J * J;
        let mut j0 = 0;
        while j0 < full {
            block::<S, W, I, O, B, J, NV>(s, args, y, j0);
            j0 += J;
        }
        // The last 1 ‥ J − 1 outputs, with a tile of their width. Constant conditions, so
        // that only the width this layer needs is compiled.
        if const { O % J == 1 } {
            block::<S, W, I, O, B, 1, NV>(s, args, y, full);
        } else if const { O % J == 2 } {
            block::<S, W, I, O, B, 2, NV>(s, args, y, full);
        } else if const { O % J == 3 } {
            block::<S, W, I, O, B, 3, NV>(s, args, y, full);
        } else if const { O % J == 4 } {
            block::<S, W, I, O, B, 4, NV>(s, args, y, full);
        } else if const { O % J == 5 } {
            block::<S, W, I, O, B, 5, NV>(s, args, y, full);
        } else if const { O % J == 6 } {
            block::<S, W, I, O, B, 6, NV>(s, args, y, full);
        } else if const { O % J == 7 } {
            block::<S, W, I, O, B, 7, NV>(s, args, y, full);
        }
    }
}

/// Products of at most this many lanes run [`by_lane`].
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
const LANE_BY_LANE: usize = 2;

/// Output vectors [`by_lane`] holds at once.
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
const BY_LANE_VECTORS: usize = 8;

/// The product lane by lane with the layer's outputs across the vector, the weight rows
/// `w` (from row `row0` on, [`Args::rows_onward`]) read in place: for one or two lanes the
/// lane tiles would leave most of each vector idle. The same fused multiply-adds in input
/// order, so the same sums.
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
#[inline(always)]
fn by_lane<S: Fma, W: Weights + ?Sized, const I: usize, const O: usize, const B: usize>(
    s: S,
    a: &Args<'_, W, I, B>,
    w: &[f32],
    y: &mut [[f32; B]; O],
) {
    let l = S::LANES;
    let mut j0 = 0;
    while j0 < O {
        let nv = (O - j0).div_ceil(l).min(BY_LANE_VECTORS);
        let bias = a.bias::<O, { BY_LANE_VECTORS * 16 }>(j0);
        for lane in 0..a.m.min(B) {
            let mut acc = [s.splat(0.0); BY_LANE_VECTORS];
            for (v, acc) in acc.iter_mut().enumerate().take(nv) {
                let mut init = [0.0f32; 16];
                for (t, e) in init.iter_mut().enumerate().take(l) {
                    let j = j0 + v * l + t;
                    *e = match (a.start, y.get(j)) {
                        (Start::Output, Some(row)) => row[lane],
                        _ => bias[v * l + t],
                    };
                }
                *acc = s.load(&init, 0);
            }
            for i in 0..I {
                let x = s.splat(a.x[i][lane]);
                for (v, acc) in acc.iter_mut().enumerate().take(nv) {
                    let wv = load_part(s, w, i * O + j0 + v * l);
                    *acc = s.fma(x, wv, *acc);
                }
            }
            for (v, acc) in acc.iter().enumerate().take(nv) {
                let mut out = [0.0f32; 16];
                s.store(s.act(a.act, *acc), &mut out, 0);
                for (t, e) in out.iter().enumerate().take(l) {
                    if let Some(row) = y.get_mut(j0 + v * l + t) {
                        row[lane] = *e;
                    }
                }
            }
        }
        j0 += nv * l;
    }
}

/// `w[at .. at + LANES]`, zeros past the end of `w`.
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
#[inline(always)]
fn load_part<S: Fma>(s: S, w: &[f32], at: usize) -> S::V {
    if at + S::LANES <= w.len() {
        s.load(w, at)
    } else {
        let mut part = [0.0f32; 16];
        let n = w.len().saturating_sub(at).min(S::LANES);
        if let Some(src) = w.get(at..at + n) {
            part[..n].copy_from_slice(src);
        }
        s.load(&part, 0)
    }
}

/// Outputs `j0 .. j0 + J` of every tile of lanes up to `m`: tiles of `NV` vectors, then one
/// vector at a time for what is left.
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
#[inline(always)]
fn block<
    S: Fma,
    W: Weights + ?Sized,
    const I: usize,
    const O: usize,
    const B: usize,
    const J: usize,
    const NV: usize,
>(
    s: S,
    a: &Args<'_, W, I, B>,
    y: &mut [[f32; B]; O],
    j0: usize,
) {
    let bias = a.bias::<O, J>(j0);
    match a.rows::<O>() {
        // `Tiled::call`'s blocks end within the row; the guard lets the compiler drop the
        // column checks of the reads.
        Some(rows) if j0 + J <= O => {
            lane_tiles::<S, W, _, I, O, B, J, NV>(s, a, &InPlace { rows, j0 }, &bias, y, j0)
        }
        _ => lane_tiles::<S, W, _, I, O, B, J, NV>(s, a, &a.tile::<O, J>(j0), &bias, y, j0),
    }
}

/// The weights of a tile of `J` outputs: `w(i, t)` is input `i`'s weight for output
/// `j0 + t`.
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
trait TileWeights<const I: usize, const J: usize> {
    fn w(&self, i: usize, t: usize) -> f32;
}

/// A widened copy ([`Args::tile`]).
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
impl<const I: usize, const J: usize> TileWeights<I, J> for [[f32; J]; I] {
    #[inline(always)]
    fn w(&self, i: usize, t: usize) -> f32 {
        self[i][t]
    }
}

/// The f32 rows of the matrix read in place, from column `j0` (`j0 + J ≤ O`).
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
struct InPlace<'a, const I: usize, const O: usize> {
    rows: &'a [[f32; O]; I],
    j0: usize,
}

#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
impl<const I: usize, const O: usize, const J: usize> TileWeights<I, J> for InPlace<'_, I, O> {
    #[inline(always)]
    fn w(&self, i: usize, t: usize) -> f32 {
        self.rows[i][self.j0 + t]
    }
}

/// [`block`]'s lane tiles with the tile's weights `tile`.
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
#[inline(always)]
fn lane_tiles<
    S: Fma,
    W: Weights + ?Sized,
    T: TileWeights<I, J>,
    const I: usize,
    const O: usize,
    const B: usize,
    const J: usize,
    const NV: usize,
>(
    s: S,
    a: &Args<'_, W, I, B>,
    tile: &T,
    bias: &[f32; J],
    y: &mut [[f32; B]; O],
    j0: usize,
) {
    let wide = NV * S::LANES;
    let mut b0 = 0;
    while b0 + wide <= B && b0 + wide - S::LANES < a.m {
        micro::<S, W, T, I, O, B, J, NV>(s, a, tile, bias, y, j0, b0);
        b0 += wide;
    }
    while b0 < a.m {
        micro::<S, W, T, I, O, B, J, 1>(s, a, tile, bias, y, j0, b0);
        b0 += S::LANES;
    }
}

/// One register tile: outputs `j0 .. j0 + J`, lanes `b0 .. b0 + NV·LANES`.
#[cfg(any(target_arch = "x86", target_arch = "x86_64", target_arch = "aarch64"))]
#[inline(always)]
fn micro<
    S: Fma,
    W: Weights + ?Sized,
    T: TileWeights<I, J>,
    const I: usize,
    const O: usize,
    const B: usize,
    const J: usize,
    const NV: usize,
>(
    s: S,
    a: &Args<'_, W, I, B>,
    tile: &T,
    bias: &[f32; J],
    y: &mut [[f32; B]; O],
    j0: usize,
    b0: usize,
) {
    let l = S::LANES;
    let mut acc = [[s.splat(0.0); NV]; J];
    for t in 0..J {
        for v in 0..NV {
            acc[t][v] = match (a.start, y.get(j0 + t)) {
                (Start::Output, Some(row)) => s.load(row, b0 + v * l),
                _ => s.splat(bias[t]),
            };
        }
    }
    for i in 0..I {
        let mut xv = [s.splat(0.0); NV];
        for (v, e) in xv.iter_mut().enumerate() {
            *e = s.load(&a.x[i], b0 + v * l);
        }
        for t in 0..J {
            let wv = s.splat(tile.w(i, t));
            for v in 0..NV {
                acc[t][v] = s.fma(xv[v], wv, acc[t][v]);
            }
        }
    }
    for t in 0..J {
        if let Some(row) = y.get_mut(j0 + t) {
            for v in 0..NV {
                s.store(s.act(a.act, acc[t][v]), row, b0 + v * l);
            }
        }
    }
}
