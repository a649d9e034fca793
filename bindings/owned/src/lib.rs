//! Owned handles over neusample blobs, shared by the C ABI (`neusample-capi`) and the Python
//! package (`neusample-python`).
//!
//! The runtime borrows: [`neusample::Blob`] views the caller's bytes and the samplers and the
//! neural material it builds view the blob. A foreign language cannot hold a borrow, so
//! the bindings hand out these owned values instead:
//!
//! - [`OwnedBlob`]: a validated blob that owns its bytes (16-byte aligned, so f32 tensors are
//!   read in place). Cheap to clone (reference-counted); validation runs once, in
//!   [`OwnedBlob::from_bytes`].
//! - [`OwnedSampler`]: whichever sampler a blob holds, or the cosine sampler without a blob.
//! - [`OwnedMaterial`]: the neural material of a neural-material blob.
//! - [`measured::OwnedMeasured`]: a measured (RGL `.bsdf`) material read from its file, with
//!   the data's own sampler.
//! - [`OwnedMeasuredBlob`]: the measured material of a measured-material blob (the same
//!   material, its tables read in place from the blob).
//!
//! Each is `Send + Sync` and immutable: one handle serves any number of threads. The
//! self-references are built with `self_cell` (no `unsafe` here). [`error_kind`] gives every
//! [`neusample::Error`] the stable name both bindings report.

pub mod measured;

use std::path::Path;
use std::sync::Arc;

use neusample::{
    Blob, BlobKind, BlobSampler, Error, MeasuredMaterial, NeuralMaterial, SamplerKind, Tensor,
};

/// The blob's bytes in 16-byte aligned storage (the format aligns tensors to 16 bytes
/// relative to the blob's start, so f32 tensors become aligned slices).
struct AlignedBytes {
    words: Box<[u128]>,
    len: usize,
}

impl AlignedBytes {
    fn new(bytes: &[u8]) -> Self {
        let mut words = vec![0u128; bytes.len().div_ceil(16)].into_boxed_slice();
        bytemuck::cast_slice_mut::<u128, u8>(&mut words)[..bytes.len()].copy_from_slice(bytes);
        AlignedBytes {
            words,
            len: bytes.len(),
        }
    }

    fn bytes(&self) -> &[u8] {
        &bytemuck::cast_slice::<u128, u8>(&self.words)[..self.len]
    }
}

type BlobOf<'a> = Blob<'a>;

self_cell::self_cell!(
    struct BlobCell {
        owner: AlignedBytes,
        #[covariant]
        dependent: BlobOf,
    }
);

/// Why a blob file could not be opened: the file could not be read, or its bytes are not a
/// valid blob.
#[derive(Debug)]
pub enum OpenError {
    /// Reading the file failed.
    Io(std::io::Error),
    /// The bytes are not a valid blob (or not of the kind asked for).
    Blob(Error),
}

impl std::fmt::Display for OpenError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OpenError::Io(e) => write!(f, "{e}"),
            OpenError::Blob(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for OpenError {}

impl From<Error> for OpenError {
    fn from(e: Error) -> Self {
        OpenError::Blob(e)
    }
}

/// A validated blob owning its bytes (any kind: a sampler or a neural material).
#[derive(Clone)]
pub struct OwnedBlob(Arc<BlobCell>);

impl std::fmt::Debug for OwnedBlob {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OwnedBlob")
            .field("kind", &self.kind())
            .field("bytes", &self.bytes().len())
            .finish()
    }
}

impl OwnedBlob {
    /// Copies `bytes` and validates them ([`Blob::open`]).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, Error> {
        BlobCell::try_new(AlignedBytes::new(bytes), |b| Blob::open(b.bytes()))
            .map(|c| OwnedBlob(Arc::new(c)))
    }

    /// Reads and validates the file at `path`.
    pub fn open(path: &Path) -> Result<Self, OpenError> {
        let bytes = std::fs::read(path).map_err(OpenError::Io)?;
        Ok(Self::from_bytes(&bytes)?)
    }

    /// The validated blob.
    #[must_use]
    pub fn blob(&self) -> &Blob<'_> {
        self.0.borrow_dependent()
    }

    /// The blob's bytes.
    #[must_use]
    pub fn bytes(&self) -> &[u8] {
        self.0.borrow_owner().bytes()
    }

    /// What the blob holds.
    #[must_use]
    pub fn kind(&self) -> BlobKind {
        self.blob().kind()
    }
}

type BlobSamplerOf<'a> = BlobSampler<'a>;

self_cell::self_cell!(
    struct SamplerCell {
        owner: Option<Arc<BlobCell>>,
        #[covariant]
        dependent: BlobSamplerOf,
    }
);

/// Whichever sampler a blob holds, owning (a share of) the blob.
pub struct OwnedSampler(SamplerCell);

impl std::fmt::Debug for OwnedSampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("OwnedSampler").field(&self.kind()).finish()
    }
}

impl OwnedSampler {
    /// The sampler of `blob`; [`Error::NotASampler`] for a neural-material blob.
    pub fn new(blob: &OwnedBlob) -> Result<Self, Error> {
        SamplerCell::try_new(Some(blob.0.clone()), |b| match b {
            Some(b) => b.borrow_dependent().sampler(),
            None => Ok(BlobSampler::cosine()),
        })
        .map(OwnedSampler)
    }

    /// The cosine sampler (needs no blob).
    #[must_use]
    pub fn cosine() -> Self {
        OwnedSampler(SamplerCell::new(None, |_| BlobSampler::cosine()))
    }

    /// The sampler.
    #[must_use]
    pub fn get(&self) -> &BlobSampler<'_> {
        self.0.borrow_dependent()
    }

    /// Its kind.
    #[must_use]
    pub fn kind(&self) -> SamplerKind {
        self.get().kind()
    }

    /// The blob it was built from (`None` for [`OwnedSampler::cosine`]).
    #[must_use]
    pub fn blob(&self) -> Option<OwnedBlob> {
        self.0.borrow_owner().clone().map(OwnedBlob)
    }
}

type MaterialOf<'a> = NeuralMaterial<Tensor<'a>>;

self_cell::self_cell!(
    struct MaterialCell {
        owner: Arc<BlobCell>,
        #[covariant]
        dependent: MaterialOf,
    }
);

/// The neural material of a neural-material blob, owning (a share of) the blob.
pub struct OwnedMaterial(MaterialCell);

impl std::fmt::Debug for OwnedMaterial {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let m = self.get();
        f.debug_struct("OwnedMaterial")
            .field("width", &m.width())
            .field("height", &m.height())
            .finish()
    }
}

impl OwnedMaterial {
    /// The neural material of `blob`; [`Error::WrongKind`] for a sampler blob.
    pub fn new(blob: &OwnedBlob) -> Result<Self, Error> {
        MaterialCell::try_new(blob.0.clone(), |b| b.borrow_dependent().neural_material())
            .map(OwnedMaterial)
    }

    /// The material.
    #[must_use]
    pub fn get(&self) -> &NeuralMaterial<Tensor<'_>> {
        self.0.borrow_dependent()
    }

    /// The blob it was built from.
    #[must_use]
    pub fn blob(&self) -> OwnedBlob {
        OwnedBlob(self.0.borrow_owner().clone())
    }
}

type MeasuredOf<'a> = MeasuredMaterial<Tensor<'a>>;

self_cell::self_cell!(
    struct MeasuredCell {
        owner: Arc<BlobCell>,
        #[covariant]
        dependent: MeasuredOf,
    }
);

/// The measured material of a measured-material blob (kind `measured`), owning (a share of)
/// the blob; its tables are read in place.
pub struct OwnedMeasuredBlob(MeasuredCell);

impl std::fmt::Debug for OwnedMeasuredBlob {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OwnedMeasuredBlob")
            .field("shape", self.get().shape())
            .field("jacobian", &self.get().jacobian())
            .finish()
    }
}

impl OwnedMeasuredBlob {
    /// The measured material of `blob`; [`Error::WrongKind`] for any other kind.
    pub fn new(blob: &OwnedBlob) -> Result<Self, Error> {
        MeasuredCell::try_new(blob.0.clone(), |b| b.borrow_dependent().measured())
            .map(OwnedMeasuredBlob)
    }

    /// Copies `bytes`, validates them and opens their measured material.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, Error> {
        Self::new(&OwnedBlob::from_bytes(bytes)?)
    }

    /// The material.
    #[must_use]
    pub fn get(&self) -> &MeasuredMaterial<Tensor<'_>> {
        self.0.borrow_dependent()
    }

    /// The blob it was built from.
    #[must_use]
    pub fn blob(&self) -> OwnedBlob {
        OwnedBlob(self.0.borrow_owner().clone())
    }

    /// The blob's label (`neusample measured-blob` writes `name=… source=… description: …`).
    #[must_use]
    pub fn label(&self) -> &str {
        self.0.borrow_owner().borrow_dependent().header().label
    }
}

/// The label of a measured blob: `name=… source=… description: …`, cut at a character
/// boundary to [`MAX_LABEL_LEN`](neusample::blob::MAX_LABEL_LEN) bytes.
#[must_use]
pub fn measured_label(name: &str, source: &str, description: &str) -> String {
    let mut l = format!(
        "name={name} source={source} description: {}",
        description.trim()
    );
    let max = neusample::blob::MAX_LABEL_LEN;
    if l.len() > max {
        let mut end = max;
        while !l.is_char_boundary(end) {
            end -= 1;
        }
        l.truncate(end);
    }
    l
}

/// The stable name of an error's kind, as both bindings report it (C: the `NsStatus` of the
/// same name; Python: `BlobError.kind`). `"other"` for variants added to
/// [`neusample::Error`] after this list.
#[must_use]
pub fn error_kind(e: &Error) -> &'static str {
    match e {
        Error::Truncated { .. } => "truncated",
        Error::BadMagic => "bad_magic",
        Error::UnsupportedVersion { .. } => "unsupported_version",
        Error::ChecksumMismatch { .. } => "checksum_mismatch",
        Error::HeaderDecode => "header_decode",
        Error::HeaderInvalid => "header_invalid",
        Error::WrongKind { .. } => "wrong_kind",
        Error::NotASampler { .. } => "not_a_sampler",
        Error::DimensionMismatch { .. } => "dimension_mismatch",
        Error::TensorMissing { .. } => "tensor_missing",
        Error::TensorShape { .. } => "tensor_shape",
        Error::TensorBounds { .. } => "tensor_bounds",
        Error::TensorDType { .. } => "tensor_dtype",
        Error::NonFinite { .. } => "non_finite",
        Error::BatchLength { .. } => "batch_length",
        Error::TableNotNormalized { .. } => "table_not_normalized",
        _ => "other",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture(rel: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures")
            .join(rel)
    }

    #[test]
    fn handles_outlive_the_blob_value() {
        let blob = OwnedBlob::open(&fixture("blobs/goat_leather_neural/flow.nsb")).unwrap();
        let sampler = OwnedSampler::new(&blob).unwrap();
        drop(blob);
        assert_eq!(sampler.kind(), SamplerKind::SplineFlow);
        let m = OwnedBlob::open(&fixture("materials/neural/goat_leather_neural.nsb")).unwrap();
        assert_eq!(m.kind(), BlobKind::NeuralMaterial);
        let mat = OwnedMaterial::new(&m).unwrap();
        assert!(matches!(
            OwnedSampler::new(&m),
            Err(Error::NotASampler { .. })
        ));
        assert!(mat.get().width() > 0);
        assert_eq!(OwnedSampler::cosine().kind(), SamplerKind::Cosine);
    }

    #[test]
    fn errors_are_typed() {
        assert!(matches!(
            OwnedBlob::open(&fixture("no/such.nsb")),
            Err(OpenError::Io(_))
        ));
        let mut bytes = std::fs::read(fixture("blobs/goat_leather_neural/analytic.nsb")).unwrap();
        bytes[100] ^= 0x40;
        let e = OwnedBlob::from_bytes(&bytes).unwrap_err();
        assert_eq!(error_kind(&e), "checksum_mismatch");
        assert_eq!(
            error_kind(&OwnedBlob::from_bytes(b"nope").unwrap_err()),
            "bad_magic"
        );
    }
}
