//! The training entry points, dispatched by [`SamplerKind`], and the trained model seen three
//! ways: its f64 mirror ([`model_pdf_disk`]), its training graph ([`graph_log_pdf`]) and its
//! fit ([`mean_kl`], [`network_mean_kl`]).

use std::time::Instant;

use glam::{Vec2, Vec3};
use neusample::nn::check_condition;
use neusample::SamplerKind;
use neusample::FEATURE_DIM;
use rayon::prelude::*;

use super::config::TrainConfig;
use super::data::{Batch, HostBatch, Pool};
use super::histogram_mixture::{self, BakedTables};
use super::source::{GtCondition, MaterialSource, TargetSource};
use super::{direct_histogram, flow, lobes, reparam};
use crate::groundtruth::TargetOptions;
use crate::materials::Material;
use crate::nn::{infer_device, to_host};

/// Ground-truth resolution of the reparameterization sampler's pool: it trains on the
/// integrand and uses only the pool's conditions.
const REPARAM_POOL_RES: usize = 8;

/// A trained sampler.
#[derive(Clone, Debug)]
pub struct Trained {
    /// The architecture.
    pub method: SamplerKind,
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
    method: SamplerKind,
    cfg: &TrainConfig,
) -> anyhow::Result<Trained> {
    train_with(&MaterialSource::new(material), method, cfg)
}

/// Trains `method` on conditions and targets drawn from `source`.
pub fn train_with(
    source: &dyn TargetSource,
    method: SamplerKind,
    cfg: &TrainConfig,
) -> anyhow::Result<Trained> {
    let schedule = cfg
        .schedule(method)
        .ok_or_else(|| anyhow::anyhow!("`{}` is not a trainable method", method.name()))?;
    anyhow::ensure!(schedule.steps > 0, "steps must be positive");
    anyhow::ensure!(cfg.common.threads > 0, "threads must be positive");
    let start = Instant::now();
    let threads = rayon::ThreadPoolBuilder::new()
        .num_threads(cfg.common.threads)
        .build()?;
    threads.install(|| {
        let c = &cfg.common;
        // The reparameterization sampler uses the pool's conditions, not its targets.
        let res = if method == SamplerKind::Reparam {
            REPARAM_POOL_RES
        } else {
            c.gt_res
        };
        let mut pool = Pool::new(
            source,
            c.pool_conditions,
            res,
            c.seed,
            c.pool_refresh_every,
            if c.horizon_targets {
                TargetOptions::horizon()
            } else {
                TargetOptions::default()
            },
        )?;
        let plain = |(p, h)| (p, None, h);
        let (params, tables, loss_history) = match method {
            SamplerKind::ImprovedBaseline => {
                lobes::train(&mut pool, c, &cfg.baseline, false).map(plain)?
            }
            SamplerKind::AnalyticMixture => {
                lobes::train(&mut pool, c, &cfg.analytic, true).map(plain)?
            }
            SamplerKind::Flow => flow::train_spline(&mut pool, c, &cfg.flow).map(plain)?,
            SamplerKind::DiskFlow => flow::train_disk(&mut pool, c, &cfg.disk_flow).map(plain)?,
            SamplerKind::AffineFlow => {
                flow::train_affine(&mut pool, c, &cfg.affine_flow).map(plain)?
            }
            SamplerKind::DirectHistogram => {
                direct_histogram::train(&mut pool, c, &cfg.direct_histogram).map(plain)?
            }
            SamplerKind::HistogramMixture => {
                histogram_mixture::train(&mut pool, c, &cfg.histogram_mixture)
                    .map(|(p, t, h)| (p, Some(t), h))?
            }
            SamplerKind::Reparam => {
                let integrand = source.integrand().ok_or_else(|| {
                    anyhow::anyhow!(
                        "the reparameterization sampler trains on the integrand itself: it \
                         needs a neural or measured material (or the synthetic target)"
                    )
                })?;
                reparam::train(&mut pool, c, &cfg.reparam, integrand).map(plain)?
            }
            SamplerKind::Cosine | SamplerKind::NeuralMaterial | SamplerKind::Measured => {
                unreachable!("schedule() is None for the kinds that are not trained")
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
        SamplerKind::ImprovedBaseline => lobes::pdf_f64(w, false, phi, wi, p),
        SamplerKind::AnalyticMixture => lobes::pdf_f64(w, true, phi, wi, p),
        SamplerKind::Flow => flow::spline_pdf_f64(w, phi, wi, p),
        SamplerKind::DiskFlow => flow::disk_pdf_f64(w, phi, wi, p),
        SamplerKind::AffineFlow => flow::affine_pdf_f64(w, phi, wi, p),
        SamplerKind::DirectHistogram => direct_histogram::pdf_f64(w, phi, wi, p),
        SamplerKind::HistogramMixture => match &trained.tables {
            Some(t) => histogram_mixture::pdf_f64(w, t, phi, wi, p),
            None => 0.0,
        },
        SamplerKind::Reparam => reparam::pdf_f64(w, phi, wi, p),
        SamplerKind::Cosine | SamplerKind::NeuralMaterial | SamplerKind::Measured => 0.0,
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
    method: SamplerKind,
    params: &[f32],
    phi: &[f32; FEATURE_DIM],
    wi: Vec3,
    points: &[Vec2],
) -> Option<Vec<f32>> {
    let wi = check_condition(phi, wi)?;
    if method == SamplerKind::Reparam {
        return Some(reparam::graph_log_pdf(params, phi, wi, points));
    }
    let device = infer_device();
    let batch = Batch::upload(HostBatch::single(phi, wi, points), &device);
    let lp = match method {
        SamplerKind::ImprovedBaseline => lobes::graph_log_pdf(params, false, &batch),
        SamplerKind::AnalyticMixture => lobes::graph_log_pdf(params, true, &batch),
        SamplerKind::Flow => flow::SplineFlow::from_flat(params, &device).log_pdf(&batch),
        SamplerKind::DiskFlow => flow::DiskFlow::from_flat(params, &device).log_pdf(&batch),
        SamplerKind::AffineFlow => flow::AffineFlow::from_flat(params, &device).log_pdf(&batch),
        SamplerKind::DirectHistogram => direct_histogram::graph_log_pdf(params, &batch),
        SamplerKind::HistogramMixture
        | SamplerKind::Cosine
        | SamplerKind::NeuralMaterial
        | SamplerKind::Measured
        | SamplerKind::Reparam => return None,
    };
    Some(to_host(lp))
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
    mean_over_conditions(source, conditions, res, seed, |g| {
        g.target
            .kl_from(|p| model_pdf_disk(trained, &g.phi, g.wi, p))
    })
}

/// The mean of `f` over `conditions` fresh conditions of `source` (targets at `res`), in
/// parallel and summed in condition order.
fn mean_over_conditions(
    source: &dyn TargetSource,
    conditions: usize,
    res: usize,
    seed: u64,
    f: impl Fn(&GtCondition) -> f64 + Sync,
) -> anyhow::Result<f64> {
    let gts = source.draw(conditions, res, seed)?;
    let values: Vec<f64> = gts.par_iter().map(&f).collect();
    Ok(values.iter().sum::<f64>() / values.len().max(1) as f64)
}

/// Mean KL(p* ‖ p_net) in nats of the *un-baked* training model of `trained` (condition
/// network + basis network, normalised numerically over the disk on the target grid) over
/// `conditions` fresh conditions of `source` at resolution `res`: the part of the baked
/// model's KL that is not due to baking (tables, T, N). Diagnostics; slow-ish (one basis
/// network evaluation per grid point and basis).
pub fn network_mean_kl(
    trained: &Trained,
    source: &dyn TargetSource,
    conditions: usize,
    res: usize,
    seed: u64,
) -> anyhow::Result<f64> {
    let tables = trained
        .tables
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("not a histogram mixture"))?;
    let h = 2.0 / res as f32;
    let points: Vec<Vec2> = (0..res * res)
        .map(|i| {
            Vec2::new(
                -1.0 + h * ((i % res) as f32 + 0.5),
                -1.0 + h * ((i / res) as f32 + 0.5),
            )
        })
        .collect();
    mean_over_conditions(source, conditions, res, seed, |g| {
        let mut d = histogram_mixture::network_density(
            &trained.params,
            &tables.basis_params,
            &g.phi,
            g.wi,
            &points,
        );
        let mut z = 0.0f64;
        for (v, p) in d.iter_mut().zip(&points) {
            if p.length_squared() >= 1.0 {
                *v = 0.0;
            }
            z += f64::from(*v) * f64::from(h * h);
        }
        let z = z.max(1e-30);
        g.target.kl_from(|p| {
            let c = (((p.x + 1.0) / h).floor().max(0.0) as usize).min(res - 1);
            let r = (((p.y + 1.0) / h).floor().max(0.0) as usize).min(res - 1);
            (f64::from(d[r * res + c]) / z) as f32
        })
    })
}
