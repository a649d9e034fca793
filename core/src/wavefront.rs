//! The batched ("wavefront") API: prepare, sample, pdf and invert over N shading points at
//! once, in structure-of-arrays form, as the paper ran its samplers and as Mitsuba's
//! LLVM/CUDA variants, GPUs and production CPU renderers call a material.
//!
//! Every sampler implements [`BatchSampler`]. Its per-point prepared state is a plain value,
//! the **lane** ([`BatchSampler::Lane`]): the scalar prepared state without its weights
//! handle. A renderer that prepares once and then samples and evaluates pdfs (BSDF sampling
//! with MIS) keeps a `Vec<Lane>` of its own; one that only needs "prepare and sample" or
//! "prepare and pdf" per call (a Mitsuba plugin) uses the fused [`BatchSampler::sample_fused`]
//! and [`BatchSampler::pdf_fused`], which prepare in chunks on the stack.
//!
//! # Contract
//!
//! - The caller provides every buffer; nothing allocates. Any N works (no multiple of a SIMD
//!   width is required); every slice of one call must have the same length, otherwise the
//!   call returns [`Error::BatchLength`](crate::Error::BatchLength) and writes nothing.
//! - Per lane, the rules of the scalar API hold: a refused condition gives a refused lane
//!   (`Lane::default()`), a refused sample gives `pdf = 0` and `wo = 0`, a direction outside
//!   the hemisphere gives a zero pdf. A bad lane never disturbs another lane.
//! - Results equal the scalar path's bit for bit: both run the same operations in the same
//!   order per lane (dense layers as small matrix products over lanes, the rest per lane
//!   through the same functions).
//!
//! Densities are with respect to **solid angle**, `p_ω = p_disk · cos θo`, as in the scalar
//! [`Prepared::pdf`](crate::Prepared::pdf).
pub use crate::batch::{
    current_isa, detected_isa, prefer_isa, BatchSampler, Features, FeaturesMut, Isa, LaneState,
    RgbMut, SamplesMut, Vec2s, Vec2sMut, Vec3s, Vec3sMut, FUSED_CHUNK,
};
pub use crate::samplers::{AffineLane, AnyLane, FlowLane, MixtureLane, ReparamLane};
