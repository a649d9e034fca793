//! [`AnySampler`]: whichever sampler a blob holds, dispatched statically by `match` (no
//! `dyn`), and [`SamplerKind::param_count`], the one table from kinds to architectures.

use glam::{Vec2, Vec3};

use crate::kind::SamplerKind;
use crate::neural_material::NeuralMaterial;
use crate::nn::FEATURE_DIM;
use crate::weights::Tensor;

use super::{
    AffineFlowSampler, AnalyticMixtureSampler, CosineSampler, DirectHistogramSampler, FlowSampler,
    HistogramMixtureSampler, ImprovedBaselineSampler, Prepared, Sample, Sampler,
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
            SamplerKind::AffineFlow => AffineFlowSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::DirectHistogram => DirectHistogramSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::HistogramMixture => HistogramMixtureSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::NeuralMaterial => NeuralMaterial::<&[f32]>::PARAM_COUNT,
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
    /// [`SamplerKind::AffineFlow`].
    AffineFlow(AffineFlowSampler<Tensor<'a>>),
    /// [`SamplerKind::DirectHistogram`].
    DirectHistogram(DirectHistogramSampler<Tensor<'a>>),
    /// [`SamplerKind::HistogramMixture`].
    HistogramMixture(HistogramMixtureSampler<Tensor<'a>>),
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
    /// See [`AnySampler::AffineFlow`].
    AffineFlow(<AffineFlowSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::DirectHistogram`].
    DirectHistogram(<DirectHistogramSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::HistogramMixture`].
    HistogramMixture(<HistogramMixtureSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
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
            AnySampler::AffineFlow(_) => SamplerKind::AffineFlow,
            AnySampler::DirectHistogram(_) => SamplerKind::DirectHistogram,
            AnySampler::HistogramMixture(_) => SamplerKind::HistogramMixture,
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
            AnySampler::AffineFlow(s) => AnyPrepared::AffineFlow(s.prepare(phi, wi)?),
            AnySampler::DirectHistogram(s) => AnyPrepared::DirectHistogram(s.prepare(phi, wi)?),
            AnySampler::HistogramMixture(s) => AnyPrepared::HistogramMixture(s.prepare(phi, wi)?),
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
            AnyPrepared::AffineFlow($p) => $e,
            AnyPrepared::DirectHistogram($p) => $e,
            AnyPrepared::HistogramMixture($p) => $e,
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
