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

/// A ReLU MLP stored from offset 0 of a flat parameter array: `dense(I, H)` and `L − 2` of
/// `dense(H, H)`, each followed by ReLU, then `dense(H, O)` without an activation (`L ≥ 2`
/// layers). A type, so that a sampler names its network once and takes its parameter count,
/// layer offsets and forward pass from it.
#[derive(Copy, Clone, Debug)]
pub struct ReluMlp<const I: usize, const H: usize, const O: usize, const L: usize>;

impl<const I: usize, const H: usize, const O: usize, const L: usize> ReluMlp<I, H, O, L> {
    /// Where each layer starts in the parameter array.
    pub const OFFSETS: [usize; L] = {
        assert!(L >= 2, "a ReLU MLP has a first and a last layer");
        let mut o = [0; L];
        let mut k = 1;
        while k < L {
            o[k] = o[k - 1] + dense_len(if k == 1 { I } else { H }, H);
            k += 1;
        }
        o
    };

    /// Number of parameters.
    pub const LEN: usize = Self::OFFSETS[L - 1] + dense_len(H, O);

    /// The network's outputs for the input `x`.
    #[inline(always)]
    #[must_use]
    pub fn forward<W: Weights + ?Sized>(w: &W, x: &[f32; I]) -> [f32; O] {
        let mut h: [f32; H] = dense(w, Self::OFFSETS[0] as u32, x, Activation::Relu);
        let mut k = 1;
        while k + 1 < L {
            h = dense(w, Self::OFFSETS[k] as u32, &h, Activation::Relu);
            k += 1;
        }
        linear(w, Self::OFFSETS[L - 1] as u32, &h)
    }
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
