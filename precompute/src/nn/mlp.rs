//! The MLP with the runtime's parameter layout (burn), its f64 mirror, and the runtime's
//! activations on tensors.

use burn::module::{Module, Param};
use burn::nn::Linear;
use burn::tensor::activation;
use burn::tensor::{Device, Tensor, TensorData};
use rand::RngExt;
use rand_pcg::Pcg64;

pub use neusample::nn::Activation;
use neusample::nn::LEAKY_RELU_SLOPE;

use super::ops::softplus_f64;
use super::tensor::to_host;

/// The runtime's activation `act` on a tensor, element-wise (the same function as
/// [`Activation::apply`]; the training graph and the runtime share the enum).
pub fn activate<const D: usize>(act: Activation, x: Tensor<D>) -> Tensor<D> {
    match act {
        Activation::Identity => x,
        Activation::Relu => activation::relu(x),
        Activation::LeakyRelu => activation::leaky_relu(x, f64::from(LEAKY_RELU_SLOPE)),
        Activation::Softplus => activation::softplus(x, 1.0),
        Activation::Sigmoid => activation::sigmoid(x),
    }
}

/// The runtime's activation `act` in f64 (for the f64 mirrors of trained models).
#[must_use]
pub fn activate_f64(act: Activation, x: f64) -> f64 {
    match act {
        Activation::Identity => x,
        Activation::Relu => x.max(0.0),
        Activation::LeakyRelu => {
            if x >= 0.0 {
                x
            } else {
                f64::from(LEAKY_RELU_SLOPE) * x
            }
        }
        Activation::Softplus => softplus_f64(x),
        Activation::Sigmoid => 1.0 / (1.0 + (-x).exp()),
    }
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
    pub fn forward(&self, x: Tensor<2>, act: Activation) -> Tensor<2> {
        self.forward_from(0, x, act)
    }

    /// Forward pass starting at layer `first` (its input is `x`).
    pub fn forward_from(&self, first: usize, mut x: Tensor<2>, act: Activation) -> Tensor<2> {
        let n = self.layers.len();
        for (l, layer) in self.layers.iter().enumerate().skip(first) {
            x = layer.forward(x);
            if l + 1 < n {
                x = activate(act, x);
            }
        }
        x
    }

    /// Applies the activation of a hidden layer (for callers that build the first layer's
    /// pre-activation themselves, e.g. from a shared condition part).
    pub fn hidden_act<const D: usize>(x: Tensor<D>, act: Activation) -> Tensor<D> {
        activate(act, x)
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
pub fn mlp_f64(
    params: &[f32],
    at: &mut usize,
    sizes: &[usize],
    act: Activation,
    x: &[f64],
) -> Vec<f64> {
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
                *v = activate_f64(act, *v);
            }
        }
        *at += i * o + o;
        h = y;
    }
    h
}
