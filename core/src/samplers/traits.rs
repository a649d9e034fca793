//! What every sampler has in common: the condition, the sample, and the two traits a
//! renderer programs against.
//!
//! A sampler is used in two steps per shading point:
//!
//! 1. [`Sampler::prepare`] runs the networks once for the condition (φ, wi) and returns a
//!    small value that borrows the sampler's weights;
//! 2. on that value, [`Prepared::sample`] draws directions and [`Prepared::pdf`] evaluates
//!    the density of any direction — as often as needed (BSDF sampling and MIS).
//!
//! Both steps are total: bad input gives `None` or a zero density, never a panic or NaN.

use core::cell::Cell;
use core::fmt;
use core::marker::PhantomData;

use glam::{Vec2, Vec3};

use crate::blob::{Header, TensorRole};
use crate::kind::SamplerKind;
use crate::nn::FEATURE_DIM;
use crate::warp;
use crate::weights::Tensor;

/// A direction drawn by a sampler, with the two densities a renderer needs (pbrt's
/// `BSDFSample` with `pdfIsProportional`, Mitsuba's weight and `BSDFSample3f::pdf`).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Sample {
    /// The sampled direction in the local shading frame (unit length, `wo.z > 0`).
    pub wo: Vec3,
    /// Its density with respect to **solid angle**: `pdf_disk · wo.z`, the density the
    /// sample was drawn with. This is what a renderer divides `f · cos θo` by (pbrt
    /// `Sample_f().pdf`, Mitsuba's `weight = f · cos θo / pdf`).
    pub pdf: f32,
    /// Its density with respect to **area on the projected unit disk**.
    pub pdf_disk: f32,
    /// The density MIS weighs the sample with, with respect to **solid angle**:
    /// [`Prepared::pdf`] at `wo`, the function every other strategy's MIS weight evaluates
    /// too, so that the weights sum to one. It is `pdf` for every sampler whose `pdf` is the
    /// density of its samples; the reparameterization sampler's samples carry the warp's
    /// exact density in `pdf` and its pdf network's value here (`core/ARCHITECTURES.md` §8).
    /// Mitsuba's `BSDFSample3f::pdf`.
    pub mis_pdf: f32,
}

impl Sample {
    /// A sample at disk point `p` with disk density `pdf_disk` (and the same MIS density),
    /// or `None` when `p` is not strictly inside the unit disk or the density is not finite
    /// and positive.
    #[inline]
    #[must_use]
    pub fn from_disk(p: Vec2, pdf_disk: f32) -> Option<Sample> {
        let wo = warp::from_disk(p)?;
        Sample::checked(wo, warp::disk_to_solid_angle(pdf_disk, wo.z), pdf_disk)
    }

    /// A sample at direction `wo` (`wo.z > 0`) drawn with solid-angle density `pdf` (and the
    /// same MIS density), or `None` when `pdf` is not finite and positive.
    #[inline]
    #[must_use]
    pub fn from_solid_angle(wo: Vec3, pdf: f32) -> Option<Sample> {
        Sample::checked(wo, pdf, warp::solid_angle_to_disk(pdf, wo.z))
    }

    /// The sample with densities `pdf` (solid angle, also its MIS density) and `pdf_disk`,
    /// or `None` when `pdf` is not finite and positive.
    #[inline(always)]
    fn checked(wo: Vec3, pdf: f32, pdf_disk: f32) -> Option<Sample> {
        if pdf > 0.0 && crate::math::is_finite(pdf) {
            Some(Sample {
                wo,
                pdf,
                pdf_disk,
                mis_pdf: pdf,
            })
        } else {
            None
        }
    }

    /// The sample with MIS density `mis_pdf` (solid angle; a non-finite or negative value
    /// gives 0: the sample then has MIS weight 0 against any other strategy).
    #[inline]
    #[must_use]
    pub fn with_mis_pdf(self, mis_pdf: f32) -> Sample {
        Sample {
            mis_pdf: crate::math::finite_density(mis_pdf),
            ..self
        }
    }
}

/// A learned (or analytic) sampler of outgoing directions conditioned on (φ, wi).
pub trait Sampler {
    /// The per-shading-point state returned by [`Sampler::prepare`].
    type Prepared<'s>: Prepared
    where
        Self: 's;

    /// Runs the sampler's networks for feature vector `phi` and incoming direction `wi`
    /// (local shading frame, pointing away from the surface; normalised here).
    ///
    /// Returns `None` when the condition is unusable: `wi` at or below the horizon, of zero
    /// length, or with a NaN/∞ component, or `phi` with a NaN/∞ component.
    fn prepare<'s>(&'s self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<Self::Prepared<'s>>;
}

/// Sampling and density evaluation at one prepared shading point.
pub trait Prepared {
    /// Draws a direction from `u ∈ [0, 1)²`. `None` when `u` is not in `[0, 1]²` (1 is
    /// clamped below 1) or the sample falls outside the unit disk (zero contribution; its
    /// probability mass is the part of the density outside the disk).
    fn sample(&self, u: Vec2) -> Option<Sample>;

    /// Density of the disk point `p` with respect to **area on the projected disk**. 0 outside
    /// the open unit disk and for non-finite `p`.
    fn pdf_disk(&self, p: Vec2) -> f32;

    /// Density of direction `wo` (local frame; normalised here) with respect to **solid
    /// angle**: `pdf_disk(wo⊥) · cos θo`. 0 at or below the horizon and for non-finite `wo`.
    /// Equal to [`Sample::mis_pdf`] for every direction [`Prepared::sample`] returns.
    #[inline]
    fn pdf(&self, wo: Vec3) -> f32 {
        match warp::upper_hemisphere(wo) {
            Some(w) => warp::disk_to_solid_angle(self.pdf_disk(warp::to_disk(w)), w.z),
            None => 0.0,
        }
    }

    /// The `u` that [`Prepared::sample`] maps to `wo`, where the method has a unique one
    /// (cosine, flows, histograms); `None` otherwise or for invalid `wo`.
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        let _ = wo;
        None
    }
}

/// A copy of a sampler's weights handle (`&[f32]`, `Tensor`, …) kept by a prepared state.
///
/// rust-gpu: two constraints of GPU shaders shape it:
/// * a prepared state must not point at its sampler: with storage-buffer weights that is a
///   pointer to a local variable holding a buffer pointer, which rust-gpu cannot remove and
///   Vulkan drivers fail on (lavapipe crashes), so the handle is copied (`W: Copy`);
/// * the handle's null-pointer niche must be hidden, so that `Option<Prepared>` is a tagged
///   enum: rust-gpu cannot test a niche-encoded `Option` holding a pointer ("cannot convert
///   pointers to integers"). A `Cell` hides niches.
pub(crate) struct Held<W>(Cell<W>);

impl<W: Copy> Held<W> {
    /// Keeps a copy of `w`.
    #[inline(always)]
    pub(crate) fn new(w: W) -> Self {
        Held(Cell::new(w))
    }
    /// The handle.
    #[inline(always)]
    pub(crate) fn get(&self) -> W {
        self.0.get()
    }
}

impl<W: Copy> Clone for Held<W> {
    #[inline(always)]
    fn clone(&self) -> Self {
        Held::new(self.get())
    }
}

impl<W> fmt::Debug for Held<W> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Held(..)")
    }
}

/// A sampler prepared for one condition whose state is a plain value: the lane `L` (the
/// state the batched API keeps per point) and a copy of the sampler's weights handle `W`.
/// The flows and the reparameterization sampler name it by their own aliases
/// ([`SplineFlowPrepared`](super::SplineFlowPrepared), …).
#[derive(Debug)]
pub struct LanePrepared<'s, W, L> {
    /// A copy of the sampler's weights handle (see `Held`).
    params: Held<W>,
    _sampler: PhantomData<&'s W>,
    lane: L,
}

impl<W: Copy, L: Copy> Clone for LanePrepared<'_, W, L> {
    #[inline]
    fn clone(&self) -> Self {
        LanePrepared::new(self.params.get(), self.lane)
    }
}

impl<W: Copy, L> LanePrepared<'_, W, L> {
    /// The state `lane` with a copy of the weights handle `params`.
    #[inline(always)]
    pub(crate) fn new(params: W, lane: L) -> Self {
        LanePrepared {
            params: Held::new(params),
            _sampler: PhantomData,
            lane,
        }
    }

    /// The weights handle.
    #[inline(always)]
    pub(crate) fn params(&self) -> W {
        self.params.get()
    }

    /// The prepared state without the weights handle.
    #[inline]
    #[must_use]
    pub fn lane(&self) -> L
    where
        L: Copy,
    {
        self.lane
    }

    /// The prepared state, borrowed.
    #[inline(always)]
    pub(crate) fn lane_ref(&self) -> &L {
        &self.lane
    }
}

/// What a sampler is built from ([`FromBlob`]): a validated blob's tensors and header.
/// [`Blob`](crate::Blob) implements it once [`Blob::open`](crate::Blob::open) has checked
/// every dimension, count and value.
pub trait BlobSource<'a> {
    /// The tensor of `role`, read in place, if the blob has it.
    fn tensor(&self, role: TensorRole) -> Option<Tensor<'a>>;
    /// The header.
    fn header(&self) -> &Header<'a>;
    /// The tensor of `role`, or an empty one when the blob has none.
    fn tensor_or_empty(&self, role: TensorRole) -> Tensor<'a> {
        self.tensor(role).unwrap_or(Tensor::F32(&[]))
    }
    /// The network parameters (empty when the blob has none).
    fn params(&self) -> Tensor<'a> {
        self.tensor_or_empty(TensorRole::Params)
    }
}

/// A sampler built from a blob of its kind: how [`Blob::sampler`](crate::Blob::sampler) and
/// [`Blob::sampler_as`](crate::Blob::sampler_as) make it.
pub trait FromBlob<'a>: Sized {
    /// The kind whose blobs hold this sampler.
    const KIND: SamplerKind;
    /// The sampler over `src`'s tensors, or `None` when they do not fit its architecture.
    fn from_blob(src: &impl BlobSource<'a>) -> Option<Self>;
}

/// A sampler whose blob is one flat parameter array (a struct `{ params: W }`): its
/// `PARAM_COUNT` (documented by `$doc`), the constructors of `params_constructors!` and its
/// [`FromBlob`] for blobs of kind `$kind`.
macro_rules! flat_params_sampler {
    ($sampler:ident, $kind:ident, $count:expr, $doc:literal) => {
        impl<W: $crate::Weights> $sampler<W> {
            #[doc = $doc]
            pub const PARAM_COUNT: usize = $count;

            $crate::samplers::traits::params_constructors!();
        }

        impl<'a> $crate::samplers::FromBlob<'a> for $sampler<$crate::Tensor<'a>> {
            const KIND: $crate::SamplerKind = $crate::SamplerKind::$kind;
            fn from_blob(src: &impl $crate::samplers::BlobSource<'a>) -> Option<Self> {
                Self::new(src.params())
            }
        }
    };
}
pub(crate) use flat_params_sampler;

/// [`Sampler`] for `$sampler<W>` (a struct `{ params: W }`) whose prepared state is a
/// [`LanePrepared`] named `$prepared<'s, W>`: the condition is checked
/// ([`check_condition`](crate::nn::check_condition)) and encoded into `$c`
/// ([`encode_condition`](crate::nn::encode_condition)), and `$lane`, an expression of `$w`
/// (`&W`, the weights) and `$c`, gives the lane, or `None` when it is unusable.
macro_rules! lane_sampler {
    ($sampler:ident => $prepared:ident, |$w:ident, $c:ident| $lane:expr) => {
        impl<W: $crate::Weights + Copy> $crate::samplers::Sampler for $sampler<W> {
            type Prepared<'s>
                = $prepared<'s, W>
            where
                W: 's;

            fn prepare<'s>(
                &'s self,
                phi: &[f32; $crate::nn::FEATURE_DIM],
                wi: glam::Vec3,
            ) -> Option<$prepared<'s, W>> {
                let wi = $crate::nn::check_condition(phi, wi)?;
                let $c = $crate::nn::encode_condition(phi, wi);
                let $w = &self.params;
                let lane = $lane?;
                Some($crate::samplers::LanePrepared::new(self.params, lane))
            }
        }
    };
}
pub(crate) use lane_sampler;

/// The constructors every sampler with one flat parameter array has (`new_unchecked`, `new`,
/// `params`), for a struct `{ params: W }` with an associated `PARAM_COUNT`.
macro_rules! params_constructors {
    () => {
        /// A sampler over `params` without the length check of [`Self::new`], for GPU shaders
        /// (`Option<Self>` with a borrowed `W` cannot be tested by rust-gpu). Not `unsafe`:
        /// reads past the end of a short array give 0.0, so wrong densities but never a panic
        /// or NaN. Check `params.len() == PARAM_COUNT` on the host.
        #[inline]
        #[must_use]
        pub const fn new_unchecked(params: W) -> Self {
            Self { params }
        }

        /// A sampler over the flat parameter array `params` (layout in
        /// `core/ARCHITECTURES.md`), or `None` when it does not hold exactly
        /// [`Self::PARAM_COUNT`] values.
        #[inline]
        #[must_use]
        pub fn new(params: W) -> Option<Self> {
            if params.len() as usize == Self::PARAM_COUNT {
                Some(Self::new_unchecked(params))
            } else {
                None
            }
        }

        /// The parameter array.
        #[inline]
        #[must_use]
        pub fn params(&self) -> &W {
            &self.params
        }
    };
}
pub(crate) use params_constructors;
