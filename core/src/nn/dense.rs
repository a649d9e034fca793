//! Dense layers. Parameters live in one flat [`Weights`] array per sampler; a dense layer with
//! `I` inputs and `O` outputs occupies `I·O + O` consecutive elements:
//!
//! ```text
//! W[0][0] W[0][1] … W[0][O−1]  W[1][0] … W[I−1][O−1]   b[0] … b[O−1]
//! ```
//!
//! i.e. the weight matrix **input-major** (row `i` holds the weights from input `i` to every
//! output — the transpose of PyTorch's `nn.Linear.weight`), followed by the bias. This order
//! makes the inner loop a contiguous multiply-add over outputs.

use crate::math;
use crate::weights::Weights;

/// Slope of the leaky ReLU used by the flow's coupling networks (as in the authors' release).
pub const LEAKY_RELU_SLOPE: f32 = 0.01;

/// Element-wise non-linearity applied after a dense layer.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[repr(u32)] // rust-gpu: a u8 discriminant needs the Int8 capability on SPIR-V
pub enum Activation {
    /// y = x.
    Identity,
    /// y = max(x, 0).
    Relu,
    /// y = x for x ≥ 0, [`LEAKY_RELU_SLOPE`]·x otherwise.
    LeakyRelu,
    /// y = ln(1 + eˣ).
    Softplus,
    /// y = 1/(1 + e⁻ˣ).
    Sigmoid,
}

impl Activation {
    /// Apply the activation to one value.
    #[inline(always)]
    #[must_use]
    pub fn apply(self, x: f32) -> f32 {
        match self {
            Activation::Identity => x,
            Activation::Relu => {
                if x > 0.0 {
                    x
                } else {
                    0.0
                }
            }
            Activation::LeakyRelu => {
                if x >= 0.0 {
                    x
                } else {
                    LEAKY_RELU_SLOPE * x
                }
            }
            Activation::Softplus => math::softplus(x),
            Activation::Sigmoid => math::sigmoid(x),
        }
    }

    /// Apply the activation to every element of an array, in place.
    #[inline(always)]
    pub fn apply_all<const N: usize>(self, x: &mut [f32; N]) {
        let mut j = 0;
        while j < N {
            x[j] = self.apply(x[j]);
            j += 1;
        }
    }
}

/// Number of parameters of a dense layer with `inputs` inputs and `outputs` outputs.
#[inline]
#[must_use]
pub const fn dense_len(inputs: usize, outputs: usize) -> usize {
    inputs * outputs + outputs
}

/// The bias of the dense layer at `offset` (with `I` inputs), as the starting accumulator.
#[inline(always)]
#[must_use]
pub fn bias<W: Weights + ?Sized, const I: usize, const O: usize>(w: &W, offset: u32) -> [f32; O] {
    w.read::<O>(offset + (I * O) as u32)
}

/// Pre-activation of a dense layer: `b + Σ_i x[i]·W[i]`.
#[inline(always)]
#[must_use]
pub fn linear<W: Weights + ?Sized, const I: usize, const O: usize>(
    w: &W,
    offset: u32,
    x: &[f32; I],
) -> [f32; O] {
    let mut acc = bias::<W, I, O>(w, offset);
    w.accumulate(offset, 0, x, &mut acc);
    acc
}

/// A dense layer followed by an activation.
#[inline(always)]
#[must_use]
pub fn dense<W: Weights + ?Sized, const I: usize, const O: usize>(
    w: &W,
    offset: u32,
    x: &[f32; I],
    act: Activation,
) -> [f32; O] {
    let mut y = linear::<W, I, O>(w, offset, x);
    act.apply_all(&mut y);
    y
}

/// Adds the contribution of inputs `first .. first + P` of the dense layer at `offset`
/// (which has `O` outputs) to `acc`. Splitting a layer's inputs this way lets a sampler
/// compute the condition's share of a first layer once in `prepare` and add the
/// per-sample share later (the flow's coupling networks do this).
#[inline(always)]
pub fn accumulate_inputs<W: Weights + ?Sized, const P: usize, const O: usize>(
    w: &W,
    offset: u32,
    first: u32,
    x: &[f32; P],
    acc: &mut [f32; O],
) {
    w.accumulate(offset, first, x, acc);
}
