//! The rational-quadratic spline of the flow's coupling layers (paper Eq. 4), batched in
//! burn for training and in f64 for checking, with exactly the runtime's conventions
//! (`neusample::distrib::spline`): `K` bins on `[−B, B]`, minimum bin width/height/derivative 1e−3,
//! `widths = min_w + (1 − K·min_w)·softmax(raw_w)`, knots the cumulative sum scaled to
//! `[−B, B]` with both ends exact, interior derivatives `min_d + softplus(raw_d)`, boundary
//! derivatives 1, identity outside `[−B, B]` (or, for the disk flow, every derivative learned on
//! `[−1, 1]`). Only the forward (density-direction) map is needed for training.

use burn::tensor::activation;
use burn::tensor::{Int, Tensor};
use neusample::distrib::spline::{MIN_BIN_HEIGHT, MIN_BIN_WIDTH, MIN_DERIVATIVE};

use crate::nn::{softmax_f64, softplus_f64};

/// Knots `[n, K + 1]` from raw sizes `[n, K]`: `−B`, the scaled running sums, `+B`.
fn knots(raw: Tensor<2>, min_size: f32, bound: f32) -> Tensor<2> {
    let [n, k] = raw.dims();
    let device = raw.device();
    let sizes = activation::softmax(raw, 1) * (1.0 - min_size * k as f32) + min_size;
    let cum = sizes.cumsum(1).narrow(1, 0, k - 1) * (2.0 * bound) - bound;
    Tensor::cat(
        vec![
            Tensor::full([n, 1], -bound, &device),
            cum,
            Tensor::full([n, 1], bound, &device),
        ],
        1,
    )
}

/// Forward map of the spline on a column `v` `[n, 1]` with raw parameters `[n, 3K − 1]`
/// (`[widths K, heights K, interior derivatives K − 1]`). Returns `(y, ln |dy/dv|)`, both
/// `[n, 1]`; identity with log-det 0 outside `[−B, B]`.
pub fn rq_forward(v: Tensor<2>, raw: Tensor<2>, bins: usize, bound: f32) -> (Tensor<2>, Tensor<2>) {
    let n = v.dims()[0];
    let device = v.device();
    let d_inner =
        activation::softplus(raw.clone().narrow(1, 2 * bins, bins - 1), 1.0) + MIN_DERIVATIVE;
    let ones = Tensor::<2>::ones([n, 1], &device);
    let d = Tensor::cat(vec![ones.clone(), d_inner, ones], 1);
    rq_forward_with(v, raw, d, bins, bound)
}

/// [`rq_forward`] of a spline on `[−1, 1]` whose boundary derivatives are learned too
/// (`neusample::distrib::spline::Knots::from_raw_free`): raw parameters `[n, 3K + 1]`
/// (`[widths K, heights K, derivatives K + 1]`), every derivative `min_d + softplus(raw)`.
pub fn rq_forward_free(v: Tensor<2>, raw: Tensor<2>, bins: usize) -> (Tensor<2>, Tensor<2>) {
    let d = activation::softplus(raw.clone().narrow(1, 2 * bins, bins + 1), 1.0) + MIN_DERIVATIVE;
    rq_forward_with(v, raw, d, bins, 1.0)
}

/// The forward map given the knot derivatives `d` `[n, K + 1]`.
fn rq_forward_with(
    v: Tensor<2>,
    raw: Tensor<2>,
    d: Tensor<2>,
    bins: usize,
    bound: f32,
) -> (Tensor<2>, Tensor<2>) {
    let n = v.dims()[0];
    let xk = knots(raw.clone().narrow(1, 0, bins), MIN_BIN_WIDTH, bound);
    let yk = knots(raw.narrow(1, bins, bins), MIN_BIN_HEIGHT, bound);

    let outside = v
        .clone()
        .lower_elem(-bound)
        .bool_or(v.clone().greater_elem(bound));
    let vc = v.clone().clamp(-bound, bound);
    // Bin: the last interior knot ≤ v (as the runtime's linear scan); index in 0..K.
    let interior = xk.clone().narrow(1, 1, bins - 1);
    let k: Tensor<2, Int> = vc
        .clone()
        .detach()
        .expand([n, bins - 1])
        .greater_equal(interior.detach())
        .int()
        .sum_dim(1);
    let k1 = k.clone() + 1;
    let x0 = xk.clone().gather(1, k.clone());
    let x1 = xk.gather(1, k1.clone());
    let y0 = yk.clone().gather(1, k.clone());
    let y1 = yk.gather(1, k1.clone());
    let d0 = d.clone().gather(1, k);
    let d1 = d.gather(1, k1);

    let w = x1 - x0.clone();
    let h = y1 - y0.clone();
    let s = h.clone() / w.clone();
    let xi = ((vc - x0) / w).clamp(0.0, 1.0);
    let om = xi.clone().neg() + 1.0;
    let t = xi.clone() * om.clone();
    let den = s.clone() + (d1.clone() + d0.clone() - s.clone() * 2.0) * t.clone();
    let num = h * (s.clone() * xi.clone().powi_scalar(2) + d0.clone() * t.clone());
    let y = y0 + num / den.clone();
    let dnum =
        s.clone().powi_scalar(2) * (d1 * xi.powi_scalar(2) + s * t * 2.0 + d0 * om.powi_scalar(2));
    let logdet = dnum.log() - den.log() * 2.0;

    let y = y.mask_where(outside.clone(), v);
    let logdet = logdet.mask_fill(outside, 0.0);
    (y, logdet)
}

/// f64 knots `[K]` (the last knot, `+B`, is implicit) as in `neusample::distrib::spline`.
fn knots_f64(raw: &[f64], min_size: f64, bound: f64) -> Vec<f64> {
    let k = raw.len();
    let sm = softmax_f64(raw);
    let scale = 1.0 - min_size * k as f64;
    let mut out = vec![-bound; k];
    let mut cum = 0.0;
    for j in 1..k {
        cum += min_size + scale * sm[j - 1];
        out[j] = 2.0 * bound * cum - bound;
    }
    out
}

/// f64 forward map of the spline: `(y, ln |dy/dv|)` (see [`rq_forward`]).
#[must_use]
pub fn rq_forward_f64(v: f64, raw: &[f64], bins: usize, bound: f64) -> (f64, f64) {
    let mut d = vec![1.0f64; bins + 1];
    for j in 1..bins {
        d[j] = f64::from(MIN_DERIVATIVE) + softplus_f64(raw[2 * bins + j - 1]);
    }
    rq_forward_with_f64(v, raw, &d, bins, bound)
}

/// f64 [`rq_forward_free`].
#[must_use]
pub fn rq_forward_free_f64(v: f64, raw: &[f64], bins: usize) -> (f64, f64) {
    let d: Vec<f64> = (0..=bins)
        .map(|j| f64::from(MIN_DERIVATIVE) + softplus_f64(raw[2 * bins + j]))
        .collect();
    rq_forward_with_f64(v, raw, &d, bins, 1.0)
}

/// The f64 forward map given the knot derivatives `d` (`K + 1` values).
fn rq_forward_with_f64(v: f64, raw: &[f64], d: &[f64], bins: usize, bound: f64) -> (f64, f64) {
    if !(v >= -bound && v <= bound) {
        return (v, 0.0);
    }
    let xk = knots_f64(&raw[..bins], f64::from(MIN_BIN_WIDTH), bound);
    let yk = knots_f64(&raw[bins..2 * bins], f64::from(MIN_BIN_HEIGHT), bound);
    let mut k = 0;
    for (j, &x) in xk.iter().enumerate().skip(1) {
        if v >= x {
            k = j;
        }
    }
    let (x1, y1) = if k + 1 < bins {
        (xk[k + 1], yk[k + 1])
    } else {
        (bound, bound)
    };
    let (w, h) = (x1 - xk[k], y1 - yk[k]);
    let s = h / w;
    let (d0, d1) = (d[k], d[k + 1]);
    let xi = ((v - xk[k]) / w).clamp(0.0, 1.0);
    let t = xi * (1.0 - xi);
    let den = s + (d1 + d0 - 2.0 * s) * t;
    let y = yk[k] + h * (s * xi * xi + d0 * t) / den;
    let dnum = s * s * (d1 * xi * xi + 2.0 * s * t + d0 * (1.0 - xi) * (1.0 - xi));
    (y, dnum.ln() - 2.0 * den.ln())
}
