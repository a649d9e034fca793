//! [`BlobWriter`]: builds blobs (the `alloc` feature). The trainer and the tests use it; the
//! runtime only reads.

use crate::dtype::DType;
use crate::kind::{BlobKind, Interpolation, SamplerKind};
use crate::nn::FEATURE_DIM;
use crate::samplers::{direct_histogram, histogram_mixture};

use super::format::{
    Extension, Header, TensorEntry, TensorRole, CHECKSUM_LEN, DATA_ALIGN, MAGIC, PREAMBLE_LEN,
};

/// Builds blobs (needs the `alloc` feature). The trainer in `neusample-precompute` and the
/// tests use it; the runtime only reads.
#[derive(Clone, Debug)]
pub struct BlobWriter<'l> {
    header: Header<'l>,
    extension: Extension,
    tensors: alloc::vec::Vec<(TensorRole, DType, alloc::vec::Vec<u8>)>,
}

impl<'l> BlobWriter<'l> {
    /// A writer for a blob of `kind` (a [`SamplerKind`] or a [`BlobKind`]) whose parameters
    /// (and table) are stored as `dtype`. Dimensions are this build's; the histogram mixture
    /// also needs [`BlobWriter::histogram_dims`].
    #[must_use]
    pub fn new(kind: impl Into<BlobKind>, dtype: DType, label: &'l str) -> Self {
        let kind = kind.into();
        let resolution = if kind == SamplerKind::DirectHistogram {
            direct_histogram::DIRECT_N as u32
        } else {
            0
        };
        BlobWriter {
            header: Header {
                kind,
                dtype,
                feature_dim: FEATURE_DIM as u32,
                param_count: kind.param_count() as u32,
                basis: if kind == SamplerKind::HistogramMixture {
                    histogram_mixture::BASES as u32
                } else {
                    0
                },
                t_levels: 0,
                resolution,
                interpolation: Interpolation::Nearest,
                label,
                tensor_count: 0,
            },
            extension: Extension::default(),
            tensors: alloc::vec::Vec::new(),
        }
    }

    /// A writer holding everything `blob` holds — header, defensive weight and every tensor's
    /// stored bytes — so that changing one field (e.g. [`BlobWriter::defensive`]) rewrites
    /// the blob with all else bit for bit.
    #[must_use]
    pub fn from_blob(blob: &crate::Blob<'l>) -> Self {
        BlobWriter {
            header: *blob.header(),
            extension: Extension {
                defensive: blob.defensive(),
                isotropic: blob.isotropic(),
            },
            tensors: blob
                .stored_tensors()
                .map(|(e, bytes)| (e.role, e.dtype, bytes.to_vec()))
                .collect(),
        }
    }

    /// A writer holding a measured material ([`BlobKind::Measured`]): its `shape` tensor
    /// (the sizes and the jacobian flag, as exact integers) and its 11 tables concatenated
    /// in the order of [`MeasuredShape::lens`](crate::MeasuredShape::lens), all f32.
    #[cfg(not(target_arch = "spirv"))]
    #[must_use]
    pub fn measured<W: crate::Weights>(
        material: &crate::MeasuredMaterial<W>,
        label: &'l str,
    ) -> Self {
        let shape = *material.shape();
        let parts = material.tables().as_array();
        let total: usize = parts.iter().map(|p| p.len() as usize).sum();
        let mut tables = alloc::vec::Vec::with_capacity(total);
        for p in parts {
            tables.extend((0..p.len()).map(|i| p.at(i)));
        }
        let mut w = BlobWriter::new(BlobKind::Measured, DType::F32, label);
        w.tensor(
            TensorRole::Shape,
            &super::measured::shape_values(&shape, material.jacobian()),
        );
        w.tensor(TensorRole::Tables, &tables);
        w
    }

    /// Sets the histogram mixture's table dimensions and latent-code lookup.
    #[must_use]
    pub fn histogram_dims(
        mut self,
        t_levels: u32,
        resolution: u32,
        interpolation: Interpolation,
    ) -> Self {
        self.header.t_levels = t_levels;
        self.header.resolution = resolution;
        self.header.interpolation = interpolation;
        self
    }

    /// Sets the neural material's texture dimensions (`width × height` texels; stored in the
    /// header's `resolution` and `t_levels` fields).
    #[must_use]
    pub fn texture_dims(mut self, width: u32, height: u32) -> Self {
        self.header.resolution = width;
        self.header.t_levels = height;
        self
    }

    /// Sets the defensive weight α ([`Defensive`](crate::samplers::Defensive)): the runtime
    /// samples `(1 − α)·p_learned + α·p_cosine`. A blob with α ≠ 0 is written as format
    /// version 2; α = 0 (the default) keeps version 1. [`Blob::open`](crate::Blob::open)
    /// accepts α ∈ [0, 1) for samplers and 0 for neural materials; the writer stores what it
    /// is given, so that tests can write invalid values.
    #[must_use]
    pub fn defensive(mut self, alpha: f32) -> Self {
        self.extension.defensive = alpha;
        self
    }

    /// Marks a sampler trained on an isotropic material with `wi` at azimuth 0
    /// ([`Defensive::with_isotropic`](crate::samplers::Defensive::with_isotropic)); such a
    /// blob is written as format version 3.
    #[must_use]
    pub fn isotropic(mut self, isotropic: bool) -> Self {
        self.extension.isotropic = isotropic;
        self
    }

    /// Overrides a header field for tests of the validator (wrong dimensions and the like).
    #[doc(hidden)]
    #[must_use]
    pub fn header_mut(&mut self) -> &mut Header<'l> {
        &mut self.header
    }

    /// The element type a role is stored with: the blob's `dtype` for parameters, the
    /// histogram table, the neural material's features and the measured material's tables
    /// (which [`Blob::open`](crate::Blob::open) accepts as f32 only), f32 for masses, CDFs
    /// and the measured material's shape.
    #[must_use]
    pub fn dtype_of(&self, role: TensorRole) -> DType {
        match role {
            TensorRole::Params | TensorRole::Table | TensorRole::Features | TensorRole::Tables => {
                self.header.dtype
            }
            TensorRole::Mass
            | TensorRole::Marginal
            | TensorRole::Conditional
            | TensorRole::Shape => DType::F32,
        }
    }

    /// Adds (or replaces) a tensor, converting to its storage type (f16 rounds to nearest).
    pub fn tensor(&mut self, role: TensorRole, values: &[f32]) -> &mut Self {
        let dtype = self.dtype_of(role);
        let mut bytes = alloc::vec::Vec::with_capacity(values.len() * dtype.size());
        for &v in values {
            match dtype {
                DType::F32 => bytes.extend_from_slice(&v.to_le_bytes()),
                DType::F16 => bytes.extend_from_slice(&half::f16::from_f32(v).to_le_bytes()),
                // Saturating (NaN → 0); `dtype_of` never answers U16 for f32 input.
                DType::U16 => bytes.extend_from_slice(&(v as u16).to_le_bytes()),
            }
        }
        self.tensors.retain(|(r, _, _)| *r != role);
        self.tensors.push((role, dtype, bytes));
        self
    }

    /// Adds (or replaces) a tensor of u16 values (the compact histogram-mixture layout's
    /// `conditional`, [`TableLayout::Compact`](crate::distrib::table2d::TableLayout::Compact)).
    pub fn tensor_u16(&mut self, role: TensorRole, values: &[u16]) -> &mut Self {
        let mut bytes = alloc::vec::Vec::with_capacity(values.len() * 2);
        for &v in values {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        self.tensors.retain(|(r, _, _)| *r != role);
        self.tensors.push((role, DType::U16, bytes));
        self
    }

    /// Serialises the blob. Tensors are written in role order.
    #[must_use]
    pub fn to_bytes(&self) -> alloc::vec::Vec<u8> {
        let mut tensors = self.tensors.clone();
        tensors.sort_by_key(|(r, _, _)| r.index());
        let mut header = self.header;
        header.tensor_count = tensors.len() as u32;
        // The oldest version that holds the content (bit-identical version-1 blobs when α = 0).
        let version = self.extension.version();

        // Header and directory sizes do not depend on the offsets' values only through
        // varint lengths, so lay out with a first pass and fix up until stable.
        let mut offsets = alloc::vec![0u32; tensors.len()];
        loop {
            let mut head = postcard::to_allocvec(&header).unwrap_or_default();
            if version >= 2 {
                let alpha = self.extension.defensive;
                head.extend_from_slice(&postcard::to_allocvec(&alpha).unwrap_or_default());
            }
            if version >= 3 {
                let isotropic = self.extension.isotropic;
                head.extend_from_slice(&postcard::to_allocvec(&isotropic).unwrap_or_default());
            }
            for (i, (role, dtype, bytes)) in tensors.iter().enumerate() {
                let e = TensorEntry {
                    role: *role,
                    dtype: *dtype,
                    offset: offsets[i],
                    count: (bytes.len() / dtype.size()) as u32,
                };
                head.extend_from_slice(&postcard::to_allocvec(&e).unwrap_or_default());
            }
            let mut at = (PREAMBLE_LEN + head.len()).div_ceil(DATA_ALIGN) * DATA_ALIGN;
            let mut changed = false;
            for (i, (_, _, bytes)) in tensors.iter().enumerate() {
                if offsets[i] != at as u32 {
                    offsets[i] = at as u32;
                    changed = true;
                }
                at = (at + bytes.len()).div_ceil(DATA_ALIGN) * DATA_ALIGN;
            }
            if changed {
                continue;
            }
            let end = tensors
                .last()
                .map(|(_, _, b)| offsets[offsets.len() - 1] as usize + b.len())
                .unwrap_or(PREAMBLE_LEN + head.len());
            let total = end + CHECKSUM_LEN;
            let mut out = alloc::vec::Vec::with_capacity(total);
            out.extend_from_slice(&MAGIC);
            out.extend_from_slice(&version.to_le_bytes());
            out.extend_from_slice(&(total as u32).to_le_bytes());
            out.extend_from_slice(&(head.len() as u32).to_le_bytes());
            out.extend_from_slice(&head);
            for (i, (_, _, bytes)) in tensors.iter().enumerate() {
                out.resize(offsets[i] as usize, 0);
                out.extend_from_slice(bytes);
            }
            let crc = crc32fast::hash(&out);
            out.extend_from_slice(&crc.to_le_bytes());
            return out;
        }
    }
}
