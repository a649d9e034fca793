//! Sinusoidal encodings and numerically stable helpers, on tensors and in f64.

use burn::tensor::Tensor;

use super::tensor::tensor2;

/// `encB(v) = [v, sin(πv), cos(πv), …, sin(2^(B−1)πv), cos(2^(B−1)πv)]` of a column
/// `[n, 1]`, giving `[n, 1 + 2B]` (the same order as `neusample::nn::encode_scalar`).
pub fn encode(v: Tensor<2>, bands: usize) -> Tensor<2> {
    let n = v.dims()[0];
    let device = v.device();
    let freqs: Vec<f32> = (0..bands)
        .map(|k| std::f32::consts::PI * (1u32 << k) as f32)
        .collect();
    let arg = v.clone() * tensor2(freqs, 1, bands, &device);
    let sc: Tensor<3> = Tensor::stack(vec![arg.clone().sin(), arg.cos()], 2);
    Tensor::cat(vec![v, sc.reshape([n, 2 * bands])], 1)
}

/// f64 version of [`encode`], appended to `out`.
pub fn encode_f64(v: f64, bands: usize, out: &mut Vec<f64>) {
    out.push(v);
    for k in 0..bands {
        let a = std::f64::consts::PI * f64::from(1u32 << k) * v;
        out.push(a.sin());
        out.push(a.cos());
    }
}

/// `clamp(x, LOG_SIGMA_MIN, LOG_SIGMA_MAX)` in the forward pass (the runtime's clamp of every
/// predicted `log σ`) with the identity as its gradient (straight-through). A plain clamp has
/// zero gradient outside the range, and a network whose `log σ` overshoots the upper bound
/// early in training then never recovers (its Gaussian loses all weight to the Lambert lobe).
pub fn clamp_log_sigma<const D: usize>(x: Tensor<D>) -> Tensor<D> {
    use neusample::distrib::gaussian::{LOG_SIGMA_MAX, LOG_SIGMA_MIN};
    let clamped = x.clone().clamp(LOG_SIGMA_MIN, LOG_SIGMA_MAX);
    x.clone() + (clamped - x).detach()
}

/// ln(eᵃ + eᵇ), element-wise and stable.
pub fn log_add_exp<const D: usize>(a: Tensor<D>, b: Tensor<D>) -> Tensor<D> {
    let m = a.clone().max_pair(b.clone());
    let d = (a - b).abs().neg().exp();
    m + (d + 1.0).log()
}

/// ln Σ exp over the last dimension of a `[.., K]` tensor (stable), keeping the dimension.
pub fn log_sum_exp_last<const D: usize>(x: Tensor<D>) -> Tensor<D> {
    let m = x.clone().max_dim(D - 1).detach();
    (x - m.clone()).exp().sum_dim(D - 1).log() + m
}

/// Stable softplus ln(1 + eˣ) in f64 (the runtime's softplus for x ≤ 20).
#[must_use]
pub fn softplus_f64(x: f64) -> f64 {
    if x > 20.0 {
        x
    } else {
        x.exp().ln_1p()
    }
}

/// Softmax of `v` in f64.
#[must_use]
pub fn softmax_f64(v: &[f64]) -> Vec<f64> {
    let m = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = v.iter().map(|x| (x - m).exp()).collect();
    let s: f64 = e.iter().sum();
    e.iter().map(|x| x / s).collect()
}
