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

use half::f16;

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

    /// `acc[j] += Σ_i x[i] · self[offset + (row0 + i)·O + j]` for `i < I`, `j < O`: the
    /// product of `x` with rows `row0 .. row0 + I` of the row-major `· × O` matrix stored at
    /// `offset`. This is the inner loop of every dense layer ([`crate::mlp`]); storages
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

/// Slice fast path of [`Weights::accumulate`]: one range check, then loops the compiler can
/// vectorise. Out-of-range windows read nothing (as if zero).
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
    let Some(m) = w.get(start..start + I * O) else {
        return;
    };
    for (xi, row) in x.iter().zip(m.chunks_exact(O)) {
        for (a, r) in acc.iter_mut().zip(row) {
            *a += xi * r;
        }
    }
}

impl Weights for [f32] {
    #[inline(always)]
    fn len(&self) -> u32 {
        <[f32]>::len(self) as u32
    }
    #[inline(always)]
    fn at(&self, i: u32) -> f32 {
        let i = i as usize;
        if i < <[f32]>::len(self) {
            self[i]
        } else {
            0.0
        }
    }
    #[cfg(not(target_arch = "spirv"))]
    #[inline(always)]
    fn accumulate<const I: usize, const O: usize>(
        &self,
        offset: u32,
        row0: u32,
        x: &[f32; I],
        acc: &mut [f32; O],
    ) {
        accumulate_slice(self, offset, row0, x, acc);
    }
}

impl<const N: usize> Weights for [f32; N] {
    #[inline(always)]
    fn len(&self) -> u32 {
        N as u32
    }
    #[inline(always)]
    fn at(&self, i: u32) -> f32 {
        let i = i as usize;
        if i < N {
            self[i]
        } else {
            0.0
        }
    }
}

impl<W: Weights + ?Sized> Weights for &W {
    #[inline(always)]
    fn len(&self) -> u32 {
        (**self).len()
    }
    #[inline(always)]
    fn at(&self, i: u32) -> f32 {
        (**self).at(i)
    }
    #[inline(always)]
    fn accumulate<const I: usize, const O: usize>(
        &self,
        offset: u32,
        row0: u32,
        x: &[f32; I],
        acc: &mut [f32; O],
    ) {
        (**self).accumulate(offset, row0, x, acc);
    }
}

/// Element type of a stored tensor.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum DType {
    /// IEEE-754 binary32, little-endian.
    F32,
    /// IEEE-754 binary16, little-endian, widened to f32 on read.
    F16,
}

impl DType {
    /// Bytes per element.
    #[inline]
    #[must_use]
    pub const fn size(self) -> usize {
        match self {
            DType::F32 => 4,
            DType::F16 => 2,
        }
    }
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
        }
    }

    /// Storage type of the elements.
    #[must_use]
    pub fn dtype(&self) -> DType {
        match self {
            Tensor::F32(_) | Tensor::F32Bytes(_) => DType::F32,
            Tensor::F16Bytes(_) => DType::F16,
        }
    }
}

impl Weights for Tensor<'_> {
    #[inline(always)]
    fn len(&self) -> u32 {
        match self {
            Tensor::F32(f) => <[f32]>::len(f) as u32,
            Tensor::F32Bytes(b) => (b.len() / 4) as u32,
            Tensor::F16Bytes(b) => (b.len() / 2) as u32,
        }
    }

    #[inline(always)]
    fn at(&self, i: u32) -> f32 {
        let i = i as usize;
        match self {
            Tensor::F32(f) => match f.get(i) {
                Some(v) => *v,
                None => 0.0,
            },
            Tensor::F32Bytes(b) => LeF32(b).at(i as u32),
            Tensor::F16Bytes(b) => LeF16(b).at(i as u32),
        }
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
        match self {
            Tensor::F32(f) => f.accumulate(offset, row0, x, acc),
            Tensor::F32Bytes(b) => accumulate_generic(&LeF32(b), offset, row0, x, acc),
            Tensor::F16Bytes(b) => accumulate_generic(&LeF16(b), offset, row0, x, acc),
        }
    }
}

/// Unaligned little-endian f32 bytes.
struct LeF32<'a>(&'a [u8]);

impl Weights for LeF32<'_> {
    #[inline(always)]
    fn len(&self) -> u32 {
        (self.0.len() / 4) as u32
    }
    #[inline(always)]
    fn at(&self, i: u32) -> f32 {
        let i = i as usize;
        match self.0.get(4 * i..4 * i + 4) {
            Some(s) => f32::from_le_bytes([s[0], s[1], s[2], s[3]]),
            None => 0.0,
        }
    }
}

/// Little-endian f16 bytes.
struct LeF16<'a>(&'a [u8]);

impl Weights for LeF16<'_> {
    #[inline(always)]
    fn len(&self) -> u32 {
        (self.0.len() / 2) as u32
    }
    #[inline(always)]
    fn at(&self, i: u32) -> f32 {
        let i = i as usize;
        match self.0.get(2 * i..2 * i + 2) {
            Some(s) => f16::from_le_bytes([s[0], s[1]]).to_f32(),
            None => 0.0,
        }
    }
}
