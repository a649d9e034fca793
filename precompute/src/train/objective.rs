//! The render's measure as a training objective.
//!
//! A sampler's variance per sample is `a²·(1 + χ²(p* ‖ p))` with `1 + χ² = ∫ p*²/p` (the
//! second moment of the estimator `f cos / p_ω` relative to its mean): KL(p* ‖ p) (maximum
//! likelihood) barely sees a region where `p ≪ p*` on little mass, and that is where the
//! weights explode. These terms estimate `ln ∫ p*²/p` per condition from a
//! [`PointKind::Regression`](super::data::PointKind::Regression) batch — points alternately
//! uniform on the disk and from p*, so from the mixture `m = ½/π + ½ p*` — by importance
//! sampling: `∫ p*²/p = E_m[p*² / (p·m)]`, computed in log space. Minimising it is the χ²
//! divergence objective of neural importance sampling (Müller et al. 2019) with samples from a
//! fixed mixture instead of the model, which keeps the estimate's variance bounded where the
//! model is poor. The uniform half reaches the rim, where p* samples are rare.

use burn::tensor::Tensor;

use super::data::Batch;
use crate::nn::log_sum_exp_last;

/// Floor of p* inside the logarithm (points where p* is 0 contribute nothing).
const TARGET_FLOOR: f32 = 1e-30;

/// `ln ∫ p*²/p = ln(χ²(p* ‖ p) + 1)` per condition `[b]`, estimated from the batch's points
/// (`log_p` `[b, s]`: the model's log density at them; the batch must carry targets).
///
/// # Panics
/// If the batch has no targets (it must be a regression batch).
#[must_use]
pub fn log_second_moment(log_p: Tensor<2>, batch: &Batch) -> Tensor<1> {
    let target = batch
        .target
        .clone()
        .expect("the χ² term needs a regression batch (targets at the points)");
    let [b, s] = log_p.dims();
    let ln_t = target.clone().clamp_min(TARGET_FLOOR).log();
    // m = ½/π + ½ p*, the density the batch's points come from.
    let ln_m = (target * 0.5 + 0.5 * std::f32::consts::FRAC_1_PI).log();
    let log_w = ln_t * 2.0 - log_p - ln_m;
    (log_sum_exp_last(log_w) - (s as f32).ln()).reshape([b])
}

/// `−mean ln p` over the batch's samples of p* (the odd columns of a regression batch): the
/// maximum-likelihood term on the same batch.
#[must_use]
pub fn nll_of_target_points(log_p: Tensor<2>) -> Tensor<1> {
    let [b, s] = log_p.dims();
    log_p.reshape([b, s / 2, 2]).narrow(2, 1, 1).mean().neg()
}

/// The fine-tuning loss `−mean ln p(p* samples) + λ · mean_c ln ∫ p*²/p` (see the module
/// docs), λ = `chi2_weight`.
#[must_use]
pub fn nll_and_chi2(log_p: Tensor<2>, batch: &Batch, chi2_weight: f32) -> Tensor<1> {
    let chi2 = log_second_moment(log_p.clone(), batch).mean();
    nll_of_target_points(log_p) + chi2 * chi2_weight
}
