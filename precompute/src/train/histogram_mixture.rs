//! Histogram mixture (paper Eq. 5–7; `core/ARCHITECTURES.md` §6).
//!
//! Training model: the condition network `10 → 32 → 32 → 32 → 40` (the runtime's) gives per
//! basis `k` a logit `a_k`, a rotation `ρ_k` and a latent code `t_k = sigmoid(τ_k)`; a larger
//! basis network `H(q, t, k)` (input `[enc6(q.x), enc6(q.y), enc3(t), one-hot(k)]`, 3 hidden
//! ReLU layers of 64, softplus output) stands for the basis histograms. The model density is
//!
//! ```text
//! p(ω⊥) = Σ_k softmax(a)_k · H(R_kᵀ ω⊥, t_k, k)                                   (Eq. 5–6)
//! ```
//!
//! fitted with the L2 loss of Eq. 7 at random points (half uniform on the disk, half drawn
//! from p*), divided by the batch's mean p*² so the scale does not depend on how peaked the
//! material is, plus the quantisation term `λ ‖t − round(t·(T−1))/(T−1)‖²`, plus a
//! self-normalised NLL term ([`super::HistogramMixture::nll_weight`], default 1; 0 = the
//! paper's objective).
//!
//! Why the NLL term: with the paper's L2 objective alone the *un-baked* network is already
//! poor ([`super::network_mean_kl`] measures it), so baking (T, N, interpolation,
//! supersampling) is not what limits the model: the L2 loss is dominated by the peak of p*
//! and leaves the tails, where KL(p* ‖ p) is decided, unfitted. The NLL term (normaliser by
//! the balance heuristic, see `self_normalised_nll`) fits them; `docs/performance.md` gives the measured
//! KL with and without it.
//!
//! Training aids that leave the model unchanged: the basis output is `S·softplus(z)` with a
//! constant S ([`super::HistogramMixture::output_scale`]; the baked tables are normalised,
//! so S cancels), the basis network starts at the uniform density, and the condition network
//! can start with every basis aligned to the mirror direction
//! ([`super::HistogramMixture::aligned_init`]).
//!
//! Baking evaluates `H(·, t_j, k)` on every `(k, level j)` slice of an `N × N` grid (the mean
//! over `ss × ss` points per cell; cells entirely outside the disk are 0), records the slice
//! total `mass[k, j] = Σ_cells value · cell_area` and divides the slice by it. With
//! `w_k ∝ softmax(a)_k · mass[k, t]`, the runtime's density is then exactly the normalised,
//! cell-averaged training model.

use burn::module::Module;
use burn::tensor::activation;
use burn::tensor::{Tensor, TensorData};
use glam::{Vec2, Vec3};
use neusample::distrib::table2d::cell_outside_disk;
use neusample::nn::RAW_CONDITION_DIM;
use neusample::samplers::histogram_mixture::{self as histogram, BASES};
use neusample::Interpolation;
use neusample::{DType, SamplerKind, FEATURE_DIM};

use super::config::{Common, HistogramMixture as Config, MaxLikelihood, Schedule, TrainConfig};
use super::data::{fit, raw_condition_f64, Batch, HostBatch, PointKind, Pool};
use super::objective;
pub use super::trainer::BakedTables;
use super::trainer::{Fitted, Run, Trained, Trainer};
use crate::nn::{
    encode, infer_device, mlp_f64, softmax_f64, tensor2, to_host, train_device, Activation, Mlp,
};
use crate::util::rng::{mix_seed, rng_for};

/// Layer sizes of the condition network (the runtime's).
pub const COND_SIZES: [usize; 5] = [RAW_CONDITION_DIM, 32, 32, 32, 4 * BASES];
/// Frequency bands of the encoding of each rotated coordinate.
pub const Q_BANDS: usize = 6;
/// Frequency bands of the encoding of the latent code.
pub const T_BANDS: usize = 3;
const Q_IN: usize = 2 * (1 + 2 * Q_BANDS);
const T_IN: usize = 1 + 2 * T_BANDS;
/// Width of the basis network's hidden layers.
pub const BASIS_HIDDEN: usize = 64;
/// Layer sizes of the basis network (training only; baked into tables).
pub const BASIS_SIZES: [usize; 5] = [
    Q_IN + T_IN + BASES,
    BASIS_HIDDEN,
    BASIS_HIDDEN,
    BASIS_HIDDEN,
    1,
];

/// The training model.
#[derive(Module, Debug)]
pub struct HistogramMixture {
    /// Condition network `10 → 32 → 32 → 32 → 40`.
    pub cond: Mlp,
    /// Basis network `H(q, t, k)`.
    pub basis: Mlp,
}

/// The basis network's first-layer contribution of `(t, k)` plus its bias, for `t` `[m, K]`:
/// `[m, K, hidden]`.
fn basis_tk_share(basis: &Mlp, t: Tensor<2>) -> Tensor<3> {
    let [m, k] = t.dims();
    let et = encode(t.reshape([m * k, 1]), T_BANDS);
    let tpart = et
        .matmul(basis.first_weight_rows(Q_IN, T_IN))
        .reshape([m, k, BASIS_HIDDEN]);
    let kpart = basis
        .first_weight_rows(Q_IN + T_IN, BASES)
        .unsqueeze_dim::<3>(0);
    tpart + kpart + basis.first_bias().unsqueeze_dim::<3>(0)
}

/// The basis network's first-layer contribution of rotated points `(qx, qy)` (columns
/// `[r, 1]`): `[r, hidden]`.
fn basis_q_part(basis: &Mlp, qx: Tensor<2>, qy: Tensor<2>) -> Tensor<2> {
    let eq = Tensor::cat(vec![encode(qx, Q_BANDS), encode(qy, Q_BANDS)], 1);
    eq.matmul(basis.first_weight_rows(0, Q_IN))
}

/// Layers after the first, from the first layer's pre-activation `[r, hidden]`, with the
/// scaled softplus output `scale · softplus(z)`: `[r, 1]`.
fn basis_rest(basis: &Mlp, pre: Tensor<2>, scale: f32) -> Tensor<2> {
    let h = Mlp::hidden_act(pre, Activation::Relu);
    activation::softplus(basis.forward_from(1, h, Activation::Relu), 1.0) * scale
}

struct Heads {
    /// softmax(a) `[b, K]`.
    weights: Tensor<2>,
    cos: Tensor<2>,
    sin: Tensor<2>,
    /// Latent codes `[b, K]`.
    t: Tensor<2>,
}

fn heads(cond: &Mlp, raw: Tensor<2>) -> Heads {
    let b = raw.dims()[0];
    let o = cond.forward(raw, Activation::Relu).reshape([b, BASES, 4]);
    let get = |j: usize| o.clone().narrow(2, j, 1).reshape([b, BASES]);
    let (rx, ry) = (get(1), get(2));
    let inv = (rx.clone().powi_scalar(2) + ry.clone().powi_scalar(2) + 1e-30)
        .sqrt()
        .recip();
    Heads {
        weights: activation::softmax(get(0), 1),
        cos: rx * inv.clone(),
        sin: ry * inv,
        t: activation::sigmoid(get(3)),
    }
}

impl HistogramMixture {
    /// Training-model density `[b, s]` at the batch points and the latent codes `[b, K]`.
    fn density(&self, batch: &Batch, scale: f32) -> (Tensor<2>, Tensor<2>) {
        let (b, s) = (batch.b, batch.s);
        let h = heads(&self.cond, batch.raw.clone());
        let x = batch.x.clone().unsqueeze_dim::<3>(2);
        let y = batch.y.clone().unsqueeze_dim::<3>(2);
        let c = h.cos.clone().unsqueeze_dim::<3>(1);
        let sn = h.sin.clone().unsqueeze_dim::<3>(1);
        // q = R_kᵀ ω⊥ for every (condition, point, basis): [b, s, K].
        let qx = x.clone() * c.clone() + y.clone() * sn.clone();
        let qy = y * c - x * sn;
        let n = b * s * BASES;
        let qpart = basis_q_part(&self.basis, qx.reshape([n, 1]), qy.reshape([n, 1])).reshape([
            b,
            s,
            BASES,
            BASIS_HIDDEN,
        ]);
        let share = basis_tk_share(&self.basis, h.t.clone()).unsqueeze_dim::<4>(1);
        let pre = (qpart + share).reshape([n, BASIS_HIDDEN]);
        let hk = basis_rest(&self.basis, pre, scale).reshape([b, s, BASES]);
        let p = (hk * h.weights.unsqueeze_dim::<3>(1))
            .sum_dim(2)
            .reshape([b, s]);
        (p, h.t)
    }
}

/// The (unnormalised) training-model density `Σ_k softmax(a)_k H(R_kᵀ p, t_k, k)` with unit
/// output scale at `points`, from exported condition and basis parameters (burn, f32). The
/// baked model is this density cell-averaged, read at the nearest or interpolated latent
/// levels, and normalised; useful to check the bake.
#[must_use]
pub fn network_density(
    params: &[f32],
    basis_params: &[f32],
    phi: &[f32; FEATURE_DIM],
    wi: Vec3,
    points: &[Vec2],
) -> Vec<f32> {
    let device = infer_device();
    let model = HistogramMixture {
        cond: Mlp::from_flat(&COND_SIZES, params, &device),
        basis: Mlp::from_flat(&BASIS_SIZES, basis_params, &device),
    };
    let wi = neusample::nn::check_condition(phi, wi).unwrap_or(Vec3::Z);
    let batch = Batch::upload(HostBatch::single(phi, wi, points), &device);
    to_host(model.density(&batch, 1.0).0)
}

/// A condition network whose every basis starts aligned with the mirror direction: hidden
/// units 0–3 of each layer carry `(wi.x, −wi.x, wi.y, −wi.y)` through the ReLUs unchanged,
/// the output gives `ρ_k ≈ −wi⊥` and `τ_k ≈ 4(|wi.x| + |wi.y|) − 2.4` (so `t_k` starts as a
/// rough function of the lobe's distance from the centre); every other weight is random as
/// in [`Mlp::new`], the aligned outputs get a small random part. Only an initialisation: the
/// architecture is the runtime's. Without it the random rotations average the lobes away
/// and training sits on the uniform plateau for thousands of steps.
fn aligned_condition_init(rng: &mut rand_pcg::Pcg64, device: &burn::tensor::Device) -> Mlp {
    let mut flat = Vec::new();
    Mlp::new(&COND_SIZES, 1.0, rng, device).export(&mut flat);
    let (wx, wy) = (FEATURE_DIM, FEATURE_DIM + 1);
    let mut at = 0;
    for l in 0..COND_SIZES.len() - 1 {
        let (i_n, o_n) = (COND_SIZES[l], COND_SIZES[l + 1]);
        let (w, rest) = flat[at..].split_at_mut(i_n * o_n);
        let b = &mut rest[..o_n];
        let last = l + 2 == COND_SIZES.len();
        if !last {
            // Units 0..4: (wi.x, −wi.x, wi.y, −wi.y), from the raw inputs in layer 0 and
            // copied from units 0..4 of the previous layer afterwards.
            let src: [(usize, f32); 4] = if l == 0 {
                [(wx, 1.0), (wx, -1.0), (wy, 1.0), (wy, -1.0)]
            } else {
                [(0, 1.0), (1, 1.0), (2, 1.0), (3, 1.0)]
            };
            for (u, &(from, sign)) in src.iter().enumerate() {
                for i in 0..i_n {
                    w[i * o_n + u] = if i == from { sign } else { 0.0 };
                }
                b[u] = 0.0;
            }
        } else {
            for k in 0..BASES {
                for j in 1..4 {
                    let o = 4 * k + j;
                    for i in 0..i_n {
                        w[i * o_n + o] *= 0.1;
                    }
                    b[o] *= 0.1;
                }
                let (rx, ry, tau) = (4 * k + 1, 4 * k + 2, 4 * k + 3);
                w[rx] -= 1.0; // −h0
                w[o_n + rx] += 1.0; // +h1
                w[2 * o_n + ry] -= 1.0; // −h2
                w[3 * o_n + ry] += 1.0; // +h3
                for u in 0..4 {
                    w[u * o_n + tau] += 4.0;
                }
                b[tau] -= 2.4;
            }
        }
        at += i_n * o_n + o_n;
    }
    Mlp::from_flat(&COND_SIZES, &flat, device)
}

/// `−mean ln p(ω*) + ln Ẑ` of a regression batch `[b, s]` (even points uniform on the disk,
/// odd points drawn from p*): a Monte-Carlo estimate of `KL(p* ‖ p/Z)` up to a constant.
/// The normaliser is estimated per condition from *all* points with the balance heuristic of
/// the two point densities, `Ẑ = mean p(ω) / (½/π + ½ p*(ω))`. (An estimate from the uniform
/// points alone, `π · mean p(ω_uniform)`, misses a narrow peak of p and rewards the model for
/// making one: training then drives that estimate down while the true KL rises.)
/// Optional addition to Eq. 7 ([`super::HistogramMixture::nll_weight`]).
fn self_normalised_nll(p: Tensor<2>, target: Tensor<2>) -> Tensor<1> {
    let [b, s] = p.dims();
    let drawn = p
        .clone()
        .reshape([b, s / 2, 2])
        .narrow(2, 1, 1)
        .reshape([b, s / 2]);
    (drawn + 1e-12).log().mean().neg() + log_normaliser(p, target).mean()
}

/// `ln Ẑ` per condition `[b, 1]` of a regression batch (see [`self_normalised_nll`]).
fn log_normaliser(p: Tensor<2>, target: Tensor<2>) -> Tensor<2> {
    let q = target * 0.5 + 0.5 * std::f32::consts::FRAC_1_PI;
    ((p / q).mean_dim(1) + 1e-12).log()
}

/// The histogram mixture's trainer. Its training graph is the continuous model, not the
/// baked one: no [`Trainer::graph_log_pdf`].
pub(crate) struct HistogramMixtureTrainer;

/// The module's trainer: the histogram mixture's.
pub(crate) const TRAINERS: &[&dyn Trainer] = &[&HistogramMixtureTrainer];

impl Trainer for HistogramMixtureTrainer {
    fn kind(&self) -> SamplerKind {
        SamplerKind::HistogramMixture
    }
    fn max_likelihood(&self, _quick: bool) -> Option<MaxLikelihood> {
        None
    }
    fn schedule_mut<'c>(&self, cfg: &'c mut TrainConfig) -> &'c mut Schedule {
        &mut cfg.histogram_mixture.schedule
    }
    fn train(&self, run: Run<'_, '_>) -> anyhow::Result<Fitted> {
        let (pool, cfg) = (run.pool, run.cfg);
        let (p, t, h) = train(pool, &cfg.common, &cfg.histogram_mixture)?;
        Ok((p, Some(t), h))
    }
    /// The baked model; 0 without tables.
    fn pdf_f64(&self, t: &Trained, phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
        t.tables
            .as_ref()
            .map_or(0.0, |tables| pdf_f64(&t.params, tables, phi, wi, p))
    }
}

/// Trains the histogram mixture and bakes its tables; returns `(params, tables, history)`.
pub fn train(
    pool: &mut Pool<'_>,
    common: &Common,
    cfg: &Config,
) -> anyhow::Result<(Vec<f32>, BakedTables, Vec<f32>)> {
    anyhow::ensure!(cfg.t_levels >= 2, "t_levels must be at least 2");
    anyhow::ensure!(cfg.res >= 1, "res must be at least 1");
    anyhow::ensure!(
        cfg.points_per_condition >= 2 && cfg.points_per_condition.is_multiple_of(2),
        "points_per_condition must be even (half uniform, half from p*)"
    );
    let device = train_device();
    let mut rng = rng_for(mix_seed(common.seed, 0x4157), 0, 0);
    let mut basis = Mlp::new(&BASIS_SIZES, 1.0, &mut rng, &device);
    // Start every basis near the uniform density 1/π: S·softplus(b) = 1/π.
    let level = f64::from(std::f32::consts::FRAC_1_PI / cfg.output_scale);
    let b0 = level.exp_m1().ln() as f32;
    if let Some(last) = basis.layers.last_mut() {
        let bias = Tensor::<1>::from_data(TensorData::new(vec![b0], [1]), &device);
        last.bias = Some(burn::module::Param::from_tensor(bias));
    }
    let cond = if cfg.aligned_init {
        aligned_condition_init(&mut rng, &device)
    } else {
        Mlp::new(&COND_SIZES, 1.0, &mut rng, &device)
    };
    let model = HistogramMixture { cond, basis };
    let levels = (cfg.t_levels - 1) as f32;
    let lambda = cfg.quant_weight;
    let nll_weight = cfg.nll_weight;
    let chi2_weight = cfg.chi2_weight;
    let (model, history) = fit(
        model,
        "histogram-mixture",
        common,
        &cfg.schedule,
        pool,
        PointKind::Regression,
        (cfg.batch_conditions, cfg.points_per_condition),
        |m: &HistogramMixture, batch: &Batch| {
            let target = batch.target.clone().expect("regression batches carry p*");
            let (p, t) = m.density(batch, cfg.output_scale);
            let scale = target.clone().powi_scalar(2).mean().detach() + 1e-12;
            let l2 = (p.clone() - target.clone()).powi_scalar(2).mean() / scale;
            let tq = (t.clone().detach() * levels).round() / levels;
            let loss = l2 + (t - tq).powi_scalar(2).mean() * lambda;
            let loss = if nll_weight > 0.0 {
                loss + self_normalised_nll(p.clone(), target.clone()) * nll_weight
            } else {
                loss
            };
            if chi2_weight > 0.0 {
                // The render's measure of the self-normalised model p/Ẑ.
                let log_p = (p.clone() + 1e-12).log() - log_normaliser(p, target);
                loss + objective::log_second_moment(log_p, batch).mean() * chi2_weight
            } else {
                loss
            }
        },
    )?;
    let mut params = Vec::new();
    model.cond.export(&mut params);
    let mut basis_params = Vec::new();
    model.basis.export(&mut basis_params);
    let interpolation = if cfg.interpolate_t {
        Interpolation::Linear
    } else {
        Interpolation::Nearest
    };
    let tables = bake(
        &basis_params,
        cfg.t_levels,
        cfg.res,
        cfg.supersample.max(1),
        interpolation,
    )?;
    Ok((params, tables, history))
}

/// Bakes the basis network into `K × T × N × N` raw slices (see the module docs) and builds
/// the normalised tables and running sums with core's `bake_slices` (f32 storage).
pub fn bake(
    basis_params: &[f32],
    t_levels: usize,
    res: usize,
    supersample: usize,
    interpolation: Interpolation,
) -> anyhow::Result<BakedTables> {
    let device = infer_device();
    let basis = Mlp::from_flat(&BASIS_SIZES, basis_params, &device);
    let ss = supersample.max(1);
    let cell = 2.0 / res as f32;
    // Points: ss × ss per cell, cells in row-major order (only those touching the disk).
    let open: Vec<usize> = (0..res * res)
        .filter(|&i| !cell_outside_disk((i / res) as u32, (i % res) as u32, res as u32))
        .collect();
    let mut qx = Vec::with_capacity(open.len() * ss * ss);
    let mut qy = Vec::with_capacity(open.len() * ss * ss);
    for &i in &open {
        let (r, c) = (i / res, i % res);
        for a in 0..ss {
            for bb in 0..ss {
                qx.push(-1.0 + cell * (c as f32 + (bb as f32 + 0.5) / ss as f32));
                qy.push(-1.0 + cell * (r as f32 + (a as f32 + 0.5) / ss as f32));
            }
        }
    }
    let np = qx.len();
    let qpart = basis_q_part(
        &basis,
        tensor2(qx, np, 1, &device),
        tensor2(qy, np, 1, &device),
    );
    let tl: Vec<f32> = (0..t_levels)
        .map(|j| j as f32 / (t_levels - 1) as f32)
        .collect();
    // [T, K, hidden] → slice order (k, j).
    let share = basis_tk_share(
        &basis,
        tensor2(tl, t_levels, 1, &device).repeat_dim(1, BASES),
    )
    .swap_dims(0, 1)
    .reshape([BASES * t_levels, BASIS_HIDDEN]);
    let slices = BASES * t_levels;
    let mut raw = vec![0.0f32; slices * res * res];
    let chunk = (1usize << 17).div_ceil(np.max(1)).clamp(1, slices);
    let qpart3 = qpart.unsqueeze_dim::<3>(0);
    let mut first = 0;
    while first < slices {
        let m = chunk.min(slices - first);
        let sh = share.clone().narrow(0, first, m).unsqueeze_dim::<3>(1);
        let pre = (qpart3.clone() + sh).reshape([m * np, BASIS_HIDDEN]);
        let vals = to_host(basis_rest(&basis, pre, 1.0));
        for sl in 0..m {
            let out = &mut raw[(first + sl) * res * res..(first + sl + 1) * res * res];
            for (o, &i) in open.iter().enumerate() {
                let at = sl * np + o * ss * ss;
                let mean: f64 = vals[at..at + ss * ss]
                    .iter()
                    .map(|&v| f64::from(v))
                    .sum::<f64>()
                    / (ss * ss) as f64;
                out[i] = mean as f32;
            }
        }
        first += m;
    }
    let baked = histogram::try_bake_slices(&raw, BASES, t_levels, res, DType::F32)
        .map_err(|e| anyhow::anyhow!("baking the histogram mixture: {e}"))?;
    Ok(BakedTables {
        baked,
        interpolation,
        raw,
        basis_params: basis_params.to_vec(),
    })
}

/// Density (projected-disk area measure) of the baked histogram mixture at `p` — the model
/// the runtime evaluates: condition network in f64 from `params`, then the tables. `wi` must
/// already be normalised. 0 outside the open unit disk.
#[must_use]
pub fn pdf_f64(
    params: &[f32],
    tables: &BakedTables,
    phi: &[f32; FEATURE_DIM],
    wi: Vec3,
    p: Vec2,
) -> f64 {
    if !(p.length_squared() < 1.0) {
        return 0.0;
    }
    let r = raw_condition_f64(phi, wi);
    let mut at = 0;
    let o = mlp_f64(params, &mut at, &COND_SIZES, Activation::Relu, &r);
    let a: Vec<f64> = (0..BASES).map(|k| o[4 * k]).collect();
    let sm = softmax_f64(&a);
    let b = &tables.baked;
    let (tn, n) = (b.t_levels as usize, b.resolution as usize);
    let slice = n * n;
    let mut num = 0.0;
    let mut den = 0.0;
    for k in 0..BASES {
        let (rx, ry, tau) = (o[4 * k + 1], o[4 * k + 2], o[4 * k + 3]);
        let len = (rx * rx + ry * ry).sqrt();
        let (cs, sn) = if len * len < 1e-24 {
            (1.0, 0.0)
        } else {
            (rx / len, ry / len)
        };
        let (px, py) = (f64::from(p.x), f64::from(p.y));
        let q = Vec2::new((cs * px + sn * py) as f32, (-sn * px + cs * py) as f32);
        let t = 1.0 / (1.0 + (-tau).exp());
        let sc = t * (tn - 1) as f64;
        let levels: [(usize, f64); 2] = if tables.interpolation == Interpolation::Linear {
            let j0 = (sc.floor() as usize).min(tn - 2);
            let f = sc - j0 as f64;
            [(j0, 1.0 - f), (j0 + 1, f)]
        } else {
            [(((sc + 0.5).floor() as usize).min(tn - 1), 1.0), (0, 0.0)]
        };
        // The runtime reads each basis on the closed square (cells outside the disk are 0).
        let cell = if q.x.abs() <= 1.0 && q.y.abs() <= 1.0 {
            let f = |v: f32| (((v + 1.0) * 0.5 * n as f32).floor().max(0.0) as usize).min(n - 1);
            Some(f(q.y) * n + f(q.x))
        } else {
            None
        };
        // Interpolated weight and histogram of basis k.
        let mk: f64 = levels
            .iter()
            .map(|&(j, f)| f * f64::from(b.mass[k * tn + j]))
            .sum();
        if let Some(c) = cell {
            let hk: f64 = levels
                .iter()
                .map(|&(j, f)| f * f64::from(b.table[(k * tn + j) * slice + c]))
                .sum();
            num += sm[k] * mk * hk;
        }
        den += sm[k] * mk;
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}
