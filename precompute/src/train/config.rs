//! Training hyper-parameters: the settings every method shares, plus each method's block (a
//! [`MaxLikelihood`] per kind for the methods trained by maximum likelihood alone).
//! Each block has one `quick()` (a few seconds per method, for tests and CI) and one
//! `default()` (the default run: about a minute per method on two cores); the quick settings
//! are written as changes to the default ones.

use std::ops::{Index, IndexMut};

use neusample::SamplerKind;

use crate::groundtruth::TargetOptions;
use crate::nn::OptimSettings;

/// Settings every method shares.
#[derive(Clone, Debug, PartialEq)]
pub struct Common {
    /// Seed of every random stream.
    pub seed: u64,
    /// Threads of the training pool (results depend on it; fixed for reproducibility).
    pub threads: usize,
    /// Show progress bars.
    pub progress: bool,
    /// Resolution of the tabulated ground truth (per side).
    pub gt_res: usize,
    /// Conditions in the ground-truth pool.
    pub pool_conditions: usize,
    /// A quarter of the pool is redrawn every this many steps (0: never).
    pub pool_refresh_every: usize,
    /// Tabulate the training targets up to the horizon
    /// ([`TargetOptions::horizon`]) instead of the fit metrics' table
    /// (cells wholly inside the disk, the release's 0.98 cut-off).
    pub horizon_targets: bool,
    /// AdamW weight decay.
    pub weight_decay: f32,
    /// Gradient-norm clipping threshold.
    pub grad_clip: f32,
}

impl Default for Common {
    fn default() -> Self {
        Common {
            seed: 1,
            threads: 2,
            progress: false,
            gt_res: 128,
            pool_conditions: 512,
            pool_refresh_every: 400,
            horizon_targets: true,
            weight_decay: 0.0,
            grad_clip: 10.0,
        }
    }
}

impl Common {
    /// A small ground-truth pool that is never refreshed.
    #[must_use]
    pub fn quick() -> Self {
        Common {
            gt_res: 48,
            pool_conditions: 32,
            pool_refresh_every: 0,
            ..Common::default()
        }
    }

    /// The options of the training targets' tables ([`Common::horizon_targets`]).
    #[must_use]
    pub fn target_options(&self) -> TargetOptions {
        if self.horizon_targets {
            TargetOptions::horizon()
        } else {
            TargetOptions::default()
        }
    }

    /// The optimiser's settings of the phase `name` run on `schedule` (the progress bar shows
    /// the loss every 10 steps).
    #[must_use]
    pub(crate) fn optim_settings(&self, name: &str, schedule: &Schedule) -> OptimSettings {
        OptimSettings {
            name: name.to_string(),
            steps: schedule.steps,
            lr: schedule.lr,
            weight_decay: self.weight_decay,
            grad_clip: self.grad_clip,
            progress: self.progress,
            report_every: 10,
        }
    }
}

/// Length and peak learning rate of one method's run (AdamW; linear warm-up, cosine decay to
/// 5 %).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Schedule {
    /// Optimisation steps.
    pub steps: usize,
    /// Peak learning rate.
    pub lr: f64,
}

impl Schedule {
    /// The schedule of every quick run.
    #[must_use]
    pub fn quick() -> Self {
        Schedule {
            steps: 120,
            lr: 3e-3,
        }
    }
}

/// A method trained by maximum likelihood of ground-truth samples (improved baseline,
/// analytic mixture, the two flows, direct histogram): batches of `batch_conditions` pool
/// conditions × `samples_per_condition` samples of p*.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaxLikelihood {
    /// Steps and learning rate.
    pub schedule: Schedule,
    /// Conditions per batch.
    pub batch_conditions: usize,
    /// Ground-truth samples per condition.
    pub samples_per_condition: usize,
    /// Weight λ of the χ² term of the fine-tuning phase (`super::objective::nll_and_chi2`);
    /// 0: no fine-tuning.
    pub chi2_weight: f32,
    /// Length of the fine-tuning phase after maximum likelihood, as a fraction of
    /// `schedule.steps` (its batches hold `samples_per_condition` samples of p* and as many
    /// uniform points; its peak learning rate is a fifth of `schedule.lr`).
    pub chi2_fraction: f64,
}

impl Default for MaxLikelihood {
    /// The default run of the lobe mixtures and the direct histogram; the flows' trainers
    /// change the schedule.
    fn default() -> Self {
        MaxLikelihood {
            schedule: Schedule {
                steps: 3000,
                lr: 5e-3,
            },
            batch_conditions: 64,
            samples_per_condition: 64,
            chi2_weight: 0.0,
            chi2_fraction: 0.0,
        }
    }
}

impl MaxLikelihood {
    /// Small batches, the quick schedule.
    #[must_use]
    pub fn quick() -> Self {
        MaxLikelihood {
            schedule: Schedule::quick(),
            batch_conditions: 16,
            samples_per_condition: 32,
            ..MaxLikelihood::default()
        }
    }

    /// The default batches with another schedule.
    #[must_use]
    pub fn with_schedule(steps: usize, lr: f64) -> Self {
        MaxLikelihood {
            schedule: Schedule { steps, lr },
            ..MaxLikelihood::default()
        }
    }
}

/// The histogram mixture: its regression batches, the baked tables and the loss terms
/// (`super::histogram_mixture`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HistogramMixture {
    /// Steps and learning rate.
    pub schedule: Schedule,
    /// Conditions per batch.
    pub batch_conditions: usize,
    /// Regression points per condition (half uniform on the disk, half from p*; even).
    pub points_per_condition: usize,
    /// Latent-code levels T of the baked tables (default 8: more levels bought little in the
    /// the table study in `docs/results.md`, at T/8 times the bytes).
    pub t_levels: usize,
    /// Cells per side N of the baked tables (default 64).
    pub res: usize,
    /// Whether the runtime interpolates linearly in t (else the nearest level, the default:
    /// at T = 8 it fits as well and reads half the tables).
    pub interpolate_t: bool,
    /// Points per cell side when baking.
    pub supersample: usize,
    /// Weight λ of the quantisation term.
    pub quant_weight: f32,
    /// Output scale S of the basis network, `H = S·softplus(z)`: lets a freshly initialised
    /// network reach the peak densities of glossy lobes quickly (the baked tables are
    /// normalised, so S does not change what the model can represent).
    pub output_scale: f32,
    /// Weight of the self-normalised NLL term (a KL(p* ‖ p) estimate) added to the paper's
    /// L2 loss; 0 gives the paper's objective (Eq. 7 + quantisation). The L2 loss ignores the
    /// low-density tails, which the NLL term covers (`core/ARCHITECTURES.md` §6 and `docs/performance.md`
    /// give the measured effect).
    pub nll_weight: f32,
    /// Initialise the condition network with every basis aligned to the mirror direction;
    /// only the starting point differs.
    pub aligned_init: bool,
    /// Weight of the χ² term (`super::objective::log_second_moment` of the self-normalised
    /// model) added to the loss; 0: none.
    pub chi2_weight: f32,
}

impl Default for HistogramMixture {
    fn default() -> Self {
        HistogramMixture {
            schedule: Schedule {
                steps: 2000,
                lr: 4e-3,
            },
            batch_conditions: 16,
            points_per_condition: 64,
            t_levels: 8,
            res: 64,
            interpolate_t: false,
            supersample: 2,
            quant_weight: 100.0,
            output_scale: 5.0,
            nll_weight: 1.0,
            aligned_init: true,
            chi2_weight: 0.0,
        }
    }
}

impl HistogramMixture {
    /// Small batches and tables, no supersampling, the quick schedule.
    #[must_use]
    pub fn quick() -> Self {
        HistogramMixture {
            schedule: Schedule::quick(),
            batch_conditions: 8,
            points_per_condition: 32,
            t_levels: 8,
            res: 16,
            interpolate_t: true,
            supersample: 1,
            ..HistogramMixture::default()
        }
    }
}

/// How the reparameterization sampler's pdf network is fitted to the warp's density `q`
/// on the warp's own samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DensityLoss {
    /// `mean |ln p̂ − ln q|` (a relative error, as the release's L1 of `p̂·det J` against
    /// `N(z)`); nothing pulls `p̂` down where the warp never lands.
    LogL1,
    /// The generalised KL `∫ q ln(q/p̂) − q + p̂` (minimised by `p̂ = q`): `−E_q[ln p̂] + ∫p̂`,
    /// with `∫p̂` estimated half from the warp's samples and half from uniform points, so
    /// `p̂` is also pushed towards 0 where the warp does not reach (where a non-zero `p̂`
    /// would bias MIS).
    GeneralizedKl,
    /// [`DensityLoss::LogL1`] plus `π·E_u[p̂]` over uniform points of the disk (a pull
    /// towards 0 wherever the warp's samples do not hold `p̂` up).
    LogL1Mass,
}

/// The reparameterization sampler: the warp's run, then the pdf network's
/// (`super::reparam`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reparam {
    /// The warp's steps and learning rate.
    pub schedule: Schedule,
    /// The pdf network's steps and learning rate (after the warp).
    pub density_schedule: Schedule,
    /// Steps and learning rate of the warp's warm start (before its own loss): regression of
    /// `T(z)` onto the tabulated target's inverse-CDF map, so that the mode-seeking loss
    /// starts from a warp that already covers every lobe.
    pub prefit: Schedule,
    /// When the warm start runs.
    pub warm_start: WarmStart,
    /// Conditions tabulated (at [`Common::gt_res`]) for the warm start.
    pub prefit_conditions: usize,
    /// The warp's steps and peak learning rate after a warm start (in place of `schedule`):
    /// its loss then refines a warp rather than searching for one, at a lower rate and for
    /// longer.
    pub refine: Schedule,
    /// Conditions per batch.
    pub batch_conditions: usize,
    /// Latent points per condition (stratified; a square is best).
    pub samples_per_condition: usize,
    /// Weight of the fixed warp `z/√(1 + |z|²)` in the warp's loss (the release: 10⁻³).
    pub defensive: f32,
    /// The pdf network's loss.
    pub density_loss: DensityLoss,
    /// Weight λ of a χ² term added to the warp's loss (0: the release's objective; 0.1 by
    /// default): per condition `ln(E_z[w²]/E_z[w]²)` with `w = f⊥(T(z))·det J/N(z)`, the
    /// log of `1 + χ²(p* ‖ q)` estimated on the batch's samples: the render's variance, which
    /// the KL term (mode seeking) lets grow where the warp under-covers the integrand.
    pub chi2_weight: f32,
    /// Weight λ of the generalised χ² `∫ q²/p̂ − 2q + p̂` (also minimised by `p̂ = q`) added
    /// to [`DensityLoss::GeneralizedKl`] (0: the KL alone): MIS weights a light sample's
    /// contribution by `p_light²/(p̂² + p_light²)`, so where `p̂ ≪ q` it carries `f/p_light`
    /// unweighted; `E_q[q/p̂]` is that term's variance, which the KL penalises only by
    /// `ln(q/p̂)`.
    pub density_chi2_weight: f32,
}

/// When the reparameterization sampler's warp gets its warm start ([`Reparam::prefit`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WarmStart {
    /// Never: the release's random start.
    Never,
    /// When every condition of the training pool has the same features φ: a material without
    /// a latent, such as a measured file, whose conditions differ only in `wi`, so that the
    /// warm start's tabulated conditions cover them. (On spatially varying materials the warm
    /// start and its lower learning rate gave mixed fits.)
    WithoutLatent,
    /// Always.
    Always,
}

impl Default for Reparam {
    fn default() -> Self {
        Reparam {
            schedule: Schedule {
                steps: 5000,
                lr: 1e-2,
            },
            density_schedule: Schedule {
                steps: 4500,
                lr: 3e-3,
            },
            prefit: Schedule {
                steps: 3000,
                lr: 3e-2,
            },
            warm_start: WarmStart::WithoutLatent,
            prefit_conditions: 128,
            refine: Schedule {
                steps: 20000,
                lr: 3e-3,
            },
            batch_conditions: 32,
            samples_per_condition: 64,
            defensive: 1e-3,
            density_loss: DensityLoss::GeneralizedKl,
            chi2_weight: 0.1,
            density_chi2_weight: 1.0,
        }
    }
}

impl Reparam {
    /// Small batches, the quick schedule for both networks.
    #[must_use]
    pub fn quick() -> Self {
        Reparam {
            schedule: Schedule::quick(),
            density_schedule: Schedule::quick(),
            prefit: Schedule {
                lr: 3e-2,
                ..Schedule::quick()
            },
            refine: Schedule {
                lr: 3e-3,
                ..Schedule::quick()
            },
            prefit_conditions: 16,
            batch_conditions: 8,
            samples_per_condition: 64,
            ..Reparam::default()
        }
    }
}

/// Training hyper-parameters of every method. Its `Default` (the default run: about a
/// minute per method on two cores) and `quick()` (a few seconds per method) take each
/// method's settings from its trainer (`method.rs`).
#[derive(Clone, Debug, PartialEq)]
pub struct TrainConfig {
    /// Settings every method shares.
    pub common: Common,
    /// The settings of the methods trained by maximum likelihood alone (the lobe mixtures,
    /// the flows, the direct histogram), by kind.
    pub max_likelihood: ByKind<MaxLikelihood>,
    /// Histogram mixture.
    pub histogram_mixture: HistogramMixture,
    /// Reparameterization sampler.
    pub reparam: Reparam,
}

/// Settings by sampler kind: one value for each kind whose trainer has them. Indexing by a
/// kind without a value panics; [`ByKind::get`] does not.
#[derive(Clone, Debug, PartialEq)]
pub struct ByKind<T>(Vec<(SamplerKind, T)>);

impl<T> ByKind<T> {
    /// The value of each kind `f` gives one for, in the order of `kinds`.
    pub(crate) fn from_fn(
        kinds: &[SamplerKind],
        mut f: impl FnMut(SamplerKind) -> Option<T>,
    ) -> Self {
        ByKind(kinds.iter().filter_map(|&k| Some((k, f(k)?))).collect())
    }

    /// The value of `kind`, if it has one.
    #[must_use]
    pub fn get(&self, kind: SamplerKind) -> Option<&T> {
        self.0.iter().find(|(k, _)| *k == kind).map(|(_, v)| v)
    }

    /// The value of `kind`, to change it, if it has one.
    pub fn get_mut(&mut self, kind: SamplerKind) -> Option<&mut T> {
        self.0.iter_mut().find(|(k, _)| *k == kind).map(|(_, v)| v)
    }

    /// Every kind with its value.
    pub fn iter_mut(&mut self) -> impl Iterator<Item = (SamplerKind, &mut T)> {
        self.0.iter_mut().map(|(k, v)| (*k, v))
    }
}

impl<T> Index<SamplerKind> for ByKind<T> {
    type Output = T;
    fn index(&self, kind: SamplerKind) -> &T {
        self.get(kind)
            .unwrap_or_else(|| panic!("no {} settings", kind.name()))
    }
}

impl<T> IndexMut<SamplerKind> for ByKind<T> {
    fn index_mut(&mut self, kind: SamplerKind) -> &mut T {
        self.get_mut(kind)
            .unwrap_or_else(|| panic!("no {} settings", kind.name()))
    }
}
