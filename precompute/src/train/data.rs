//! Training data: a pool of ground-truth conditions refreshed during training, the per-step
//! batches drawn from it, and the loop that feeds them to the optimiser.
//!
//! Every random number is drawn from a PCG stream seeded by `(seed, step, index)`, so a batch
//! does not depend on how rayon schedules its construction.

use burn::module::Module;
use burn::tensor::{Device, Tensor};
use glam::{Vec2, Vec3};
use neusample::nn::{check_condition, encode_condition, raw_condition};
use neusample::nn::{CONDITION_DIM, RAW_CONDITION_DIM};
use neusample::FEATURE_DIM;
use rand::RngExt;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::config::{Common, Schedule};
use super::source::{GtCondition, TargetSource};
use crate::groundtruth::{TargetOptions, TargetPdf};
use crate::nn::{optimise, tensor2, train_device};
use crate::util::rng::{mix_seed, rng_for};

/// The conditions training draws its batches from. A quarter of the pool is replaced by
/// fresh conditions every `refresh_every` steps, so long runs see many more conditions than
/// the pool holds at once.
pub struct Pool<'a> {
    source: &'a dyn TargetSource,
    items: Vec<GtCondition>,
    res: usize,
    seed: u64,
    refresh_every: usize,
    opts: TargetOptions,
    round: u64,
    cursor: usize,
}

impl<'a> Pool<'a> {
    /// Draws the initial `size` conditions, their targets tabulated with `opts`.
    pub fn new(
        source: &'a dyn TargetSource,
        size: usize,
        res: usize,
        seed: u64,
        refresh_every: usize,
        opts: TargetOptions,
    ) -> anyhow::Result<Self> {
        anyhow::ensure!(
            size > 0,
            "the ground-truth pool needs at least one condition"
        );
        let items = source.draw_with(size, res, mix_seed(seed, 0), &opts)?;
        anyhow::ensure!(
            items.len() == size,
            "the ground-truth source returned {} conditions instead of {size}",
            items.len()
        );
        Ok(Pool {
            source,
            items,
            res,
            seed,
            refresh_every,
            opts,
            round: 0,
            cursor: 0,
        })
    }

    /// Replaces a quarter of the pool when `step` is a refresh step (not step 0).
    pub fn maybe_refresh(&mut self, step: usize) -> anyhow::Result<()> {
        if self.refresh_every == 0 || step == 0 || !step.is_multiple_of(self.refresh_every) {
            return Ok(());
        }
        self.round += 1;
        let n = self.items.len().div_ceil(4);
        let fresh =
            self.source
                .draw_with(n, self.res, mix_seed(self.seed, self.round), &self.opts)?;
        for g in fresh {
            let i = self.cursor;
            self.items[i] = g;
            self.cursor = (self.cursor + 1) % self.items.len();
        }
        Ok(())
    }

    /// The conditions.
    #[must_use]
    pub fn items(&self) -> &[GtCondition] {
        &self.items
    }
}

/// The conditions of training step `step`'s batch: `b` of `items`, drawn with replacement
/// from the random stream `stream` (the caller's seed mixed with its salt).
fn pick_from(items: &[GtCondition], b: usize, stream: u64, step: usize) -> Vec<&GtCondition> {
    let mut rng = rng_for(stream, step as u64, 0);
    (0..b)
        .map(|_| &items[rng.random_range(0..items.len())])
        .collect()
}

/// `row(rng, condition, wi)` for each of `b` conditions drawn with replacement from `items`
/// for `step` (the stream of `seed` mixed with `salts.0`), in parallel. Row `j` draws from
/// its own stream (`seed` mixed with `salts.1`, at `step` and `j`) and gets its condition's
/// `wi` as the runtime checks it (`+z` where the runtime refuses the condition).
pub fn map_picked_from<R: Send>(
    items: &[GtCondition],
    b: usize,
    seed: u64,
    salts: (u64, u64),
    step: usize,
    row: impl Fn(&mut Pcg64, &GtCondition, Vec3) -> R + Sync + Send,
) -> Vec<R> {
    let chosen = pick_from(items, b, mix_seed(seed, salts.0), step);
    chosen
        .par_iter()
        .enumerate()
        .map(|(j, g)| {
            let mut rng = rng_for(mix_seed(seed, salts.1), step as u64, j as u64);
            let wi = check_condition(&g.phi, g.wi).unwrap_or(Vec3::Z);
            row(&mut rng, g, wi)
        })
        .collect()
}

/// How the points of a batch are chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PointKind {
    /// Samples of p* (maximum likelihood, paper §3 "Fitting").
    FromTarget,
    /// Half uniform on the disk, half from p*, each with its target value p*(ω⊥) (the L2
    /// regression of the histogram mixture, Eq. 7).
    Regression,
}

/// One training batch, host side: `b` conditions × `s` points.
pub struct HostBatch {
    /// Number of conditions.
    pub b: usize,
    /// Points per condition.
    pub s: usize,
    /// Encoded conditions, `b × CONDITION_DIM`.
    pub cond: Vec<f32>,
    /// Raw conditions, `b × RAW_CONDITION_DIM`.
    pub raw: Vec<f32>,
    /// Point x coordinates, `b × s`.
    pub x: Vec<f32>,
    /// Point y coordinates, `b × s`.
    pub y: Vec<f32>,
    /// p* at the points (only for [`PointKind::Regression`]), `b × s`.
    pub target: Vec<f32>,
}

impl HostBatch {
    /// One condition `(φ, wi)` (`wi` already checked) with `points` and no targets: the
    /// training graph evaluated at chosen points.
    #[must_use]
    pub fn single(phi: &[f32; FEATURE_DIM], wi: Vec3, points: &[Vec2]) -> HostBatch {
        HostBatch {
            b: 1,
            s: points.len(),
            cond: encode_condition(phi, wi).to_vec(),
            raw: raw_condition(phi, wi).to_vec(),
            x: points.iter().map(|p| p.x).collect(),
            y: points.iter().map(|p| p.y).collect(),
            target: Vec::new(),
        }
    }
}

/// The encoded condition of the lobe, flow and direct-histogram networks in f64 (for the
/// f64 mirrors of trained models).
#[must_use]
pub fn encoded_condition_f64(phi: &[f32; FEATURE_DIM], wi: Vec3) -> Vec<f64> {
    encode_condition(phi, wi)
        .iter()
        .map(|&v| f64::from(v))
        .collect()
}

/// The raw condition of the histogram networks in f64.
#[must_use]
pub fn raw_condition_f64(phi: &[f32; FEATURE_DIM], wi: Vec3) -> Vec<f64> {
    raw_condition(phi, wi)
        .iter()
        .map(|&v| f64::from(v))
        .collect()
}

/// A uniform point on the open unit disk.
fn uniform_disk(rng: &mut Pcg64) -> Vec2 {
    loop {
        let p = Vec2::new(
            rng.random_range(-1.0f32..1.0),
            rng.random_range(-1.0f32..1.0),
        );
        if p.length_squared() < 1.0 {
            return p;
        }
    }
}

fn sample_target(t: &TargetPdf, rng: &mut Pcg64) -> Vec2 {
    for _ in 0..64 {
        let u = Vec2::new(rng.random(), rng.random());
        if let Some(p) = t.sample(u) {
            if p.is_finite() && p.length_squared() < 1.0 {
                return p;
            }
        }
    }
    // A target without samples: fall back to uniform points (never seen with real data).
    uniform_disk(rng)
}

/// Builds the batch of `step`: `b` pool conditions (with replacement) × `s` points.
pub fn make_batch(
    pool: &Pool<'_>,
    b: usize,
    s: usize,
    kind: PointKind,
    seed: u64,
    step: usize,
) -> HostBatch {
    let items = pool.items();
    let rows = map_picked_from(items, b, seed, (0xba7c, 0x9017), step, |rng, g, wi| {
        let cond = encode_condition(&g.phi, wi);
        let raw = raw_condition(&g.phi, wi);
        let mut xs = Vec::with_capacity(s);
        let mut ys = Vec::with_capacity(s);
        let mut ts = Vec::new();
        for k in 0..s {
            let p = match kind {
                PointKind::FromTarget => sample_target(&g.target, rng),
                PointKind::Regression if k % 2 == 0 => uniform_disk(rng),
                PointKind::Regression => sample_target(&g.target, rng),
            };
            xs.push(p.x);
            ys.push(p.y);
            if kind == PointKind::Regression {
                ts.push(g.target.pdf(p));
            }
        }
        (cond, raw, xs, ys, ts)
    });
    let mut out = HostBatch {
        b,
        s,
        cond: Vec::with_capacity(b * CONDITION_DIM),
        raw: Vec::with_capacity(b * RAW_CONDITION_DIM),
        x: Vec::with_capacity(b * s),
        y: Vec::with_capacity(b * s),
        target: Vec::new(),
    };
    for (cond, raw, xs, ys, ts) in rows {
        out.cond.extend_from_slice(&cond);
        out.raw.extend_from_slice(&raw);
        out.x.extend(xs);
        out.y.extend(ys);
        out.target.extend(ts);
    }
    out
}

/// A batch on the training device.
pub struct Batch {
    /// Number of conditions.
    pub b: usize,
    /// Points per condition.
    pub s: usize,
    /// Encoded conditions `[b, 30]`.
    pub cond: Tensor<2>,
    /// Raw conditions `[b, 10]`.
    pub raw: Tensor<2>,
    /// Point coordinates `[b, s]`.
    pub x: Tensor<2>,
    /// Point coordinates `[b, s]`.
    pub y: Tensor<2>,
    /// p* at the points `[b, s]` (regression batches only).
    pub target: Option<Tensor<2>>,
    /// The host copy (for index computations done on the CPU).
    pub host: HostBatch,
}

impl Batch {
    /// Uploads a host batch to `device`.
    pub fn upload(host: HostBatch, device: &Device) -> Self {
        let (b, s) = (host.b, host.s);
        let cond = tensor2(host.cond.clone(), b, CONDITION_DIM, device);
        let raw = tensor2(host.raw.clone(), b, RAW_CONDITION_DIM, device);
        let x = tensor2(host.x.clone(), b, s, device);
        let y = tensor2(host.y.clone(), b, s, device);
        let target = if host.target.is_empty() {
            None
        } else {
            Some(tensor2(host.target.clone(), b, s, device))
        };
        Batch {
            b,
            s,
            cond,
            raw,
            x,
            y,
            target,
            host,
        }
    }
}

/// Minimises `loss` over the schedule's steps with the optimiser of [`crate::nn::optimise`];
/// step `s` trains on the batch of step `s` (`batch.0` pool conditions × `batch.1` points of
/// `kind`), refreshing the pool first when due. Returns the model and the loss of every step.
pub fn fit<M: Module>(
    model: M,
    name: &str,
    common: &Common,
    schedule: &Schedule,
    pool: &mut Pool<'_>,
    kind: PointKind,
    batch: (usize, usize),
    loss: impl Fn(&M, &Batch) -> Tensor<1>,
) -> anyhow::Result<(M, Vec<f32>)> {
    let device = train_device();
    optimise(model, &common.optim_settings(name, schedule), |m, step| {
        pool.maybe_refresh(step)?;
        let host = make_batch(pool, batch.0, batch.1, kind, common.seed, step);
        Ok(loss(m, &Batch::upload(host, &device)))
    })
}
