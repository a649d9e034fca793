//! The reparameterization sampler (`core/ARCHITECTURES.md` §8; after Wu et al. 2025): a warp
//! MLP trained on the integrand itself, then a pdf network fitted to the warp's own density.
//!
//! * **Warp** (`dense(32,16)` SiLU, `dense(16,16)` SiLU, `dense(16,3)`): its 2 × 2 Jacobian is
//!   computed on the training graph by forward-mode tangents, the same formulas as the runtime
//!   ([`warp_graph`]). Loss, over stratified standard-normal `z` per condition:
//!   `−mean ln((1 − α)·f⊥(T(z))·relu(det J) + α·f⊥(F(z))·det J_F)` with the fixed warp
//!   `F(z) = z/√(1 + |z|²)` and `α` = [`Reparam::defensive`] (the release's 10⁻³): KL(q ‖ p*)
//!   up to constants, where `f⊥` is the integrand on the disk ([`Integrand`]: the neural
//!   material's luminance through its burn decoder, so gradients flow through `f(T(z))`).
//!   `relu` pushes towards an orientation-preserving warp; at initialisation the output's
//!   `b` row is negated if most of a batch has `det J < 0` (a reversed start gets no gradient).
//! * **Warm start** ([`Reparam::prefit`], before that loss, by default for materials without a
//!   latent: [`WarmStart`]): `T(z)` regressed onto the
//!   tabulated target's own inverse-CDF map (`target_map`). The loss above is mode seeking:
//!   from a random start it gets no gradient from a narrow lobe its samples never reach, and
//!   settles on the broad part of the target; from the warm start the warp covers the lobes
//!   and the loss refines it ([`Reparam::refine`]: a lower rate, more steps).
//! * **pdf network** (`dense(32,16)` ReLU, `dense(16,1)`, `p̂ = exp(o)`), trained with the warp
//!   frozen on its samples `x = T(z)` with their exact `q(x) = N(z)/det J` (computed by the
//!   runtime's own warp): [`DensityLoss`], with the generalised χ² of
//!   [`Reparam::density_chi2_weight`] beside its KL.

use anyhow::{bail, ensure, Result};
use burn::module::Module;
use burn::tensor::activation;
use burn::tensor::{Device, Tensor};
use glam::{Vec2, Vec3};
use neusample::distrib::gaussian::box_muller;
use neusample::nn::{encode_condition, CONDITION_DIM};
use neusample::samplers::reparam::{
    DENSITY_L0, LOG_DENSITY_MAX, LOG_DENSITY_MIN, REPARAM_HIDDEN, REPARAM_INPUTS,
    REPARAM_PARAM_COUNT, WARP_OUTPUTS,
};
use neusample::samplers::ReparamSampler;
use neusample::{Sampler, SamplerKind, FEATURE_DIM};
use rand::RngExt;

use super::config::{
    Common, DensityLoss, MaxLikelihood, Reparam, Schedule, TrainConfig, WarmStart,
};
use super::data::{encoded_condition_f64, map_picked_from, Batch, Pool};
use super::integrand::{ConditionRows, Integrand};
use super::source::{GtCondition, TargetSource};
use super::trainer::{Fitted, Run, Trained, Trainer};
use crate::groundtruth::TargetPdf;
use crate::nn::{log_sum_exp_last, mlp_f64, optimise, tensor2, train_device, Activation, Mlp};
use crate::util::rng::{mix_seed, rng_for};

/// Layer sizes of the warp.
pub const WARP_SIZES: [usize; 4] = [REPARAM_INPUTS, REPARAM_HIDDEN, REPARAM_HIDDEN, WARP_OUTPUTS];
/// Layer sizes of the pdf network.
pub const DENSITY_SIZES: [usize; 3] = [REPARAM_INPUTS, REPARAM_HIDDEN, 1];

const LN_TWO_PI: f64 = 1.837_877_066_409_345_5;

/// The warp's outputs on the training graph, `[n, 1]` each.
pub struct WarpGraph {
    /// `v = (a, b, softplus(w)) / |·|`, the sampled direction, `[n, 3]`.
    pub wo: Tensor<2>,
    /// `det ∂T/∂z`, `[n, 1]`.
    pub det: Tensor<2>,
}

fn layer(net: &Mlp, l: usize) -> (Tensor<2>, Tensor<2>) {
    let lin = &net.layers[l];
    let b = lin
        .bias
        .as_ref()
        .expect("every layer has a bias")
        .val()
        .unsqueeze_dim(0);
    (lin.weight.val(), b)
}

/// `(silu(a), silu'(a))`.
fn silu_slope(a: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
    let s = activation::sigmoid(a.clone());
    let y = a.clone() * s.clone();
    let d = s.clone() * ((a * (s.neg() + 1.0)) + 1.0);
    (y, d)
}

fn col(t: &Tensor<2>, j: usize) -> Tensor<2> {
    t.clone().narrow(1, j, 1)
}

/// The warp `T(z)` of encoded conditions `cond` (`[n, 30]`) at latent points `z` (`[n, 2]`)
/// with `det ∂T/∂z` by forward-mode tangents: `ARCHITECTURES.md` §8 on tensors.
pub fn warp_graph(net: &Mlp, cond: Tensor<2>, z: Tensor<2>) -> WarpGraph {
    let n = z.dims()[0];
    let (w0, b0) = layer(net, 0);
    let a1 = Tensor::cat(vec![cond, z], 1).matmul(w0.clone()) + b0;
    let r0 = w0.clone().narrow(0, CONDITION_DIM, 1);
    let r1 = w0.narrow(0, CONDITION_DIM + 1, 1);
    let (h1, d1) = silu_slope(a1);
    // Both tangents stacked: rows 0..n are ∂/∂z.x, rows n..2n ∂/∂z.y.
    let t1 = Tensor::cat(vec![d1.clone() * r0, d1 * r1], 0);
    let (w1, b1) = layer(net, 1);
    let a2 = h1.matmul(w1.clone()) + b1;
    let u2 = t1.matmul(w1);
    let (h2, d2) = silu_slope(a2);
    let t2 = Tensor::cat(vec![d2.clone(), d2], 0) * u2;
    let (w2, b2) = layer(net, 2);
    let o = h2.matmul(w2.clone()) + b2;
    let dout = t2.matmul(w2);
    let (g0, g1) = (dout.clone().narrow(0, 0, n), dout.narrow(0, n, n));
    let s = activation::softplus(col(&o, 2), 1.0);
    let ds = activation::sigmoid(col(&o, 2));
    let len =
        (col(&o, 0).powi_scalar(2) + col(&o, 1).powi_scalar(2) + s.clone().powi_scalar(2)).sqrt();
    let inv = len.recip();
    let (vx, vy, vz) = (
        col(&o, 0) * inv.clone(),
        col(&o, 1) * inv.clone(),
        s * inv.clone(),
    );
    let tangent = |g: &Tensor<2>| {
        let t =
            vx.clone() * col(g, 0) + vy.clone() * col(g, 1) + vz.clone() * ds.clone() * col(g, 2);
        let x = (col(g, 0) - vx.clone() * t.clone()) * inv.clone();
        let y = (col(g, 1) - vy.clone() * t) * inv.clone();
        (x, y)
    };
    let (x0, y0) = tangent(&g0);
    let (x1, y1) = tangent(&g1);
    WarpGraph {
        wo: Tensor::cat(vec![vx, vy, vz], 1),
        det: x0 * y1 - x1 * y0,
    }
}

/// The pdf network's log-density (before the runtime's clamp) at disk points `p` (`[n, 2]`).
pub fn density_graph(net: &Mlp, cond: Tensor<2>, p: Tensor<2>) -> Tensor<2> {
    net.forward(Tensor::cat(vec![cond, p], 1), Activation::Relu)
}

/// The warp model being trained.
#[derive(Module, Debug)]
pub struct WarpModel {
    /// The warp MLP.
    pub net: Mlp,
}

/// The pdf network being trained.
#[derive(Module, Debug)]
pub struct DensityModel {
    /// The pdf MLP.
    pub net: Mlp,
}

/// One step's data: conditions, latent points and the defensive warp's term.
struct WarpBatch {
    conds: Vec<([f32; FEATURE_DIM], Vec3)>,
    /// Encoded conditions repeated per sample, `[n, 30]`.
    cond: Vec<f32>,
    /// `z`, `[n, 2]`.
    z: Vec<f32>,
    /// `f⊥(F(z))·det J_F`, `[n]`.
    fixed: Vec<f32>,
    /// `ln N(z; 0, I)`, `[n]`.
    log_normal: Vec<f32>,
    s: usize,
}

/// `s` stratified standard-normal points (`k × k` jittered cells of `[0, 1)²`, Box–Muller).
fn stratified_z(s: usize, rng: &mut rand_pcg::Pcg64) -> Vec<Vec2> {
    let k = (s as f64).sqrt().round().max(1.0) as usize;
    (0..s)
        .map(|i| {
            let (a, b) = ((i % k) as f32, ((i / k) % k) as f32);
            let u = Vec2::new(
                ((a + rng.random::<f32>()) / k as f32).min(neusample::ONE_MINUS_EPSILON),
                ((b + rng.random::<f32>()) / k as f32).min(neusample::ONE_MINUS_EPSILON),
            );
            box_muller(u)
        })
        .collect()
}

/// `F(z) = z/√(1 + |z|²)` as a direction, and `det J_F = (1 + |z|²)⁻²`.
fn fixed_warp(z: Vec2) -> (Vec3, f32) {
    let q = 1.0 + z.length_squared();
    let inv = 1.0 / q.sqrt();
    (Vec3::new(z.x * inv, z.y * inv, inv), 1.0 / (q * q))
}

/// The batch of `step`: `b` pool conditions (with replacement) × `s` latent points.
fn warp_batch(
    pool: &Pool<'_>,
    integrand: &dyn Integrand,
    b: usize,
    s: usize,
    seed: u64,
    step: usize,
) -> WarpBatch {
    let items = pool.items();
    let rows = map_picked_from(items, b, seed, (0x7e9a, 0x2a7b), step, |rng, g, wi| {
        let z = stratified_z(s, rng);
        let fixed: Vec<f32> = z
            .iter()
            .map(|&z| {
                let (wo, det) = fixed_warp(z);
                integrand.f(&g.phi, wi, wo) * det
            })
            .collect();
        ((g.phi, wi), encode_condition(&g.phi, wi), z, fixed)
    });
    let mut out = WarpBatch {
        conds: Vec::with_capacity(b),
        cond: Vec::with_capacity(b * s * CONDITION_DIM),
        z: Vec::with_capacity(2 * b * s),
        fixed: Vec::with_capacity(b * s),
        log_normal: Vec::with_capacity(b * s),
        s,
    };
    for (c, enc, z, fixed) in rows {
        out.conds.push(c);
        for _ in 0..s {
            out.cond.extend_from_slice(&enc);
        }
        out.log_normal.extend(
            z.iter()
                .map(|v| -0.5 * v.length_squared() - LN_TWO_PI as f32),
        );
        out.z.extend(z.iter().flat_map(|v| [v.x, v.y]));
        out.fixed.extend(fixed);
    }
    out
}

/// The warp loss of a batch (module docs; with the χ² term of [`Reparam::chi2_weight`]).
fn warp_loss(
    m: &WarpModel,
    batch: &WarpBatch,
    integrand: &dyn Integrand,
    cfg: &Reparam,
    device: &Device,
) -> Tensor<1> {
    let n = batch.z.len() / 2;
    let alpha = cfg.defensive;
    let cond = tensor2(batch.cond.clone(), n, CONDITION_DIM, device);
    let z = tensor2(batch.z.clone(), n, 2, device);
    let w = warp_graph(&m.net, cond, z);
    let rows = ConditionRows {
        conds: &batch.conds,
        repeat: batch.s,
    };
    let log_f = integrand.log_f(rows, w.wo, device).clamp(
        neusample::neural_material::LOG_F_MIN,
        neusample::neural_material::LOG_F_MAX,
    );
    let det = activation::relu(w.det);
    let fixed = tensor2(batch.fixed.clone(), n, 1, device);
    let mixed = log_f.clone().exp() * det.clone() * (1.0 - alpha) + fixed * alpha;
    let kl = (mixed + 1e-30).log().mean().neg();
    if !(cfg.chi2_weight > 0.0) {
        return kl;
    }
    // ln w = ln f + ln det − ln N(z), per condition: ln E[w²] − 2 ln E[w].
    let b = batch.conds.len();
    let log_normal = tensor2(batch.log_normal.clone(), n, 1, device);
    let lw = (log_f + (det + 1e-30).log() - log_normal).reshape([b, batch.s]);
    let chi =
        log_sum_exp_last(lw.clone() * 2.0) - log_sum_exp_last(lw) * 2.0 + (batch.s as f32).ln();
    kl + chi.mean() * cfg.chi2_weight
}

/// The full parameter array with the pdf network's part zero.
fn with_zero_density(warp: &[f32]) -> Vec<f32> {
    let mut p = warp.to_vec();
    p.resize(REPARAM_PARAM_COUNT, 0.0);
    p
}

/// Mean sign of `det J` of a warp (exported parameters) over a few pool conditions.
fn orientation(warp: &[f32], pool: &Pool<'_>, seed: u64) -> f64 {
    let params = with_zero_density(warp);
    let s = ReparamSampler::new(params.as_slice()).expect("parameter count");
    let mut rng = rng_for(mix_seed(seed, 0x0e1e), 0, 0);
    let (mut sum, mut n) = (0.0, 0usize);
    for g in pool.items().iter().take(16) {
        let Some(p) = s.prepare(&g.phi, g.wi) else {
            continue;
        };
        for z in stratified_z(64, &mut rng) {
            let d = p.warp(z).det;
            if d.is_finite() {
                sum += f64::from(d.signum());
                n += 1;
            }
        }
    }
    sum / n.max(1) as f64
}

/// A fresh warp: PyTorch-style initialisation, with the `b` output negated when most of the
/// pool's first conditions see `det J < 0`.
fn init_warp(pool: &Pool<'_>, seed: u64, device: &Device) -> Mlp {
    let mut rng = rng_for(mix_seed(seed, 0x3a4b), 0, 0);
    let net = Mlp::new(&WARP_SIZES, 1.0, &mut rng, device);
    let mut flat = Vec::new();
    net.export(&mut flat);
    if orientation(&flat, pool, seed) >= 0.0 {
        return net;
    }
    // The last layer is W [16 × 3] then b [3]: negate column 1 and its bias.
    let h = REPARAM_HIDDEN;
    let last = flat.len() - (h * WARP_OUTPUTS + WARP_OUTPUTS);
    for i in 0..h {
        flat[last + i * WARP_OUTPUTS + 1] *= -1.0;
    }
    flat[last + h * WARP_OUTPUTS + 1] *= -1.0;
    Mlp::from_flat(&WARP_SIZES, &flat, device)
}

/// `Φ(x)`, the standard normal CDF.
fn normal_cdf(x: f32) -> f32 {
    0.5 * libm::erfcf(-x * std::f32::consts::FRAC_1_SQRT_2)
}

/// The tabulated target's inverse-CDF map as a map of `z`: `u = (Φ(z.y), Φ(z.x))` through
/// [`TargetPdf::sample`] (`u.x` picks the row, so `z.y` moves the point along y and `z.x`
/// along x: the map preserves orientation, `det > 0` as the warp's loss wants).
fn target_map(target: &TargetPdf, z: Vec2) -> Option<Vec2> {
    let u =
        Vec2::new(normal_cdf(z.y), normal_cdf(z.x)).min(Vec2::splat(neusample::ONE_MINUS_EPSILON));
    target.sample(u)
}

/// One step of the warm start: per picked condition, `s` stratified `z` with the target map's
/// point of each (where it has one).
fn prefit_batch(
    conds: &[GtCondition],
    b: usize,
    s: usize,
    seed: u64,
    step: usize,
) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let rows = map_picked_from(conds, b, seed, (0x9f17, 0x51c3), step, |rng, g, wi| {
        let points: Vec<(Vec2, Vec2)> = stratified_z(s, rng)
            .into_iter()
            .filter_map(|z| target_map(&g.target, z).map(|p| (z, p)))
            .collect();
        (encode_condition(&g.phi, wi), points)
    });
    let (mut cond, mut zs, mut ps) = (Vec::new(), Vec::new(), Vec::new());
    for (enc, points) in rows {
        for (z, p) in points {
            cond.extend_from_slice(&enc);
            zs.extend([z.x, z.y]);
            ps.extend([p.x, p.y]);
        }
    }
    (cond, zs, ps)
}

/// True when every condition has the same features φ ([`WarmStart::WithoutLatent`]).
fn one_latent(conds: &[GtCondition]) -> bool {
    conds.windows(2).all(|w| w[0].phi == w[1].phi)
}

/// Whether the warp starts from [`Reparam::prefit`]'s fit on `pool` (then it refines with
/// [`Reparam::refine`]) rather than from random weights.
fn warm_starts(cfg: &Reparam, pool: &Pool<'_>) -> bool {
    cfg.prefit.steps > 0
        && match cfg.warm_start {
            WarmStart::Never => false,
            WarmStart::WithoutLatent => one_latent(pool.items()),
            WarmStart::Always => true,
        }
}

/// The warp's schedule: [`Reparam::refine`] after a warm start, else [`Reparam::schedule`].
fn warp_schedule(cfg: &Reparam, warm: bool) -> Schedule {
    if warm {
        cfg.refine
    } else {
        cfg.schedule
    }
}

/// The warp's warm start ([`Reparam::prefit`]): `cfg.prefit_conditions` conditions of the
/// source tabulated at `common.gt_res`, and `T(z)`'s point on the disk regressed onto
/// [`target_map`] (mean squared distance). The map is exact for the table but discontinuous
/// between its rows; the warp's own loss then takes over from a warp that covers the target.
fn prefit_warp(
    net: Mlp,
    source: &dyn TargetSource,
    common: &Common,
    cfg: &Reparam,
    device: &Device,
) -> Result<(Mlp, Vec<f32>)> {
    let conds = source.draw_with(
        cfg.prefit_conditions.max(1),
        common.gt_res,
        mix_seed(common.seed, 0x7a2e),
        &common.target_options(),
    )?;
    let (b, s) = (cfg.batch_conditions, cfg.samples_per_condition);
    let (m, history) = optimise(
        WarpModel { net },
        &common.optim_settings("reparam warm start", &cfg.prefit),
        |m, step| {
            let (cond, z, p) = prefit_batch(&conds, b, s, common.seed, step);
            let n = z.len() / 2;
            ensure!(n > 0, "the warm start's targets have no samples");
            let w = warp_graph(
                &m.net,
                tensor2(cond, n, CONDITION_DIM, device),
                tensor2(z, n, 2, device),
            );
            let xy = w.wo.narrow(1, 0, 2);
            Ok((xy - tensor2(p, n, 2, device))
                .powi_scalar(2)
                .sum_dim(1)
                .mean())
        },
    )?;
    Ok((m.net, history))
}

/// One step's data of the pdf network: warp samples with their log-density and uniform
/// points of the disk.
struct DensityBatch {
    /// Conditions with at least one warp sample, and per condition its rows.
    cond_q: Vec<f32>,
    x: Vec<f32>,
    log_q: Vec<f32>,
    /// Condition index of each warp sample.
    owner: Vec<usize>,
    cond_u: Vec<f32>,
    u: Vec<f32>,
    conditions: usize,
}

fn density_batch(
    pool: &Pool<'_>,
    warp: &ReparamSampler<&[f32]>,
    b: usize,
    s: usize,
    seed: u64,
    step: usize,
) -> DensityBatch {
    let items = pool.items();
    let rows = map_picked_from(items, b, seed, (0xde75, 0x9d3e), step, |rng, g, wi| {
        let enc = encode_condition(&g.phi, wi);
        let mut xs = Vec::with_capacity(s);
        if let Some(p) = warp.prepare(&g.phi, wi) {
            for z in stratified_z(s, rng) {
                let t = p.warp(z);
                let lq = -0.5 * f64::from(z.length_squared()) - LN_TWO_PI - f64::from(t.det).ln();
                if t.det > 0.0 && lq.is_finite() && t.point.length_squared() < 1.0 {
                    xs.push((t.point, lq as f32));
                }
            }
        }
        let us: Vec<Vec2> = (0..s)
            .map(|_| {
                let r = rng.random::<f32>().sqrt();
                let a = std::f32::consts::TAU * rng.random::<f32>();
                Vec2::new(r * a.cos(), r * a.sin()) * 0.9999
            })
            .collect();
        (enc, xs, us)
    });
    let mut out = DensityBatch {
        cond_q: Vec::new(),
        x: Vec::new(),
        log_q: Vec::new(),
        owner: Vec::new(),
        cond_u: Vec::new(),
        u: Vec::new(),
        conditions: b,
    };
    for (j, (enc, xs, us)) in rows.into_iter().enumerate() {
        for (p, lq) in xs {
            out.cond_q.extend_from_slice(&enc);
            out.x.extend([p.x, p.y]);
            out.log_q.push(lq);
            out.owner.push(j);
        }
        for p in us {
            out.cond_u.extend_from_slice(&enc);
            out.u.extend([p.x, p.y]);
        }
    }
    out
}

/// Largest `ln(q/p̂)` of one sample in the pdf network's χ² term.
const DENSITY_RATIO_EXP_MAX: f32 = 30.0;

/// The pdf network's loss of a batch ([`DensityLoss`]; with [`GeneralizedKl`](DensityLoss::GeneralizedKl),
/// `chi2_weight` λ of [`Reparam::density_chi2_weight`]).
fn density_loss(
    m: &DensityModel,
    b: &DensityBatch,
    kind: DensityLoss,
    chi2_weight: f32,
    device: &Device,
) -> Tensor<1> {
    let nq = b.log_q.len();
    let cond = tensor2(b.cond_q.clone(), nq, CONDITION_DIM, device);
    let x = tensor2(b.x.clone(), nq, 2, device);
    let lp = density_graph(&m.net, cond, x).clamp(LOG_DENSITY_MIN, LOG_DENSITY_MAX);
    let lq = tensor2(b.log_q.clone(), nq, 1, device);
    let uniform_mass = || {
        let nu = b.u.len() / 2;
        let cu = tensor2(b.cond_u.clone(), nu, CONDITION_DIM, device);
        let u = tensor2(b.u.clone(), nu, 2, device);
        density_graph(&m.net, cu, u)
            .clamp(LOG_DENSITY_MIN, LOG_DENSITY_MAX)
            .exp()
            .mean()
            * std::f32::consts::PI
    };
    match kind {
        DensityLoss::LogL1 => (lp - lq).abs().mean(),
        DensityLoss::LogL1Mass => (lp - lq).abs().mean() + uniform_mass(),
        DensityLoss::GeneralizedKl => {
            let c = b.conditions.max(1) as f32;
            let mut counts = vec![0usize; b.conditions];
            for &o in &b.owner {
                counts[o] += 1;
            }
            // Each warp sample's weight 1/(count of its condition · conditions).
            let wq: Vec<f32> = b
                .owner
                .iter()
                .map(|&o| 1.0 / (counts[o].max(1) as f32 * c))
                .collect();
            let wq = tensor2(wq, nq, 1, device);
            generalized_kl_chi2(lp, lq, wq, uniform_mass(), chi2_weight)
        }
    }
}

/// The pdf network's generalised divergences from the warp's density: `−E_q[ln p̂] + ∫p̂`
/// (KL) plus `λ·(E_q[q/p̂] + ∫p̂)` (χ²), with `∫p̂` estimated half from the warp's own samples
/// (`E_q[p̂/q]`) and half from uniform points (`uniform_mass`, `π·E_u[p̂]`). `lp`, `lq`: `ln p̂`
/// and `ln q` at the warp's samples (`[n, 1]`), `wq` their weights (summing to 1 over a
/// batch: `1/(samples of its condition · conditions)`). Per point, minimised by `p̂ = q`.
fn generalized_kl_chi2(
    lp: Tensor<2>,
    lq: Tensor<2>,
    wq: Tensor<2>,
    uniform_mass: Tensor<1>,
    chi2_weight: f32,
) -> Tensor<1> {
    let nll = (lp.clone().neg() * wq.clone()).sum();
    let ratio = ((lp.clone() - lq.clone()).exp() * wq.clone()).sum();
    let mass = (ratio + uniform_mass) * 0.5;
    if chi2_weight > 0.0 {
        // `E_q[q/p̂]`, the exponent capped so that one sample far outside `p̂` cannot
        // overflow the batch.
        let over = ((lq - lp).clamp_max(DENSITY_RATIO_EXP_MAX).exp() * wq).sum();
        nll + mass * (1.0 + chi2_weight) + over * chi2_weight
    } else {
        nll + mass
    }
}

/// Ground-truth resolution of the reparameterization sampler's pool: it trains on the
/// integrand and uses only the pool's conditions.
const POOL_RES: usize = 8;

/// The reparameterization sampler's trainer.
pub(crate) struct ReparamTrainer;

/// The module's trainer: the reparameterization sampler's.
pub(crate) const TRAINERS: &[&dyn Trainer] = &[&ReparamTrainer];

impl Trainer for ReparamTrainer {
    fn kind(&self) -> SamplerKind {
        SamplerKind::Reparam
    }
    fn max_likelihood(&self, _quick: bool) -> Option<MaxLikelihood> {
        None
    }
    fn schedule_mut<'c>(&self, cfg: &'c mut TrainConfig) -> &'c mut Schedule {
        &mut cfg.reparam.schedule
    }
    /// The warp's phase, from a random start or after a warm start.
    fn set_steps(&self, cfg: &mut TrainConfig, steps: usize) {
        cfg.reparam.schedule.steps = steps;
        cfg.reparam.refine.steps = steps;
    }
    /// The warp's refining schedule after a warm start, else its schedule.
    fn main_steps(&self, cfg: &TrainConfig, pool: &Pool<'_>) -> usize {
        warp_schedule(&cfg.reparam, warm_starts(&cfg.reparam, pool)).steps
    }
    /// The warp's schedule and the pdf network's.
    fn scale_steps(&self, cfg: &mut TrainConfig, scale: &dyn Fn(&mut Schedule)) {
        scale(&mut cfg.reparam.schedule);
        scale(&mut cfg.reparam.density_schedule);
        scale(&mut cfg.reparam.prefit);
        scale(&mut cfg.reparam.refine);
    }
    fn train(&self, run: Run<'_, '_>) -> Result<Fitted> {
        let (pool, cfg, source) = (run.pool, run.cfg, run.source);
        let integrand = source.integrand().ok_or_else(|| {
            anyhow::anyhow!(
                "the reparameterization sampler trains on the integrand itself: it needs a \
                 neural or measured material (or the synthetic target)"
            )
        })?;
        let (p, h) = train(pool, source, &cfg.common, &cfg.reparam, integrand)?;
        Ok((p, None, h))
    }
    fn pdf_f64(&self, t: &Trained, phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
        pdf_f64(&t.params, phi, wi, p)
    }
    fn graph(&self, params: &[f32], batch: &Batch) -> Option<Tensor<2>> {
        Some(graph_log_pdf(params, batch))
    }
    fn pool_res(&self, _: &Common) -> usize {
        POOL_RES
    }
    fn needs_integrand(&self) -> bool {
        true
    }
}

/// Trains the warp, then the pdf network (module docs). Returns the runtime's parameter
/// array (warp, then pdf network) and the loss of every step: warm start (if any), warp, pdf
/// network.
pub fn train(
    pool: &mut Pool<'_>,
    source: &dyn TargetSource,
    common: &Common,
    cfg: &Reparam,
    integrand: &dyn Integrand,
) -> Result<(Vec<f32>, Vec<f32>)> {
    ensure!(
        cfg.samples_per_condition > 0 && cfg.batch_conditions > 0,
        "the reparameterization sampler needs samples and conditions per batch"
    );
    if !(cfg.defensive >= 0.0 && cfg.defensive < 1.0) {
        bail!("the warp's defensive weight must be in [0, 1)");
    }
    let device = train_device();
    let mut net = init_warp(pool, common.seed, &device);
    let mut history = Vec::new();
    let warm = warm_starts(cfg, pool);
    if warm {
        let (fitted, h) = prefit_warp(net, source, common, cfg, &device)?;
        net = fitted;
        history = h;
    }
    let warp = WarpModel { net };
    let (b, s) = (cfg.batch_conditions, cfg.samples_per_condition);
    let schedule = warp_schedule(cfg, warm);
    let (warp, h1) = optimise(
        warp,
        &common.optim_settings("reparam warp", &schedule),
        |m, step| {
            pool.maybe_refresh(step)?;
            let batch = warp_batch(pool, integrand, b, s, common.seed, step);
            Ok(warp_loss(m, &batch, integrand, cfg, &device))
        },
    )?;
    history.extend(h1);
    let mut warp_params = Vec::new();
    warp.net.export(&mut warp_params);
    let frozen = with_zero_density(&warp_params);
    let sampler = ReparamSampler::new(frozen.as_slice()).expect("parameter count");
    let mut rng = rng_for(mix_seed(common.seed, 0xd3a5), 0, 0);
    let bias = [(0usize, (1.0f32 / std::f32::consts::PI).ln())];
    let density = DensityModel {
        net: Mlp::new_with_output_bias(&DENSITY_SIZES, 0.1, &bias, &mut rng, &device),
    };
    let offset = schedule.steps;
    let (density, h2) = optimise(
        density,
        &common.optim_settings("reparam pdf", &cfg.density_schedule),
        |m, step| {
            pool.maybe_refresh(offset + step)?;
            let batch = density_batch(pool, &sampler, b, s, common.seed, offset + step);
            Ok(density_loss(
                m,
                &batch,
                cfg.density_loss,
                cfg.density_chi2_weight,
                &device,
            ))
        },
    )?;
    history.extend(h2);
    let mut params = warp_params;
    density.net.export(&mut params);
    debug_assert_eq!(params.len(), REPARAM_PARAM_COUNT);
    Ok((params, history))
}

/// The pdf network `p̂` of exported parameters at disk point `p` in f64 (`wi` normalised); 0
/// outside the open unit disk.
#[must_use]
pub fn pdf_f64(params: &[f32], phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
    if !(p.length_squared() < 1.0) {
        return 0.0;
    }
    let mut x = encoded_condition_f64(phi, wi);
    x.extend([f64::from(p.x), f64::from(p.y)]);
    let mut at = DENSITY_L0;
    let o = mlp_f64(params, &mut at, &DENSITY_SIZES, Activation::Relu, &x)[0];
    o.clamp(f64::from(LOG_DENSITY_MIN), f64::from(LOG_DENSITY_MAX))
        .exp()
}

/// The warp of exported parameters at latent point `z` in f64 (`wi` normalised): the disk
/// point and `det ∂T/∂z`, by forward-mode tangents as the runtime computes them.
#[must_use]
pub fn warp_f64(params: &[f32], phi: &[f32; FEATURE_DIM], wi: Vec3, z: Vec2) -> (Vec2, f64) {
    let cond = encoded_condition_f64(phi, wi);
    let (p, j) = warp_jacobian_f64(params, &cond, [f64::from(z.x), f64::from(z.y)]);
    (Vec2::new(p[0] as f32, p[1] as f32), jacobian_det(&j))
}

/// `det ∂T/∂z` of a Jacobian from [`warp_jacobian_f64`].
#[must_use]
pub fn jacobian_det(j: &[[f64; 2]; 2]) -> f64 {
    j[0][0] * j[1][1] - j[0][1] * j[1][0]
}

/// The warp of exported parameters at latent point `z` for an encoded condition `cond`
/// (`neusample::nn::encode_condition`, widened to f64), all in f64: the disk point and the Jacobian `∂T/∂z`, rows
/// the point's coordinates, columns `z.x`, `z.y`.
#[must_use]
pub fn warp_jacobian_f64(params: &[f32], cond: &[f64], z: [f64; 2]) -> ([f64; 2], [[f64; 2]; 2]) {
    let mut x = cond.to_vec();
    x.extend(z);
    // Value and the two tangents through each layer.
    let mut at = 0usize;
    let mut h = x;
    let mut t: [Vec<f64>; 2] = [vec![0.0; REPARAM_INPUTS], vec![0.0; REPARAM_INPUTS]];
    t[0][CONDITION_DIM] = 1.0;
    t[1][CONDITION_DIM + 1] = 1.0;
    for l in 0..WARP_SIZES.len() - 1 {
        let (i, o) = (WARP_SIZES[l], WARP_SIZES[l + 1]);
        let w = &params[at..at + i * o];
        let bias = &params[at + i * o..at + i * o + o];
        let mut y: Vec<f64> = bias.iter().map(|&v| f64::from(v)).collect();
        let mut dy = [vec![0.0; o], vec![0.0; o]];
        for (k, row) in w.chunks_exact(o).enumerate() {
            for j in 0..o {
                let wk = f64::from(row[j]);
                y[j] += h[k] * wk;
                dy[0][j] += t[0][k] * wk;
                dy[1][j] += t[1][k] * wk;
            }
        }
        at += i * o + o;
        if l + 2 < WARP_SIZES.len() {
            for j in 0..o {
                let s = 1.0 / (1.0 + (-y[j]).exp());
                let d = s * (1.0 + y[j] * (1.0 - s));
                y[j] *= s;
                dy[0][j] *= d;
                dy[1][j] *= d;
            }
        }
        h = y;
        t = dy;
    }
    let s = crate::nn::softplus_f64(h[2]);
    let ds = 1.0 / (1.0 + (-h[2]).exp());
    let n = (h[0] * h[0] + h[1] * h[1] + s * s).sqrt();
    let v = [h[0] / n, h[1] / n, s / n];
    let d = |g: &Vec<f64>| {
        let tt = v[0] * g[0] + v[1] * g[1] + v[2] * ds * g[2];
        ((g[0] - v[0] * tt) / n, (g[1] - v[1] * tt) / n)
    };
    let (x0, y0) = d(&t[0]);
    let (x1, y1) = d(&t[1]);
    ([v[0], v[1]], [[x0, x1], [y0, y1]])
}

/// The pdf network's log-density on the training graph for exported parameters at the
/// points of `batch` (`[b, s]`; for checks against the runtime).
pub fn graph_log_pdf(params: &[f32], batch: &Batch) -> Tensor<2> {
    let device = batch.x.device();
    let net = Mlp::from_flat(&DENSITY_SIZES, &params[DENSITY_L0..], &device);
    let (b, s) = (batch.b, batch.s);
    // One row per point: its condition's encoding, then the point.
    let cond = batch
        .cond
        .clone()
        .unsqueeze_dim::<3>(1)
        .repeat_dim(1, s)
        .reshape([b * s, CONDITION_DIM]);
    let p = Tensor::cat(
        vec![
            batch.x.clone().reshape([b * s, 1]),
            batch.y.clone().reshape([b * s, 1]),
        ],
        1,
    );
    density_graph(&net, cond, p)
        .clamp(LOG_DENSITY_MIN, LOG_DENSITY_MAX)
        .reshape([b, s])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::groundtruth::cell_midpoint;
    use rand::SeedableRng;

    /// A table with a narrow lobe off the centre and a broad floor.
    fn lobe_table(res: usize) -> TargetPdf {
        let mut values = Vec::with_capacity(res * res);
        for r in 0..res {
            for c in 0..res {
                let p = cell_midpoint(res, r, c) - Vec2::new(0.3, -0.2);
                values.push(0.2 + 50.0 * (-p.length_squared() / 0.004).exp());
            }
        }
        TargetPdf::from_values(res, values)
    }

    #[test]
    fn the_pdf_networks_loss_is_least_where_it_equals_the_warps_density() {
        // `p̂ = e^s·q` with `∫q = 1`: the loss is `−E[ln q] − s + (1 + λ)·e^s + λ·e^−s`
        // (up to the estimates), least at `s = 0` for every λ.
        let device = train_device();
        let lq = [0.3f32, -1.2, 2.0, 0.7];
        let loss = |s: f32, lambda: f32| -> f32 {
            let lp: Vec<f32> = lq.iter().map(|l| l + s).collect();
            let t = |v: Vec<f32>| tensor2(v, lq.len(), 1, &device);
            let mass = Tensor::<1>::from_floats([s.exp()], &device);
            let l = generalized_kl_chi2(t(lp), t(lq.to_vec()), t(vec![0.25; 4]), mass, lambda);
            l.into_scalar()
        };
        for lambda in [0.0, 1.0, 5.0] {
            let at = |s: f32| loss(s, lambda);
            for s in [-0.2, -0.02, 0.02, 0.2] {
                let (l, l0) = (at(s), at(0.0));
                assert!(l > l0 + 1e-6, "λ {lambda}, s {s}: {l} ≤ {l0}");
            }
            let mean_lq = lq.iter().sum::<f32>() / 4.0;
            let expected = -mean_lq + 1.0 + 2.0 * lambda;
            assert!((at(0.0) - expected).abs() < 1e-5, "λ {lambda}: {}", at(0.0));
        }
    }

    #[test]
    fn the_default_warm_start_is_for_conditions_that_share_their_features() {
        let cond = |phi0: f32, wi: Vec3| GtCondition {
            phi: {
                let mut phi = [0.0; FEATURE_DIM];
                phi[0] = phi0;
                phi
            },
            wi,
            target: lobe_table(8),
        };
        let measured = [cond(0.0, Vec3::Z), cond(0.0, Vec3::new(0.6, 0.0, 0.8))];
        assert!(one_latent(&measured));
        let textured = [cond(0.0, Vec3::Z), cond(0.5, Vec3::Z)];
        assert!(!one_latent(&textured));
    }

    #[test]
    fn target_map_preserves_orientation_and_pushes_normals_to_the_table() {
        let res = 32;
        let t = lobe_table(res);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let (eps, n) = (1e-3, 40_000);
        let mut counts = vec![0usize; res * res];
        let mut mapped = 0;
        for _ in 0..n {
            let z = box_muller(Vec2::new(rng.random(), rng.random()));
            let Some(p) = target_map(&t, z) else { continue };
            mapped += 1;
            counts[t.cell_of(p).expect("inside the table")] += 1;
            // z.x moves the point within its row, z.y moves the row: det ≥ 0 everywhere.
            if let (Some(px), Some(py)) = (
                target_map(&t, z + Vec2::new(eps, 0.0)),
                target_map(&t, z + Vec2::new(0.0, eps)),
            ) {
                let (a, b) = (px - p, py - p);
                assert!(a.y == 0.0 && a.x >= 0.0, "z.x left its row at {z}: {a}");
                assert!(a.x * b.y - a.y * b.x >= 0.0, "orientation at {z}: {a} {b}");
            }
        }
        assert!(mapped as f64 > 0.999 * n as f64, "{mapped} of {n} mapped");
        // Pearson's χ² of the cell counts against the table's cell masses, over the cells
        // with an expected count of at least 5.
        let h2 = (2.0 / res as f64).powi(2);
        let (mut chi2, mut dof) = (0.0, 0usize);
        for (i, &k) in counts.iter().enumerate() {
            let e = f64::from(t.density()[i]) * h2 * mapped as f64;
            if e >= 5.0 {
                chi2 += (k as f64 - e).powi(2) / e;
                dof += 1;
            }
        }
        // The 99.9 % quantile of χ²(dof) is below dof + 4.5·√(2·dof) for these sizes.
        let bound = dof as f64 + 4.5 * (2.0 * dof as f64).sqrt();
        assert!(
            chi2 < bound,
            "χ² {chi2:.1} over {dof} cells (bound {bound:.1})"
        );
    }
}
