//! The one list of sampler kinds. A leaf: the list names its types, which each use of it
//! resolves where it expands.

/// The one list of sampler kinds. Each line: the variant with its documentation, its blob
/// tag (the number a blob's header and the C ABI carry; never reused, so old blobs open),
/// its stable name (CLI, JSON, file names), its sampler type over a blob's tensors
/// (lifetime `'a`) and its batched lane. `sampler_kinds!(m)` calls `m!` with the list;
/// every per-kind table of the crate is such an `m`.
macro_rules! sampler_kinds {
    ($m:ident) => {
        $m! {
            /// Cosine-hemisphere sampling (no parameters).
            Cosine = 0, "cosine", CosineSampler, CosinePrepared;
            /// Improved baseline: Lambert + isotropic Gaussian (paper Eq. 1).
            ImprovedBaseline = 1, "baseline", ImprovedBaselineSampler<Tensor<'a>>, ImprovedBaselinePrepared;
            /// Analytic mixture: Lambert + two anisotropic Gaussians (paper Eq. 2).
            AnalyticMixture = 2, "analytic", AnalyticMixtureSampler<Tensor<'a>>, AnalyticMixturePrepared;
            /// Conditional rational-quadratic spline flow (paper Eq. 3–4).
            SplineFlow = 3, "flow", SplineFlowSampler<Tensor<'a>>, SplineFlowLane;
            /// Disk flow: the paper's spline couplings on a uniform base with every mass inside
            /// the disk (`core/ARCHITECTURES.md` §9).
            DiskFlow = 9, "disk-flow", DiskFlowSampler<Tensor<'a>>, DiskFlowLane;
            /// Affine-coupling flow baseline (Xie et al. 2019).
            AffineFlow = 4, "affine-flow", AffineFlowSampler<Tensor<'a>>, AffineFlowLane;
            /// Direct histogram baseline (Zhu et al. 2021).
            DirectHistogram = 5, "direct-histogram", DirectHistogramSampler<Tensor<'a>>, DirectHistogramPrepared;
            /// Histogram mixture (paper Eq. 5–6).
            HistogramMixture = 6, "histogram-mixture", HistogramMixtureSampler<Tensor<'a>>, HistogramMixtureLane;
            /// Reparameterization sampler (Wu et al. 2025): an MLP warp of a Gaussian with its
            /// exact Jacobian weight, and a pdf network for MIS ([`crate::samplers::reparam`]).
            Reparam = 8, "reparam", ReparamSampler<Tensor<'a>>, ReparamLane;
        }
    };
}
pub(crate) use sampler_kinds;
