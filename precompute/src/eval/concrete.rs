//! A blob's sampler as its concrete type. [`neusample::AnySampler`]'s own batched lanes are
//! an enum as large as the largest kind's; the evaluation hands the renderer and the cost
//! measurements the concrete sampler instead, with its own lanes, as a renderer that knows
//! its material's sampler kind would.

use neusample::wavefront::BatchSampler;
use neusample::{AnySampler, BlobSampler, Defensive, Sampler};

/// Work that is generic over the concrete sampler type ([`with_concrete`]).
pub trait WithSampler {
    /// The result.
    type Output;
    /// Runs on the concrete sampler.
    fn run<S: Sampler + BatchSampler + Copy + Sync>(self, s: S) -> Self::Output
    where
        S::Lane: Send;
}

/// Runs `work` on the concrete sampler inside `s`, with `s`'s defensive weight.
pub fn with_concrete<W: WithSampler>(s: BlobSampler<'_>, work: W) -> W::Output {
    fn d<S>(x: S, alpha: f32) -> Defensive<S> {
        Defensive::new_unchecked(x, alpha)
    }
    let alpha = s.alpha();
    match *s.inner() {
        AnySampler::Cosine(x) => work.run(d(x, alpha)),
        AnySampler::ImprovedBaseline(x) => work.run(d(x, alpha)),
        AnySampler::AnalyticMixture(x) => work.run(d(x, alpha)),
        AnySampler::Flow(x) => work.run(d(x, alpha)),
        AnySampler::DiskFlow(x) => work.run(d(x, alpha)),
        AnySampler::AffineFlow(x) => work.run(d(x, alpha)),
        AnySampler::DirectHistogram(x) => work.run(d(x, alpha)),
        AnySampler::HistogramMixture(x) => work.run(d(x, alpha)),
        AnySampler::Reparam(x) => work.run(d(x, alpha)),
    }
}
