//! Training every sampler of `neusample` to the paper's objectives, producing the flat
//! parameter arrays (and, for the histogram mixture, the baked tables) the runtime consumes.
//!
//! * Improved baseline, analytic mixture, RQ-spline flow, affine flow and direct histogram:
//!   maximum likelihood of samples of the ground truth p* (paper §3 "Fitting"): every batch
//!   is `batch_conditions` random conditions × `samples_per_condition` samples of p*, and
//!   the loss is `−mean ln p(ω⊥)` (equivalently `KL(p* ‖ p)` up to a constant).
//! * Flows, optionally (`MaxLikelihood::chi2_weight`): a fine-tuning phase with the render's
//!   measure, `−mean ln p + λ·ln ∫ p*²/p` ([`objective`]).
//! * Training targets are tabulated up to the horizon by default ([`Common::horizon_targets`]).
//! * Histogram mixture: the L2 loss of Eq. 7 plus the latent-code quantisation term, plus
//!   (our addition, on by default) a self-normalised NLL term, then baking of the basis
//!   network into tables ([`histogram_mixture`]).
//! * Reparameterization sampler: a warp trained on the integrand itself (the neural
//!   material's decoder, through which gradients flow), then a pdf network fitted to the
//!   warp's own density ([`reparam`]).
//!
//! The forward passes are `core/ARCHITECTURES.md` operation for operation; the layouts are
//! the runtime's (input-major weights, bias after weights, layers in the listed order).
//! [`model_pdf_disk`] evaluates a trained model in f64 from the exported arrays, so a blob
//! can be checked against it.
//!
//! Methods are named by the runtime's [`neusample::SamplerKind`] ([`METHODS`]).
//!
//! Files: `config` (the hyper-parameters: common settings plus each method's block, by kind),
//! `source` (where conditions come from), `data` (pool, batches, the loop feeding the
//! optimiser), one file per method family (`lobes`: baseline and analytic; `flow` with its
//! `spline`: the three flows; `direct_histogram`; `histogram_mixture`; `reparam`), each with
//! its method's trainer (`trainer`: what a trainer provides and what training returns),
//! `method` (the list of trainer modules; a trainer is found by its kind), `dispatch` (the entry points and the trained
//! model's f64 mirror), and [`neural_material`] (fitting a neural material to a material:
//! the same building blocks, another model).
//!
//! Reproducibility: all randomness comes from PCG streams seeded by [`Common::seed`], and
//! training runs on a private rayon pool of [`Common::threads`] threads, so a run is
//! bit-reproducible on one machine for a given seed and thread count.

mod config;
mod data;
mod dispatch;
mod integrand;
mod method;
pub mod objective;
mod source;
mod trainer;

pub mod direct_histogram;
pub mod flow;
pub mod histogram_mixture;
pub mod lobes;
pub mod neural_material;
pub mod reparam;
pub mod spline;

pub use config::{
    ByKind, Common, DensityLoss, HistogramMixture, MaxLikelihood, Reparam, Schedule, TrainConfig,
    WarmStart,
};
pub use data::{map_picked_from, Batch, HostBatch, PointKind, Pool};
pub use dispatch::{
    graph_log_pdf, mean_kl, model_pdf_disk, network_mean_kl, train, train_with, Trained,
};
pub use histogram_mixture::BakedTables;
pub use integrand::{ConditionRows, Integrand, MeasuredIntegrand, NeuralIntegrand};
pub use method::{needs_integrand, parse_method, pole_tolerance, METHODS};
pub use source::{
    has_integrand, material_integrand, GtCondition, MaterialSource, SyntheticIntegrand,
    SyntheticSource, TargetSource,
};
