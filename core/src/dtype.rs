//! [`DType`]: how a blob stores a tensor's elements.

use serde::{Deserialize, Serialize};

/// Element type of a stored tensor.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum DType {
    /// IEEE-754 binary32, little-endian.
    F32,
    /// IEEE-754 binary16, little-endian, widened to f32 on read.
    F16,
    /// Unsigned 16-bit integers, little-endian, read as the f32 of the same value (exact):
    /// the quantised conditional CDFs of compact histogram-mixture tables.
    U16,
}

impl DType {
    /// Bytes per element.
    #[inline]
    #[must_use]
    pub const fn size(self) -> usize {
        match self {
            DType::F32 => 4,
            DType::F16 | DType::U16 => 2,
        }
    }

    /// Lower-case name as `neusample inspect` prints it (`f32`, `f16`, `u16`).
    #[inline]
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            DType::F32 => "f32",
            DType::F16 => "f16",
            DType::U16 => "u16",
        }
    }
}
