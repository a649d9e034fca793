//! [`AnySampler`]: whichever sampler a blob holds, dispatched statically by `match` (no
//! `dyn`), and [`SamplerKind::param_count`], the one table from kinds to architectures.

use glam::{Vec2, Vec3};

use crate::kind::SamplerKind;
use crate::neural_material::NeuralMaterial;
use crate::nn::FEATURE_DIM;
use crate::weights::Tensor;

use super::{
    AffineFlowSampler, AnalyticMixtureSampler, CosineSampler, DirectHistogramSampler,
    DiskFlowSampler, FlowSampler, HistogramMixtureSampler, ImprovedBaselineSampler, Prepared,
    ReparamSampler, Sample, Sampler,
};

impl SamplerKind {
    /// Number of network parameters this build's architecture of the kind has.
    #[must_use]
    pub const fn param_count(self) -> usize {
        match self {
            SamplerKind::Cosine => 0,
            SamplerKind::ImprovedBaseline => ImprovedBaselineSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::AnalyticMixture => AnalyticMixtureSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::Flow => FlowSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::DiskFlow => DiskFlowSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::AffineFlow => AffineFlowSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::DirectHistogram => DirectHistogramSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::HistogramMixture => HistogramMixtureSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::NeuralMaterial => NeuralMaterial::<&[f32]>::PARAM_COUNT,
            SamplerKind::Reparam => ReparamSampler::<&[f32]>::PARAM_COUNT,
            // Tables, no network.
            SamplerKind::Measured => 0,
        }
    }
}

/// Any sampler held by a blob (static dispatch by `match`; no `dyn`).
#[derive(Copy, Clone, Debug)]
#[allow(clippy::large_enum_variant)]
pub enum AnySampler<'a> {
    /// [`SamplerKind::Cosine`].
    Cosine(CosineSampler),
    /// [`SamplerKind::ImprovedBaseline`].
    ImprovedBaseline(ImprovedBaselineSampler<Tensor<'a>>),
    /// [`SamplerKind::AnalyticMixture`].
    AnalyticMixture(AnalyticMixtureSampler<Tensor<'a>>),
    /// [`SamplerKind::Flow`].
    Flow(FlowSampler<Tensor<'a>>),
    /// [`SamplerKind::DiskFlow`].
    DiskFlow(DiskFlowSampler<Tensor<'a>>),
    /// [`SamplerKind::AffineFlow`].
    AffineFlow(AffineFlowSampler<Tensor<'a>>),
    /// [`SamplerKind::DirectHistogram`].
    DirectHistogram(DirectHistogramSampler<Tensor<'a>>),
    /// [`SamplerKind::HistogramMixture`].
    HistogramMixture(HistogramMixtureSampler<Tensor<'a>>),
    /// [`SamplerKind::Reparam`].
    Reparam(ReparamSampler<Tensor<'a>>),
}

/// The prepared state of an [`AnySampler`].
#[allow(clippy::large_enum_variant)]
pub enum AnyPrepared<'s, 'a: 's> {
    /// See [`AnySampler::Cosine`].
    Cosine(<CosineSampler as Sampler>::Prepared<'s>),
    /// See [`AnySampler::ImprovedBaseline`].
    ImprovedBaseline(<ImprovedBaselineSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::AnalyticMixture`].
    AnalyticMixture(<AnalyticMixtureSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::Flow`].
    Flow(<FlowSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::DiskFlow`].
    DiskFlow(<DiskFlowSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::AffineFlow`].
    AffineFlow(<AffineFlowSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::DirectHistogram`].
    DirectHistogram(<DirectHistogramSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::HistogramMixture`].
    HistogramMixture(<HistogramMixtureSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::Reparam`].
    Reparam(<ReparamSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
}

impl<'a> AnySampler<'a> {
    /// The kind of the sampler.
    #[must_use]
    pub fn kind(&self) -> SamplerKind {
        match self {
            AnySampler::Cosine(_) => SamplerKind::Cosine,
            AnySampler::ImprovedBaseline(_) => SamplerKind::ImprovedBaseline,
            AnySampler::AnalyticMixture(_) => SamplerKind::AnalyticMixture,
            AnySampler::Flow(_) => SamplerKind::Flow,
            AnySampler::DiskFlow(_) => SamplerKind::DiskFlow,
            AnySampler::AffineFlow(_) => SamplerKind::AffineFlow,
            AnySampler::DirectHistogram(_) => SamplerKind::DirectHistogram,
            AnySampler::HistogramMixture(_) => SamplerKind::HistogramMixture,
            AnySampler::Reparam(_) => SamplerKind::Reparam,
        }
    }
}

impl<'a> Sampler for AnySampler<'a> {
    type Prepared<'s>
        = AnyPrepared<'s, 'a>
    where
        Self: 's;

    #[inline]
    fn prepare<'s>(&'s self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<AnyPrepared<'s, 'a>> {
        Some(match self {
            AnySampler::Cosine(s) => AnyPrepared::Cosine(s.prepare(phi, wi)?),
            AnySampler::ImprovedBaseline(s) => AnyPrepared::ImprovedBaseline(s.prepare(phi, wi)?),
            AnySampler::AnalyticMixture(s) => AnyPrepared::AnalyticMixture(s.prepare(phi, wi)?),
            AnySampler::Flow(s) => AnyPrepared::Flow(s.prepare(phi, wi)?),
            AnySampler::DiskFlow(s) => AnyPrepared::DiskFlow(s.prepare(phi, wi)?),
            AnySampler::AffineFlow(s) => AnyPrepared::AffineFlow(s.prepare(phi, wi)?),
            AnySampler::DirectHistogram(s) => AnyPrepared::DirectHistogram(s.prepare(phi, wi)?),
            AnySampler::HistogramMixture(s) => AnyPrepared::HistogramMixture(s.prepare(phi, wi)?),
            AnySampler::Reparam(s) => AnyPrepared::Reparam(s.prepare(phi, wi)?),
        })
    }
}

macro_rules! dispatch {
    ($self:expr, $p:ident => $e:expr) => {
        match $self {
            AnyPrepared::Cosine($p) => $e,
            AnyPrepared::ImprovedBaseline($p) => $e,
            AnyPrepared::AnalyticMixture($p) => $e,
            AnyPrepared::Flow($p) => $e,
            AnyPrepared::DiskFlow($p) => $e,
            AnyPrepared::AffineFlow($p) => $e,
            AnyPrepared::DirectHistogram($p) => $e,
            AnyPrepared::HistogramMixture($p) => $e,
            AnyPrepared::Reparam($p) => $e,
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
    #[inline]
    fn exact_pdf(&self) -> bool {
        dispatch!(self, p => p.exact_pdf())
    }
}

#[cfg(not(target_arch = "spirv"))]
mod batch {
    //! [`AnySampler`] over wavefronts: one `match` per call, then the concrete sampler's
    //! batched kernels.

    use super::*;
    use crate::batch::{
        BatchSampler, Features, LaneState, SamplesMut, Vec2s, Vec2sMut, Vec3s, FUSED_CHUNK,
    };
    use crate::error::{Error, Result};
    use crate::samplers::{
        AffineLane, AnalyticMixturePrepared, CosinePrepared, DirectHistogramPrepared, DiskFlowLane,
        FlowLane, ImprovedBaselinePrepared, MixtureLane, ReparamLane,
    };

    /// The lane of an [`AnySampler`]: the concrete sampler's lane. It is as large as the
    /// largest lane (the direct histogram's 2 KiB table); prefer the concrete sampler's
    /// lanes, or the fused calls, for wavefronts of other kinds.
    #[derive(Copy, Clone, Debug, Default)]
    #[allow(clippy::large_enum_variant)]
    pub enum AnyLane {
        /// A refused lane.
        #[default]
        Refused,
        /// [`SamplerKind::Cosine`].
        Cosine(CosinePrepared),
        /// [`SamplerKind::ImprovedBaseline`].
        ImprovedBaseline(ImprovedBaselinePrepared),
        /// [`SamplerKind::AnalyticMixture`].
        AnalyticMixture(AnalyticMixturePrepared),
        /// [`SamplerKind::Flow`].
        Flow(FlowLane),
        /// [`SamplerKind::DiskFlow`].
        DiskFlow(DiskFlowLane),
        /// [`SamplerKind::AffineFlow`].
        AffineFlow(AffineLane),
        /// [`SamplerKind::DirectHistogram`].
        DirectHistogram(DirectHistogramPrepared),
        /// [`SamplerKind::HistogramMixture`].
        HistogramMixture(MixtureLane),
        /// [`SamplerKind::Reparam`].
        Reparam(ReparamLane),
    }

    impl LaneState for AnyLane {
        #[inline(always)]
        fn is_prepared(&self) -> bool {
            !matches!(self, AnyLane::Refused)
        }
    }

    /// Runs `f` on chunks of typed lanes converted from and to [`AnyLane`]s.
    macro_rules! typed {
        ($lanes:expr, $variant:ident, $lane:ty, |$typed:ident, $a:ident| $body:expr) => {{
            let lanes = $lanes;
            let mut buf: [Option<$lane>; FUSED_CHUNK] = [None; FUSED_CHUNK];
            let mut $a = 0;
            while $a < lanes.len() {
                let b = ($a + FUSED_CHUNK).min(lanes.len());
                for (t, l) in buf.iter_mut().zip(&lanes[$a..b]) {
                    *t = match l {
                        AnyLane::$variant(x) => Some(*x),
                        _ => None,
                    };
                }
                let $typed = &buf[..b - $a];
                $body?;
                $a = b;
            }
            Ok(())
        }};
    }

    /// One arm per kind: `$m!(sampler, Variant, LaneType)`.
    macro_rules! each_kind {
        ($s:expr, $m:ident) => {
            match $s {
                AnySampler::Cosine(s) => $m!(s, Cosine, CosinePrepared),
                AnySampler::ImprovedBaseline(s) => {
                    $m!(s, ImprovedBaseline, ImprovedBaselinePrepared)
                }
                AnySampler::AnalyticMixture(s) => $m!(s, AnalyticMixture, AnalyticMixturePrepared),
                AnySampler::Flow(s) => $m!(s, Flow, FlowLane),
                AnySampler::DiskFlow(s) => $m!(s, DiskFlow, DiskFlowLane),
                AnySampler::AffineFlow(s) => $m!(s, AffineFlow, AffineLane),
                AnySampler::DirectHistogram(s) => $m!(s, DirectHistogram, DirectHistogramPrepared),
                AnySampler::HistogramMixture(s) => $m!(s, HistogramMixture, MixtureLane),
                AnySampler::Reparam(s) => $m!(s, Reparam, ReparamLane),
            }
        };
    }

    impl BatchSampler for AnySampler<'_> {
        type Lane = AnyLane;

        #[inline]
        fn exact_pdf(&self) -> bool {
            self.kind().exact_pdf()
        }

        fn prepare_batch(
            &self,
            phi: Features<'_>,
            wi: Vec3s<'_>,
            lanes: &mut [AnyLane],
        ) -> Result<()> {
            let n = crate::batch::check_prepare_args(&phi, &wi, lanes)?;
            macro_rules! prep {
                ($s:expr, $variant:ident, $lane:ty) => {{
                    let mut buf: [Option<$lane>; FUSED_CHUNK] = [None; FUSED_CHUNK];
                    let mut a = 0;
                    while a < n {
                        let b = (a + FUSED_CHUNK).min(n);
                        $s.prepare_batch(phi.range(a, b), wi.range(a, b), &mut buf[..b - a])?;
                        for (l, t) in lanes[a..b].iter_mut().zip(&buf[..b - a]) {
                            *l = match t {
                                Some(x) => AnyLane::$variant(*x),
                                None => AnyLane::Refused,
                            };
                        }
                        a = b;
                    }
                    Ok::<(), Error>(())
                }};
            }
            each_kind!(self, prep)
        }

        fn sample_batch(
            &self,
            lanes: &[AnyLane],
            u: Vec2s<'_>,
            mut out: SamplesMut<'_>,
        ) -> Result<()> {
            crate::batch::check_sample_args(lanes, &u, &out)?;
            macro_rules! samp {
                ($s:expr, $variant:ident, $lane:ty) => {
                    typed!(lanes, $variant, $lane, |t, a| $s.sample_batch(
                        t,
                        u.range(a, a + t.len()),
                        out.range(a, a + t.len())
                    ))
                };
            }
            each_kind!(self, samp)
        }

        fn pdf_batch(&self, lanes: &[AnyLane], wo: Vec3s<'_>, pdf: &mut [f32]) -> Result<()> {
            crate::batch::check_pdf_args(lanes, &wo, pdf)?;
            macro_rules! dens {
                ($s:expr, $variant:ident, $lane:ty) => {
                    typed!(lanes, $variant, $lane, |t, a| $s.pdf_batch(
                        t,
                        wo.range(a, a + t.len()),
                        &mut pdf[a..a + t.len()]
                    ))
                };
            }
            each_kind!(self, dens)
        }

        fn invert_batch(
            &self,
            lanes: &[AnyLane],
            wo: Vec3s<'_>,
            mut u: Vec2sMut<'_>,
            ok: &mut [bool],
        ) -> Result<()> {
            crate::batch::check_invert_args(lanes, &wo, &u, ok)?;
            macro_rules! inv {
                ($s:expr, $variant:ident, $lane:ty) => {
                    typed!(lanes, $variant, $lane, |t, a| $s.invert_batch(
                        t,
                        wo.range(a, a + t.len()),
                        u.range(a, a + t.len()),
                        &mut ok[a..a + t.len()]
                    ))
                };
            }
            each_kind!(self, inv)
        }

        fn sample_fused(
            &self,
            phi: Features<'_>,
            wi: Vec3s<'_>,
            u: Vec2s<'_>,
            out: SamplesMut<'_>,
        ) -> Result<()> {
            macro_rules! fused {
                ($s:expr, $variant:ident, $lane:ty) => {
                    $s.sample_fused(phi, wi, u, out)
                };
            }
            each_kind!(self, fused)
        }

        fn pdf_fused(
            &self,
            phi: Features<'_>,
            wi: Vec3s<'_>,
            wo: Vec3s<'_>,
            pdf: &mut [f32],
        ) -> Result<()> {
            macro_rules! fused {
                ($s:expr, $variant:ident, $lane:ty) => {
                    $s.pdf_fused(phi, wi, wo, pdf)
                };
            }
            each_kind!(self, fused)
        }
    }
}

#[cfg(not(target_arch = "spirv"))]
pub use batch::AnyLane;
