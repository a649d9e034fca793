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
//! - Sample, pdf and invert work in a sampler's [`BatchSampler::Scratch`] (tens of KiB for
//!   the flows, nothing for most kinds). Each call makes its own on the stack; a renderer
//!   keeps one per thread and passes it to [`BatchSampler::sample_batch_in`] and
//!   [`BatchSampler::pdf_batch_in`] ([`AnyScratch`] for an [`AnySampler`](crate::AnySampler)),
//!   so that no call fills it again. Results never depend on its contents.
//! - Per lane, the rules of the scalar API hold: a refused condition gives a refused lane
//!   (`Lane::default()`), a refused sample gives `pdf = 0` and `wo = 0`, a direction outside
//!   the hemisphere gives a zero pdf. A bad lane never disturbs another lane.
//! - Results agree with the scalar path's within a tolerance, not bit for bit: on x86-64 the
//!   networks run with fused multiply-adds (AVX-512 or AVX2 + FMA, chosen at run time;
//!   [`current_isa`]), and on aarch64 with NEON's, one rounding per step where the scalar
//!   path has two; and the samplers' element-wise steps (`exp`, sigmoids, Box–Muller, …)
//!   use fast branch-free approximations where the scalar path calls libm. Densities at the
//!   same direction agree within 5·10⁻⁴ relative and sampled directions within 10⁻³ (tested
//!   on every committed fixture blob with adversarial lanes; away from `u = 1`, where the
//!   sampling maps are steep enough that rounding moves the sample further). The portable
//!   path ([`prefer_isa`]`(Some(Isa::Portable))`) runs the networks without fused
//!   multiply-adds, as the scalar path does.
//! - Inside one instruction set the results are exact and deterministic: a sample's pdf is
//!   [`BatchSampler::pdf_batch`] at its direction bit for bit (as for the scalar API, for
//!   MIS), fused calls equal unfused ones, and a lane's result depends neither on N nor on
//!   the other lanes.
//!
//! Densities are with respect to **solid angle**, `p_ω = p_disk · cos θo`, as in the scalar
//! [`Prepared::pdf`](crate::Prepared::pdf).
//!
//! Each sampler's lane type is in its module ([`crate::samplers`]); [`AnyLane`] is the lane of
//! any of them.
//!
//! The building blocks the samplers and the materials implement their batched calls with
//! (chunked kernels, their run-time instruction-set dispatch, dense layers over lanes) are
//! this module's private submodules.
pub(crate) mod chunked;
pub(crate) mod dense;
pub(crate) mod lanes;
mod sampler;
pub(crate) mod simd;
mod views;

pub(crate) use chunked::{mlp_lane_sampler, per_lane_chunks};
pub(crate) use sampler::{
    check_invert_args, check_pdf_args, check_prepare_args, check_sample_args, chunks, column,
    encoded_conditions, identity_index, lanes_from_outputs, pdf_fused_chunks, raw_conditions,
    sample_fused_chunks, set_column, FromOutputs, Soa,
};
pub use sampler::{BatchSampler, LaneState, Scratch, FUSED_CHUNK};
pub use simd::{current as current_isa, detected as detected_isa, prefer as prefer_isa, Isa};
pub(crate) use views::check_len;
pub use views::{Features, FeaturesMut, RgbMut, SamplesMut, Vec2s, Vec2sMut, Vec3s, Vec3sMut};

pub use crate::samplers::{AnyLane, AnyScratch, SamplerVisitor};

/// The lane of a [`BlobSampler`](crate::samplers::BlobSampler): whichever kind the blob holds,
/// with the turn of an isotropic blob.
pub type BlobLane = crate::samplers::DefensiveLane<AnyLane>;

/// One dense layer `dense(I, O)` at `offset` of `w` (`core/ARCHITECTURES.md`: weights
/// input-major `W[i][o]`, then the bias) over a chunk of `B` lanes in structure-of-arrays
/// form (`x[i][b]` is input `i` of lane `b`; `B` a multiple of 16, checked when compiled), for
/// the first `m` lanes (rounded up to a register tile; other lanes of `y` are overwritten or
/// left as they were): `y[o][b] = act(bias_o + Σ_i x[i][b]·W[i][o])`.
///
/// The register-tiled kernel every batched network of this crate runs, on the instruction
/// set of [`current_isa`]; exposed for benchmarks and for callers who batch their own
/// networks. Results within the rounding of the products of [`nn::dense`](crate::nn::dense)'s.
#[inline]
pub fn dense_layer<W: crate::Weights + ?Sized, const I: usize, const O: usize, const B: usize>(
    w: &W,
    offset: u32,
    x: &[[f32; B]; I],
    act: crate::nn::Activation,
    y: &mut [[f32; B]; O],
    m: usize,
) {
    dense::dense(w, offset, x, act, y, m);
}
