//! The `#[repr(C)]` types of the ABI: status codes, kinds, vectors, structure-of-arrays
//! views, and the opaque handles.

use neusample::wavefront::BlobLane;
use neusample::{BlobKind, DType, Interpolation, SamplerKind, FEATURE_DIM};
use neusample_owned::{OwnedBlob, OwnedMaterial, OwnedMeasuredBlob, OwnedSampler};

/// The result of every call. `NS_OK` is 0; errors are positive; `NS_REFUSED` (a scalar call
/// whose condition or sample the sampler refused, with zeroed outputs) is not an error.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[allow(non_camel_case_types)]
pub enum NsStatus {
    /// Success.
    NS_OK = 0,
    /// A scalar call was refused: `wi` at or below the horizon, or a sample outside the
    /// support (the renderer's "no sample"). Outputs are zero (`pdf = 0`, `wo = 0`). Not an
    /// error: the last error message is not touched.
    NS_REFUSED = 1,
    /// A required pointer was NULL.
    NS_ERR_NULL_POINTER = 2,
    /// An argument is invalid: a misaligned float pointer, a length too large, an output
    /// overlapping another argument, a non-UTF-8 path, an `NsPrepared` used with another
    /// sampler than the one that prepared it.
    NS_ERR_INVALID_ARGUMENT = 3,
    /// A scalar call received a NaN or infinite input (φ, a direction or `u`).
    NS_ERR_NOT_FINITE = 4,
    /// A file could not be read.
    NS_ERR_IO = 5,
    /// A panic was caught at the boundary (a bug in neusample: please report it).
    NS_ERR_PANIC = 6,
    /// A measured-material file (RGL `.bsdf`, Mitsuba's `tensor_file`) is not one, or holds
    /// a field wrongly (truncated, missing, wrong shape or type, non-finite values): the
    /// message names the file and the field.
    NS_ERR_MEASURED_FILE = 7,
    /// Blob: fewer bytes than the format needs.
    NS_ERR_TRUNCATED = 10,
    /// Blob: not a neusample blob (bad magic).
    NS_ERR_BAD_MAGIC = 11,
    /// Blob: a format version this build does not read.
    NS_ERR_UNSUPPORTED_VERSION = 12,
    /// Blob: the CRC-32 does not match (a corrupted file).
    NS_ERR_CHECKSUM_MISMATCH = 13,
    /// Blob: the header could not be decoded.
    NS_ERR_HEADER_DECODE = 14,
    /// Blob: the header is inconsistent.
    NS_ERR_HEADER_INVALID = 15,
    /// Blob: a different kind than asked for (e.g. a sampler blob as a material).
    NS_ERR_WRONG_KIND = 16,
    /// Blob: a material (neural or measured) where a sampler was asked for.
    NS_ERR_NOT_A_SAMPLER = 17,
    /// Blob: an architecture dimension differs from this build's.
    NS_ERR_DIMENSION_MISMATCH = 18,
    /// Blob: a required tensor is missing, duplicated or unexpected.
    NS_ERR_TENSOR_MISSING = 19,
    /// Blob: a tensor has the wrong number of elements.
    NS_ERR_TENSOR_SHAPE = 20,
    /// Blob: a tensor lies outside the data section.
    NS_ERR_TENSOR_BOUNDS = 21,
    /// Blob: a tensor's element type is not allowed.
    NS_ERR_TENSOR_DTYPE = 22,
    /// Blob: a tensor holds NaN or ±∞.
    NS_ERR_NON_FINITE = 23,
    /// Batched call: argument lengths differ (cannot happen through this ABI, which takes
    /// one `n`; kept for completeness).
    NS_ERR_BATCH_LENGTH = 24,
    /// Blob: a baked table is not normalised.
    NS_ERR_TABLE_NOT_NORMALIZED = 25,
    /// Blob: another defect (a newer runtime's error).
    NS_ERR_BLOB_OTHER = 29,
}

/// What a blob holds (`neusample::BlobKind`; each constant is the kind's blob tag).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[allow(non_camel_case_types)]
pub enum NsKind {
    /// Cosine-hemisphere sampling.
    NS_KIND_COSINE = 0,
    /// Improved baseline (paper Eq. 1).
    NS_KIND_IMPROVED_BASELINE = 1,
    /// Analytic mixture (paper Eq. 2).
    NS_KIND_ANALYTIC_MIXTURE = 2,
    /// Rational-quadratic spline flow (paper Eq. 3–4).
    NS_KIND_FLOW = 3,
    /// Affine-coupling flow baseline.
    NS_KIND_AFFINE_FLOW = 4,
    /// Direct histogram baseline.
    NS_KIND_DIRECT_HISTOGRAM = 5,
    /// Histogram mixture (paper Eq. 5–6).
    NS_KIND_HISTOGRAM_MIXTURE = 6,
    /// A neural material (not a sampler).
    NS_KIND_NEURAL_MATERIAL = 7,
    /// Reparameterization sampler (Wu et al. 2025): its samples carry the warp's exact
    /// density, its pdf is a network's approximation (a sample's `mis_pdf`).
    NS_KIND_REPARAM = 8,
    /// Disk flow: spline couplings on chords, uniform base, every mass inside the disk.
    NS_KIND_DISK_FLOW = 9,
    /// A measured (RGL) material with its own VNDF sampler (not a sampler kind: open it with
    /// `ns_measured_new`, or its `.bsdf` file with `ns_measured_open_bsdf`).
    NS_KIND_MEASURED = 10,
}

impl From<BlobKind> for NsKind {
    /// The constant whose value is the kind's blob tag ([`BlobKind::tag`]; tested).
    fn from(k: BlobKind) -> Self {
        match k {
            BlobKind::Sampler(SamplerKind::Cosine) => NsKind::NS_KIND_COSINE,
            BlobKind::Sampler(SamplerKind::ImprovedBaseline) => NsKind::NS_KIND_IMPROVED_BASELINE,
            BlobKind::Sampler(SamplerKind::AnalyticMixture) => NsKind::NS_KIND_ANALYTIC_MIXTURE,
            BlobKind::Sampler(SamplerKind::SplineFlow) => NsKind::NS_KIND_FLOW,
            BlobKind::Sampler(SamplerKind::AffineFlow) => NsKind::NS_KIND_AFFINE_FLOW,
            BlobKind::Sampler(SamplerKind::DirectHistogram) => NsKind::NS_KIND_DIRECT_HISTOGRAM,
            BlobKind::Sampler(SamplerKind::HistogramMixture) => NsKind::NS_KIND_HISTOGRAM_MIXTURE,
            BlobKind::NeuralMaterial => NsKind::NS_KIND_NEURAL_MATERIAL,
            BlobKind::Sampler(SamplerKind::Reparam) => NsKind::NS_KIND_REPARAM,
            BlobKind::Sampler(SamplerKind::DiskFlow) => NsKind::NS_KIND_DISK_FLOW,
            BlobKind::Measured => NsKind::NS_KIND_MEASURED,
        }
    }
}

impl From<SamplerKind> for NsKind {
    fn from(k: SamplerKind) -> Self {
        BlobKind::Sampler(k).into()
    }
}

/// Number of feature channels φ (`neusample::FEATURE_DIM`).
pub const NS_FEATURE_DIM: usize = 8;
const _: () = assert!(NS_FEATURE_DIM == FEATURE_DIM);

/// A 2-vector (`u`, a texture coordinate).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct NsVec2 {
    /// First component.
    pub x: f32,
    /// Second component.
    pub y: f32,
}

/// A direction in the local shading frame (z = normal).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct NsVec3 {
    /// x.
    pub x: f32,
    /// y.
    pub y: f32,
    /// z (the normal's axis).
    pub z: f32,
}

/// The feature vector φ of one shading point.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct NsPhi {
    /// The [`NS_FEATURE_DIM`] channels.
    pub v: [f32; NS_FEATURE_DIM],
}

/// A linear RGB value (the BRDF, without the cosine).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct NsRgb {
    /// Red.
    pub r: f32,
    /// Green.
    pub g: f32,
    /// Blue.
    pub b: f32,
}

/// A sampled direction and its two solid-angle densities: `pdf`, the density it was drawn
/// with (the number a renderer divides `f · cos θo` by), and `mis_pdf`, the density MIS
/// weighs it with (`ns_prepared_pdf` at `wo`, as for every other strategy). They are equal
/// for every kind but the reparameterization sampler. A refused sample is all zeros.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct NsSample {
    /// The direction (local shading frame, unit length, `wo.z > 0`).
    pub wo: NsVec3,
    /// Its solid-angle density.
    pub pdf: f32,
    /// Its MIS density (solid angle).
    pub mis_pdf: f32,
}

/// A direction drawn by a measured material's own sampler: its density with respect to
/// solid angle and the RGB weight `f · cos θo / pdf`. A refused sample is all zeros.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct NsMeasuredSample {
    /// The direction (local shading frame, unit length, `wo.z > 0`).
    pub wo: NsVec3,
    /// Its solid-angle density.
    pub pdf: f32,
    /// `f(wi, wo) · cos θo / pdf` per RGB channel.
    pub weight: NsRgb,
}

/// A blob's header (`neusample::blob::Header` without the label: see `ns_blob_label`).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct NsHeader {
    /// What the blob holds.
    pub kind: NsKind,
    /// Storage type: 0 = f32, 1 = f16, 2 = u16.
    pub dtype: u32,
    /// Length of φ (8).
    pub feature_dim: u32,
    /// Number of network parameters.
    pub param_count: u32,
    /// Histogram mixture: bases K; else 0.
    pub basis: u32,
    /// Histogram mixture: latent levels T; neural material: texture height.
    pub t_levels: u32,
    /// Histograms: grid resolution N; neural material: texture width.
    pub resolution: u32,
    /// Histogram mixture: 0 = nearest level, 1 = linear.
    pub interpolation: u32,
    /// Number of tensors.
    pub tensor_count: u32,
    /// Size of the blob in bytes.
    pub bytes: u64,
}

impl NsHeader {
    pub(crate) fn of(blob: &OwnedBlob) -> Self {
        let h = blob.blob().header();
        NsHeader {
            kind: h.kind.into(),
            dtype: match h.dtype {
                DType::F32 => 0,
                DType::F16 => 1,
                DType::U16 => 2,
            },
            feature_dim: h.feature_dim,
            param_count: h.param_count,
            basis: h.basis,
            t_levels: h.t_levels,
            resolution: h.resolution,
            interpolation: match h.interpolation {
                Interpolation::Nearest => 0,
                Interpolation::Linear => 1,
            },
            tensor_count: h.tensor_count,
            bytes: blob.bytes().len() as u64,
        }
    }
}

/// `n` 2-vectors as two arrays (`x[i]`, `y[i]`). A `(2, n)` row-major array `a` is
/// `{a, a + n}`.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct NsVec2s {
    /// First components.
    pub x: *const f32,
    /// Second components.
    pub y: *const f32,
}

/// `n` directions as three arrays. A `(3, n)` row-major array `a` is `{a, a + n, a + 2n}`.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct NsVec3s {
    /// x components.
    pub x: *const f32,
    /// y components.
    pub y: *const f32,
    /// z components.
    pub z: *const f32,
}

/// The feature vectors of `n` points, one array per channel. A `(8, n)` row-major array `a`
/// is `{a, a + n, …, a + 7n}`.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct NsFeatures {
    /// The channels.
    pub c: [*const f32; NS_FEATURE_DIM],
}

/// Where `ns_material_features_batch` writes φ, one array per channel.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct NsFeaturesMut {
    /// The channels.
    pub c: [*mut f32; NS_FEATURE_DIM],
}

/// Where `ns_material_eval_batch` writes: one array per RGB channel.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct NsRgbMut {
    /// Red.
    pub r: *mut f32,
    /// Green.
    pub g: *mut f32,
    /// Blue.
    pub b: *mut f32,
}

/// Where `ns_sample_batch` writes: directions, their solid-angle densities and MIS
/// densities (as `NsSample`; refused lanes: all zeros).
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct NsSamplesMut {
    /// x components of `wo`.
    pub x: *mut f32,
    /// y components of `wo`.
    pub y: *mut f32,
    /// z components of `wo`.
    pub z: *mut f32,
    /// Densities (solid angle).
    pub pdf: *mut f32,
    /// MIS densities (solid angle).
    pub mis_pdf: *mut f32,
}

/// A validated blob that owns a copy of its bytes. Opaque.
pub struct NsBlob(pub(crate) OwnedBlob);

/// A sampler (any kind; shares its blob's bytes). Opaque; immutable; thread-safe.
pub struct NsSampler(pub(crate) OwnedSampler);

/// A neural material (feature texture + decoder). Opaque; immutable; thread-safe.
pub struct NsMaterial(pub(crate) OwnedMaterial);

/// A measured material (RGL data) with its own sampler, read in place from a measured blob
/// (shares the blob's bytes; a `.bsdf` file opened with `ns_measured_open_bsdf` is held as
/// the blob `neusample measured-blob` would write). Opaque; immutable; thread-safe.
pub struct NsMeasured(pub(crate) OwnedMeasuredBlob);

/// The prepared state of one shading point (the sampler's networks evaluated for `(φ, wi)`),
/// reusable: allocate one per thread with `ns_prepared_new`, fill it with `ns_prepare` at
/// each shading point, then call `ns_prepared_sample` / `ns_prepared_pdf` as often as needed.
/// Opaque.
pub struct NsPrepared {
    pub(crate) lane: BlobLane,
    /// Address of the sampler that prepared it (0: none yet).
    pub(crate) owner: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every C constant is its kind's blob tag, so a C caller can compare it with the header.
    #[test]
    fn ns_kind_is_the_blob_tag() {
        let kinds = SamplerKind::ALL
            .into_iter()
            .map(BlobKind::Sampler)
            .chain([BlobKind::NeuralMaterial, BlobKind::Measured]);
        for k in kinds {
            assert_eq!(NsKind::from(k) as u32, k.tag(), "{k:?}");
        }
    }
}
