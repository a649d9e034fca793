//! Evaluation through the runtime's public API, as a renderer uses the samplers:
//!
//! * `fit` — a sampler's density against the ground truth p* ([`fit()`], [`fit_to`]), and a
//!   neural material against its source ([`fit_report`]);
//! * `cost` — single-thread ns per call of a sampler's hot path ([`cost()`]) and of a
//!   material's evaluation ([`eval_cost`]);
//! * `oracle` — the tabulated near-optimal sampler ([`OracleSampler`], paper Fig. 10);
//! * [`metrics`] — rendering metrics with `neusample_render` (paper §4: MSE at equal spp and
//!   equal time, convergence, speed-up over the improved baseline).

mod cost;
mod fit;
pub mod metrics;
mod oracle;

pub use cost::{cost, eval_cost, Cost, EvalCost};
pub use fit::{fit, fit_report, fit_to, Fit, FitReport};
pub use oracle::{OraclePrepared, OracleSampler};
