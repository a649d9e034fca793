//! The samplers, one file per method, and the two traits a renderer programs against
//! ([`Sampler`], [`Prepared`]).
//!
//! | module | paper | density |
//! |---|---|---|
//! | [`cosine`] | — | 1/π on the projected disk |
//! | [`improved_baseline`] | Eq. 1 | Lambert + an isotropic Gaussian |
//! | [`analytic_mixture`] | Eq. 2 | Lambert + two anisotropic Gaussians ([`lobes`]: what they share) |
//! | [`spline_flow`] | Eq. 3–4 | RQ-spline coupling flow |
//! | [`disk_flow`] | Eq. 3–4 on chords | RQ-spline couplings, uniform base, all mass in the disk |
//! | [`affine_flow`] | Xie et al. 2019 | affine coupling flow |
//! | [`direct_histogram`] | Zhu et al. 2021 | MLP → 16 × 16 histogram |
//! | [`histogram_mixture`] | Eq. 5–6 | MLP → weights, rotations, latent codes of baked tables |
//! | [`reparam`] | Wu et al. 2025 | MLP warp of a Gaussian (exact Jacobian weights) + pdf network for MIS |
//! | [`defensive`] | — | `(1 − α)·p_learned + α/π`: any of the above mixed with cosine |
//!
//! Each module also holds its architecture's constants (layer sizes and parameter offsets,
//! `core/ARCHITECTURES.md`), which the trainer uses to export parameters in the runtime's
//! layout. [`AnySampler`] dispatches over all of them.
//!
//! A kind is defined once: its folder (the sampler, its architecture, its batched lanes and
//! its [`FromBlob`]), its module here and one line of the list (`kinds.rs`), from which [`SamplerKind`], its
//! names and blob tags, [`AnySampler`], [`AnyPrepared`], `AnyLane` and the concrete visitor
//! are generated.
//!
//! [`SamplerKind`]: crate::SamplerKind

pub mod affine_flow;
pub mod analytic_mixture;
mod any;
pub mod cosine;
mod coupling;
pub mod defensive;
pub mod direct_histogram;
pub mod disk_flow;
pub mod histogram_mixture;
pub mod improved_baseline;
pub(crate) mod kinds;
pub mod lobes;
mod mixture_tables;
mod mlp;
pub mod reparam;
pub mod spline_flow;
mod traits;

pub use affine_flow::{AffineFlowLane, AffineFlowPrepared, AffineFlowSampler};
pub use analytic_mixture::{AnalyticMixturePrepared, AnalyticMixtureSampler};
#[cfg(not(target_arch = "spirv"))]
pub use any::{AnyLane, AnyScratch, SamplerVisitor};
pub use any::{AnyPrepared, AnySampler};
pub use cosine::{CosinePrepared, CosineSampler};
pub use defensive::{BlobSampler, Defensive, DefensiveLane, DefensivePrepared, Turn};
pub use direct_histogram::{DirectHistogramPrepared, DirectHistogramSampler};
pub use disk_flow::{DiskFlowLane, DiskFlowPrepared, DiskFlowSampler};
pub use histogram_mixture::{
    HistogramMixtureLane, HistogramMixturePrepared, HistogramMixtureSampler,
};
pub use improved_baseline::{ImprovedBaselinePrepared, ImprovedBaselineSampler};
pub use reparam::{ReparamLane, ReparamPrepared, ReparamSampler};
pub use spline_flow::{SplineFlowLane, SplineFlowPrepared, SplineFlowSampler};
pub(crate) use traits::Held;
pub use traits::{BlobSource, FromBlob, LanePrepared, Prepared, Sample, Sampler};
