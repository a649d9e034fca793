//! The optimisation loop every trainer runs: AdamW with gradient-norm clipping, a linear
//! warm-up and cosine decay of the learning rate, a progress bar, and steps whose loss is not
//! finite skipped.

use burn::module::Module;
use burn::optim::{AdamWConfig, GradientsParams};
use burn::tensor::Tensor;

use crate::util::progress::steps_bar;

/// Steps in a row whose loss is not finite before [`optimise`] gives up.
const MAX_BAD_STEPS: usize = 20;

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

/// Settings of [`optimise`].
#[derive(Clone, Debug, PartialEq)]
pub struct OptimSettings {
    /// Shown before the progress bar and in errors.
    pub name: String,
    /// Optimisation steps.
    pub steps: usize,
    /// Peak learning rate ([`learning_rate`]).
    pub lr: f64,
    /// AdamW weight decay.
    pub weight_decay: f32,
    /// Gradient-norm clipping threshold.
    pub grad_clip: f32,
    /// Show a progress bar.
    pub progress: bool,
    /// The bar shows the loss every this many steps.
    pub report_every: usize,
}

/// Minimises `loss(model, step)` over `s.steps` steps with AdamW. Returns the trained model
/// and the loss of every step. A step whose loss is not finite makes no update; too many in a
/// row is an error.
pub fn optimise<M: Module>(
    mut model: M,
    s: &OptimSettings,
    mut loss: impl FnMut(&M, usize) -> anyhow::Result<Tensor<1>>,
) -> anyhow::Result<(M, Vec<f32>)> {
    let mut optim = AdamWConfig::new()
        .with_weight_decay(s.weight_decay)
        .with_grad_clipping(Some(burn::grad_clipping::GradientClippingConfig::Norm(
            s.grad_clip,
        )))
        .init();
    let bar = steps_bar(s.steps, s.name.clone(), s.progress);
    let mut history = Vec::with_capacity(s.steps);
    let mut bad_in_a_row = 0usize;
    for step in 0..s.steps {
        let l = loss(&model, step)?;
        let value: f32 = l.clone().into_scalar();
        history.push(value);
        if !value.is_finite() {
            bad_in_a_row += 1;
            anyhow::ensure!(
                bad_in_a_row < MAX_BAD_STEPS,
                "{}: loss not finite for {MAX_BAD_STEPS} steps in a row (step {step})",
                s.name
            );
            bar.inc(1);
            continue;
        }
        bad_in_a_row = 0;
        let grads = GradientsParams::from_grads(l.backward(), &model);
        model = optim.step(learning_rate(s.lr, step, s.steps), model, grads);
        if step % s.report_every.max(1) == 0 {
            bar.set_message(format!("loss {value:.4}"));
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok((model, history))
}
