//! The blob container: one versioned, checksummed file format for every sampler, for the
//! neural materials they sample ([`BlobKind::NeuralMaterial`](crate::BlobKind),
//! [`Blob::neural_material`]) and for measured materials ([`Blob::measured`]).
//!
//! The byte layout is specified in `core/BLOB.md`. In short:
//!
//! ```text
//! magic "NEUSAMP\0" | version u32 | total_len u32 | header_len u32 | header (postcard)
//! | from version 2: extension (postcard: the defensive weight α; version 3: isotropic)
//! | tensor directory (postcard, one entry per tensor) | zero padding to 16
//! | tensor data, each tensor 16-byte aligned | CRC-32 of everything before it (u32)
//! ```
//!
//! [`Blob::open`] validates everything once — lengths, checksum, header, dimensions against
//! the architectures compiled into this build, tensor bounds, finiteness, table
//! normalisation — and returns a typed [`Error`](crate::Error) otherwise. It never panics,
//! whatever the bytes. After that, the samplers built from the blob read the tensors in place
//! (zero-copy; f32 tensors are used as `&[f32]` when the blob's buffer is 4-byte aligned).
//!
//! `format` names the layout, `read` opens blobs, `validate` holds the checks beyond the
//! layout and `write` (the `alloc` feature) builds blobs.

mod format;
// Measured blobs are read on hosts: shaders take the tables as storage buffers
// (`MeasuredMaterial::new_unchecked`).
#[cfg(not(target_arch = "spirv"))]
mod measured;
mod read;
mod validate;
#[cfg(feature = "alloc")]
mod write;

pub use format::{
    Extension, Header, TensorEntry, TensorRole, CHECKSUM_LEN, DATA_ALIGN, FORMAT_VERSION, MAGIC,
    MAX_LABEL_LEN, MAX_TENSORS, MEASURED_SHAPE_LEN, MIN_FORMAT_VERSION, PREAMBLE_LEN,
};
pub use read::Blob;
#[cfg(feature = "alloc")]
pub use write::BlobWriter;
