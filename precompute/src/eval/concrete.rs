//! A blob's sampler as its concrete type. [`neusample::AnySampler`]'s own batched lanes are
//! an enum as large as the largest kind's; the evaluation hands the renderer and the cost
//! measurements the concrete sampler instead, with its own lanes, as a renderer that knows
//! its material's sampler kind would.

use neusample::wavefront::BatchSampler;
use neusample::{AnySampler, Sampler};

/// Work that is generic over the concrete sampler type ([`with_concrete`]).
pub trait WithSampler {
    /// The result.
    type Output;
    /// Runs on the concrete sampler.
    fn run<S: Sampler + BatchSampler + Copy + Sync>(self, s: S) -> Self::Output
    where
        S::Lane: Send;
}

/// Runs `work` on the concrete sampler inside `s`.
pub fn with_concrete<W: WithSampler>(s: AnySampler<'_>, work: W) -> W::Output {
    match s {
        AnySampler::Cosine(x) => work.run(x),
        AnySampler::ImprovedBaseline(x) => work.run(x),
        AnySampler::AnalyticMixture(x) => work.run(x),
        AnySampler::Flow(x) => work.run(x),
        AnySampler::AffineFlow(x) => work.run(x),
        AnySampler::DirectHistogram(x) => work.run(x),
        AnySampler::HistogramMixture(x) => work.run(x),
    }
}
