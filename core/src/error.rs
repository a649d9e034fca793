//! The error type of blob decoding and validation.
//!
//! One `#[non_exhaustive]` enum whose variants name the phase that failed, after postcard's
//! `Error`. Sampling itself never fails with an error: it returns `None` or a zero density.

use core::fmt;

use crate::dtype::DType;
use crate::kind::BlobKind;

/// Why a blob could not be opened.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Error {
    /// Fewer bytes than the fixed preamble, the declared header or a declared tensor needs.
    Truncated {
        /// Bytes needed at least.
        needed: u64,
        /// Bytes present.
        got: u64,
    },
    /// The first 8 bytes are not the blob magic `NEUSAMP\0`.
    BadMagic,
    /// A format version this build does not read.
    UnsupportedVersion {
        /// Version found in the blob.
        found: u32,
        /// Version this build reads.
        supported: u32,
    },
    /// The CRC-32 stored in the last 4 bytes does not match the content.
    ChecksumMismatch {
        /// Checksum stored in the blob.
        stored: u32,
        /// Checksum of the bytes.
        computed: u32,
    },
    /// The postcard-encoded header could not be decoded.
    HeaderDecode,
    /// The header decoded but is inconsistent (trailing bytes, impossible sizes).
    HeaderInvalid,
    /// The blob holds a different kind of sampler than the caller asked for.
    WrongKind {
        /// Kind the caller asked for.
        expected: BlobKind,
        /// Kind stored in the blob.
        found: BlobKind,
    },
    /// [`Blob::sampler`](crate::blob::Blob::sampler) was called on a blob that holds no
    /// sampler (a neural material: open it with
    /// [`Blob::neural_material`](crate::blob::Blob::neural_material)).
    NotASampler {
        /// Kind stored in the blob.
        found: BlobKind,
    },
    /// An architecture dimension differs from the one compiled into this build, or a table
    /// dimension is zero or above its limit.
    DimensionMismatch {
        /// Which dimension.
        what: &'static str,
        /// Value this build expects (or the limit).
        expected: u32,
        /// Value stored in the blob.
        found: u32,
    },
    /// A tensor the sampler kind requires is absent, duplicated, or not expected.
    TensorMissing {
        /// The tensor's role name.
        role: &'static str,
    },
    /// A tensor's element count differs from what the dimensions require.
    TensorShape {
        /// The tensor's role name.
        role: &'static str,
        /// Elements required.
        expected: u32,
        /// Elements stored.
        found: u32,
    },
    /// A tensor's byte range lies outside the data section or is misaligned.
    TensorBounds {
        /// The tensor's role name.
        role: &'static str,
    },
    /// A tensor's element type is not allowed for its role.
    TensorDType {
        /// The tensor's role name.
        role: &'static str,
        /// The type found.
        found: DType,
    },
    /// A tensor holds NaN or ±∞.
    NonFinite {
        /// The tensor's role name.
        role: &'static str,
        /// Index of the first bad element.
        index: u32,
    },
    /// The slices of one batched call ([`crate::wavefront`]) differ in length.
    BatchLength {
        /// Which argument.
        what: &'static str,
        /// Length of the call's lanes (or of its first argument).
        expected: u32,
        /// Length of this argument.
        found: u32,
    },
    /// A baked table is negative, not normalised, or its CDFs do not match its values.
    TableNotNormalized {
        /// The tensor's role name.
        role: &'static str,
        /// Index of the first bad element (or slice).
        index: u32,
    },
}

/// `Result` with this crate's [`Error`].
pub type Result<T> = core::result::Result<T, Error>;

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Truncated { needed, got } => {
                write!(
                    f,
                    "blob truncated: needs at least {needed} bytes, has {got}"
                )
            }
            Error::BadMagic => write!(f, "not a neusample blob (bad magic)"),
            Error::UnsupportedVersion { found, supported } => write!(
                f,
                "unsupported blob format version {found} (this build reads version {supported})"
            ),
            Error::ChecksumMismatch { stored, computed } => write!(
                f,
                "blob checksum mismatch (stored {stored:#010x}, computed {computed:#010x}): \
                 the file is corrupted"
            ),
            Error::HeaderDecode => write!(f, "blob header could not be decoded"),
            Error::HeaderInvalid => write!(f, "blob header is inconsistent"),
            Error::WrongKind { expected, found } => write!(
                f,
                "blob holds a {} sampler, expected {}",
                found.name(),
                expected.name()
            ),
            Error::NotASampler { found } => {
                write!(f, "blob holds a {}, not a sampler", found.name())
            }
            Error::DimensionMismatch {
                what,
                expected,
                found,
            } => write!(
                f,
                "dimension `{what}` is {found}, this build requires {expected}"
            ),
            Error::TensorMissing { role } => {
                write!(f, "tensor `{role}` missing, duplicated or unexpected")
            }
            Error::TensorShape {
                role,
                expected,
                found,
            } => write!(
                f,
                "tensor `{role}` has {found} elements, expected {expected}"
            ),
            Error::TensorBounds { role } => {
                write!(f, "tensor `{role}` lies outside the data section")
            }
            Error::TensorDType { role, found } => {
                write!(
                    f,
                    "tensor `{role}` has element type {found:?}, not allowed there"
                )
            }
            Error::NonFinite { role, index } => {
                write!(
                    f,
                    "tensor `{role}` has a NaN or infinite value at index {index}"
                )
            }
            Error::BatchLength {
                what,
                expected,
                found,
            } => write!(
                f,
                "batched call: `{what}` has {found} elements, the batch has {expected}"
            ),
            Error::TableNotNormalized { role, index } => write!(
                f,
                "table `{role}` is negative, unnormalised or inconsistent with its CDF at {index}"
            ),
        }
    }
}

impl core::error::Error for Error {}
