//! Evaluation through the runtime's public API, as a renderer uses the samplers:
//!
//! * `fit` — a sampler's density against the ground truth p* ([`fit()`], [`fit_to`]), and a
//!   neural material against its source ([`fit_report`]);
//! * `cost` — single-thread ns per shading point of a sampler's hot path, batched and scalar
//!   ([`cost()`]), and of a material's evaluation ([`eval_cost`]), with the timing
//!   primitives `neusample bench` shares;
//! * `oracle` — the tabulated near-optimal sampler ([`OracleSampler`], paper Fig. 10);
//! * [`warp_inverse`] — the reparameterization sampler's exact sampling density anywhere on
//!   the disk, by inverting its warp, and what it shows ([`warp_inverse::exact_fit`]);
//! * [`metrics`] — rendering metrics with `neusample_render` (paper §4: MSE at equal spp and
//!   equal time, convergence, speed-up over the improved baseline).

pub mod cost;
mod fit;
pub mod measured_data;
pub mod metrics;
mod oracle;
pub mod warp_inverse;

pub use cost::{cost, cost_any, cost_scalar, eval_cost, Cost, EvalCost, COST_BATCH};
pub use fit::{
    fit, fit_report, fit_to, samples_carry_pdf, Fit, FitReport, SampledFit, FIT_SAMPLES,
};
pub use oracle::{OraclePrepared, OracleSampler};
