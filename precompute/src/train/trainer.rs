//! What every method's trainer provides ([`Trainer`]) and what training produces
//! ([`Trained`], [`BakedTables`]). The trainers live in their methods' files; the list of
//! them is `method`.

use anyhow::Result;
use burn::tensor::Tensor;
use glam::{Vec2, Vec3};
use neusample::samplers::histogram_mixture as histogram;
use neusample::{DType, Interpolation, SamplerKind, FEATURE_DIM};

use super::config::{Common, MaxLikelihood, Schedule, TrainConfig};
use super::data::{Batch, HostBatch, Pool};
use super::source::TargetSource;
use crate::nn::{infer_device, to_host};

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
    /// Its settings in `TrainConfig::max_likelihood` (`quick`: those of the quick run);
    /// `None` for a method with settings of their own type.
    fn max_likelihood(&self, quick: bool) -> Option<MaxLikelihood> {
        let _ = quick;
        None
    }
    /// Whether its `max_likelihood` settings' χ² fine-tuning options apply (the spline flows).
    fn fine_tunes_chi2(&self) -> bool {
        false
    }
    /// The method's schedule in `cfg`.
    fn schedule_mut<'c>(&self, cfg: &'c mut TrainConfig) -> &'c mut Schedule;
    /// `scale` applied to every step count of the method in `cfg` (by default, its schedule).
    fn scale_steps(&self, cfg: &mut TrainConfig, scale: &dyn Fn(&mut Schedule)) {
        scale(self.schedule_mut(cfg));
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
