//! Training every sampler of `neusample` to the paper's objectives, producing the flat
//! parameter arrays (and, for the histogram mixture, the baked tables) the runtime consumes.
//!
//! * Improved baseline, analytic mixture, RQ-spline flow, affine flow and direct histogram:
//!   maximum likelihood of samples of the ground truth p* (paper §3 "Fitting"): every batch
//!   is `batch_conditions` random conditions × `samples_per_condition` samples of p*, and
//!   the loss is `−mean ln p(ω⊥)` (equivalently `KL(p* ‖ p)` up to a constant).
//! * Histogram mixture: the L2 loss of Eq. 7 plus the latent-code quantisation term, plus
//!   (our addition, on by default) a self-normalised NLL term, then baking of the basis
//!   network into tables ([`histogram_mixture`]).
//!
//! The forward passes are `core/ARCHITECTURES.md` operation for operation; the layouts are
//! the runtime's (input-major weights, bias after weights, layers in the listed order).
//! [`model_pdf_disk`] evaluates a trained model in f64 from the exported arrays, so a blob
//! can be checked against it.
//!
//! Reproducibility: all randomness comes from PCG streams seeded by [`TrainConfig::seed`],
//! and training runs on a private rayon pool of [`TrainConfig::threads`] threads, so a run is
//! bit-reproducible on one machine for a given seed and thread count.

pub mod data;
pub mod direct_histogram;
pub mod flow;
pub mod histogram_mixture;
pub mod lobes;
mod material;
pub mod nn;
pub mod spline;

use std::fmt;
use std::str::FromStr;
use std::time::Instant;

use glam::{Vec2, Vec3};
use neusample::nn::check_condition;
use neusample::FEATURE_DIM;

use crate::materials::Material;

pub use data::{GtCondition, SyntheticSource, TargetSource};
pub use histogram_mixture::BakedTables;
pub use material::MaterialSource;

/// A trainable sampler architecture (`core/ARCHITECTURES.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Improved baseline, Lambert + isotropic Gaussian (paper Eq. 1).
    Baseline,
    /// Analytic mixture, Lambert + two diagonal Gaussians (paper Eq. 2).
    Analytic,
    /// Conditional RQ-spline coupling flow (paper Eq. 3–4).
    Flow,
    /// Affine-coupling flow baseline (Xie et al. 2019).
    AffineFlow,
    /// Direct 16 × 16 histogram baseline (Zhu et al. 2021).
    DirectHistogram,
    /// Histogram mixture with baked basis tables (paper Eq. 5–7).
    HistogramMixture,
}

impl Method {
    /// Every method, in the paper's order.
    pub const ALL: [Method; 6] = [
        Method::Baseline,
        Method::Analytic,
        Method::Flow,
        Method::AffineFlow,
        Method::DirectHistogram,
        Method::HistogramMixture,
    ];

    /// The command-line name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Method::Baseline => "baseline",
            Method::Analytic => "analytic",
            Method::Flow => "flow",
            Method::AffineFlow => "affine-flow",
            Method::DirectHistogram => "direct-histogram",
            Method::HistogramMixture => "histogram-mixture",
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> anyhow::Result<Method> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Method::ALL.iter().map(|m| m.name()).collect();
                anyhow::anyhow!("unknown method `{s}`; expected one of {}", names.join(", "))
            })
    }
}

/// Training hyper-parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainConfig {
    /// Optimisation steps.
    pub steps: usize,
    /// Conditions per batch (maximum-likelihood methods).
    pub batch_conditions: usize,
    /// Ground-truth samples per condition (maximum-likelihood methods).
    pub samples_per_condition: usize,
    /// Peak learning rate (AdamW; linear warm-up, cosine decay to 5 %).
    pub lr: f64,
    /// Seed of every random stream.
    pub seed: u64,
    /// Resolution of the tabulated ground truth (per side).
    pub gt_res: usize,
    /// Conditions in the ground-truth pool.
    pub pool_conditions: usize,
    /// A quarter of the pool is redrawn every this many steps (0: never).
    pub pool_refresh_every: usize,
    /// Latent-code levels T of the baked histogram mixture.
    pub hist_t_levels: usize,
    /// Cells per side N of the baked histogram mixture.
    pub hist_res: usize,
    /// Whether the runtime interpolates the histogram mixture linearly in t.
    pub interpolate_t: bool,
    /// Points per cell side when baking the histogram mixture.
    pub hist_supersample: usize,
    /// Weight λ of the quantisation term of the histogram mixture.
    pub hist_quant_weight: f32,
    /// Output scale S of the basis network, `H = S·softplus(z)`: lets a freshly initialised
    /// network reach the peak densities of glossy lobes quickly (the baked tables are
    /// normalised, so S does not change what the model can represent).
    pub hist_output_scale: f32,
    /// Weight of the self-normalised NLL term (a KL(p* ‖ p) estimate) added to the paper's
    /// L2 loss of the histogram mixture; 0 gives the paper's objective (Eq. 7 + quantisation).
    /// The L2 loss ignores the low-density tails, which the NLL term covers. Default 1.0:
    /// KL(p* ‖ p) of the baked model (24 conditions) goat_leather 0.370 → 0.169,
    /// brushed_metal 1.200 → 0.580, gold 0.121 → 0.035 (L2 only, 3000 steps → with the term,
    /// 2000 steps); see `core/ARCHITECTURES.md` §6.
    pub hist_nll_weight: f32,
    /// Initialise the histogram mixture's condition network with every basis aligned to the
    /// mirror direction (see `histogram_mixture`); only the starting point differs.
    pub hist_aligned_init: bool,
    /// Conditions per batch of the histogram mixture.
    pub hist_batch_conditions: usize,
    /// Regression points per condition of the histogram mixture.
    pub hist_points_per_condition: usize,
    /// AdamW weight decay.
    pub weight_decay: f32,
    /// Gradient-norm clipping threshold.
    pub grad_clip: f32,
    /// Threads of the training pool (results depend on it; fixed for reproducibility).
    pub threads: usize,
    /// Show progress bars.
    pub progress: bool,
}

impl TrainConfig {
    /// A short run for tests and CI (a few seconds per method).
    #[must_use]
    pub fn quick() -> Self {
        TrainConfig {
            steps: 120,
            batch_conditions: 16,
            samples_per_condition: 32,
            lr: 3e-3,
            seed: 1,
            gt_res: 48,
            pool_conditions: 32,
            pool_refresh_every: 0,
            hist_t_levels: 8,
            hist_res: 16,
            interpolate_t: true,
            hist_supersample: 1,
            hist_quant_weight: 100.0,
            hist_output_scale: 5.0,
            hist_nll_weight: 1.0,
            hist_aligned_init: true,
            hist_batch_conditions: 8,
            hist_points_per_condition: 32,
            weight_decay: 0.0,
            grad_clip: 10.0,
            threads: 2,
            progress: false,
        }
    }

    /// The default run of `method`: about a minute on two cores.
    #[must_use]
    pub fn default_for(method: Method) -> Self {
        let (steps, lr) = match method {
            Method::Baseline | Method::Analytic | Method::DirectHistogram => (3000, 5e-3),
            Method::Flow => (2000, 5e-3),
            Method::AffineFlow => (2000, 4e-3),
            Method::HistogramMixture => (2000, 4e-3),
        };
        TrainConfig {
            steps,
            batch_conditions: 64,
            samples_per_condition: 64,
            lr,
            seed: 1,
            gt_res: 128,
            pool_conditions: 512,
            pool_refresh_every: 400,
            hist_t_levels: 32,
            hist_res: 64,
            interpolate_t: true,
            hist_supersample: 2,
            hist_quant_weight: 100.0,
            hist_output_scale: 5.0,
            hist_nll_weight: 1.0,
            hist_aligned_init: true,
            hist_batch_conditions: 16,
            hist_points_per_condition: 64,
            weight_decay: 0.0,
            grad_clip: 10.0,
            threads: 2,
            progress: false,
        }
    }
}

/// A trained sampler.
#[derive(Clone, Debug)]
pub struct Trained {
    /// The architecture.
    pub method: Method,
    /// The flat parameter array in the runtime layout (`core/ARCHITECTURES.md`).
    pub params: Vec<f32>,
    /// The baked tables (histogram mixture only).
    pub tables: Option<BakedTables>,
    /// The loss of every step.
    pub loss_history: Vec<f32>,
    /// Wall-clock training time (including ground truth and baking), seconds.
    pub seconds: f64,
}

/// Trains `method` on `material` (ground truth from `crate::groundtruth`).
pub fn train(
    material: &dyn Material,
    method: Method,
    cfg: &TrainConfig,
) -> anyhow::Result<Trained> {
    train_with(&MaterialSource::new(material), method, cfg)
}

/// Trains `method` on conditions and targets drawn from `source`.
pub fn train_with(
    source: &dyn TargetSource,
    method: Method,
    cfg: &TrainConfig,
) -> anyhow::Result<Trained> {
    anyhow::ensure!(cfg.steps > 0, "steps must be positive");
    anyhow::ensure!(cfg.threads > 0, "threads must be positive");
    let start = Instant::now();
    let threads = rayon::ThreadPoolBuilder::new()
        .num_threads(cfg.threads)
        .build()?;
    threads.install(|| {
        let mut pool = data::Pool::new(
            source,
            cfg.pool_conditions,
            cfg.gt_res,
            cfg.seed,
            cfg.pool_refresh_every,
        )?;
        let (params, tables, loss_history) = match method {
            Method::Baseline => lobes::train(&mut pool, cfg, false).map(|(p, h)| (p, None, h))?,
            Method::Analytic => lobes::train(&mut pool, cfg, true).map(|(p, h)| (p, None, h))?,
            Method::Flow => flow::train_spline(&mut pool, cfg).map(|(p, h)| (p, None, h))?,
            Method::AffineFlow => flow::train_affine(&mut pool, cfg).map(|(p, h)| (p, None, h))?,
            Method::DirectHistogram => {
                direct_histogram::train(&mut pool, cfg).map(|(p, h)| (p, None, h))?
            }
            Method::HistogramMixture => {
                histogram_mixture::train(&mut pool, cfg).map(|(p, t, h)| (p, Some(t), h))?
            }
        };
        Ok(Trained {
            method,
            params,
            tables,
            loss_history,
            seconds: start.elapsed().as_secs_f64(),
        })
    })
}

/// The trained model's density at disk point `p` for condition `(phi, wi)`, with respect to
/// **area on the projected disk**, evaluated in f64 from `trained.params` (plain Rust
/// mirroring the training graph). `wi` is normalised here; 0 for an unusable condition and
/// outside the open unit disk.
///
/// For the histogram mixture this is the *baked* model (condition network + tables), which
/// is what the runtime evaluates; it is 0 when `trained.tables` is `None`.
#[must_use]
pub fn model_pdf_disk(trained: &Trained, phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f32 {
    let Some(wi) = check_condition(phi, wi) else {
        return 0.0;
    };
    let w = &trained.params;
    let v = match trained.method {
        Method::Baseline => lobes::pdf_f64(w, false, phi, wi, p),
        Method::Analytic => lobes::pdf_f64(w, true, phi, wi, p),
        Method::Flow => flow::spline_pdf_f64(w, phi, wi, p),
        Method::AffineFlow => flow::affine_pdf_f64(w, phi, wi, p),
        Method::DirectHistogram => direct_histogram::pdf_f64(w, phi, wi, p),
        Method::HistogramMixture => match &trained.tables {
            Some(t) => histogram_mixture::pdf_f64(w, t, phi, wi, p),
            None => 0.0,
        },
    };
    if v.is_finite() && v > 0.0 {
        v as f32
    } else {
        0.0
    }
}

/// Log densities `ln p(points)` of the *training graph* (burn, f32) of an ML-trained method
/// rebuilt from `params`, for checking the graph against [`model_pdf_disk`] and the runtime.
/// Points must lie inside the unit disk. `None` for the histogram mixture (its training
/// graph is the continuous model, not the baked one) and for an unusable condition.
#[must_use]
pub fn graph_log_pdf(
    method: Method,
    params: &[f32],
    phi: &[f32; FEATURE_DIM],
    wi: Vec3,
    points: &[Vec2],
) -> Option<Vec<f32>> {
    let wi = check_condition(phi, wi)?;
    let host = data::HostBatch {
        b: 1,
        s: points.len(),
        cond: neusample::nn::encode_condition(phi, wi).to_vec(),
        raw: neusample::nn::raw_condition(phi, wi).to_vec(),
        x: points.iter().map(|p| p.x).collect(),
        y: points.iter().map(|p| p.y).collect(),
        target: Vec::new(),
    };
    let device = nn::infer_device();
    let batch = nn::Batch::upload(host, &device);
    let lp = match method {
        Method::Baseline => lobes::graph_log_pdf(params, false, &batch),
        Method::Analytic => lobes::graph_log_pdf(params, true, &batch),
        Method::Flow => flow::SplineFlow::from_flat(params, &device).log_pdf(&batch),
        Method::AffineFlow => flow::AffineFlow::from_flat(params, &device).log_pdf(&batch),
        Method::DirectHistogram => direct_histogram::graph_log_pdf(params, &batch),
        Method::HistogramMixture => return None,
    };
    Some(nn::to_host(lp))
}

/// Mean KL(p* ‖ p) in nats of a trained model over `conditions` fresh conditions of
/// `source` (targets at resolution `res`, seed `seed`).
pub fn mean_kl(
    trained: &Trained,
    source: &dyn TargetSource,
    conditions: usize,
    res: usize,
    seed: u64,
) -> anyhow::Result<f64> {
    use rayon::prelude::*;
    let gts = source.draw(conditions, res, seed)?;
    let kls: Vec<f64> = gts
        .par_iter()
        .map(|g| {
            g.target
                .kl_from(|p| model_pdf_disk(trained, &g.phi, g.wi, p))
        })
        .collect();
    Ok(kls.iter().sum::<f64>() / kls.len().max(1) as f64)
}
