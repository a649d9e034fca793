//! The integrands the reparameterization sampler trains on ([`Integrand`]): a neural
//! material's luminance through its decoder, frozen ([`NeuralIntegrand`]), and a measured
//! material's through its tables with a host-side gradient ([`MeasuredIntegrand`]); the
//! synthetic target's is beside it ([`crate::train::SyntheticIntegrand`]).

use burn::tensor::{Device, Tensor};
use glam::Vec3;
use neusample::neural_material::{DECODER_HIDDEN, DECODER_INPUTS, DECODER_OUTPUTS};
use neusample::neural_material::{LOG_F_MAX, LOG_F_MIN};
use neusample::{MeasuredMaterial, NeuralMaterial, FEATURE_DIM};
use rayon::prelude::*;

use crate::materials::luminance;
use crate::nn::{log_sum_exp_last, tensor2, to_host};

/// The conditions of a batch's rows: row `i` belongs to condition `conds[i / repeat]`.
#[derive(Clone, Copy, Debug)]
pub struct ConditionRows<'a> {
    /// `(φ, wi)` per condition.
    pub conds: &'a [([f32; FEATURE_DIM], Vec3)],
    /// Rows per condition.
    pub repeat: usize,
}

impl ConditionRows<'_> {
    /// Number of rows, `conds.len() · repeat`.
    #[must_use]
    pub fn len(&self) -> usize {
        self.conds.len() * self.repeat
    }

    /// `true` without rows.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// A `[n, width]` tensor whose rows hold their condition's `width` values, which `write`
    /// appends once per condition.
    pub fn per_condition(
        &self,
        width: usize,
        device: &Device,
        mut write: impl FnMut(&[f32; FEATURE_DIM], Vec3, &mut Vec<f32>),
    ) -> Tensor<2> {
        let mut host = Vec::with_capacity(self.len() * width);
        let mut row = Vec::with_capacity(width);
        for (phi, wi) in self.conds {
            row.clear();
            write(phi, *wi, &mut row);
            debug_assert_eq!(row.len(), width);
            for _ in 0..self.repeat {
                host.extend_from_slice(&row);
            }
        }
        tensor2(host, self.len(), width, device)
    }
}

/// The unnormalised target of the reparameterization sampler on the projected disk,
/// `f⊥(ω⊥ | φ, wi)` (for a material, the luminance of its BRDF: p* up to its normaliser),
/// with a differentiable training graph.
pub trait Integrand: Sync {
    /// `ln f⊥` at the directions `wo` (`[n, 3]`, unit, on the training graph) of the `rows`.
    /// Returns `[n, 1]`.
    fn log_f(&self, rows: ConditionRows<'_>, wo: Tensor<2>, device: &Device) -> Tensor<2>;

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
    fn log_f(&self, rows: ConditionRows<'_>, wo: Tensor<2>, device: &Device) -> Tensor<2> {
        let base = rows.per_condition(FEATURE_DIM + 2, device, |phi, wi, row| {
            row.extend_from_slice(phi);
            row.extend([wi.x, wi.y]);
        });
        let wi = rows.per_condition(3, device, |_, wi, row| row.extend(wi.to_array()));
        // A row whose wo is not finite reads LOG_F_MIN: its components are replaced by 0
        // first, so that neither its value nor its gradient is NaN.
        let bad = wo.clone().is_finite().bool_not();
        let bad_row = bad.clone().any_dim(1);
        let wo = wo.mask_fill(bad, 0.0);
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
        log_sum_exp_last(o + ln_w).mask_fill(bad_row, LOG_F_MIN)
    }

    fn f(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> f32 {
        luminance(self.material.eval(phi, wi, wo)).max(0.0)
    }
}

/// A measured material's `f⊥ = Y(f(wi, wo))` (φ is ignored: the data is homogeneous).
///
/// The tables are not on the training graph. [`Integrand::log_f`] returns the exact value
/// `ln f⊥(wo)` with the gradient of `ln f⊥` at `wo` attached as a first-order term:
/// `c + (wo − wo₀)·g` with `wo₀` the same values as constants, so the value is `c` and the
/// derivative with respect to `wo` is `g`. `g` comes from central differences of `ln f⊥` on
/// the host (one-sided where a side leaves the upper hemisphere or reads `f⊥ = 0`); the
/// tables are piecewise bilinear, so this is their derivative up to the step's smoothing.
pub struct MeasuredIntegrand<'a> {
    material: &'a MeasuredMaterial<Vec<f32>>,
}

/// Step of the central differences of [`MeasuredIntegrand`] (in the direction's components).
const MEASURED_GRADIENT_STEP: f32 = 5e-4;

impl<'a> MeasuredIntegrand<'a> {
    /// The integrand of `material`.
    #[must_use]
    pub fn new(material: &'a MeasuredMaterial<Vec<f32>>) -> Self {
        MeasuredIntegrand { material }
    }

    /// `ln f⊥` at `wo` clamped to the neural material's range, or `None` where `f⊥ = 0`
    /// (below the horizon, or where the data holds no reflectance).
    fn ln_f(
        prepared: &neusample::measured::MeasuredPrepared<'_, Vec<f32>>,
        wo: Vec3,
    ) -> Option<f32> {
        if !(wo.z > 0.0) {
            return None;
        }
        let f = luminance(prepared.eval(wo.normalize()));
        (f > 0.0).then(|| f.ln().clamp(LOG_F_MIN, LOG_F_MAX))
    }

    /// `(ln f⊥, ∂ ln f⊥ / ∂wo)` at unit `wo` (`(LOG_F_MIN, 0)` where `f⊥ = 0`).
    fn value_and_gradient(
        prepared: &neusample::measured::MeasuredPrepared<'_, Vec<f32>>,
        wo: Vec3,
    ) -> (f32, [f32; 3]) {
        let Some(c) = Self::ln_f(prepared, wo) else {
            return (LOG_F_MIN, [0.0; 3]);
        };
        let h = MEASURED_GRADIENT_STEP;
        let mut g = [0.0; 3];
        for (k, gk) in g.iter_mut().enumerate() {
            let e = Vec3::AXES[k] * h;
            *gk = match (Self::ln_f(prepared, wo + e), Self::ln_f(prepared, wo - e)) {
                (Some(a), Some(b)) => (a - b) / (2.0 * h),
                (Some(a), None) => (a - c) / h,
                (None, Some(b)) => (c - b) / h,
                (None, None) => 0.0,
            };
        }
        (c, g)
    }
}

impl Integrand for MeasuredIntegrand<'_> {
    fn log_f(&self, rows: ConditionRows<'_>, wo: Tensor<2>, device: &Device) -> Tensor<2> {
        let (n, repeat) = (rows.len(), rows.repeat);
        let host = to_host(wo.clone());
        let rows: Vec<(f32, [f32; 3])> = rows
            .conds
            .par_iter()
            .enumerate()
            .flat_map_iter(|(i, (_, wi))| {
                let prepared = self.material.prepare(*wi);
                let host = &host;
                (0..repeat).map(move |j| {
                    let r = 3 * (i * repeat + j);
                    let w = Vec3::new(host[r], host[r + 1], host[r + 2]);
                    match &prepared {
                        Some(p) if w.is_finite() => Self::value_and_gradient(p, w),
                        _ => (LOG_F_MIN, [0.0; 3]),
                    }
                })
            })
            .collect();
        let value = tensor2(rows.iter().map(|r| r.0).collect(), n, 1, device);
        let grad = tensor2(rows.iter().flat_map(|r| r.1).collect(), n, 3, device);
        let constant = tensor2(host, n, 3, device);
        // wo − wo₀ is NaN on a row whose wo is not finite (its value is LOG_F_MIN, its
        // gradient 0): 0 there, so that the row adds nothing.
        let step = wo - constant;
        let step = step.clone().mask_fill(step.is_nan(), 0.0);
        value + (step * grad).sum_dim(1)
    }

    fn f(&self, _phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> f32 {
        self.material
            .prepare(wi)
            .map_or(0.0, |p| luminance(p.eval(wo)).max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::train_device;
    use neusample_owned::measured::OwnedMeasured;

    fn mint() -> OwnedMeasured {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../fixtures/measured/chm_mint_rgb.bsdf"
        );
        OwnedMeasured::open(std::path::Path::new(path)).expect("the mint fixture opens")
    }

    /// `ln f⊥` on the graph at the directions `wos` of one condition, and its gradient with
    /// respect to them (`3 · wos.len()` values).
    fn log_f_and_gradient(
        integrand: &dyn Integrand,
        phi: &[f32; FEATURE_DIM],
        wi: Vec3,
        wos: &[[f32; 3]],
    ) -> (Vec<f32>, Vec<f32>) {
        let device = train_device();
        let host: Vec<f32> = wos.iter().flatten().copied().collect();
        let wo = tensor2(host, wos.len(), 3, &device).require_grad();
        let conds = vec![(*phi, wi); wos.len()];
        let rows = ConditionRows {
            conds: &conds,
            repeat: 1,
        };
        let log_f = integrand.log_f(rows, wo.clone(), &device);
        let values = to_host(log_f.clone());
        let grads = log_f.sum().backward();
        (values, to_host(wo.grad(&grads).expect("wo has a gradient")))
    }

    /// Rows whose `wo` is NaN or infinite read `LOG_F_MIN` with a zero gradient, on both
    /// integrands, and leave the other rows' values as they are without them.
    #[test]
    fn rows_with_a_non_finite_wo_read_the_floor() {
        let data = mint();
        let neural = crate::materials::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../fixtures/materials/neural/goat_leather_neural.nsb"
        )))
        .expect("the neural fixture opens");
        let measured = MeasuredIntegrand::new(data.material());
        let neural = crate::train::source::material_integrand(neural.as_ref())
            .expect("a neural material has an integrand");
        let wi = Vec3::new(0.3, -0.2, 0.93).normalize();
        let good = Vec3::new(-0.25, 0.2, 0.95).normalize();
        let rows = [
            [good.x, good.y, good.z],
            [f32::NAN, 0.1, 0.9],
            [0.0, f32::INFINITY, 0.5],
            [f32::NEG_INFINITY, f32::NAN, f32::INFINITY],
        ];
        for (name, integrand) in [
            ("measured", &measured as &dyn Integrand),
            ("neural", &*neural),
        ] {
            let phi = [0.1; FEATURE_DIM];
            let (values, grads) = log_f_and_gradient(integrand, &phi, wi, &rows);
            let (alone, alone_grad) = log_f_and_gradient(integrand, &phi, wi, &rows[..1]);
            assert_eq!(values[0], alone[0], "{name}: the finite row's value");
            assert_eq!(
                grads[..3],
                alone_grad[..],
                "{name}: the finite row's gradient"
            );
            for (i, v) in values.iter().enumerate().skip(1) {
                assert_eq!(*v, LOG_F_MIN, "{name}: row {i}");
            }
            assert!(grads[3..].iter().all(|g| *g == 0.0), "{name}: {grads:?}");
        }
    }

    /// On the graph, the measured integrand's value is the host's `ln f⊥` and its gradient
    /// with respect to `wo` points uphill: a small step along it raises `ln f⊥` on the host,
    /// by the first-order amount, on the flank of the mint's specular lobe.
    #[test]
    fn measured_log_f_value_and_gradient() {
        let data = mint();
        let integrand = MeasuredIntegrand::new(data.material());
        let wi = Vec3::new(0.5, 0.1, 0.86).normalize();
        let mirror = Vec3::new(-wi.x, -wi.y, wi.z);
        // Points around the mirror direction, off its peak, where the lobe is steep.
        let wos: Vec<Vec3> = (0..12)
            .map(|k| {
                let a = k as f32 * std::f32::consts::TAU / 12.0;
                (mirror + 0.06 * Vec3::new(a.cos(), a.sin(), 0.0)).normalize()
            })
            .collect();
        let rows: Vec<[f32; 3]> = wos.iter().map(|w| w.to_array()).collect();
        let (values, g) = log_f_and_gradient(&integrand, &[0.0; FEATURE_DIM], wi, &rows);
        let mut rising = 0;
        for (i, &w) in wos.iter().enumerate() {
            let f = integrand.f(&[0.0; FEATURE_DIM], wi, w);
            assert!(f > 0.0, "the lobe's flank reflects");
            assert!(
                (values[i] - f.ln()).abs() < 1e-5,
                "value {} vs {}",
                values[i],
                f.ln()
            );
            let gi = Vec3::new(g[3 * i], g[3 * i + 1], g[3 * i + 2]);
            // The step along the gradient's tangential part.
            let t = gi - gi.dot(w) * w;
            assert!(
                t.length() > 1.0,
                "the flank is steep: |∇ ln f| = {}",
                t.length()
            );
            let eta = 2e-3 / t.length();
            let up = integrand.f(&[0.0; FEATURE_DIM], wi, (w + eta * t).normalize());
            let predicted = eta * t.length_squared();
            let gained = up.ln() - f.ln();
            if gained > 0.5 * predicted && gained < 1.5 * predicted {
                rising += 1;
            }
        }
        assert!(
            rising >= 10,
            "{rising} of 12 steps rose as the gradient predicts"
        );
    }
}
