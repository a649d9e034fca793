//! What every method's trainer provides ([`Trainer`]) and what training produces
//! ([`Trained`], [`BakedTables`]). The trainers live in their methods' files; the list of
//! them is `method`.

use anyhow::Result;
use burn::module::Module;
use burn::tensor::Tensor;
use glam::{Vec2, Vec3};
use neusample::samplers::histogram_mixture as histogram;
use neusample::{DType, Interpolation, SamplerKind, FEATURE_DIM};

use super::config::{Common, MaxLikelihood, Schedule, TrainConfig};
use super::data::{fit, Batch, HostBatch, PointKind, Pool};
use super::objective;
use super::source::TargetSource;
use crate::nn::{infer_device, to_host};
use crate::util::rng::mix_seed;

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
    /// Steps of the main phase as it ran (the trainer's `main_steps`), for labels and summaries.
    pub steps: usize,
    /// Whether it was trained with `wi` at azimuth 0 ([`TargetSource::isotropic`](super::TargetSource::isotropic)):
    /// its densities at any other `wi` are those at `wi` turned there.
    pub isotropic: bool,
    /// Wall-clock training time (including ground truth and baking), seconds.
    pub seconds: f64,
}

/// The baked tables of a histogram mixture (`core/ARCHITECTURES.md` §6), with what is needed
/// to re-bake them.
#[derive(Clone, Debug)]
pub struct BakedTables {
    /// mass, table, marginal and conditional as core builds them
    /// ([`neusample::samplers::histogram_mixture::try_bake_slices`], f32 storage).
    pub baked: histogram::BakedTables,
    /// How the runtime reads the latent axis.
    pub interpolation: Interpolation,
    /// The raw slices `K × T × N × N` (cell means of the basis network) given to
    /// `bake_slices`; re-bake them for another storage type (f16 rounds before the sums).
    pub raw: Vec<f32>,
    /// The trained basis network (runtime layout), for diagnostics.
    pub basis_params: Vec<f32>,
}

impl BakedTables {
    /// Re-bakes the raw slices for `storage` (f16 values and matching running sums).
    pub fn rebake(&self, storage: DType) -> anyhow::Result<histogram::BakedTables> {
        let b = &self.baked;
        histogram::try_bake_slices(
            &self.raw,
            b.bases as usize,
            b.t_levels as usize,
            b.resolution as usize,
            storage,
        )
        .map_err(|e| anyhow::anyhow!("baking the histogram mixture: {e}"))
    }
}

/// One training run: the pool, the settings and where the pool's conditions come from.
pub(crate) struct Run<'r, 'p> {
    /// The pool of conditions and targets.
    pub pool: &'r mut Pool<'p>,
    /// The settings.
    pub cfg: &'r TrainConfig,
    /// The pool's source (the integrand, for a method that trains on it).
    pub source: &'r dyn TargetSource,
}

/// What training returns: the runtime's flat parameters, the baked tables (the histogram
/// mixture's) and the loss of every step.
pub(crate) type Fitted = (Vec<f32>, Option<BakedTables>, Vec<f32>);

/// How one method trains, and its trained model in f64 and as a training graph.
pub(crate) trait Trainer: Sync {
    /// The kind it trains.
    fn kind(&self) -> SamplerKind;
    /// Its settings in `TrainConfig::max_likelihood` (`quick`: those of the quick run); by
    /// default the presets; `None` for a method with settings of their own type.
    fn max_likelihood(&self, quick: bool) -> Option<MaxLikelihood> {
        Some(if quick {
            MaxLikelihood::quick()
        } else {
            MaxLikelihood::default()
        })
    }
    /// Whether its `max_likelihood` settings' χ² fine-tuning options apply (the spline flows).
    fn fine_tunes_chi2(&self) -> bool {
        false
    }
    /// The method's schedule in `cfg`; by default its `max_likelihood` settings' (a method
    /// with settings of their own type overrides it).
    fn schedule_mut<'c>(&self, cfg: &'c mut TrainConfig) -> &'c mut Schedule {
        &mut cfg.max_likelihood[self.kind()].schedule
    }
    /// Sets the steps of the method's main phase in `cfg` (by default, its schedule's).
    fn set_steps(&self, cfg: &mut TrainConfig, steps: usize) {
        self.schedule_mut(cfg).steps = steps;
    }
    /// `scale` applied to every step count of the method in `cfg` (by default, its schedule).
    fn scale_steps(&self, cfg: &mut TrainConfig, scale: &dyn Fn(&mut Schedule)) {
        scale(self.schedule_mut(cfg));
    }
    /// The steps its main phase runs on `pool` (by default, its schedule's).
    fn main_steps(&self, cfg: &TrainConfig, _pool: &Pool<'_>) -> usize {
        cfg.schedule(self.kind()).map_or(0, |s| s.steps)
    }
    /// Trains on `run`'s pool.
    fn train(&self, run: Run<'_, '_>) -> Result<Fitted>;
    /// The trained model's density at disk point `p` (projected-disk area), in f64 from
    /// `trained`; `wi` already normalised.
    fn pdf_f64(&self, trained: &Trained, phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64;
    /// `ln p` of `batch`'s points under the training graph rebuilt from `params`; `None`
    /// where the training graph is not the exported model (the histogram mixture's).
    fn graph(&self, params: &[f32], batch: &Batch) -> Option<Tensor<2>> {
        let _ = (params, batch);
        None
    }
    /// `ln p(points)` of the training graph rebuilt from `params` at one condition (`wi`
    /// normalised): [`Trainer::graph`] on those points.
    fn graph_log_pdf(
        &self,
        params: &[f32],
        phi: &[f32; FEATURE_DIM],
        wi: Vec3,
        points: &[Vec2],
    ) -> Option<Vec<f32>> {
        let batch = Batch::upload(HostBatch::single(phi, wi, points), &infer_device());
        self.graph(params, &batch).map(to_host)
    }
    /// The ground-truth resolution of the training pool.
    fn pool_res(&self, common: &Common) -> usize {
        common.gt_res
    }
    /// Whether the method trains on the integrand itself rather than on samples of p*.
    fn needs_integrand(&self) -> bool {
        false
    }
    /// The blob check's tolerance within 1e-2 of a pole of the disk (`|y| > 0.99`), where
    /// the method's f32 runtime loses precision that its f64 mirror keeps; `None`: those
    /// points count with all others.
    fn pole_tolerance(&self) -> Option<f64> {
        None
    }
}

/// A trained model's flat parameters, in the order its sampler reads them.
pub(crate) trait ExportParams {
    /// The parameters, flattened.
    fn export_params(&self) -> Vec<f32>;
}

/// Maximum likelihood of samples of p* over `cfg.schedule`, then, when `cfg.chi2_weight > 0`,
/// the fine-tuning phase of [`objective::nll_and_chi2`] (`cfg.chi2_fraction` of the steps,
/// a fifth of the learning rate, regression batches of `samples_per_condition` samples of
/// p* and as many uniform points, its own batch seeds). Returns the fitted model's
/// [`ExportParams::export_params`] and the loss history of both phases.
pub(crate) fn train_max_likelihood<M: Module + ExportParams>(
    model: M,
    name: &str,
    pool: &mut Pool<'_>,
    common: &Common,
    cfg: &MaxLikelihood,
    log_pdf: impl Fn(&M, &Batch) -> Tensor<2>,
) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
    let (model, mut history) = fit(
        model,
        name,
        common,
        &cfg.schedule,
        pool,
        PointKind::FromTarget,
        (cfg.batch_conditions, cfg.samples_per_condition),
        |m: &M, batch: &Batch| log_pdf(m, batch).mean().neg(),
    )?;
    let steps = (cfg.schedule.steps as f64 * cfg.chi2_fraction).round() as usize;
    if !(cfg.chi2_weight > 0.0) || steps == 0 {
        return Ok((model.export_params(), history));
    }
    let tune = Schedule {
        steps,
        lr: cfg.schedule.lr * 0.2,
    };
    let tune_common = Common {
        seed: mix_seed(common.seed, 0xc412),
        ..common.clone()
    };
    let (model, more) = fit(
        model,
        &format!("{name} (χ²)"),
        &tune_common,
        &tune,
        pool,
        PointKind::Regression,
        (cfg.batch_conditions, 2 * cfg.samples_per_condition),
        |m: &M, batch: &Batch| objective::nll_and_chi2(log_pdf(m, batch), batch, cfg.chi2_weight),
    )?;
    history.extend(more);
    Ok((model.export_params(), history))
}
