//! [`AnySampler`]: whichever sampler a blob holds, dispatched statically by `match` (no
//! `dyn`), generated with its prepared state, its batched lane and its visitor from the one
//! list of kinds ([`sampler_kinds!`](super)).

use glam::{Vec2, Vec3};

use crate::kind::{BlobKind, SamplerKind};
use crate::neural_material::NeuralMaterial;
use crate::nn::FEATURE_DIM;
use crate::weights::Tensor;

use super::*;

/// The batched calls of [`AnySampler`], written once over `each_kind!` (not on SPIR-V, which
/// has no batched path).
#[cfg(not(target_arch = "spirv"))]
macro_rules! batch_impl {
    ($each_kind:ident) => {
        impl LaneState for AnyLane {
            #[inline(always)]
            fn is_prepared(&self) -> bool {
                !matches!(self, AnyLane::Refused)
            }
        }

        /// Runs `f` on chunks of typed lanes converted from and to [`AnyLane`]s.
        macro_rules! typed {
            ($lanes:expr, $variant:ident, $lane_ty:ty, |$typed:ident, $a:ident| $body:expr) => {{
                let lanes = $lanes;
                let mut buf: [Option<$lane_ty>; FUSED_CHUNK] = [None; FUSED_CHUNK];
                for ($a, b) in crate::wavefront::chunks(lanes.len(), FUSED_CHUNK) {
                    for (t, l) in buf.iter_mut().zip(&lanes[$a..b]) {
                        *t = match l {
                            AnyLane::$variant(x) => Some(*x),
                            _ => None,
                        };
                    }
                    let $typed = &buf[..b - $a];
                    $body?;
                }
                Ok(())
            }};
        }

        /// `$scratch` (`&mut AnyScratch`) as kind `$variant`'s working memory, made anew
        /// when it held another kind's.
        macro_rules! scratch_of {
            ($scratch:expr, $variant:ident, $fresh:ident) => {{
                if !matches!($scratch, AnyScratch::$variant(_)) {
                    *$scratch = AnyScratch::$variant(Scratch::NEW);
                }
                match $scratch {
                    AnyScratch::$variant(ws) => ws,
                    // Not reached (set above); fresh memory gives the same results.
                    _ => {
                        $fresh = Scratch::NEW;
                        &mut $fresh
                    }
                }
            }};
        }

        impl BatchSampler for AnySampler<'_> {
            type Lane = AnyLane;
            type Scratch = AnyScratch;

            fn prepare_batch(
                &self,
                phi: Features<'_>,
                wi: Vec3s<'_>,
                lanes: &mut [AnyLane],
            ) -> Result<()> {
                let n = crate::wavefront::check_prepare_args(&phi, &wi, lanes)?;
                macro_rules! prep {
                    ($s:expr, $variant:ident, $lane_ty:ty) => {{
                        let mut buf: [Option<$lane_ty>; FUSED_CHUNK] = [None; FUSED_CHUNK];
                        for (a, b) in crate::wavefront::chunks(n, FUSED_CHUNK) {
                            $s.prepare_batch(phi.range(a, b), wi.range(a, b), &mut buf[..b - a])?;
                            for (l, t) in lanes[a..b].iter_mut().zip(&buf[..b - a]) {
                                *l = match t {
                                    Some(x) => AnyLane::$variant(*x),
                                    None => AnyLane::Refused,
                                };
                            }
                        }
                        Ok::<(), Error>(())
                    }};
                }
                $each_kind!(self, prep)
            }

            fn sample_batch_in(
                &self,
                lanes: &[AnyLane],
                u: Vec2s<'_>,
                mut out: SamplesMut<'_>,
                scratch: &mut AnyScratch,
            ) -> Result<()> {
                crate::wavefront::check_sample_args(lanes, &u, &out)?;
                macro_rules! samp {
                    ($s:expr, $variant:ident, $lane_ty:ty) => {{
                        let mut fresh;
                        let ws = scratch_of!(scratch, $variant, fresh);
                        typed!(lanes, $variant, $lane_ty, |t, a| $s.sample_batch_in(
                            t,
                            u.range(a, a + t.len()),
                            out.range(a, a + t.len()),
                            ws
                        ))
                    }};
                }
                $each_kind!(self, samp)
            }

            fn pdf_batch_in(
                &self,
                lanes: &[AnyLane],
                wo: Vec3s<'_>,
                pdf: &mut [f32],
                scratch: &mut AnyScratch,
            ) -> Result<()> {
                crate::wavefront::check_pdf_args(lanes, &wo, pdf)?;
                macro_rules! dens {
                    ($s:expr, $variant:ident, $lane_ty:ty) => {{
                        let mut fresh;
                        let ws = scratch_of!(scratch, $variant, fresh);
                        typed!(lanes, $variant, $lane_ty, |t, a| $s.pdf_batch_in(
                            t,
                            wo.range(a, a + t.len()),
                            &mut pdf[a..a + t.len()],
                            ws
                        ))
                    }};
                }
                $each_kind!(self, dens)
            }

            fn invert_batch(
                &self,
                lanes: &[AnyLane],
                wo: Vec3s<'_>,
                mut u: Vec2sMut<'_>,
                ok: &mut [bool],
            ) -> Result<()> {
                crate::wavefront::check_invert_args(lanes, &wo, &u, ok)?;
                macro_rules! inv {
                    ($s:expr, $variant:ident, $lane_ty:ty) => {
                        typed!(lanes, $variant, $lane_ty, |t, a| $s.invert_batch(
                            t,
                            wo.range(a, a + t.len()),
                            u.range(a, a + t.len()),
                            &mut ok[a..a + t.len()]
                        ))
                    };
                }
                $each_kind!(self, inv)
            }

            fn sample_fused(
                &self,
                phi: Features<'_>,
                wi: Vec3s<'_>,
                u: Vec2s<'_>,
                out: SamplesMut<'_>,
            ) -> Result<()> {
                macro_rules! fused {
                    ($s:expr, $variant:ident, $lane_ty:ty) => {
                        $s.sample_fused(phi, wi, u, out)
                    };
                }
                $each_kind!(self, fused)
            }

            fn pdf_fused(
                &self,
                phi: Features<'_>,
                wi: Vec3s<'_>,
                wo: Vec3s<'_>,
                pdf: &mut [f32],
            ) -> Result<()> {
                macro_rules! fused {
                    ($s:expr, $variant:ident, $lane_ty:ty) => {
                        $s.pdf_fused(phi, wi, wo, pdf)
                    };
                }
                $each_kind!(self, fused)
            }
        }
    };
}
/// The per-kind tables of this module, from the list of kinds.
macro_rules! any_sampler {
    ($($(#[$doc:meta])* $variant:ident = $tag:literal, $name:literal, $sampler:ty, $lane:ty;)*) => {
        impl<'a> SamplerKind {
            /// Number of network parameters this build's architecture of the kind has.
            #[must_use]
            pub const fn param_count(self) -> usize {
                match self {
                    $(SamplerKind::$variant => <$sampler>::PARAM_COUNT,)*
                }
            }
        }

        /// Any sampler held by a blob (static dispatch by `match`; no `dyn`).
        #[derive(Copy, Clone, Debug)]
        #[allow(clippy::large_enum_variant)]
        pub enum AnySampler<'a> {
            $(#[doc = concat!("[`SamplerKind::", stringify!($variant), "`].")] $variant($sampler),)*
        }

        /// The prepared state of an [`AnySampler`].
        #[allow(clippy::large_enum_variant)]
        pub enum AnyPrepared<'s, 'a: 's> {
            $(#[doc = concat!("See [`AnySampler::", stringify!($variant), "`].")]
            $variant(<$sampler as Sampler>::Prepared<'s>),)*
        }

        impl<'a> AnySampler<'a> {
            /// The kind of the sampler.
            #[must_use]
            pub fn kind(&self) -> SamplerKind {
                match self {
                    $(AnySampler::$variant(_) => SamplerKind::$variant,)*
                }
            }

            /// The sampler of kind `kind` over `src`'s tensors, or `None` when they do not
            /// fit its architecture.
            pub fn from_blob(kind: SamplerKind, src: &impl BlobSource<'a>) -> Option<Self> {
                Some(match kind {
                    $(SamplerKind::$variant => AnySampler::$variant(<$sampler>::from_blob(src)?),)*
                })
            }
        }

        impl<'a> Sampler for AnySampler<'a> {
            type Prepared<'s>
                = AnyPrepared<'s, 'a>
            where
                Self: 's;

            #[inline]
            fn prepare<'s>(
                &'s self,
                phi: &[f32; FEATURE_DIM],
                wi: Vec3,
            ) -> Option<AnyPrepared<'s, 'a>> {
                Some(match self {
                    $(AnySampler::$variant(s) => AnyPrepared::$variant(s.prepare(phi, wi)?),)*
                })
            }
        }

        macro_rules! dispatch {
            ($self_:expr, $p:ident => $e:expr) => {
                match $self_ {
                    $(AnyPrepared::$variant($p) => $e,)*
                }
            };
        }

impl Prepared for AnyPrepared<'_, '_> {
            #[inline]
            fn sample(&self, u: Vec2) -> Option<Sample> {
                dispatch!(self, p => p.sample(u))
            }
            #[inline]
            fn pdf_disk(&self, q: Vec2) -> f32 {
                dispatch!(self, p => p.pdf_disk(q))
            }
            #[inline]
            fn pdf(&self, wo: Vec3) -> f32 {
                dispatch!(self, p => p.pdf(wo))
            }
            #[inline]
            fn invert(&self, wo: Vec3) -> Option<Vec2> {
                dispatch!(self, p => p.invert(wo))
            }
        }

        #[cfg(not(target_arch = "spirv"))]
        mod batch {
            //! [`AnySampler`] over wavefronts: one `match` per call, then the concrete
            //! sampler's batched kernels; and the visitor that hands out the concrete sampler.

            use super::*;
            use crate::wavefront::{
                BatchSampler, Features, LaneState, SamplesMut, Scratch, Vec2s, Vec2sMut, Vec3s,
                FUSED_CHUNK,
            };
            use crate::error::{Error, Result};

            /// The lane of an [`AnySampler`]: the concrete sampler's lane. It is as large as
            /// the largest lane (the direct histogram's 2 KiB table); prefer the concrete
            /// sampler's lanes ([`BlobSampler::visit`]), or the fused calls, for wavefronts.
            #[derive(Copy, Clone, Debug, Default)]
            #[allow(clippy::large_enum_variant)]
            pub enum AnyLane {
                /// A refused lane.
                #[default]
                Refused,
                $(#[doc = concat!("[`SamplerKind::", stringify!($variant), "`].")] $variant($lane),)*
            }

            /// The working memory of an [`AnySampler`]'s batched calls: the concrete
            /// sampler's ([`BatchSampler::Scratch`]), made anew when a call's kind differs
            /// from the last one's. As large as the largest (a flow's, tens of KiB): keep one
            /// per thread, not per lane.
            #[allow(clippy::large_enum_variant)]
            pub enum AnyScratch {
                /// Fresh: no call yet.
                Fresh,
                $(#[doc = concat!("[`SamplerKind::", stringify!($variant), "`].")]
                $variant(<Tensor<'static> as KindScratch<$tag>>::Scratch),)*
            }

            impl Scratch for AnyScratch {
                const NEW: Self = AnyScratch::Fresh;
            }

            /// The working memory of the kind with blob tag `TAG`, named without the blob's
            /// lifetime (no kind's working memory depends on it), so that one
            /// [`AnyScratch`] serves samplers of any blob.
            pub trait KindScratch<const TAG: u32> {
                /// [`BatchSampler::Scratch`] of the kind's sampler.
                type Scratch: Scratch;
            }

            $(impl<'a> KindScratch<$tag> for Tensor<'a> {
                type Scratch = <$sampler as BatchSampler>::Scratch;
            })*

            /// One arm per kind: `$m!(sampler, Variant, LaneType)`.
            macro_rules! each_kind {
                ($s:expr, $m:ident) => {
                    match $s {
                        $(AnySampler::$variant(s) => $m!(s, $variant, $lane),)*
                    }
                };
            }

            /// Work generic over the concrete sampler type ([`BlobSampler::visit`]).
            pub trait SamplerVisitor {
                /// The result.
                type Output;
                /// Runs on the concrete sampler.
                fn visit<S: Sampler + BatchSampler + Copy + Sync>(self, s: S) -> Self::Output
                where
                    S::Lane: Send;
            }

            impl BlobSampler<'_> {
                /// Runs `v` on the concrete sampler inside, with the same defensive weight and
                /// turn: a
                /// renderer's wavefront then holds that sampler's own lanes, as one that
                /// knows its material's sampler kind would, not [`AnyLane`]s.
                pub fn visit<V: SamplerVisitor>(&self, v: V) -> V::Output {
                    let (alpha, iso) = (self.alpha(), self.is_isotropic());
                    match *self.inner() {
                        $(AnySampler::$variant(x) => v.visit(
                            Defensive::new_unchecked(x, alpha).with_isotropic(iso)
                        ),)*
                    }
                }
            }

            batch_impl!(each_kind);
        }
    };
}

super::kinds::sampler_kinds!(any_sampler);

impl BlobKind {
    /// Number of network parameters this build's architecture of the kind has.
    #[must_use]
    pub const fn param_count(self) -> usize {
        match self {
            BlobKind::Sampler(k) => k.param_count(),
            BlobKind::NeuralMaterial => NeuralMaterial::<&[f32]>::PARAM_COUNT,
            // Tables, no network.
            BlobKind::Measured => 0,
        }
    }
}

#[cfg(not(target_arch = "spirv"))]
pub use batch::{AnyLane, AnyScratch, SamplerVisitor};
