//! # neusample — importance sampling for neural materials
//!
//! The runtime of *NeuSample: Importance Sampling for Neural Materials* (Xu et al.,
//! SIGGRAPH 2023): learned samplers of outgoing directions `wo` conditioned on a material's
//! per-texel feature vector φ and the incoming direction `wi`, with exact densities for
//! multiple importance sampling.
//!
//! The crate is `#![no_std]`, does not allocate, and its hot path (prepare → sample → pdf)
//! never panics and never returns NaN. The same code compiles for x86-64, embedded targets
//! (thumbv7em, wasm32) and GPU shaders through rust-gpu.
//!
//! ## Measures
//!
//! Samplers live on the **projected unit disk** `wo⊥ = (wo.x, wo.y)` of the local shading
//! frame (z = normal). [`Prepared::pdf_disk`] is a density with respect to disk area;
//! [`Prepared::pdf`] and [`Sample::pdf`] are with respect to **solid angle**,
//! `p_ω = p_disk · cos θo` ([`warp`]).
//!
//! ## Layout
//!
//! Data flows one way, from leaves to the blob reader:
//!
//! | module | what |
//! |---|---|
//! | `dtype`, `error`, `kind`, `math`, [`warp`], `weights` | leaves: the storage type, the error type, the kind enums, the only calls to transcendental functions, disk ↔ hemisphere warps, parameter storage ([`Weights`]) |
//! | [`nn`] | dense layers and the condition encodings |
//! | [`distrib`] | Gaussians, RQ splines, [`Table2D`], [`distrib::Marginal2D`] |
//! | [`wavefront`] | the batched API (not on SPIR-V): structure-of-arrays views, the `BatchSampler` trait, and its private building blocks (chunked kernels, run-time instruction-set dispatch, dense layers over lanes) |
//! | [`samplers`] | one file per method (scalar, and batched beside it), the [`Sampler`]/[`Prepared`] traits, [`AnySampler`] |
//! | [`neural_material`] | the neural BRDF the samplers are trained for |
//! | [`measured`] | measured (RGL) BRDFs: their evaluation and their own VNDF sampler |
//! | [`blob`] | the file format: layout, reader, validation, writer |
//!
//! Everything a renderer needs is re-exported here: a blob's sampler is dispatched over its
//! kind ([`AnySampler`], [`BlobSampler`]). A concrete sampler type (for a renderer that knows
//! its material's kind, or a trainer) is in [`samplers`], its architecture constants and
//! building blocks in its module.
//!
//! ## A renderer's view
//!
//! ```
//! use neusample::{Blob, BlobWriter, DType, Prepared, Sampler, SamplerKind, TensorRole, Vec2, Vec3};
//!
//! # let params = vec![0.0f32; SamplerKind::AnalyticMixture.param_count()];
//! # let mut w = BlobWriter::new(SamplerKind::AnalyticMixture, DType::F32, "doc");
//! # w.tensor(TensorRole::Params, &params);
//! # let bytes = w.to_bytes();
//! // Once, when the material loads: validate the blob and build its sampler.
//! let blob = Blob::open(&bytes)?;
//! let sampler = blob.sampler()?;
//!
//! // At a shading point: the material's feature vector φ and the incoming direction wi,
//! // both in the local shading frame (z = normal, wi pointing away from the surface).
//! let phi = [0.1f32; 8];
//! let wi = Vec3::new(0.3, -0.2, 0.93);
//! if let Some(prepared) = sampler.prepare(&phi, wi) {
//!     // BSDF sampling: a direction and its solid-angle density (divide f·cos by it).
//!     if let Some(s) = prepared.sample(Vec2::new(0.25, 0.75)) {
//!         assert!(s.wo.z > 0.0 && s.pdf > 0.0);
//!         // The density of the same direction, e.g. for MIS weights: the same number.
//!         assert_eq!(prepared.pdf(s.wo), s.pdf);
//!     }
//!     // Light sampling picked another direction: its BSDF-sampling density for MIS.
//!     let _p_light = prepared.pdf(Vec3::new(0.0, 0.6, 0.8));
//! }
//! # Ok::<(), neusample::Error>(())
//! ```
#![cfg_attr(not(feature = "std"), no_std)]
#![cfg_attr(docsrs, feature(doc_cfg))]

#[cfg(feature = "alloc")]
extern crate alloc;

pub mod blob;
pub mod distrib;
mod dtype;
mod error;
mod kind;
mod math;
pub mod measured;
pub mod neural_material;
pub mod nn;
pub mod samplers;
pub mod warp;
#[cfg(not(target_arch = "spirv"))]
pub mod wavefront;
mod weights;

#[cfg(feature = "alloc")]
pub use blob::BlobWriter;
pub use blob::{Blob, TensorRole};
pub use distrib::Table2D;
pub use dtype::DType;
pub use error::{Error, Result};
pub use glam::{Vec2, Vec3};
pub use kind::{BlobKind, Interpolation, SamplerKind, UnknownTag};
pub use math::ONE_MINUS_EPSILON;
pub use measured::{
    MeasuredMaterial, MeasuredPrepared, MeasuredPreparedCopied, MeasuredSample, MeasuredShape,
    MeasuredTables,
};
pub use neural_material::NeuralMaterial;
pub use nn::FEATURE_DIM;
pub use samplers::{
    AnyPrepared, AnySampler, BlobSampler, Defensive, DefensivePrepared, Prepared, Sample, Sampler,
};
pub use warp::Frame;
pub use weights::{Tensor, Weights};
