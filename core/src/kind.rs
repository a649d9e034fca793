//! The names the format and the API share: which sampler a blob holds ([`SamplerKind`]), how
//! a tensor is stored ([`DType`]) and how the histogram mixture reads its latent axis
//! ([`Interpolation`]). A leaf: it depends on nothing else in the crate.

use serde::{Deserialize, Serialize};

/// The kind of sampler a blob holds (or the neural material it samples).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum SamplerKind {
    /// Cosine-hemisphere sampling (no parameters).
    Cosine,
    /// Improved baseline: Lambert + isotropic Gaussian (paper Eq. 1).
    ImprovedBaseline,
    /// Analytic mixture: Lambert + two anisotropic Gaussians (paper Eq. 2).
    AnalyticMixture,
    /// Conditional rational-quadratic spline flow (paper Eq. 3–4).
    Flow,
    /// Affine-coupling flow baseline (Xie et al. 2019).
    AffineFlow,
    /// Direct histogram baseline (Zhu et al. 2021).
    DirectHistogram,
    /// Histogram mixture (paper Eq. 5–6).
    HistogramMixture,
    /// Not a sampler: a NeuMIP-style neural material (feature texture + decoder,
    /// [`crate::neural_material`]), the BRDF the samplers are trained for. Opened with
    /// [`Blob::neural_material`](crate::Blob::neural_material); [`Blob::sampler`](crate::Blob::sampler) refuses it. Not in [`SamplerKind::ALL`].
    NeuralMaterial,
    /// Reparameterization sampler (Wu et al. 2025): an MLP warp of a Gaussian with its exact
    /// Jacobian weight, and a pdf network for MIS ([`crate::samplers::reparam`]).
    Reparam,
    /// Disk flow: the paper's spline couplings on a uniform base with every mass inside the
    /// disk (`core/ARCHITECTURES.md` §9).
    DiskFlow,
    /// Not a sampler: a measured material of the RGL database ([`crate::measured`]), with its
    /// own VNDF sampler. Opened with [`Blob::measured`](crate::Blob::measured);
    /// [`Blob::sampler`](crate::Blob::sampler) refuses it. Not in [`SamplerKind::ALL`].
    Measured,
}

impl SamplerKind {
    /// Every sampler kind, in a stable order (the materials, [`SamplerKind::NeuralMaterial`]
    /// and [`SamplerKind::Measured`], which are not samplers, are not listed).
    pub const ALL: [SamplerKind; 9] = [
        SamplerKind::Cosine,
        SamplerKind::ImprovedBaseline,
        SamplerKind::AnalyticMixture,
        SamplerKind::Flow,
        SamplerKind::DiskFlow,
        SamplerKind::AffineFlow,
        SamplerKind::DirectHistogram,
        SamplerKind::HistogramMixture,
        SamplerKind::Reparam,
    ];

    /// The kind's stable name (CLI and JSON).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            SamplerKind::Cosine => "cosine",
            SamplerKind::ImprovedBaseline => "baseline",
            SamplerKind::AnalyticMixture => "analytic",
            SamplerKind::Flow => "flow",
            SamplerKind::DiskFlow => "disk-flow",
            SamplerKind::AffineFlow => "affine-flow",
            SamplerKind::DirectHistogram => "direct-histogram",
            SamplerKind::HistogramMixture => "histogram-mixture",
            SamplerKind::NeuralMaterial => "neural-material",
            SamplerKind::Reparam => "reparam",
            SamplerKind::Measured => "measured",
        }
    }

    /// Whether a sample's density is the kind's `pdf` at the sampled direction (every kind
    /// but [`SamplerKind::Reparam`], whose samples carry the warp's exact density and whose
    /// `pdf` is its pdf network's: see [`Prepared::mis_pdf`](crate::Prepared::mis_pdf)).
    #[must_use]
    pub const fn exact_pdf(self) -> bool {
        !matches!(self, SamplerKind::Reparam)
    }

    /// Whether the kind is a sampler (every kind but the materials,
    /// [`SamplerKind::NeuralMaterial`] and [`SamplerKind::Measured`]).
    #[must_use]
    pub const fn is_sampler(self) -> bool {
        !matches!(self, SamplerKind::NeuralMaterial | SamplerKind::Measured)
    }

    /// The kind with the given [`SamplerKind::name`] (the materials included).
    #[must_use]
    pub fn from_name(name: &str) -> Option<SamplerKind> {
        if name.as_bytes() == SamplerKind::NeuralMaterial.name().as_bytes() {
            return Some(SamplerKind::NeuralMaterial);
        }
        if name.as_bytes() == SamplerKind::Measured.name().as_bytes() {
            return Some(SamplerKind::Measured);
        }
        let mut i = 0;
        while i < Self::ALL.len() {
            if Self::ALL[i].name().as_bytes() == name.as_bytes() {
                return Some(Self::ALL[i]);
            }
            i += 1;
        }
        None
    }
}

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
