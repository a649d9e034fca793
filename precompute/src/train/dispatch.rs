//! The training entry points, dispatched by [`SamplerKind`] to each method's trainer, and the trained model seen three
//! ways: its f64 mirror ([`model_pdf_disk`]), its training graph ([`graph_log_pdf`]) and its
//! fit ([`mean_kl`], [`network_mean_kl`]).

use std::time::Instant;

use glam::{Vec2, Vec3};
use neusample::nn::check_condition;
use neusample::samplers::Turn;
use neusample::SamplerKind;
use neusample::FEATURE_DIM;
use rayon::prelude::*;

use super::config::TrainConfig;
use super::data::Pool;
use super::histogram_mixture;
use super::method::trainer;
use super::source::{GtCondition, MaterialSource, TargetSource};
use super::trainer::Run;
pub use super::trainer::Trained;
use crate::materials::Material;

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
    let trainer = trainer(method)
        .ok_or_else(|| anyhow::anyhow!("`{}` is not a trainable method", method.name()))?;
    threads.install(|| {
        let c = &cfg.common;
        let mut pool = Pool::new(
            source,
            c.pool_conditions,
            trainer.pool_res(c),
            c.seed,
            c.pool_refresh_every,
            c.target_options(),
        )?;
        let steps = trainer.main_steps(cfg, &pool);
        let (params, tables, loss_history) = trainer.train(Run {
            pool: &mut pool,
            cfg,
            source,
        })?;
        Ok(Trained {
            method,
            params,
            tables,
            loss_history,
            steps,
            isotropic: source.isotropic(),
            seconds: start.elapsed().as_secs_f64(),
        })
    })
}

/// The trained model's density at disk point `p` for condition `(phi, wi)`, with respect to
/// **area on the projected disk**, evaluated in f64 from `trained.params` (plain Rust
/// mirroring the training graph). `wi` is normalised here; 0 for an unusable condition and
/// outside the open unit disk. A model trained with `wi` at azimuth 0 is evaluated as the
/// runtime does: `wi` and `p` turned there.
///
/// For the histogram mixture this is the *baked* model (condition network + tables), which
/// is what the runtime evaluates; it is 0 when `trained.tables` is `None`.
#[must_use]
pub fn model_pdf_disk(trained: &Trained, phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f32 {
    let (wi, p) = if trained.isotropic {
        let (turn, wi) = Turn::aligning(wi);
        (wi, turn.to_local_2d(p))
    } else {
        (wi, p)
    };
    let Some(wi) = check_condition(phi, wi) else {
        return 0.0;
    };
    let v = trainer(trained.method).map_or(0.0, |t| t.pdf_f64(trained, phi, wi, p));
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
    trainer(method)?.graph_log_pdf(params, phi, wi, points)
}

/// Mean KL(p* ‖ p) in nats of a trained model over the conditions `gts` (fresh ones, from
/// [`TargetSource::draw`]).
#[must_use]
pub fn mean_kl(trained: &Trained, gts: &[GtCondition]) -> f64 {
    mean_over_conditions(gts, |g| {
        g.target
            .kl_from(|p| model_pdf_disk(trained, &g.phi, g.wi, p))
    })
}

/// The mean of `f` over the conditions `gts`, in parallel and summed in condition order.
fn mean_over_conditions(gts: &[GtCondition], f: impl Fn(&GtCondition) -> f64 + Sync) -> f64 {
    let values: Vec<f64> = gts.par_iter().map(&f).collect();
    values.iter().sum::<f64>() / values.len().max(1) as f64
}

/// Mean KL(p* ‖ p_net) in nats of the *un-baked* training model of `trained` (condition
/// network + basis network, normalised numerically over the disk on the target grid) over
/// the conditions `gts` (their targets share one resolution): the part of the baked model's
/// KL that is not due to baking (tables, T, N). Diagnostics; slow-ish (one basis network
/// evaluation per grid point and basis).
pub fn network_mean_kl(trained: &Trained, gts: &[GtCondition]) -> anyhow::Result<f64> {
    let tables = trained
        .tables
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("not a histogram mixture"))?;
    let Some(res) = gts.first().map(|g| g.target.res()) else {
        return Ok(0.0);
    };
    let h = 2.0 / res as f32;
    let points: Vec<Vec2> = (0..res * res)
        .map(|i| {
            Vec2::new(
                -1.0 + h * ((i % res) as f32 + 0.5),
                -1.0 + h * ((i / res) as f32 + 0.5),
            )
        })
        .collect();
    Ok(mean_over_conditions(gts, |g| {
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
    }))
}
