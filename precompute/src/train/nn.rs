//! Pieces shared by every trainer: the burn MLP with the runtime's parameter layout, its
//! plain-Rust f64 mirror, the sinusoidal encodings, log-density helpers and the generic
//! optimisation loop.
//!
//! Layout contract (`core/ARCHITECTURES.md`): burn's `Linear` stores its weight as
//! `[d_input, d_output]`, which is exactly the runtime's input-major `W[i][o]`, so a layer
//! exports as `weight` (row-major) followed by `bias`.

use burn::module::{Module, Param};
use burn::nn::Linear;
use burn::optim::{AdamWConfig, GradientsParams};
use burn::tensor::activation;
use burn::tensor::{Device, Tensor, TensorData};
use indicatif::{ProgressBar, ProgressStyle};
use rand::RngExt;
use rand_pcg::Pcg64;

use neusample::nn::LEAKY_RELU_SLOPE;

use super::data::{make_batch, HostBatch, PointKind, Pool};
use super::TrainConfig;

/// The device training runs on: burn's pure-Rust CPU backend with autodiff.
#[must_use]
pub fn train_device() -> Device {
    Device::flex().autodiff()
}

/// The device for inference without gradients (baking).
#[must_use]
pub fn infer_device() -> Device {
    Device::flex()
}

/// Hidden-layer non-linearity.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    /// max(x, 0).
    Relu,
    /// x for x ≥ 0, 0.01·x otherwise (the flow's coupling networks).
    Leaky,
}

impl Act {
    fn apply<const D: usize>(self, x: Tensor<D>) -> Tensor<D> {
        match self {
            Act::Relu => activation::relu(x),
            Act::Leaky => activation::leaky_relu(x, f64::from(LEAKY_RELU_SLOPE)),
        }
    }

    fn apply_f64(self, x: f64) -> f64 {
        match self {
            Act::Relu => x.max(0.0),
            Act::Leaky => {
                if x >= 0.0 {
                    x
                } else {
                    f64::from(LEAKY_RELU_SLOPE) * x
                }
            }
        }
    }
}

/// A 2-D tensor from host values.
#[must_use]
pub fn tensor2(v: Vec<f32>, rows: usize, cols: usize, device: &Device) -> Tensor<2> {
    Tensor::from_data(TensorData::new(v, [rows, cols]), device)
}

/// A tensor's values on the host.
#[must_use]
pub fn to_host<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .try_into_vec::<f32>()
        .expect("float tensors hold f32 values")
}

/// A multi-layer perceptron: dense layers with a non-linearity after every layer but the
/// last (identity output).
#[derive(Module, Debug)]
pub struct Mlp {
    /// The dense layers in order.
    pub layers: Vec<Linear>,
}

impl Mlp {
    /// PyTorch-style initialisation `U(−1/√in, 1/√in)` for weights and biases, the last
    /// layer scaled by `last_scale` (small values start a model near its "neutral" output).
    pub fn new(sizes: &[usize], last_scale: f32, rng: &mut Pcg64, device: &Device) -> Self {
        let mut layers = Vec::with_capacity(sizes.len() - 1);
        for l in 0..sizes.len() - 1 {
            let (i, o) = (sizes[l], sizes[l + 1]);
            let k = 1.0 / (i as f32).sqrt();
            let scale = if l + 2 == sizes.len() {
                last_scale
            } else {
                1.0
            };
            let w: Vec<f32> = (0..i * o)
                .map(|_| scale * rng.random_range(-k..k))
                .collect();
            let b: Vec<f32> = (0..o).map(|_| scale * rng.random_range(-k..k)).collect();
            layers.push(linear_from(w, b, i, o, device));
        }
        Mlp { layers }
    }

    /// [`Mlp::new`], then sets the listed biases of the output layer: `(output, value)`.
    pub fn new_with_output_bias(
        sizes: &[usize],
        last_scale: f32,
        bias: &[(usize, f32)],
        rng: &mut Pcg64,
        device: &Device,
    ) -> Self {
        let mut flat = Vec::new();
        Mlp::new(sizes, last_scale, rng, device).export(&mut flat);
        let out = sizes[sizes.len() - 1];
        let end = flat.len();
        for &(o, v) in bias {
            flat[end - out + o] = v;
        }
        Mlp::from_flat(sizes, &flat, device)
    }

    /// An MLP from flat parameters in the runtime layout.
    pub fn from_flat(sizes: &[usize], params: &[f32], device: &Device) -> Self {
        let mut layers = Vec::with_capacity(sizes.len() - 1);
        let mut at = 0;
        for l in 0..sizes.len() - 1 {
            let (i, o) = (sizes[l], sizes[l + 1]);
            let w = params[at..at + i * o].to_vec();
            let b = params[at + i * o..at + i * o + o].to_vec();
            at += i * o + o;
            layers.push(linear_from(w, b, i, o, device));
        }
        Mlp { layers }
    }

    /// Forward pass over rows of `x`.
    pub fn forward(&self, x: Tensor<2>, act: Act) -> Tensor<2> {
        self.forward_from(0, x, act)
    }

    /// Forward pass starting at layer `first` (its input is `x`).
    pub fn forward_from(&self, first: usize, mut x: Tensor<2>, act: Act) -> Tensor<2> {
        let n = self.layers.len();
        for (l, layer) in self.layers.iter().enumerate().skip(first) {
            x = layer.forward(x);
            if l + 1 < n {
                x = act.apply(x);
            }
        }
        x
    }

    /// Applies the activation of a hidden layer (for callers that build the first layer's
    /// pre-activation themselves, e.g. from a shared condition part).
    pub fn hidden_act<const D: usize>(x: Tensor<D>, act: Act) -> Tensor<D> {
        act.apply(x)
    }

    /// Rows `start .. start + len` of the first layer's weight matrix (the weights of those
    /// inputs), `[len, d_output]`.
    pub fn first_weight_rows(&self, start: usize, len: usize) -> Tensor<2> {
        self.layers[0].weight.val().narrow(0, start, len)
    }

    /// The first layer's bias, `[1, d_output]`.
    pub fn first_bias(&self) -> Tensor<2> {
        self.layers[0]
            .bias
            .as_ref()
            .expect("every layer has a bias")
            .val()
            .unsqueeze_dim(0)
    }

    /// Appends the parameters in the runtime layout (per layer: `W[i][o]`, then `b[o]`).
    pub fn export(&self, out: &mut Vec<f32>) {
        for layer in &self.layers {
            out.extend(to_host(layer.weight.val()));
            out.extend(to_host(
                layer.bias.as_ref().expect("every layer has a bias").val(),
            ));
        }
    }
}

fn linear_from(w: Vec<f32>, b: Vec<f32>, i: usize, o: usize, device: &Device) -> Linear {
    Linear {
        weight: Param::from_tensor(Tensor::from_data(TensorData::new(w, [i, o]), device)),
        bias: Some(Param::from_tensor(Tensor::from_data(
            TensorData::new(b, [o]),
            device,
        ))),
    }
}

/// Number of parameters of an MLP with these layer sizes.
#[must_use]
pub const fn mlp_len(sizes: &[usize]) -> usize {
    let mut n = 0;
    let mut l = 0;
    while l + 1 < sizes.len() {
        n += sizes[l] * sizes[l + 1] + sizes[l + 1];
        l += 1;
    }
    n
}

/// f64 forward pass of the MLP stored at `params[*at..]` (runtime layout); advances `at`.
#[must_use]
pub fn mlp_f64(params: &[f32], at: &mut usize, sizes: &[usize], act: Act, x: &[f64]) -> Vec<f64> {
    let mut h = x.to_vec();
    for l in 0..sizes.len() - 1 {
        let (i, o) = (sizes[l], sizes[l + 1]);
        debug_assert_eq!(h.len(), i);
        let w = &params[*at..*at + i * o];
        let b = &params[*at + i * o..*at + i * o + o];
        let mut y: Vec<f64> = b.iter().map(|&v| f64::from(v)).collect();
        for (xi, row) in h.iter().zip(w.chunks_exact(o)) {
            for (yj, wij) in y.iter_mut().zip(row) {
                *yj += xi * f64::from(*wij);
            }
        }
        if l + 2 < sizes.len() {
            for v in &mut y {
                *v = act.apply_f64(*v);
            }
        }
        *at += i * o + o;
        h = y;
    }
    h
}

// ---------------------------------------------------------------------------------------
// Encodings and small numerical helpers
// ---------------------------------------------------------------------------------------

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

/// Stable softplus ln(1 + eˣ) in f64 (matches `neusample::math::softplus` for x ≤ 20).
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

// ---------------------------------------------------------------------------------------
// Optimisation loop
// ---------------------------------------------------------------------------------------

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
        let cond = tensor2(host.cond.clone(), b, neusample::nn::CONDITION_DIM, device);
        let raw = tensor2(
            host.raw.clone(),
            b,
            neusample::nn::RAW_CONDITION_DIM,
            device,
        );
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

/// Learning rate at `step`: a short linear warm-up, then cosine decay to 5 % of `lr`.
#[must_use]
pub fn learning_rate(lr: f64, step: usize, steps: usize) -> f64 {
    let warm = (steps / 50).clamp(1, 50);
    if step < warm {
        return lr * (step + 1) as f64 / warm as f64;
    }
    let t = (step - warm) as f64 / (steps - warm).max(1) as f64;
    lr * (0.05 + 0.95 * 0.5 * (1.0 + (std::f64::consts::PI * t).cos()))
}

/// Minimises `loss` over `cfg.steps` batches with AdamW. Returns the trained model and the
/// loss of every step. Steps whose loss is not finite are skipped (no update); too many in
/// a row is an error.
pub fn fit<M: Module>(
    mut model: M,
    name: &str,
    cfg: &TrainConfig,
    pool: &mut Pool<'_>,
    kind: PointKind,
    batch_size: (usize, usize),
    loss: impl Fn(&M, &Batch) -> Tensor<1>,
) -> anyhow::Result<(M, Vec<f32>)> {
    let device = train_device();
    let mut optim = AdamWConfig::new()
        .with_weight_decay(cfg.weight_decay)
        .with_grad_clipping(Some(burn::grad_clipping::GradientClippingConfig::Norm(
            cfg.grad_clip,
        )))
        .init();
    let bar = if cfg.progress {
        let bar = ProgressBar::new(cfg.steps as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix:>18} {bar:30} {pos}/{len} {msg} [{elapsed_precise}<{eta_precise}]",
            )
            .expect("valid progress template"),
        );
        bar.set_prefix(name.to_string());
        bar
    } else {
        ProgressBar::hidden()
    };
    let mut history = Vec::with_capacity(cfg.steps);
    let mut bad_in_a_row = 0usize;
    for step in 0..cfg.steps {
        pool.maybe_refresh(step)?;
        let host = make_batch(pool, batch_size.0, batch_size.1, kind, cfg.seed, step);
        let batch = Batch::upload(host, &device);
        let l = loss(&model, &batch);
        let value: f32 = l.clone().into_scalar();
        history.push(value);
        if !value.is_finite() {
            bad_in_a_row += 1;
            anyhow::ensure!(
                bad_in_a_row < 20,
                "{name}: loss not finite for 20 steps in a row (step {step})"
            );
            bar.inc(1);
            continue;
        }
        bad_in_a_row = 0;
        let grads = GradientsParams::from_grads(l.backward(), &model);
        model = optim.step(learning_rate(cfg.lr, step, cfg.steps), model, grads);
        if step % 10 == 0 {
            bar.set_message(format!("loss {value:.4}"));
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok((model, history))
}
