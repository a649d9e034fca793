//! Builds neusample blobs: materials → ground truth → training → baking → evaluation.
//!
//! The data flows one way: [`materials`] give the BRDF and the per-texel features φ;
//! [`groundtruth`] tabulates the target pdf p* for a condition (φ, wi); [`train`] fits every
//! sampler of the runtime to it; [`bake`] writes and verifies the blob; [`eval`] measures the
//! blob through the runtime's public API; [`demo`] runs the whole chain and reports.

pub mod bake;
pub mod bench;
pub mod demo;
pub mod eval;
pub mod figures;
pub mod groundtruth;
pub mod io;
pub mod materials;
pub mod metrics;
pub mod neural;
pub mod render;
pub mod train;
