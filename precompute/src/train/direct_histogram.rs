//! Direct histogram baseline (Zhu et al. 2021; `core/ARCHITECTURES.md` §5): MLP
//! `30 → 64 → 64 → 256` predicting the logits of a 16 × 16 grid over `[−1, 1]²` (row = y
//! index, column = x index). Cells entirely outside the unit disk are masked out, the others
//! get softmax probabilities `P_rc`, and `p(ω⊥) = P_rc / cell_area` inside the disk.
//!
//! Trained by maximum likelihood of ground-truth samples (equivalently, cross-entropy
//! between the target's cell masses and `P`).

use burn::module::Module;
use burn::tensor::activation;
use burn::tensor::{Int, Tensor, TensorData};
use glam::{Vec2, Vec3};
use neusample::distrib::table2d::cell_outside_disk;
use neusample::nn::CONDITION_DIM;
use neusample::samplers::direct_histogram::DIRECT_N;
use neusample::{SamplerKind, FEATURE_DIM};

use super::config::{Common, MaxLikelihood};
use super::data::{encoded_condition_f64, Batch, Pool};
use super::trainer::{train_max_likelihood, ExportParams, Fitted, Run, Trained, Trainer};
use crate::nn::{mlp_f64, softmax_f64, tensor2, train_device, Activation, Mlp};
use crate::util::rng::{mix_seed, rng_for};

/// Grid resolution (cells per side).
pub const GRID: usize = DIRECT_N;
/// Layer sizes.
pub const SIZES: [usize; 4] = [CONDITION_DIM, 64, 64, GRID * GRID];
/// Logit offset of masked cells: `exp` of it underflows to exactly 0 in f32.
const MASKED: f32 = -1.0e4;

/// `true` for cells lying entirely outside the unit disk (core's mask).
#[must_use]
pub fn masked(r: usize, c: usize) -> bool {
    cell_outside_disk(r as u32, c as u32, GRID as u32)
}

/// The cell index `r·16 + c` of a point of `[−1, 1]²`.
#[must_use]
pub fn cell_index(p: Vec2) -> usize {
    let f = |v: f32| (((v + 1.0) * 0.5 * GRID as f32).floor().max(0.0) as usize).min(GRID - 1);
    f(p.y) * GRID + f(p.x)
}

/// The network.
#[derive(Module, Debug)]
pub struct DirectHistogram {
    /// `30 → 64 → 64 → 256`.
    pub net: Mlp,
}

impl ExportParams for DirectHistogram {
    fn export_params(&self) -> Vec<f32> {
        let mut params = Vec::new();
        self.net.export(&mut params);
        params
    }
}

/// Per-point log density `[b, s]` of the network `net` at the batch points.
fn log_pdf(net: &Mlp, batch: &Batch) -> Tensor<2> {
    let device = batch.x.device();
    let mask: Vec<f32> = (0..GRID * GRID)
        .map(|i| {
            if masked(i / GRID, i % GRID) {
                MASKED
            } else {
                0.0
            }
        })
        .collect();
    let mask = tensor2(mask, 1, GRID * GRID, &device);
    let ln_area = (2.0f32 / GRID as f32).powi(2).ln();
    let logits = net.forward(batch.cond.clone(), Activation::Relu) + mask;
    let logp = activation::log_softmax(logits, 1);
    let idx: Vec<i64> = batch
        .host
        .x
        .iter()
        .zip(&batch.host.y)
        .map(|(&x, &y)| cell_index(Vec2::new(x, y)) as i64)
        .collect();
    let idx = Tensor::<2, Int>::from_data(TensorData::new(idx, [batch.b, batch.s]), &device);
    logp.gather(1, idx) - ln_area
}

/// Per-point log density `[b, s]` of the training graph for exported parameters.
pub fn graph_log_pdf(params: &[f32], batch: &Batch) -> Tensor<2> {
    log_pdf(&Mlp::from_flat(&SIZES, params, &batch.x.device()), batch)
}

/// The direct histogram's trainer.
pub(crate) struct DirectHistogramTrainer;

/// The module's trainer: the direct histogram's.
pub(crate) const TRAINERS: &[&dyn Trainer] = &[&DirectHistogramTrainer];

impl Trainer for DirectHistogramTrainer {
    fn kind(&self) -> SamplerKind {
        SamplerKind::DirectHistogram
    }
    fn train(&self, run: Run<'_, '_>) -> anyhow::Result<Fitted> {
        let (pool, cfg) = (run.pool, run.cfg);
        let (p, h) = train(pool, &cfg.common, &cfg.max_likelihood[self.kind()])?;
        Ok((p, None, h))
    }
    fn pdf_f64(&self, t: &Trained, phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
        pdf_f64(&t.params, phi, wi, p)
    }
    fn graph(&self, params: &[f32], batch: &Batch) -> Option<Tensor<2>> {
        Some(graph_log_pdf(params, batch))
    }
}

/// Trains the direct histogram; returns `(params, loss history)`.
pub fn train(
    pool: &mut Pool<'_>,
    common: &Common,
    cfg: &MaxLikelihood,
) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
    let device = train_device();
    let mut rng = rng_for(mix_seed(common.seed, 0xd1e), 0, 0);
    let model = DirectHistogram {
        net: Mlp::new(&SIZES, 0.1, &mut rng, &device),
    };
    train_max_likelihood(model, "direct-histogram", pool, common, cfg, |m, b| {
        log_pdf(&m.net, b)
    })
}

/// Density (projected-disk area measure) of a trained direct histogram at `p`, in f64 from
/// the exported parameters; `wi` must already be normalised. 0 outside the open unit disk.
#[must_use]
pub fn pdf_f64(params: &[f32], phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
    if !(p.length_squared() < 1.0) {
        return 0.0;
    }
    let c = encoded_condition_f64(phi, wi);
    let mut at = 0;
    let o = mlp_f64(params, &mut at, &SIZES, Activation::Relu, &c);
    let open: Vec<usize> = (0..GRID * GRID)
        .filter(|&i| !masked(i / GRID, i % GRID))
        .collect();
    let logits: Vec<f64> = open.iter().map(|&i| o[i]).collect();
    let prob = softmax_f64(&logits);
    let cell = cell_index(p);
    let area = (2.0 / GRID as f64).powi(2);
    open.iter()
        .position(|&i| i == cell)
        .map_or(0.0, |j| prob[j] / area)
}
