//! The trainable methods, named by the runtime's [`SamplerKind`] (the names of
//! [`SamplerKind::name`]: `baseline`, `analytic`, `flow`, `affine-flow`, `direct-histogram`,
//! `histogram-mixture`, `reparam`).

use neusample::SamplerKind;

/// Every trainable method, in the paper's order (every sampler kind but cosine), then the
/// reparameterization sampler (which needs an integrand: [`needs_integrand`]).
pub const METHODS: [SamplerKind; 8] = [
    SamplerKind::ImprovedBaseline,
    SamplerKind::AnalyticMixture,
    SamplerKind::Flow,
    SamplerKind::DiskFlow,
    SamplerKind::AffineFlow,
    SamplerKind::DirectHistogram,
    SamplerKind::HistogramMixture,
    SamplerKind::Reparam,
];

/// The trainable method named `name`; the error lists the names.
pub fn parse_method(name: &str) -> anyhow::Result<SamplerKind> {
    SamplerKind::from_name(name)
        .filter(|k| METHODS.contains(k))
        .ok_or_else(|| {
            let names: Vec<_> = METHODS.iter().map(|m| m.name()).collect();
            anyhow::anyhow!(
                "unknown method `{name}`; expected one of {}",
                names.join(", ")
            )
        })
}

/// Whether `method` trains on the integrand itself (a neural material or the synthetic
/// target) rather than on samples of p*: only the reparameterization sampler.
#[must_use]
pub fn needs_integrand(method: SamplerKind) -> bool {
    method == SamplerKind::Reparam
}
