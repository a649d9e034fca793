//! Read-only views of parameter storage.
//!
//! Every network and table in this crate reads its numbers through [`Weights`], so that one
//! implementation serves three kinds of storage:
//!
//! * [`Tensor`] — a tensor inside a blob, f32 or f16 little-endian bytes, read in place
//!   (zero-copy; cast to `&[f32]` when the bytes happen to be 4-byte aligned);
//! * `[f32]` / `&[f32]` — host arrays and GPU storage buffers (the shader path: the host
//!   decodes a blob into flat f32 buffers, postcard never runs on the GPU).
//!
//! Reads are indexed by `u32` and never panic: an index past the end reads 0.0. Blob
//! validation guarantees in-range indices for every architecture, so the fallback is a
//! guard, not a code path.

use core::marker::PhantomData;

use half::f16;

use crate::dtype::DType;

/// Random access to an array of `f32` parameters.
pub trait Weights {
    /// Number of elements.
    fn len(&self) -> u32;
    /// Element `i` as f32; 0.0 when `i` is out of range.
    fn at(&self, i: u32) -> f32;
    /// `true` when there are no elements.
    #[inline(always)]
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The elements as an `f32` slice, when they are stored as one (host arrays, aligned
    /// f32 blob tensors); `None` for storage that must be decoded element by element.
    #[inline(always)]
    fn as_f32_slice(&self) -> Option<&[f32]> {
        None
    }

    /// `acc[j] += Σ_i x[i] · self[offset + (row0 + i)·O + j]` for `i < I`, `j < O`: the
    /// product of `x` with rows `row0 .. row0 + I` of the row-major `· × O` matrix stored at
    /// `offset`. This is the inner loop of every dense layer ([`crate::nn`]); storages
    /// override it to read their elements without per-element dispatch.
    #[inline(always)]
    fn accumulate<const I: usize, const O: usize>(
        &self,
        offset: u32,
        row0: u32,
        x: &[f32; I],
        acc: &mut [f32; O],
    ) {
        accumulate_generic(self, offset, row0, x, acc);
    }

    /// Elements `offset .. offset + N` as an array (0.0 for indices past the end): how dense
    /// layers read their bias. Storages override it to read the window with one range check.
    #[inline(always)]
    fn read<const N: usize>(&self, offset: u32) -> [f32; N] {
        read_generic(self, offset)
    }
}

/// The portable body of [`Weights::read`]: one [`Weights::at`] per element.
#[inline(always)]
pub fn read_generic<W: Weights + ?Sized, const N: usize>(w: &W, offset: u32) -> [f32; N] {
    let mut out = [0.0f32; N];
    let mut j = 0;
    while j < N {
        out[j] = w.at(offset + j as u32);
        j += 1;
    }
    out
}

/// Slice fast path of [`Weights::read`]: one range check for the window.
// rust-gpu: the slice fast paths use sub-slices and iterators, which rust-gpu rejects;
// shaders take the portable index loops.
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
fn read_slice<const N: usize>(w: &[f32], offset: u32) -> [f32; N] {
    let start = offset as usize;
    match w.get(start..start + N) {
        Some(s) => {
            let mut out = [0.0f32; N];
            out.copy_from_slice(s);
            out
        }
        None => read_generic(w, offset),
    }
}

/// The portable body of [`Weights::accumulate`]: index loops only (rust-gpu friendly).
#[inline(always)]
pub fn accumulate_generic<W: Weights + ?Sized, const I: usize, const O: usize>(
    w: &W,
    offset: u32,
    row0: u32,
    x: &[f32; I],
    acc: &mut [f32; O],
) {
    let mut i = 0;
    while i < I {
        let xi = x[i];
        let base = offset + (row0 + i as u32) * O as u32;
        let mut j = 0;
        while j < O {
            acc[j] += xi * w.at(base + j as u32);
            j += 1;
        }
        i += 1;
    }
}

/// Slice fast path of [`Weights::accumulate`]: one range check, then the outputs in blocks
/// of up to 32 (8 × 4 lanes) whose partial sums stay in SIMD registers (`glam::Vec4`, SSE2
/// on x86-64) while the block's rows stream past. Every output is still
/// `acc[j] + x[0]·W[0][j] + x[1]·W[1][j] + …` in input order with separate multiplies and
/// adds, so the result is bit for bit that of [`accumulate_generic`]. Out-of-range windows
/// read nothing (as if zero).
///
/// When `O` is not a multiple of 4 and the (up to 3) elements after the matrix exist — the
/// next layer's or this layer's bias — the last 4-wide vector runs past column `O − 1` into
/// lanes that are computed and dropped; otherwise the leftover columns are summed one by one.
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
fn accumulate_slice<const I: usize, const O: usize>(
    w: &[f32],
    offset: u32,
    row0: u32,
    x: &[f32; I],
    acc: &mut [f32; O],
) {
    let start = offset as usize + row0 as usize * O;
    #[cfg(any(
        target_feature = "sse2",
        target_feature = "neon",
        target_feature = "simd128"
    ))]
    match w.get(start..start + I * O + (4 - O % 4) % 4) {
        Some(m) => window::accumulate_window::<I, O, true>(m, x, acc),
        None => {
            if let Some(m) = w.get(start..start + I * O) {
                window::accumulate_window::<I, O, false>(m, x, acc);
            }
        }
    }
    // Without SIMD registers (thumbv7em, plain wasm32) blocking only costs code size: one
    // vectorisable pass per input instead.
    #[cfg(not(any(
        target_feature = "sse2",
        target_feature = "neon",
        target_feature = "simd128"
    )))]
    if let Some(m) = w.get(start..start + I * O) {
        for (xi, row) in x.iter().zip(m.chunks_exact(O)) {
            for (a, r) in acc.iter_mut().zip(row) {
                *a += xi * r;
            }
        }
    }
}

#[cfg(all(
    not(target_arch = "spirv"),
    any(
        target_feature = "sse2",
        target_feature = "neon",
        target_feature = "simd128"
    )
))]
mod window {
    //! The SIMD-register blocks of [`accumulate_slice`](super::accumulate_slice).

    /// [`accumulate_slice`](super::accumulate_slice) on its window `m` (`I` rows of `O`, plus the
    /// padding if `PADDED`): blocks of 8 vectors, then one block of the 1‥8 vectors left (the last
    /// one possibly running past the row; so that no pass over the rows has fewer independent sums
    /// than needed), then the unpadded leftover columns.
    #[inline(always)]
    pub(super) fn accumulate_window<const I: usize, const O: usize, const PADDED: bool>(
        m: &[f32],
        x: &[f32; I],
        acc: &mut [f32; O],
    ) {
        let vecs = if PADDED { O.div_ceil(4) } else { O / 4 };
        // Blocks of 8 whole vectors (inside the row); the 1‥8 vectors left go to `accumulate_last`.
        let full = O / 4 / 8 * 8;
        let mut v = 0;
        while v < full {
            accumulate_block::<I, O, 8>(m, 4 * v, x, acc);
            v += 8;
        }
        let j0 = 4 * full;
        match vecs - full {
            1 => accumulate_last::<I, O, 1>(m, j0, x, acc),
            2 => accumulate_last::<I, O, 2>(m, j0, x, acc),
            3 => accumulate_last::<I, O, 3>(m, j0, x, acc),
            4 => accumulate_last::<I, O, 4>(m, j0, x, acc),
            5 => accumulate_last::<I, O, 5>(m, j0, x, acc),
            6 => accumulate_last::<I, O, 6>(m, j0, x, acc),
            7 => accumulate_last::<I, O, 7>(m, j0, x, acc),
            8 => accumulate_last::<I, O, 8>(m, j0, x, acc),
            _ => {}
        }
        let mut j = 4 * vecs;
        while j < O {
            accumulate_one::<I, O>(m, j, x, acc);
            j += 1;
        }
    }

    /// Outputs `j0 .. j0 + 4V` of [`accumulate_slice`](super::accumulate_slice), all inside the row
    /// (`j0 + 4V ≤ O`).
    #[inline(always)]
    fn accumulate_block<const I: usize, const O: usize, const V: usize>(
        m: &[f32],
        j0: usize,
        x: &[f32; I],
        acc: &mut [f32; O],
    ) {
        use glam::Vec4;
        let Some(dst) = acc.get_mut(j0..j0 + 4 * V) else {
            return;
        };
        let mut a = [Vec4::ZERO; V];
        for (v, d) in a.iter_mut().zip(dst.chunks_exact(4)) {
            *v = Vec4::new(d[0], d[1], d[2], d[3]);
        }
        for (xi, row) in x.iter().zip(m.chunks_exact(O)) {
            let Some(r) = row.get(j0..j0 + 4 * V) else {
                return;
            };
            let xv = Vec4::splat(*xi);
            for (v, c) in a.iter_mut().zip(r.chunks_exact(4)) {
                *v += xv * Vec4::new(c[0], c[1], c[2], c[3]);
            }
        }
        for (v, d) in a.iter().zip(dst.chunks_exact_mut(4)) {
            d.copy_from_slice(&v.to_array());
        }
    }

    /// The last block of [`accumulate_slice`](super::accumulate_slice): outputs `j0 ..` up to `O`,
    /// in `V` vectors whose lanes past `O − 1` (padded windows only) read the elements after each
    /// row and are dropped.
    #[inline(always)]
    fn accumulate_last<const I: usize, const O: usize, const V: usize>(
        m: &[f32],
        j0: usize,
        x: &[f32; I],
        acc: &mut [f32; O],
    ) {
        use glam::Vec4;
        let mut a = [[0.0f32; 4]; V];
        let mut l = 0;
        while l < 4 * V {
            if let Some(v) = acc.get(j0 + l) {
                a[l / 4][l % 4] = *v;
            }
            l += 1;
        }
        let mut a = a.map(Vec4::from_array);
        let mut i = 0;
        while i < I {
            let Some(r) = m.get(i * O + j0..i * O + j0 + 4 * V) else {
                return;
            };
            let xv = Vec4::splat(x[i]);
            for (v, c) in a.iter_mut().zip(r.chunks_exact(4)) {
                *v += xv * Vec4::new(c[0], c[1], c[2], c[3]);
            }
            i += 1;
        }
        l = 0;
        while l < 4 * V {
            if let Some(d) = acc.get_mut(j0 + l) {
                *d = a[l / 4][l % 4];
            }
            l += 1;
        }
    }

    /// Output `j` of [`accumulate_slice`](super::accumulate_slice) alone (the < 4 outputs left
    /// after the blocks).
    #[inline(always)]
    fn accumulate_one<const I: usize, const O: usize>(
        m: &[f32],
        j: usize,
        x: &[f32; I],
        acc: &mut [f32; O],
    ) {
        let Some(a) = acc.get_mut(j) else {
            return;
        };
        let mut s = *a;
        for (xi, row) in x.iter().zip(m.chunks_exact(O)) {
            if let Some(r) = row.get(j) {
                s += xi * r;
            }
        }
        *a = s;
    }
}

/// Implements every [`Weights`] method of an `f32` storage indexed in place (`$s[i]`), whose
/// element count is `$n` (a `usize` expression of `$s`).
macro_rules! contiguous_weights {
    ($s:ident, $n:expr) => {
        #[inline(always)]
        fn len(&$s) -> u32 {
            $n as u32
        }
        #[inline(always)]
        fn as_f32_slice(&$s) -> Option<&[f32]> {
            Some($s)
        }
        #[inline(always)]
        fn at(&$s, i: u32) -> f32 {
            let i = i as usize;
            if i < $n {
                $s[i]
            } else {
                0.0
            }
        }
        #[cfg(not(target_arch = "spirv"))]
        #[inline(always)]
        fn accumulate<const I: usize, const O: usize>(
            &$s,
            offset: u32,
            row0: u32,
            x: &[f32; I],
            acc: &mut [f32; O],
        ) {
            accumulate_slice($s, offset, row0, x, acc);
        }
        #[cfg(not(target_arch = "spirv"))]
        #[inline(always)]
        fn read<const M: usize>(&$s, offset: u32) -> [f32; M] {
            read_slice($s, offset)
        }
    };
}

impl Weights for [f32] {
    contiguous_weights!(self, <[f32]>::len(self));
}

/// Implements every [`Weights`] method by forwarding it to `$inner`, an expression of `$s`
/// (the storage these wrappers view).
macro_rules! forward_weights {
    ($s:ident => $inner:expr) => {
        #[inline(always)]
        fn len(&$s) -> u32 {
            Weights::len($inner)
        }
        #[inline(always)]
        fn at(&$s, i: u32) -> f32 {
            Weights::at($inner, i)
        }
        #[inline(always)]
        fn as_f32_slice(&$s) -> Option<&[f32]> {
            Weights::as_f32_slice($inner)
        }
        #[inline(always)]
        fn accumulate<const I: usize, const O: usize>(
            &$s,
            offset: u32,
            row0: u32,
            x: &[f32; I],
            acc: &mut [f32; O],
        ) {
            Weights::accumulate($inner, offset, row0, x, acc);
        }
        #[inline(always)]
        fn read<const M: usize>(&$s, offset: u32) -> [f32; M] {
            Weights::read($inner, offset)
        }
    };
}

/// Fixed-size arrays (test tables, constants). Indexed directly rather than forwarded to the
/// slice impl: rust-gpu cannot make a slice of an array.
impl<const N: usize> Weights for [f32; N] {
    contiguous_weights!(self, N);
}

/// Host arrays the caller owns (measured materials read from files, test tables).
#[cfg(feature = "alloc")]
impl Weights for alloc::vec::Vec<f32> {
    forward_weights!(self => self.as_slice());
}

impl<W: Weights + ?Sized> Weights for &W {
    forward_weights!(self => &**self);
}

/// A borrowed tensor: a flat array of f32 or f16 values stored little-endian.
///
/// Built by the blob decoder after validation (length, finiteness); can also be built by
/// hand with [`Tensor::from_f32`] or [`Tensor::from_bytes`].
#[derive(Copy, Clone, Debug)]
pub enum Tensor<'a> {
    /// Aligned f32 data, read directly.
    F32(&'a [f32]),
    /// Unaligned f32 little-endian bytes (length a multiple of 4).
    F32Bytes(&'a [u8]),
    /// f16 little-endian bytes (length a multiple of 2).
    F16Bytes(&'a [u8]),
    /// u16 little-endian bytes (length a multiple of 2), read as exact f32 values.
    U16Bytes(&'a [u8]),
}

impl<'a> Tensor<'a> {
    /// A tensor over host f32 data.
    #[must_use]
    pub const fn from_f32(data: &'a [f32]) -> Self {
        Tensor::F32(data)
    }

    /// A tensor over little-endian bytes of the given type: zero-copy, and cast to `&[f32]`
    /// when the bytes are aligned (and the host is little-endian). Trailing bytes that do not
    /// form a whole element are ignored.
    #[must_use]
    pub fn from_bytes(dtype: DType, bytes: &'a [u8]) -> Self {
        let whole = bytes.len() - bytes.len() % dtype.size();
        let bytes = &bytes[..whole];
        match dtype {
            DType::F32 => {
                if cfg!(target_endian = "little") {
                    if let Ok(f) = bytemuck::try_cast_slice::<u8, f32>(bytes) {
                        return Tensor::F32(f);
                    }
                }
                Tensor::F32Bytes(bytes)
            }
            DType::F16 => Tensor::F16Bytes(bytes),
            DType::U16 => Tensor::U16Bytes(bytes),
        }
    }

    /// Elements `start .. start + len` as a tensor of the same storage, without copying
    /// (aligned f32 stays [`Tensor::F32`]), or `None` when the range is not inside the tensor.
    /// How one stored tensor is split into several tables (a measured material's).
    // rust-gpu: sub-slices are not supported there; shaders read flat buffers instead.
    #[cfg(not(target_arch = "spirv"))]
    #[must_use]
    pub fn range(&self, start: u32, len: u32) -> Option<Tensor<'a>> {
        let end = start.checked_add(len)?;
        if end > Weights::len(self) {
            return None;
        }
        let (start, end) = (start as usize, end as usize);
        Some(match *self {
            Tensor::F32(f) => Tensor::F32(f.get(start..end)?),
            Tensor::F32Bytes(b) => Tensor::F32Bytes(b.get(4 * start..4 * end)?),
            Tensor::F16Bytes(b) => Tensor::F16Bytes(b.get(2 * start..2 * end)?),
            Tensor::U16Bytes(b) => Tensor::U16Bytes(b.get(2 * start..2 * end)?),
        })
    }

    /// Storage type of the elements.
    #[must_use]
    pub fn dtype(&self) -> DType {
        match self {
            Tensor::F32(_) | Tensor::F32Bytes(_) => DType::F32,
            Tensor::F16Bytes(_) => DType::F16,
            Tensor::U16Bytes(_) => DType::U16,
        }
    }
}

/// By the storage of tensor `$t`: `$aligned` with `$f` the aligned `&[f32]`, or `$bytes` with
/// `$e` a [`Weights`] view of the little-endian bytes (`&Le<…>`). One dispatch per call.
macro_rules! by_storage {
    ($t:expr, |$f:ident| $aligned:expr, |$e:ident| $bytes:expr) => {
        match $t {
            Tensor::F32($f) => $aligned,
            Tensor::F32Bytes(b) => {
                let $e = &Le::<F32Le>::new(b);
                $bytes
            }
            Tensor::F16Bytes(b) => {
                let $e = &Le::<F16Le>::new(b);
                $bytes
            }
            Tensor::U16Bytes(b) => {
                let $e = &Le::<U16Le>::new(b);
                $bytes
            }
        }
    };
}

impl Weights for Tensor<'_> {
    #[inline(always)]
    fn len(&self) -> u32 {
        match self {
            Tensor::F32(f) => <[f32]>::len(f) as u32,
            Tensor::F32Bytes(b) => (b.len() / 4) as u32,
            Tensor::F16Bytes(b) | Tensor::U16Bytes(b) => (b.len() / 2) as u32,
        }
    }

    #[inline(always)]
    fn as_f32_slice(&self) -> Option<&[f32]> {
        match self {
            Tensor::F32(f) => Some(f),
            _ => None,
        }
    }

    #[inline(always)]
    fn at(&self, i: u32) -> f32 {
        by_storage!(
            self,
            |f| match f.get(i as usize) {
                Some(v) => *v,
                None => 0.0,
            },
            |e| e.at(i)
        )
    }

    #[inline(always)]
    fn accumulate<const I: usize, const O: usize>(
        &self,
        offset: u32,
        row0: u32,
        x: &[f32; I],
        acc: &mut [f32; O],
    ) {
        // Dispatch on the storage once per block, not once per element.
        by_storage!(self, |f| f.accumulate(offset, row0, x, acc), |e| {
            accumulate_generic(e, offset, row0, x, acc)
        })
    }

    #[inline(always)]
    fn read<const N: usize>(&self, offset: u32) -> [f32; N] {
        by_storage!(self, |f| f.read(offset), |e| read_generic(e, offset))
    }
}

/// How one element of a byte tensor is stored.
trait LeElement {
    /// Bytes per element.
    const SIZE: usize;
    /// The element whose little-endian bytes are `s` (`SIZE` of them), as f32.
    fn decode(s: &[u8]) -> f32;
}

/// Unaligned little-endian f32.
struct F32Le;
/// Little-endian f16.
struct F16Le;
/// Little-endian u16, read as an exact f32 value.
struct U16Le;

impl LeElement for F32Le {
    const SIZE: usize = 4;
    #[inline(always)]
    fn decode(s: &[u8]) -> f32 {
        f32::from_le_bytes([s[0], s[1], s[2], s[3]])
    }
}

impl LeElement for F16Le {
    const SIZE: usize = 2;
    #[inline(always)]
    fn decode(s: &[u8]) -> f32 {
        f16::from_le_bytes([s[0], s[1]]).to_f32()
    }
}

impl LeElement for U16Le {
    const SIZE: usize = 2;
    #[inline(always)]
    fn decode(s: &[u8]) -> f32 {
        u16::from_le_bytes([s[0], s[1]]) as f32
    }
}

/// Little-endian bytes of elements `E`, read one element at a time.
struct Le<'a, E>(&'a [u8], PhantomData<E>);

impl<'a, E: LeElement> Le<'a, E> {
    #[inline(always)]
    fn new(bytes: &'a [u8]) -> Self {
        Le(bytes, PhantomData)
    }
}

impl<E: LeElement> Weights for Le<'_, E> {
    #[inline(always)]
    fn len(&self) -> u32 {
        (self.0.len() / E::SIZE) as u32
    }
    #[inline(always)]
    fn at(&self, i: u32) -> f32 {
        let i = i as usize;
        match self.0.get(E::SIZE * i..E::SIZE * i + E::SIZE) {
            Some(s) => E::decode(s),
            None => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random values in [−1, 1) (no RNG dependency in core).
    fn values(n: usize, seed: u32) -> [f32; 4096] {
        let mut out = [0.0f32; 4096];
        let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(1);
        let mut i = 0;
        while i < n && i < 4096 {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            out[i] = (s >> 8) as f32 / (1u32 << 23) as f32 - 1.0;
            i += 1;
        }
        out
    }

    /// The slice kernel against the per-element one, bit for bit, for windows with and
    /// without room for the padded last vector and with an offset row.
    fn check<const I: usize, const O: usize>() {
        let w = values(4096, (I * 131 + O) as u32);
        let xs = values(I, 7);
        let mut x = [0.0f32; I];
        x.copy_from_slice(&xs[..I]);
        for (offset, row0, len) in [
            (0u32, 0u32, I * O),     // exactly the matrix: no padding
            (0, 0, I * O + 3),       // room for the padded lanes
            (5, 1, 5 + (I + 1) * O), // offset and first row, no padding
            (3, 0, 4096),
            (0, 0, I * O - 1), // too short: reads nothing
        ] {
            let len = len.min(4096);
            let w = &w[..len];
            let start = values(O, 3);
            let mut fast = [0.0f32; O];
            fast.copy_from_slice(&start[..O]);
            let mut slow = fast;
            w.accumulate(offset, row0, &x, &mut fast);
            let in_range = offset as usize + (row0 as usize + I) * O <= len;
            if in_range {
                accumulate_generic(w, offset, row0, &x, &mut slow);
            }
            for j in 0..O {
                assert_eq!(
                    fast[j].to_bits(),
                    slow[j].to_bits(),
                    "I={I} O={O} offset={offset} row0={row0} len={len} j={j}"
                );
            }
        }
    }

    #[test]
    fn slice_kernel_matches_generic_bit_for_bit() {
        check::<9, 32>();
        check::<30, 32>();
        check::<32, 59>();
        check::<32, 11>();
        check::<32, 5>();
        check::<32, 2>();
        check::<32, 1>();
        check::<10, 40>();
        check::<32, 4>();
        check::<7, 3>();
        check::<60, 64>();
        check::<16, 61>();
        check::<16, 29>();
        check::<8, 31>();
        check::<8, 63>();
        check::<8, 256>();
        check::<3, 1>();
        check::<2, 3>();
        check::<1, 36>();
    }

    #[test]
    fn range_views_without_copying() {
        let v: [f32; 6] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let t = Tensor::from_f32(&v);
        let r = t.range(2, 3).unwrap();
        assert!(matches!(r, Tensor::F32(_)));
        assert_eq!((r.len(), r.at(0), r.at(2), r.at(3)), (3, 2.0, 4.0, 0.0));
        assert_eq!(t.range(6, 0).map(|r| r.len()), Some(0));
        assert!(t.range(4, 3).is_none());
        assert!(t.range(u32::MAX, 2).is_none());
        let mut bytes = [0u8; 25];
        for (i, x) in v.iter().enumerate() {
            bytes[1 + 4 * i..5 + 4 * i].copy_from_slice(&x.to_le_bytes());
        }
        let unaligned = Tensor::F32Bytes(&bytes[1..]);
        let r = unaligned.range(1, 4).unwrap();
        assert!(matches!(r, Tensor::F32Bytes(_)));
        assert_eq!((r.len(), r.at(0), r.at(3)), (4, 1.0, 4.0));
        let h = Tensor::F16Bytes(&bytes[1..]);
        assert_eq!(h.range(10, 2).map(|r| r.len()), Some(2));
        assert!(h.range(11, 2).is_none());
    }

    #[test]
    fn read_matches_at() {
        let w = values(100, 11);
        let s = &w[..100];
        let a: [f32; 7] = s.read(90);
        let b: [f32; 7] = read_generic(s, 90);
        assert_eq!(a, b);
        // Past the end: zeros, as `at` gives.
        let a: [f32; 7] = s.read(97);
        assert_eq!(a[..3], s[97..100]);
        assert_eq!(a[3..], [0.0; 4]);
    }
}
