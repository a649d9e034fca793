//! The schema of `report.json` (`docs/report_schema.md` documents it): typed, serialised and read back by
//! serde. Numbers that cannot be computed are written as `null` and read back as NaN
//! ([`crate::util::json`]).

use neusample_render::Estimator;
use serde::{Deserialize, Serialize};

use crate::eval::metrics::{ConvergencePoint, RenderSettings, Verdict};
use crate::eval::{Cost, EvalCost, Fit, FitReport};
use crate::util::json::f64_or_nan;
use crate::util::stats::Estimate;

/// Schema version of `report.json` (`docs/report_schema.md` documents it).
pub const REPORT_SCHEMA: u32 = 5;

/// Rendering results of one method on one material (see [`crate::eval::metrics`]).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RenderReport {
    /// Single-thread render-loop time per pixel sample, ns (oracle: table build excluded).
    #[serde(deserialize_with = "f64_or_nan")]
    pub ns_per_sample: f64,
    /// `ns_per_sample` relative to cosine sampling's (Table 1, "Rendering" row ratios).
    #[serde(deserialize_with = "f64_or_nan")]
    pub time_vs_cosine: f64,
    /// Samples per pixel of the equal-spp comparison.
    pub equal_spp: u32,
    /// MSE at `equal_spp` (reference noise subtracted).
    #[serde(deserialize_with = "f64_or_nan")]
    pub mse_equal_spp: f64,
    /// Samples per pixel this method affords in the baseline's time for `equal_spp`.
    pub equal_time_spp: u32,
    /// MSE of the equal-time render.
    #[serde(deserialize_with = "f64_or_nan")]
    pub mse_equal_time: f64,
    /// The same speed-up from the measured MSEs against the reference (noisier).
    #[serde(deserialize_with = "f64_or_nan")]
    pub speedup_measured_mse: f64,
    /// Expected MSE at `equal_spp` from the per-pixel sample variances (`mean σ²/N`, a
    /// plain mean dominated by rare bright samples; the speed-up uses `variance` instead).
    #[serde(deserialize_with = "f64_or_nan")]
    pub mse_expected_equal_spp: f64,
    /// Independent sample blocks of the equal-spp render (the units the intervals resample).
    pub blocks: u32,
    /// Per-sample variance `V`: the median of means over the blocks of
    /// `(block MSE − reference noise) · block spp`, with its 95 % bootstrap interval.
    pub variance: Estimate,
    /// Expected MSE at `equal_spp`, `V / N`, with its interval.
    pub mse_equal_spp_interval: Estimate,
    /// The equal-time render's MSE from its own blocks, with its interval (the interval is
    /// null with fewer than two blocks).
    pub mse_equal_time_interval: Estimate,
    /// Speed-up over the improved baseline at equal quality (Table 2), with its 95 %
    /// interval.
    pub speedup: Estimate,
    /// Expected-MSE ratio baseline / method at equal spp (the speed-up if sampling cost
    /// nothing: the paper's "sampling rate" view), with its interval.
    pub mse_ratio: Estimate,
    /// MSE vs spp and vs single-thread time.
    pub convergence: Vec<ConvergencePoint>,
    /// Equal-time image, linear (relative to the output folder).
    pub equal_time_exr: String,
    /// Equal-time image, tonemapped sRGB.
    pub equal_time_png: String,
    /// Equal-spp image, tonemapped sRGB.
    pub equal_spp_png: String,
}

/// One method's results on one material.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MethodReport {
    /// Method name (`cosine`, `baseline`, …, `oracle`).
    pub method: String,
    /// Training time in seconds (0 for cosine, the oracle and fixture blobs).
    #[serde(deserialize_with = "f64_or_nan")]
    pub train_seconds: f64,
    /// Final training loss (null for cosine, the oracle and fixtures).
    pub final_loss: Option<f32>,
    /// Blob size in bytes.
    pub blob_bytes: usize,
    /// Largest relative difference between the blob and the trained model.
    pub blob_vs_model: Option<f64>,
    /// The fit to p* (its fields stand beside the others in the JSON).
    #[serde(flatten)]
    pub fit: Fit,
    /// For a neural material with a known source: mean KL(p*_source ‖ p) in nats, the
    /// sampler (conditioned on the neural φ) against the source material's ground truth at
    /// the same uv and wi; null otherwise.
    pub kl_vs_source: Option<f64>,
    /// Single-thread cost.
    pub cost: Cost,
    /// Rendering results (null with `--no-render`).
    pub render: Option<RenderReport>,
}

impl MethodReport {
    /// `cost.total_ns / cost.material_eval_ns` (Table 1: sampling against material
    /// evaluation).
    #[must_use]
    pub fn cost_vs_material_eval(&self) -> f64 {
        self.cost.total_ns / self.cost.material_eval_ns.max(1e-9)
    }

    /// The speed-up over the improved baseline at equal quality (Table 2); `None` without
    /// rendering.
    #[must_use]
    pub fn speedup_vs_baseline(&self) -> Option<f64> {
        self.render.as_ref().map(|r| r.speedup.value)
    }
}

/// The reference image of a material.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReferenceReport {
    /// Samples per pixel.
    pub spp: u32,
    /// Oracle table resolution.
    pub res: usize,
    /// Always `mis`.
    pub estimator: Estimator,
    /// Expected MSE contribution of its own noise (subtracted from every MSE).
    #[serde(deserialize_with = "f64_or_nan")]
    pub noise: f64,
    /// Pixels hitting an object (where MSE is measured).
    pub pixels: usize,
    /// Wall time of its render, seconds.
    #[serde(deserialize_with = "f64_or_nan")]
    pub seconds: f64,
    /// Linear image.
    pub exr: String,
    /// Tonemapped image.
    pub png: String,
}

/// Figures of a material (paths relative to the output folder).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FigureReport {
    /// Reference and every method at equal time, labelled (Figs. 1, 9).
    pub equal_time: String,
    /// Reference and every method at equal spp, labelled.
    pub equal_spp: String,
    /// MSE vs spp and vs time, log-log (Fig. 8).
    pub convergence: String,
    /// p* beside every method's p at a few conditions (Fig. 7).
    pub pdfs: String,
    /// Each learned sampler's sample weights p*/p on the disk at its worst-χ² conditions.
    #[serde(default)]
    pub weights: String,
}

/// How well a neural material reproduces its source ([`crate::eval::fit_report`]).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct NeuralReport {
    /// Source material name.
    pub source: String,
    /// Fit measures against the source.
    pub fit: FitReport,
    /// Single-thread cost of the neural material (`features`, `eval`), ns.
    pub cost: EvalCost,
    /// The same for the source material.
    pub source_cost: EvalCost,
}

/// All methods on one material.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MaterialReport {
    /// Material name.
    pub material: String,
    /// For a neural material with a known source: its fit and cost (null otherwise).
    pub neural: Option<NeuralReport>,
    /// Per method.
    pub methods: Vec<MethodReport>,
    /// The reference render (null with `--no-render`).
    pub reference: Option<ReferenceReport>,
    /// Figures (null with `--no-render`).
    pub figures: Option<FigureReport>,
    /// Single-thread time budget of the equal-time renders, seconds per image.
    pub equal_time_budget_seconds: Option<f64>,
    /// The best practical method at equal quality and whether its interval clears the
    /// others' (null without rendering).
    #[serde(default)]
    pub verdict: Option<Verdict>,
}

/// Rendering setup shared by all materials.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RenderSetup {
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Sun radiance.
    pub sun_radiance: f32,
    /// Sun angular radius, degrees.
    pub sun_radius_deg: f32,
    /// Environment map file, if any.
    pub env_map: Option<String>,
    /// Uniform white lighting instead of the sky.
    pub uniform_light: bool,
    /// Sizes, seeds and the estimator.
    pub settings: RenderSettings,
}

/// The whole report (`report.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Report {
    /// Schema version of this JSON ([`REPORT_SCHEMA`]).
    pub schema: u32,
    /// Whether the run was a smoke test (`--smoke`): its numbers are not results.
    pub quick: bool,
    /// Whether fixture blobs were used instead of training.
    pub fixtures: bool,
    /// The folder the pretrained blobs came from when not the committed fixtures.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blobs: Option<String>,
    /// Seed.
    pub seed: u64,
    /// Training steps relative to `neusample train`'s defaults (null with a smoke test or
    /// fixtures).
    pub steps_scale: Option<f64>,
    /// Evaluation conditions per material and method.
    pub eval_conditions: usize,
    /// Ground-truth resolution of the evaluation.
    pub eval_res: usize,
    /// Rendering setup (null with `--no-render`).
    pub render: Option<RenderSetup>,
    /// Wall time of the whole run, seconds.
    #[serde(deserialize_with = "f64_or_nan")]
    pub seconds: f64,
    /// Per material.
    pub materials: Vec<MaterialReport>,
}

/// How a learned method's blob came about; [`Training::NONE`] for the references (cosine,
/// the oracle, a measured material's own sampler) and for committed fixtures.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Training {
    /// Wall-clock training time, seconds.
    pub seconds: f64,
    /// The last step's loss.
    pub final_loss: Option<f32>,
    /// The blob's size.
    pub blob_bytes: usize,
    /// The blob check's largest relative difference from the trained model.
    pub blob_vs_model: Option<f64>,
}

impl Training {
    /// Nothing trained.
    pub const NONE: Training = Training {
        seconds: 0.0,
        final_loss: None,
        blob_bytes: 0,
        blob_vs_model: None,
    };
}

/// A method's report without rendering results (filled in by the rendering step): its
/// training, its fit with the KL to the source material where there is one, its cost.
pub(crate) fn method_report(
    method: &str,
    training: Training,
    (fit, kl_vs_source): (Fit, Option<f64>),
    cost: Cost,
) -> MethodReport {
    MethodReport {
        method: method.to_string(),
        train_seconds: training.seconds,
        final_loss: training.final_loss,
        blob_bytes: training.blob_bytes,
        blob_vs_model: training.blob_vs_model,
        fit,
        kl_vs_source,
        cost,
        render: None,
    }
}
