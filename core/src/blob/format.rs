//! The byte layout's vocabulary (`core/BLOB.md`): constants, the header, the tensor
//! directory entry and the tensor roles.

use serde::{Deserialize, Serialize};

use crate::dtype::DType;
use crate::kind::{BlobKind, Interpolation};

/// The 8 bytes every blob starts with.
pub const MAGIC: [u8; 8] = *b"NEUSAMP\0";
/// The newest format version this build reads and writes. Version 2 adds the
/// [`Extension`] (the defensive weight α) after the header, version 3 its `isotropic` flag;
/// the writer uses the oldest version that holds the content, so blobs without a defensive
/// part are still written, byte for byte, as version 1.
pub const FORMAT_VERSION: u32 = 3;
/// The oldest format version this build reads.
pub const MIN_FORMAT_VERSION: u32 = 1;
/// Bytes before the header: magic, version, total length, header length.
pub const PREAMBLE_LEN: usize = 20;
/// Alignment of the data section and of every tensor, relative to the blob start.
pub const DATA_ALIGN: usize = 16;
/// Bytes of the trailing checksum.
pub const CHECKSUM_LEN: usize = 4;
/// Most tensors a blob may declare.
pub const MAX_TENSORS: usize = 8;
/// Longest label accepted, in bytes.
pub const MAX_LABEL_LEN: usize = 4096;

/// Elements of a measured material's [`TensorRole::Shape`] tensor: `n_phi, n_theta`, the
/// `[width, height]` of the ndf, sigma, vndf and rgb tables, and the jacobian flag (0 or 1).
pub const MEASURED_SHAPE_LEN: usize = 11;

/// Number of tensor roles.
pub(crate) const ROLES: usize = 8;

/// What a tensor holds.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum TensorRole {
    /// The flat network parameter array (layouts in `core/ARCHITECTURES.md`).
    Params,
    /// Histogram mixture: per-(basis, level) mass of the training model, K × T.
    Mass,
    /// Histogram mixture: normalised densities, K × T × N × N.
    Table,
    /// Histogram mixture: running row totals, K × T × N.
    Marginal,
    /// Histogram mixture: running sums within rows, K × T × N × N.
    Conditional,
    /// Neural material: the feature texture, H × W × 8 (texel-major, channels last).
    Features,
    /// Measured material: its table sizes, 11 f32 holding exact integers
    /// ([`MEASURED_SHAPE_LEN`]; layout in `core/BLOB.md`).
    Shape,
    /// Measured material: its 11 tables concatenated in the order of
    /// [`MeasuredShape::lens`](crate::MeasuredShape::lens), f32 only.
    Tables,
}

impl TensorRole {
    /// The role's stable name.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            TensorRole::Params => "params",
            TensorRole::Mass => "mass",
            TensorRole::Table => "table",
            TensorRole::Marginal => "marginal",
            TensorRole::Conditional => "conditional",
            TensorRole::Features => "features",
            TensorRole::Shape => "shape",
            TensorRole::Tables => "tables",
        }
    }

    pub(crate) const fn index(self) -> usize {
        match self {
            TensorRole::Params => 0,
            TensorRole::Mass => 1,
            TensorRole::Table => 2,
            TensorRole::Marginal => 3,
            TensorRole::Conditional => 4,
            TensorRole::Features => 5,
            TensorRole::Shape => 6,
            TensorRole::Tables => 7,
        }
    }

    /// Every role, in directory order.
    pub const ALL: [TensorRole; ROLES] = [
        TensorRole::Params,
        TensorRole::Mass,
        TensorRole::Table,
        TensorRole::Marginal,
        TensorRole::Conditional,
        TensorRole::Features,
        TensorRole::Shape,
        TensorRole::Tables,
    ];
}

/// The blob header (postcard-encoded after the preamble).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header<'a> {
    /// What the blob holds (stored as its [`BlobKind::tag`]).
    pub kind: BlobKind,
    /// Storage type of the network parameters and of the histogram table.
    pub dtype: DType,
    /// Length of φ the sampler was trained for (this build: [`FEATURE_DIM`](crate::FEATURE_DIM)).
    pub feature_dim: u32,
    /// Number of network parameters ([`BlobKind::param_count`]).
    pub param_count: u32,
    /// Histogram mixture: number of bases K; 0 otherwise.
    pub basis: u32,
    /// Histogram mixture: number of latent-code levels T; neural material: texture height
    /// (texels along v); 0 otherwise.
    pub t_levels: u32,
    /// Histogram mixture / direct histogram: grid resolution N; neural material: texture
    /// width (texels along u); 0 otherwise.
    pub resolution: u32,
    /// Histogram mixture: how t is looked up.
    pub interpolation: Interpolation,
    /// Free text: material, method, training settings (UTF-8, ≤ [`MAX_LABEL_LEN`] bytes).
    #[serde(borrow)]
    pub label: &'a str,
    /// Number of tensor directory entries that follow the header.
    pub tensor_count: u32,
}

/// What versions 2 and 3 add after the header (postcard-encoded, before the tensor
/// directory): version 2 the field `defensive`, version 3 both fields in order.
#[derive(Copy, Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct Extension {
    /// The defensive weight α ∈ [0, 1) of a sampler blob: the runtime samples
    /// `p = (1 − α)·p_learned + α·p_cosine` ([`Defensive`](crate::samplers::Defensive)).
    /// 0 for version-1 blobs and for neural materials.
    pub defensive: f32,
    /// Whether the sampler was trained on an isotropic material with `wi` at azimuth 0: the
    /// runtime turns every condition there and the directions with it
    /// ([`Defensive::with_isotropic`](crate::samplers::Defensive::with_isotropic)). False
    /// before version 3 and for neural materials.
    pub isotropic: bool,
}

impl Extension {
    /// The oldest format version that holds this extension.
    #[must_use]
    pub fn version(&self) -> u32 {
        if self.isotropic {
            3
        } else if self.defensive.to_bits() != 0 {
            2
        } else {
            MIN_FORMAT_VERSION
        }
    }
}

/// One entry of the tensor directory.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TensorEntry {
    /// What the tensor holds.
    pub role: TensorRole,
    /// Element type.
    pub dtype: DType,
    /// Byte offset from the start of the blob (a multiple of [`DATA_ALIGN`]).
    pub offset: u32,
    /// Number of elements.
    pub count: u32,
}

/// The little-endian `u32` at byte `at`, or 0 past the end.
pub(crate) fn u32_at(bytes: &[u8], at: usize) -> u32 {
    match bytes.get(at..at + 4) {
        Some(b) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        None => 0,
    }
}
