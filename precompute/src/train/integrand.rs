//! The integrands the reparameterization sampler trains on ([`Integrand`]) and a neural
//! material's luminance through its decoder, frozen ([`NeuralIntegrand`]); the synthetic
//! target's is beside it ([`crate::train::SyntheticIntegrand`]).

use burn::tensor::{Device, Tensor};
use glam::Vec3;
use neusample::neural_material::{DECODER_HIDDEN, DECODER_INPUTS, DECODER_OUTPUTS};
use neusample::{NeuralMaterial, FEATURE_DIM};

use crate::materials::luminance;
use crate::nn::{log_sum_exp_last, tensor2};

/// The unnormalised target of the reparameterization sampler on the projected disk,
/// `f⊥(ω⊥ | φ, wi)` (for a material, the luminance of its BRDF: p* up to its normaliser),
/// with a differentiable training graph.
pub trait Integrand: Sync {
    /// `ln f⊥` at the directions `wo` (`[n, 3]`, unit, on the training graph) of the rows:
    /// row `i` belongs to condition `conds[i / repeat]`. Returns `[n, 1]`.
    fn log_f(
        &self,
        conds: &[([f32; FEATURE_DIM], Vec3)],
        repeat: usize,
        wo: Tensor<2>,
        device: &Device,
    ) -> Tensor<2>;

    /// `f⊥` at one direction on the host (no gradient), ≥ 0.
    fn f(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> f32;
}

/// Luminance weights of linear RGB (as [`luminance`]).
const LUMINANCE: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// Layer sizes of the neural material's decoder.
const DECODER: [usize; 5] = [
    DECODER_INPUTS,
    DECODER_HIDDEN,
    DECODER_HIDDEN,
    DECODER_HIDDEN,
    DECODER_OUTPUTS,
];

/// A neural material's `f⊥ = Y(f(φ, wi, wo))`: on the host by the runtime, on the training
/// graph by its decoder with constant weights (no gradient reaches the material).
pub struct NeuralIntegrand<'a> {
    material: NeuralMaterial<&'a [f32]>,
}

impl<'a> NeuralIntegrand<'a> {
    /// The integrand of `material`.
    #[must_use]
    pub fn new(material: NeuralMaterial<&'a [f32]>) -> Self {
        NeuralIntegrand { material }
    }
}

impl Integrand for NeuralIntegrand<'_> {
    fn log_f(
        &self,
        conds: &[([f32; FEATURE_DIM], Vec3)],
        repeat: usize,
        wo: Tensor<2>,
        device: &Device,
    ) -> Tensor<2> {
        let n = conds.len() * repeat;
        let mut base = Vec::with_capacity(n * (FEATURE_DIM + 2));
        let mut wi = Vec::with_capacity(n * 3);
        for (phi, w) in conds {
            for _ in 0..repeat {
                base.extend_from_slice(phi);
                base.extend([w.x, w.y]);
                wi.extend([w.x, w.y, w.z]);
            }
        }
        let base = tensor2(base, n, FEATURE_DIM + 2, device);
        let wi = tensor2(wi, n, 3, device);
        // The half vector of the decoder input (`neusample::neural_material::decoder_input`).
        let s = wi + wo.clone();
        let h = s.clone() / s.powi_scalar(2).sum_dim(1).sqrt();
        let mut x = Tensor::cat(vec![base, wo.narrow(1, 0, 2), h.narrow(1, 0, 2)], 1);
        let params: &[f32] = self.material.params();
        let mut at = 0;
        for l in 0..DECODER.len() - 1 {
            let (i, o) = (DECODER[l], DECODER[l + 1]);
            let w = tensor2(params[at..at + i * o].to_vec(), i, o, device);
            let b = tensor2(params[at + i * o..at + i * o + o].to_vec(), 1, o, device);
            at += i * o + o;
            x = x.matmul(w) + b;
            if l + 2 < DECODER.len() {
                x = burn::tensor::activation::relu(x);
            }
        }
        let ln_w = tensor2(LUMINANCE.iter().map(|w| w.ln()).collect(), 1, 3, device);
        let o = x.clamp(
            neusample::neural_material::LOG_F_MIN,
            neusample::neural_material::LOG_F_MAX,
        );
        log_sum_exp_last(o + ln_w)
    }

    fn f(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> f32 {
        luminance(self.material.eval(phi, wi, wo)).max(0.0)
    }
}
