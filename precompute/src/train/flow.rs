//! Flows (`core/ARCHITECTURES.md` §3–4), trained by maximum likelihood of ground-truth
//! samples in the density direction `ω⊥ → z`:
//!
//! * the paper's conditional RQ-spline flow (Eq. 3–4): base network `30 → 32 → 4`
//!   (diagonal Gaussian), coupling 1 transforms y given `[c, enc4(x)]`, then coupling 0
//!   transforms x given `[c, enc4(y')]`, each `39 → 32 → 32 → 59` with LeakyReLU(0.01);
//! * the affine-coupling baseline (Xie et al. 2019): four layers `39 → 32 → 32 → 2` (ReLU),
//!   layer `l` transforms coordinate `l mod 2`, `v ← v·eˢ + t`, `s = 4 tanh(s_raw/4)`,
//!   standard normal base.
//!
//! The condition's share of each coupling network's first layer is computed once per
//! condition and broadcast over its samples, like the runtime's `prepare`.

use burn::module::Module;
use burn::tensor::Tensor;
use glam::{Vec2, Vec3};
use neusample::distrib::gaussian::{LOG_SIGMA_MAX, LOG_SIGMA_MIN};
use neusample::nn::CONDITION_DIM;
use neusample::samplers::affine_flow::{
    AFFINE_LAYERS, AFFINE_NET_LEN, AFFINE_OUTPUTS, AFFINE_SCALE_BOUND,
};
use neusample::samplers::disk_flow::{
    DISK_FLOW_BINS, DISK_FLOW_COUPLING0, DISK_FLOW_COUPLING1, DISK_NET_LEN, DISK_SPLINE_RAW_LEN,
};
use neusample::samplers::spline_flow::{
    BASE_OUTPUTS, COUPLING_INPUTS, FLOW_BASE_LEN, FLOW_COUPLING0, FLOW_COUPLING1, HIDDEN,
    OTHER_BANDS, SPLINE_BINS, SPLINE_NET_LEN, SPLINE_RAW_LEN, TAIL_BOUND,
};
use neusample::{SamplerKind, FEATURE_DIM};

use super::config::{Common, MaxLikelihood};
use super::data::{encoded_condition_f64, fit, Batch, PointKind, Pool};
use super::spline::{rq_forward, rq_forward_f64, rq_forward_free, rq_forward_free_f64};
use super::trainer::{train_max_likelihood, ExportParams, Fitted, Run, Trained, Trainer};
use crate::nn::{self, encode, encode_f64, mlp_f64, train_device, Activation, Mlp};
use crate::util::rng::{mix_seed, rng_for};

const LN_TWO_PI: f32 = 1.837_877_1;
const LN_PI: f32 = 1.144_729_9;

/// Layer sizes of the flow's base network.
pub const BASE_SIZES: [usize; 3] = [CONDITION_DIM, HIDDEN, BASE_OUTPUTS];
/// Layer sizes of a spline coupling network.
pub const SPLINE_NET_SIZES: [usize; 4] = [COUPLING_INPUTS, HIDDEN, HIDDEN, SPLINE_RAW_LEN];
/// Layer sizes of a disk-flow coupling network.
pub const DISK_NET_SIZES: [usize; 4] = [COUPLING_INPUTS, HIDDEN, HIDDEN, DISK_SPLINE_RAW_LEN];
/// Layer sizes of an affine coupling network.
pub const AFFINE_NET_SIZES: [usize; 4] = [COUPLING_INPUTS, HIDDEN, HIDDEN, AFFINE_OUTPUTS];

const _: () = {
    assert!(nn::mlp_len(&BASE_SIZES) == FLOW_BASE_LEN);
    assert!(nn::mlp_len(&SPLINE_NET_SIZES) == SPLINE_NET_LEN);
    assert!(nn::mlp_len(&AFFINE_NET_SIZES) == AFFINE_NET_LEN);
    assert!(nn::mlp_len(&DISK_NET_SIZES) == DISK_NET_LEN);
    assert!(DISK_FLOW_COUPLING0 == 0 && DISK_FLOW_COUPLING1 == DISK_NET_LEN);
    assert!(FLOW_COUPLING1 == FLOW_COUPLING0 + SPLINE_NET_LEN);
};

/// Runs a coupling network on `[b·s]` points: the condition part of the first layer from
/// `cond` `[b, 30]`, broadcast over the `s` points, plus the encoded other coordinate
/// `other` `[b, s]`. Returns the raw outputs `[b·s, O]`.
fn coupling(net: &Mlp, cond: &Tensor<2>, other: Tensor<2>, act: Activation) -> Tensor<2> {
    let [b, s] = other.dims();
    let share = cond.clone().matmul(net.first_weight_rows(0, CONDITION_DIM)) + net.first_bias();
    let e = encode(other.reshape([b * s, 1]), OTHER_BANDS);
    let part = e.matmul(net.first_weight_rows(CONDITION_DIM, COUPLING_INPUTS - CONDITION_DIM));
    let h = part.reshape([b, s, HIDDEN]) + share.unsqueeze_dim::<3>(1);
    let h = Mlp::hidden_act(h.reshape([b * s, HIDDEN]), act);
    net.forward_from(1, h, act)
}

/// The RQ-spline flow.
#[derive(Module, Debug)]
pub struct SplineFlow {
    /// Base network `30 → 32 → 4`.
    pub base: Mlp,
    /// Coupling network 0 (transforms x).
    pub c0: Mlp,
    /// Coupling network 1 (transforms y).
    pub c1: Mlp,
}

impl SplineFlow {
    /// The flow from exported parameters.
    pub fn from_flat(params: &[f32], device: &burn::tensor::Device) -> Self {
        SplineFlow {
            base: Mlp::from_flat(&BASE_SIZES, &params[..FLOW_BASE_LEN], device),
            c0: Mlp::from_flat(&SPLINE_NET_SIZES, &params[FLOW_COUPLING0..], device),
            c1: Mlp::from_flat(&SPLINE_NET_SIZES, &params[FLOW_COUPLING1..], device),
        }
    }

    /// Per-point log density `[b, s]`.
    pub fn log_pdf(&self, batch: &Batch) -> Tensor<2> {
        let (b, s) = (batch.b, batch.s);
        let raw1 = coupling(
            &self.c1,
            &batch.cond,
            batch.x.clone(),
            Activation::LeakyRelu,
        );
        let (yl, ld1) = rq_forward(
            batch.y.clone().reshape([b * s, 1]),
            raw1,
            SPLINE_BINS,
            TAIL_BOUND,
        );
        let yl = yl.reshape([b, s]);
        let raw0 = coupling(&self.c0, &batch.cond, yl.clone(), Activation::LeakyRelu);
        let (xl, ld0) = rq_forward(
            batch.x.clone().reshape([b * s, 1]),
            raw0,
            SPLINE_BINS,
            TAIL_BOUND,
        );
        let xl = xl.reshape([b, s]);
        let o = self.base.forward(batch.cond.clone(), Activation::Relu);
        let mx = o.clone().narrow(1, 0, 1);
        let my = o.clone().narrow(1, 1, 1);
        let lsx = nn::clamp_log_sigma(o.clone().narrow(1, 2, 1));
        let lsy = nn::clamp_log_sigma(o.narrow(1, 3, 1));
        let dx = (xl - mx) * lsx.clone().neg().exp();
        let dy = (yl - my) * lsy.clone().neg().exp();
        let lbase = (dx.powi_scalar(2) + dy.powi_scalar(2)) * (-0.5) - LN_TWO_PI - lsx - lsy;
        lbase + (ld0 + ld1).reshape([b, s])
    }
}

impl ExportParams for SplineFlow {
    fn export_params(&self) -> Vec<f32> {
        let mut params = Vec::with_capacity(FLOW_COUPLING1 + SPLINE_NET_LEN);
        self.base.export(&mut params);
        self.c0.export(&mut params);
        self.c1.export(&mut params);
        params
    }
}

/// The disk flow (`core/ARCHITECTURES.md` §9): uniform base on the disk, two spline couplings
/// on chords.
#[derive(Module, Debug)]
pub struct DiskFlow {
    /// Coupling network 0 (transforms x given the base point's y).
    pub c0: Mlp,
    /// Coupling network 1 (transforms y given x).
    pub c1: Mlp,
}

/// `√((1 − v)(1 + v))` (as the runtime computes it, precise at the rim), kept away from 0 so
/// that its gradient stays finite there.
fn chord(v: Tensor<2>) -> Tensor<2> {
    ((v.clone().neg() + 1.0) * (v + 1.0))
        .clamp_min(1e-12)
        .sqrt()
}

impl DiskFlow {
    /// The flow from exported parameters.
    pub fn from_flat(params: &[f32], device: &burn::tensor::Device) -> Self {
        DiskFlow {
            c0: Mlp::from_flat(&DISK_NET_SIZES, &params[DISK_FLOW_COUPLING0..], device),
            c1: Mlp::from_flat(&DISK_NET_SIZES, &params[DISK_FLOW_COUPLING1..], device),
        }
    }

    /// Per-point log density `[b, s]` (density direction, `DiskFlowPrepared::to_base`).
    pub fn log_pdf(&self, batch: &Batch) -> Tensor<2> {
        let (b, s) = (batch.b, batch.s);
        let (x, y) = (batch.x.clone(), batch.y.clone());
        let cy = chord(x.clone());
        let eta = (y / cy.clone()).clamp(-1.0, 1.0);
        let raw1 = coupling(&self.c1, &batch.cond, x.clone(), Activation::LeakyRelu);
        let (sy, ld1) = rq_forward_free(eta.reshape([b * s, 1]), raw1, DISK_FLOW_BINS);
        let yb = cy * sy.reshape([b, s]);
        let xi = (x / chord(yb.clone())).clamp(-1.0, 1.0);
        let raw0 = coupling(&self.c0, &batch.cond, yb, Activation::LeakyRelu);
        let (_, ld0) = rq_forward_free(xi.reshape([b * s, 1]), raw0, DISK_FLOW_BINS);
        (ld0 + ld1).reshape([b, s]) - LN_PI
    }
}

impl ExportParams for DiskFlow {
    fn export_params(&self) -> Vec<f32> {
        let mut params = Vec::with_capacity(2 * DISK_NET_LEN);
        self.c0.export(&mut params);
        self.c1.export(&mut params);
        params
    }
}

/// The affine-coupling flow.
#[derive(Module, Debug)]
pub struct AffineFlow {
    /// Coupling networks, layer 0..3.
    pub nets: Vec<Mlp>,
}

impl ExportParams for AffineFlow {
    fn export_params(&self) -> Vec<f32> {
        let mut params = Vec::with_capacity(AFFINE_LAYERS * AFFINE_NET_LEN);
        for net in &self.nets {
            net.export(&mut params);
        }
        params
    }
}

impl AffineFlow {
    /// The flow from exported parameters.
    pub fn from_flat(params: &[f32], device: &burn::tensor::Device) -> Self {
        AffineFlow {
            nets: (0..AFFINE_LAYERS)
                .map(|l| Mlp::from_flat(&AFFINE_NET_SIZES, &params[l * AFFINE_NET_LEN..], device))
                .collect(),
        }
    }

    /// Per-point log density `[b, s]`.
    pub fn log_pdf(&self, batch: &Batch) -> Tensor<2> {
        let (b, s) = (batch.b, batch.s);
        let mut x = batch.x.clone();
        let mut y = batch.y.clone();
        let mut ld: Option<Tensor<2>> = None;
        for (l, net) in self.nets.iter().enumerate() {
            let other = if l % 2 == 0 { y.clone() } else { x.clone() };
            let o = coupling(net, &batch.cond, other, Activation::Relu);
            let sc = (o.clone().narrow(1, 0, 1) / AFFINE_SCALE_BOUND).tanh() * AFFINE_SCALE_BOUND;
            let sc = sc.reshape([b, s]);
            let t = o.narrow(1, 1, 1).reshape([b, s]);
            if l % 2 == 0 {
                x = x * sc.clone().exp() + t;
            } else {
                y = y * sc.clone().exp() + t;
            }
            ld = Some(match ld {
                Some(acc) => acc + sc,
                None => sc,
            });
        }
        let lbase = (x.powi_scalar(2) + y.powi_scalar(2)) * (-0.5) - LN_TWO_PI;
        match ld {
            Some(ld) => lbase + ld,
            None => lbase,
        }
    }
}

/// The trainer of one of the three flows.
pub(crate) enum FlowTrainer {
    /// The RQ-spline flow.
    Spline,
    /// The disk flow.
    Disk,
    /// The affine-coupling flow.
    Affine,
}

/// The module's trainers: the RQ-spline flow's, the disk flow's and the affine flow's.
pub(crate) const TRAINERS: &[&dyn Trainer] = &[
    &FlowTrainer::Spline,
    &FlowTrainer::Disk,
    &FlowTrainer::Affine,
];

/// The disk flow's blob-check tolerance within 1e-2 of a pole of the disk (`|y| > 0.99`),
/// where `1 ± y/C(x)` cancels in f32 before the second spline sees it
/// (`host_tests/tests/flow.rs` measures it against an f64 reference).
pub const DISK_POLE_TOLERANCE: f64 = 1e-2;

impl Trainer for FlowTrainer {
    fn kind(&self) -> SamplerKind {
        match self {
            FlowTrainer::Spline => SamplerKind::SplineFlow,
            FlowTrainer::Disk => SamplerKind::DiskFlow,
            FlowTrainer::Affine => SamplerKind::AffineFlow,
        }
    }
    /// The flows' default run is shorter than the lobe mixtures', at a lower learning rate
    /// for the affine flow.
    fn max_likelihood(&self, quick: bool) -> Option<MaxLikelihood> {
        Some(match self {
            _ if quick => MaxLikelihood::quick(),
            FlowTrainer::Spline | FlowTrainer::Disk => MaxLikelihood::with_schedule(2000, 5e-3),
            FlowTrainer::Affine => MaxLikelihood::with_schedule(2000, 4e-3),
        })
    }
    fn fine_tunes_chi2(&self) -> bool {
        matches!(self, FlowTrainer::Spline | FlowTrainer::Disk)
    }
    fn train(&self, run: Run<'_, '_>) -> anyhow::Result<Fitted> {
        let (pool, cfg) = (run.pool, run.cfg);
        let (c, m) = (&cfg.common, &cfg.max_likelihood[self.kind()]);
        let (p, h) = match self {
            FlowTrainer::Spline => train_spline(pool, c, m),
            FlowTrainer::Disk => train_disk(pool, c, m),
            FlowTrainer::Affine => train_affine(pool, c, m),
        }?;
        Ok((p, None, h))
    }
    fn pdf_f64(&self, t: &Trained, phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
        match self {
            FlowTrainer::Spline => spline_pdf_f64(&t.params, phi, wi, p),
            FlowTrainer::Disk => disk_pdf_f64(&t.params, phi, wi, p),
            FlowTrainer::Affine => affine_pdf_f64(&t.params, phi, wi, p),
        }
    }
    fn graph(&self, params: &[f32], b: &Batch) -> Option<Tensor<2>> {
        let device = crate::nn::infer_device();
        Some(match self {
            FlowTrainer::Spline => SplineFlow::from_flat(params, &device).log_pdf(b),
            FlowTrainer::Disk => DiskFlow::from_flat(params, &device).log_pdf(b),
            FlowTrainer::Affine => AffineFlow::from_flat(params, &device).log_pdf(b),
        })
    }
    fn pole_tolerance(&self) -> Option<f64> {
        matches!(self, FlowTrainer::Disk).then_some(DISK_POLE_TOLERANCE)
    }
}

/// Trains the RQ-spline flow; returns `(params, loss history)`.
pub fn train_spline(
    pool: &mut Pool<'_>,
    common: &Common,
    cfg: &MaxLikelihood,
) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
    let device = train_device();
    let mut rng = rng_for(mix_seed(common.seed, 0xf10e), 0, 0);
    // Small output layers start the couplings near a uniform spline and the base near N(0, I).
    let model = SplineFlow {
        base: Mlp::new(&BASE_SIZES, 0.1, &mut rng, &device),
        c0: Mlp::new(&SPLINE_NET_SIZES, 0.1, &mut rng, &device),
        c1: Mlp::new(&SPLINE_NET_SIZES, 0.1, &mut rng, &device),
    };
    train_max_likelihood(model, "flow", pool, common, cfg, |m: &SplineFlow, b| {
        m.log_pdf(b)
    })
}

/// A disk-flow coupling network whose knot derivatives start at 1 (`min_d + softplus(raw)` with
/// the raw bias `ln(e^(1 − min_d) − 1)`), so that the zero-initialised flow is near the
/// identity and the density near uniform.
fn disk_coupling_net(rng: &mut rand_pcg::Pcg64, device: &burn::tensor::Device) -> Mlp {
    let min_d = f64::from(neusample::distrib::spline::MIN_DERIVATIVE);
    let one = ((1.0 - min_d).exp() - 1.0).ln() as f32;
    let bias: Vec<(usize, f32)> = (2 * DISK_FLOW_BINS..DISK_SPLINE_RAW_LEN)
        .map(|o| (o, one))
        .collect();
    Mlp::new_with_output_bias(&DISK_NET_SIZES, 0.1, &bias, rng, device)
}

/// Trains the disk flow; returns `(params, loss history)`.
pub fn train_disk(
    pool: &mut Pool<'_>,
    common: &Common,
    cfg: &MaxLikelihood,
) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
    let device = train_device();
    let mut rng = rng_for(mix_seed(common.seed, 0xd15c), 0, 0);
    let model = DiskFlow {
        c0: disk_coupling_net(&mut rng, &device),
        c1: disk_coupling_net(&mut rng, &device),
    };
    train_max_likelihood(model, "disk-flow", pool, common, cfg, |m: &DiskFlow, b| {
        m.log_pdf(b)
    })
}

/// Trains the affine-coupling flow; returns `(params, loss history)`.
pub fn train_affine(
    pool: &mut Pool<'_>,
    common: &Common,
    cfg: &MaxLikelihood,
) -> anyhow::Result<(Vec<f32>, Vec<f32>)> {
    let device = train_device();
    let mut rng = rng_for(mix_seed(common.seed, 0xaff1), 0, 0);
    let model = AffineFlow {
        nets: (0..AFFINE_LAYERS)
            .map(|_| Mlp::new(&AFFINE_NET_SIZES, 0.1, &mut rng, &device))
            .collect(),
    };
    let (model, history) = fit(
        model,
        "affine-flow",
        common,
        &cfg.schedule,
        pool,
        PointKind::FromTarget,
        (cfg.batch_conditions, cfg.samples_per_condition),
        |m: &AffineFlow, batch: &Batch| m.log_pdf(batch).mean().neg(),
    )?;
    Ok((model.export_params(), history))
}

fn coupling_f64(
    params: &[f32],
    offset: usize,
    sizes: &[usize],
    c: &[f64],
    other: f64,
    act: Activation,
) -> Vec<f64> {
    let mut input = c.to_vec();
    encode_f64(other, OTHER_BANDS, &mut input);
    let mut at = offset;
    mlp_f64(params, &mut at, sizes, act, &input)
}

/// Density (projected-disk area measure) of a trained RQ-spline flow at `p`, in f64 from the
/// exported parameters; `wi` must already be normalised. 0 outside the open unit disk.
#[must_use]
pub fn spline_pdf_f64(params: &[f32], phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
    if !(p.length_squared() < 1.0) {
        return 0.0;
    }
    let c = encoded_condition_f64(phi, wi);
    let (x, y) = (f64::from(p.x), f64::from(p.y));
    let bound = f64::from(TAIL_BOUND);
    let raw1 = coupling_f64(
        params,
        FLOW_COUPLING1,
        &SPLINE_NET_SIZES,
        &c,
        x,
        Activation::LeakyRelu,
    );
    let (yl, ld1) = rq_forward_f64(y, &raw1, SPLINE_BINS, bound);
    let raw0 = coupling_f64(
        params,
        FLOW_COUPLING0,
        &SPLINE_NET_SIZES,
        &c,
        yl,
        Activation::LeakyRelu,
    );
    let (xl, ld0) = rq_forward_f64(x, &raw0, SPLINE_BINS, bound);
    let mut at = 0;
    let o = mlp_f64(params, &mut at, &BASE_SIZES, Activation::Relu, &c);
    let clamp = |v: f64| v.clamp(f64::from(LOG_SIGMA_MIN), f64::from(LOG_SIGMA_MAX));
    let (lsx, lsy) = (clamp(o[2]), clamp(o[3]));
    let dx = (xl - o[0]) / lsx.exp();
    let dy = (yl - o[1]) / lsy.exp();
    let lp = -0.5 * (dx * dx + dy * dy) - (std::f64::consts::TAU).ln() - lsx - lsy + ld0 + ld1;
    lp.exp()
}

/// Density (projected-disk area measure) of a trained disk flow at `p`, in f64 from the
/// exported parameters (see [`spline_pdf_f64`]).
#[must_use]
pub fn disk_pdf_f64(params: &[f32], phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
    if !(p.length_squared() < 1.0) {
        return 0.0;
    }
    let c = encoded_condition_f64(phi, wi);
    let (x, y) = (f64::from(p.x), f64::from(p.y));
    let chord = |v: f64| (1.0 - v * v).max(0.0).sqrt();
    let ratio = |a: f64, c: f64| {
        if c > 0.0 {
            (a / c).clamp(-1.0, 1.0)
        } else {
            0.0
        }
    };
    let raw1 = coupling_f64(
        params,
        DISK_FLOW_COUPLING1,
        &DISK_NET_SIZES,
        &c,
        x,
        Activation::LeakyRelu,
    );
    let (sy, ld1) = rq_forward_free_f64(ratio(y, chord(x)), &raw1, DISK_FLOW_BINS);
    let yb = chord(x) * sy;
    let raw0 = coupling_f64(
        params,
        DISK_FLOW_COUPLING0,
        &DISK_NET_SIZES,
        &c,
        yb,
        Activation::LeakyRelu,
    );
    let (_, ld0) = rq_forward_free_f64(ratio(x, chord(yb)), &raw0, DISK_FLOW_BINS);
    (ld0 + ld1 - std::f64::consts::PI.ln()).exp()
}

/// Density (projected-disk area measure) of a trained affine flow at `p` (see
/// [`spline_pdf_f64`]).
#[must_use]
pub fn affine_pdf_f64(params: &[f32], phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f64 {
    if !(p.length_squared() < 1.0) {
        return 0.0;
    }
    let c = encoded_condition_f64(phi, wi);
    let (mut x, mut y) = (f64::from(p.x), f64::from(p.y));
    let mut ld = 0.0;
    let bound = f64::from(AFFINE_SCALE_BOUND);
    for l in 0..AFFINE_LAYERS {
        let other = if l % 2 == 0 { y } else { x };
        let o = coupling_f64(
            params,
            l * AFFINE_NET_LEN,
            &AFFINE_NET_SIZES,
            &c,
            other,
            Activation::Relu,
        );
        let s = bound * (o[0] / bound).tanh();
        if l % 2 == 0 {
            x = x * s.exp() + o[1];
        } else {
            y = y * s.exp() + o[1];
        }
        ld += s;
    }
    (-0.5 * (x * x + y * y) - (std::f64::consts::TAU).ln() + ld).exp()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::TrainConfig;

    /// The command line's χ² options (`TrainConfig::fine_tuned_mut`) reach the two spline
    /// flows only.
    #[test]
    fn chi2_options_reach_the_spline_flows_only() {
        let mut cfg = TrainConfig::default();
        for m in cfg.fine_tuned_mut() {
            m.chi2_weight = 7.0;
        }
        for k in SamplerKind::ALL {
            if let Some(m) = cfg.max_likelihood.get(k) {
                let spline = matches!(k, SamplerKind::SplineFlow | SamplerKind::DiskFlow);
                assert_eq!(m.chi2_weight == 7.0, spline, "{k:?}");
            }
        }
    }
}
