//! Dense layers over a chunk of `B` lanes in structure-of-arrays form: `x[i][b]` is input
//! `i` of lane `b`. The product runs in register tiles of 4 outputs × 16 lanes, so a weight
//! is read once per 16 lanes and every multiply and add is a SIMD operation. Per lane the
//! sum is `bias + x[0]·W[0] + x[1]·W[1] + …` in input order with separate multiplies and
//! adds: bit for bit the scalar [`nn::dense`](crate::nn::dense).

use super::lanes::V8;
use crate::nn::Activation;
use crate::weights::Weights;

/// Outputs per register tile.
const TJ: usize = 4;
/// Lanes per register tile (two [`V8`]).
pub(crate) const TB: usize = 16;

/// `acc[j][b] += Σ_{i < I} x[i][b] · W[offset + (row0 + i)·O + j]` for `j < O`, `b < B`:
/// rows `row0 .. row0 + I` of the row-major `· × O` matrix at `offset`, as
/// [`Weights::accumulate`] reads them, for the first `m` lanes (rounded up to a tile; `B`
/// must be a multiple of 16). Each tile's weights are read (f16 and unaligned bytes widened)
/// once per chunk.
#[inline(always)]
pub(crate) fn accumulate<W: Weights + ?Sized, const I: usize, const O: usize, const B: usize>(
    w: &W,
    offset: u32,
    row0: u32,
    x: &[[f32; B]; I],
    acc: &mut [[f32; B]; O],
    m: usize,
) {
    const { assert!(B % TB == 0, "lane chunks are whole tiles") };
    let base = offset as usize + row0 as usize * O;
    let slice = w.as_f32_slice().and_then(|s| s.get(base..base + I * O));
    let mut j0 = 0;
    while j0 < O {
        let cols = if O - j0 >= TJ { TJ } else { O - j0 };
        let mut tile = [[0.0f32; TJ]; I];
        for (i, row) in tile.iter_mut().enumerate() {
            for (t, v) in row.iter_mut().enumerate().take(cols) {
                let k = i * O + j0 + t;
                *v = match slice {
                    Some(s) => s[k],
                    None => w.at((base + k) as u32),
                };
            }
        }
        let mut b0 = 0;
        while b0 < m && b0 < B {
            tile_product::<I, O, B>(&tile, x, acc, j0, cols, b0);
            b0 += TB;
        }
        j0 += TJ;
    }
}

/// Outputs `j0 .. j0 + cols` (`cols ≤ 4`) of lanes `b0 .. b0 + 16`, in 8 vector registers.
#[inline(always)]
fn tile_product<const I: usize, const O: usize, const B: usize>(
    tile: &[[f32; TJ]; I],
    x: &[[f32; B]; I],
    acc: &mut [[f32; B]; O],
    j0: usize,
    cols: usize,
    b0: usize,
) {
    let mut a = [[V8::splat(0.0); 2]; TJ];
    for t in 0..cols {
        a[t][0] = V8::load(&acc[j0 + t][b0..]);
        a[t][1] = V8::load(&acc[j0 + t][b0 + 8..]);
    }
    for i in 0..I {
        let x0 = V8::load(&x[i][b0..]);
        let x1 = V8::load(&x[i][b0 + 8..]);
        for t in 0..TJ {
            let wv = V8::splat(tile[i][t]);
            a[t][0] = a[t][0] + x0 * wv;
            a[t][1] = a[t][1] + x1 * wv;
        }
    }
    for t in 0..cols {
        a[t][0].store(&mut acc[j0 + t][b0..]);
        a[t][1].store(&mut acc[j0 + t][b0 + 8..]);
    }
}

/// `y[j][b] = act(b_j + Σ_i x[i][b] · W[i][j])`: the dense layer `dense(I, O)` at `offset`
/// (weights then bias, `core/ARCHITECTURES.md`) for the first `m` lanes.
#[inline(always)]
pub(crate) fn dense<W: Weights + ?Sized, const I: usize, const O: usize, const B: usize>(
    w: &W,
    offset: u32,
    x: &[[f32; B]; I],
    act: Activation,
    y: &mut [[f32; B]; O],
    m: usize,
) {
    bias::<W, I, O, B>(w, offset, y);
    accumulate::<W, I, O, B>(w, offset, 0, x, y, m);
    activate(act, y, m);
}

/// Every lane of `y[j]` set to the bias `b_j` of the dense layer `dense(I, O)` at `offset`.
#[inline(always)]
pub(crate) fn bias<W: Weights + ?Sized, const I: usize, const O: usize, const B: usize>(
    w: &W,
    offset: u32,
    y: &mut [[f32; B]; O],
) {
    let b: [f32; O] = w.read(offset + (I * O) as u32);
    for (row, v) in y.iter_mut().zip(b) {
        *row = [v; B];
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
