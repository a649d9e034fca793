//! Lobe mixtures (paper Eq. 1–2; `core/ARCHITECTURES.md` §1–2), trained by maximum
//! likelihood of ground-truth samples.
//!
//! * Improved baseline: MLP `30 → 32 → 32 → 32 → 5`, `p = w_L/π + w_G N(μ, σ²I)`.
//! * Analytic mixture: MLP `30 → 32 → 11`,
//!   `p = w0/π + w1 N(μ1, diag σ1²) + w2 N(μ2, diag σ2²)`.
//!
//! Weights are softmaxes of raw logits; every `log σ` is clamped to `[−7, 1]` before `exp`
//! (with a straight-through gradient, [`nn::clamp_log_sigma`]).
//! Training points are ground-truth samples, strictly inside the disk, so the Lambert term
//! is the constant `1/π` there.

use burn::module::Module;
use burn::tensor::activation;
use burn::tensor::Tensor;
use glam::{Vec2, Vec3};
use neusample::distrib::gaussian::{LOG_SIGMA_MAX, LOG_SIGMA_MIN};
use neusample::nn::CONDITION_DIM;
use neusample::{SamplerKind, FEATURE_DIM};

use super::config::{Common, MaxLikelihood};
use super::data::{encoded_condition_f64, Batch, Pool};
use super::trainer::{train_max_likelihood, ExportParams, Fitted, Run, Trained, Trainer};
use crate::nn::{self, log_sum_exp_last, mlp_f64, softmax_f64, train_device, Activation, Mlp};
use crate::util::rng::{mix_seed, rng_for};
use anyhow::Result;

const LN_PI: f32 = 1.144_729_9;
const LN_TWO_PI: f32 = 1.837_877_1;

/// Layer sizes of the improved baseline.
pub const BASELINE_SIZES: [usize; 5] = [CONDITION_DIM, 32, 32, 32, 5];
/// Layer sizes of the analytic mixture.
pub const ANALYTIC_SIZES: [usize; 3] = [CONDITION_DIM, 32, 11];

/// The lobe network (either architecture).
#[derive(Module, Debug)]
pub struct LobeModel {
    /// The condition network.
    pub net: Mlp,
}

impl ExportParams for LobeModel {
    fn export_params(&self) -> Vec<f32> {
        let mut params = Vec::new();
        self.net.export(&mut params);
        params
    }
}

/// ln N(p; μ, diag(e^{2 ls_x}, e^{2 ls_y})) with broadcasting (`[b, s]` points against
/// `[b, 1]` parameters).
fn log_normal(
    x: Tensor<2>,
    y: Tensor<2>,
    mx: Tensor<2>,
    my: Tensor<2>,
    lsx: Tensor<2>,
    lsy: Tensor<2>,
) -> Tensor<2> {
    let dx = (x - mx) * lsx.clone().neg().exp();
    let dy = (y - my) * lsy.clone().neg().exp();
    (dx.powi_scalar(2) + dy.powi_scalar(2)) * (-0.5) - LN_TWO_PI - lsx - lsy
}

fn col(o: &Tensor<2>, j: usize) -> Tensor<2> {
    o.clone().narrow(1, j, 1)
}

fn clamp_ls(t: Tensor<2>) -> Tensor<2> {
    nn::clamp_log_sigma(t)
}

/// Per-point log density `[b, s]` of the improved baseline.
fn baseline_log_pdf(o: Tensor<2>, batch: &Batch) -> Tensor<2> {
    let logw = activation::log_softmax(o.clone().narrow(1, 3, 2), 1);
    let ls = clamp_ls(col(&o, 2));
    let lg = log_normal(
        batch.x.clone(),
        batch.y.clone(),
        col(&o, 0),
        col(&o, 1),
        ls.clone(),
        ls,
    ) + col(&logw, 1);
    let ll = (col(&logw, 0) - LN_PI).expand([batch.b, batch.s]);
    let stacked: Tensor<3> = Tensor::stack(vec![ll, lg], 2);
    log_sum_exp_last(stacked).squeeze_dim(2)
}

/// Per-point log density `[b, s]` of the analytic mixture.
fn analytic_log_pdf(o: Tensor<2>, batch: &Batch) -> Tensor<2> {
    let logw = activation::log_softmax(o.clone().narrow(1, 8, 3), 1);
    let ll = (col(&logw, 0) - LN_PI).expand([batch.b, batch.s]);
    // Gaussian `k`: mean `(o[2k], o[2k + 1])`, log-scales `o[4 + 2k]`, `o[5 + 2k]`, log
    // weight `logw[1 + k]`.
    let gaussian = |k: usize| {
        log_normal(
            batch.x.clone(),
            batch.y.clone(),
            col(&o, 2 * k),
            col(&o, 2 * k + 1),
            clamp_ls(col(&o, 4 + 2 * k)),
            clamp_ls(col(&o, 5 + 2 * k)),
        ) + col(&logw, 1 + k)
    };
    let stacked: Tensor<3> = Tensor::stack(vec![ll, gaussian(0), gaussian(1)], 2);
    log_sum_exp_last(stacked).squeeze_dim(2)
}

/// The trainer of the improved baseline (`analytic == false`) or the analytic mixture.
pub(crate) struct Lobes {
    analytic: bool,
}

/// The improved baseline's trainer.
pub(crate) const BASELINE: Lobes = Lobes { analytic: false };
/// The analytic mixture's trainer.
pub(crate) const ANALYTIC: Lobes = Lobes { analytic: true };
/// The module's trainers.
pub(crate) const TRAINERS: &[&dyn Trainer] = &[&BASELINE, &ANALYTIC];

impl Trainer for Lobes {
    fn kind(&self) -> SamplerKind {
        if self.analytic {
            SamplerKind::AnalyticMixture
        } else {
            SamplerKind::ImprovedBaseline
        }
    }
    fn train(&self, run: Run<'_, '_>) -> Result<Fitted> {
        let (pool, cfg) = (run.pool, run.cfg);
        let m = &cfg.max_likelihood[self.kind()];
        let (p, h) = train(pool, &cfg.common, m, self.analytic)?;
        Ok((p, None, h))
    }
    fn pdf_f64(&self, t: &Trained, phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
        pdf_f64(&t.params, self.analytic, phi, wi, p)
    }
    fn graph(&self, params: &[f32], batch: &Batch) -> Option<Tensor<2>> {
        Some(graph_log_pdf(params, self.analytic, batch))
    }
}

/// Trains the improved baseline (`analytic == false`) or the analytic mixture.
pub fn train(
    pool: &mut Pool<'_>,
    common: &Common,
    cfg: &MaxLikelihood,
    analytic: bool,
) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
    let device = train_device();
    let mut rng = rng_for(mix_seed(common.seed, 0x10be), 0, 0);
    let sizes: &[usize] = if analytic {
        &ANALYTIC_SIZES
    } else {
        &BASELINE_SIZES
    };
    // Start the Gaussians at σ ≈ 0.3 (log σ = −1.2): a unit-σ Gaussian has less density than
    // the Lambert lobe everywhere on the disk, and its weight collapses before σ can shrink.
    let bias: &[(usize, f32)] = if analytic {
        &[(4, -1.2), (5, -1.2), (6, -1.2), (7, -1.2)]
    } else {
        &[(2, -1.2)]
    };
    let model = LobeModel {
        net: Mlp::new_with_output_bias(sizes, 0.1, bias, &mut rng, &device),
    };
    let name = if analytic { "analytic" } else { "baseline" };
    train_max_likelihood(model, name, pool, common, cfg, |m, batch| {
        let o = m.net.forward(batch.cond.clone(), Activation::Relu);
        if analytic {
            analytic_log_pdf(o, batch)
        } else {
            baseline_log_pdf(o, batch)
        }
    })
}

/// Per-point log density `[b, s]` of the training graph for exported parameters `params`
/// (on `batch`'s device).
pub fn graph_log_pdf(params: &[f32], analytic: bool, batch: &Batch) -> Tensor<2> {
    let device = batch.x.device();
    let sizes: &[usize] = if analytic {
        &ANALYTIC_SIZES
    } else {
        &BASELINE_SIZES
    };
    let o = Mlp::from_flat(sizes, params, &device).forward(batch.cond.clone(), Activation::Relu);
    if analytic {
        analytic_log_pdf(o, batch)
    } else {
        baseline_log_pdf(o, batch)
    }
}

fn normal_f64(p: Vec2, mx: f64, my: f64, sx: f64, sy: f64) -> f64 {
    let dx = (f64::from(p.x) - mx) / sx;
    let dy = (f64::from(p.y) - my) / sy;
    (-0.5 * (dx * dx + dy * dy)).exp() / (std::f64::consts::TAU * sx * sy)
}

fn sigma_f64(ls: f64) -> f64 {
    ls.clamp(f64::from(LOG_SIGMA_MIN), f64::from(LOG_SIGMA_MAX))
        .exp()
}

/// Density (projected-disk area measure) of a trained lobe mixture at `p`, in f64 from the
/// exported parameters; `wi` must already be normalised. 0 outside the open unit disk.
#[must_use]
pub fn pdf_f64(params: &[f32], analytic: bool, phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
    if !(p.length_squared() < 1.0) {
        return 0.0;
    }
    let c = encoded_condition_f64(phi, wi);
    let mut at = 0;
    let inv_pi = std::f64::consts::FRAC_1_PI;
    if analytic {
        let o = mlp_f64(params, &mut at, &ANALYTIC_SIZES, Activation::Relu, &c);
        let w = softmax_f64(&o[8..11]);
        w[0] * inv_pi
            + w[1] * normal_f64(p, o[0], o[1], sigma_f64(o[4]), sigma_f64(o[5]))
            + w[2] * normal_f64(p, o[2], o[3], sigma_f64(o[6]), sigma_f64(o[7]))
    } else {
        let o = mlp_f64(params, &mut at, &BASELINE_SIZES, Activation::Relu, &c);
        let w = softmax_f64(&o[3..5]);
        let s = sigma_f64(o[2]);
        w[0] * inv_pi + w[1] * normal_f64(p, o[0], o[1], s, s)
    }
}
