//! Builds neusample blobs: materials → ground truth → training → baking → evaluation.
//!
//! Modules depend only on modules listed before them (no cycles; `tools/module_cycles.py`
//! checks it):
//!
//! | module          | what                                                                  |
//! |-----------------|-----------------------------------------------------------------------|
//! | [`util`]        | seeded streams (one SplitMix64), the timing harness, stats, atomic I/O, progress bars, JSON nulls |
//! | [`materials`]   | the [`materials::Material`] trait, the analytic models, their shared pieces, material files, the neural material model |
//! | [`groundtruth`] | the target density p*(ω⊥ \| φ, wi) tabulated per condition           |
//! | [`nn`]          | burn building blocks: MLP in the runtime layout, encodings, the optimisation loop |
//! | [`train`]       | training every sampler kind (config, data, one file per method family) and the neural material |
//! | [`bake`]        | a trained model → blob, verified against the model by the runtime     |
//! | [`eval`]        | fit, cost, the tabulated oracle, rendering metrics (through the runtime's public API) |
//! | [`jobs`]        | the command-line jobs as library calls: typed settings in, typed reports out |
//! | [`demo`]        | the full evaluation run and the fixture generator                    |
//!
//! The renderer is its own crate, `neusample-render` (`precompute/render/`), which links the
//! runtime alone; the binary `neusample` (`src/bin/cli/`) parses arguments into the
//! typed settings of [`jobs`] and [`demo`].

pub mod bake;
pub mod defend;
pub mod demo;
pub mod eval;
pub mod groundtruth;
pub mod jobs;
pub mod materials;
pub mod nn;
pub mod train;
pub mod util;
