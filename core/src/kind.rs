//! The names the format and the API share: what a blob holds ([`BlobKind`], [`SamplerKind`])
//! and how the histogram mixture reads its latent axis ([`Interpolation`]). It depends on nothing else in the crate but the list of kinds
//! ([`sampler_kinds!`](crate::samplers)). Lookups are loops, as rust-gpu compiles them (no
//! iterators).

use serde::{Deserialize, Serialize};

/// Generates [`SamplerKind`] from [`sampler_kinds!`](crate::samplers): the enum, its list,
/// names and blob tags.
macro_rules! sampler_kind_enum {
    ($($(#[$doc:meta])* $variant:ident = $tag:literal, $name:literal, $sampler:ty, $lane:ty;)*) => {
        /// The kind of sampler a blob holds. Materials, which blobs hold too, are
        /// [`BlobKind`]s that are not sampler kinds.
        #[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
        pub enum SamplerKind {
            $($(#[$doc])* $variant,)*
        }

        impl SamplerKind {
            /// Every sampler kind, in a stable order.
            pub const ALL: [SamplerKind; [$(SamplerKind::$variant),*].len()] =
                [$(SamplerKind::$variant),*];

            /// The kind's stable name (CLI and JSON).
            #[must_use]
            pub const fn name(self) -> &'static str {
                match self {
                    $(SamplerKind::$variant => $name,)*
                }
            }

            /// The number a blob's header stores for the kind ([`BlobKind::tag`]).
            #[must_use]
            pub const fn tag(self) -> u32 {
                match self {
                    $(SamplerKind::$variant => $tag,)*
                }
            }
        }
    };
}

crate::samplers::kinds::sampler_kinds!(sampler_kind_enum);

impl SamplerKind {
    /// The kind with the given [`SamplerKind::name`].
    #[must_use]
    pub fn from_name(name: &str) -> Option<SamplerKind> {
        let mut i = 0;
        while i < Self::ALL.len() {
            if Self::ALL[i].name().as_bytes() == name.as_bytes() {
                return Some(Self::ALL[i]);
            }
            i += 1;
        }
        None
    }

    /// The kind with the given [`SamplerKind::tag`].
    #[must_use]
    pub fn from_tag(tag: u32) -> Option<SamplerKind> {
        let mut i = 0;
        while i < Self::ALL.len() {
            if Self::ALL[i].tag() == tag {
                return Some(Self::ALL[i]);
            }
            i += 1;
        }
        None
    }
}

/// What a blob holds: a sampler of some [`SamplerKind`], or a material. Stored in a blob's
/// header as its tag ([`BlobKind::tag`]), a postcard varint (the bytes of the enum this
/// replaced, so every blob written before opens).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "u32", try_from = "u32")]
pub enum BlobKind {
    /// A sampler.
    Sampler(SamplerKind),
    /// A NeuMIP-style neural material (feature texture + decoder, [`crate::neural_material`]),
    /// the BRDF the samplers are trained for. Opened with
    /// [`Blob::neural_material`](crate::Blob::neural_material).
    NeuralMaterial,
    /// A measured material of the RGL database ([`crate::measured`]) with its own VNDF
    /// sampler. Opened with [`Blob::measured`](crate::Blob::measured).
    Measured,
}

impl BlobKind {
    /// Tag of [`BlobKind::NeuralMaterial`].
    const NEURAL_MATERIAL_TAG: u32 = 7;
    /// Tag of [`BlobKind::Measured`].
    const MEASURED_TAG: u32 = 10;

    /// The number a blob's header stores (and the C ABI's `NsKind`).
    #[must_use]
    pub const fn tag(self) -> u32 {
        match self {
            BlobKind::Sampler(k) => k.tag(),
            BlobKind::NeuralMaterial => Self::NEURAL_MATERIAL_TAG,
            BlobKind::Measured => Self::MEASURED_TAG,
        }
    }

    /// The kind stored as `tag`.
    #[must_use]
    pub fn from_tag(tag: u32) -> Option<BlobKind> {
        match tag {
            Self::NEURAL_MATERIAL_TAG => Some(BlobKind::NeuralMaterial),
            Self::MEASURED_TAG => Some(BlobKind::Measured),
            t => SamplerKind::from_tag(t).map(BlobKind::Sampler),
        }
    }

    /// The stable name: the sampler kind's, `neural-material` or `measured`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            BlobKind::Sampler(k) => k.name(),
            BlobKind::NeuralMaterial => "neural-material",
            BlobKind::Measured => "measured",
        }
    }

    /// The kind with the given [`BlobKind::name`].
    #[must_use]
    pub fn from_name(name: &str) -> Option<BlobKind> {
        if name.as_bytes() == BlobKind::NeuralMaterial.name().as_bytes() {
            return Some(BlobKind::NeuralMaterial);
        }
        if name.as_bytes() == BlobKind::Measured.name().as_bytes() {
            return Some(BlobKind::Measured);
        }
        SamplerKind::from_name(name).map(BlobKind::Sampler)
    }

    /// The sampler kind, if the blob holds a sampler.
    #[must_use]
    pub const fn sampler(self) -> Option<SamplerKind> {
        match self {
            BlobKind::Sampler(k) => Some(k),
            _ => None,
        }
    }
}

impl From<SamplerKind> for BlobKind {
    fn from(k: SamplerKind) -> BlobKind {
        BlobKind::Sampler(k)
    }
}

impl PartialEq<SamplerKind> for BlobKind {
    fn eq(&self, k: &SamplerKind) -> bool {
        *self == BlobKind::Sampler(*k)
    }
}

impl From<BlobKind> for u32 {
    fn from(k: BlobKind) -> u32 {
        k.tag()
    }
}

/// A blob tag that names no kind this build knows.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct UnknownTag(pub u32);

impl core::fmt::Display for UnknownTag {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "unknown blob kind tag {}", self.0)
    }
}

impl TryFrom<u32> for BlobKind {
    type Error = UnknownTag;
    fn try_from(tag: u32) -> Result<BlobKind, UnknownTag> {
        BlobKind::from_tag(tag).ok_or(UnknownTag(tag))
    }
}

/// How the histogram mixture reads the latent-code axis of its tables.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum Interpolation {
    /// The nearest level `round(t·(T − 1))` (the paper's rounding).
    #[default]
    Nearest,
    /// Linear interpolation between levels `⌊s⌋` and `⌊s⌋ + 1`, `s = t·(T − 1)`; exactly
    /// normalised because each slice is.
    Linear,
}
