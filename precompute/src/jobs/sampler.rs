//! Samplers as jobs: train one method on a material, bake it and write the blob once the
//! runtime reproduced the trained model (`train`), or every method in turn with a typed
//! summary (`train --method all`, `summary.json`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use neusample::samplers::CosineSampler;
use neusample::DType;
use neusample::{Blob, SamplerKind};
use serde::{Deserialize, Serialize};

use crate::bake::{self, Verification};
use crate::eval;
use crate::materials::Material;
use crate::train::{self, TrainConfig, Trained};
use crate::util::io;
use crate::util::rng::Stream;

/// Conditions of the blob check after training ([`bake::verify`]).
const VERIFY_CONDITIONS: usize = 16;

/// Trains `method` on `material`, bakes the blob with storage `dtype`, verifies it against the
/// model and writes it atomically to `out`.
pub fn train_sampler(
    material: &dyn Material,
    method: SamplerKind,
    cfg: &TrainConfig,
    dtype: DType,
    out: &Path,
) -> Result<(Trained, Vec<u8>, Verification)> {
    let trained = train::train(material, method, cfg)?;
    let label = format!(
        "material={} method={} steps={} seed={} dtype={:?}",
        material.name(),
        method.name(),
        trained.steps,
        cfg.common.seed,
        dtype
    );
    let (bytes, v) = bake::checked_blob_bytes(
        &trained,
        dtype,
        &label,
        material,
        VERIFY_CONDITIONS,
        Stream::BlobCheck.of(cfg.common.seed),
    )
    .with_context(|| format!("verifying the blob for {}", out.display()))?;
    io::atomic_write(out, &bytes)?;
    Ok((trained, bytes, v))
}

/// `train --method all` (or a list): every method in turn on one material.
#[derive(Clone, Debug)]
pub struct SweepJob {
    /// The methods, in order.
    pub methods: Vec<SamplerKind>,
    /// Training settings of every method.
    pub config: TrainConfig,
    /// Storage type of the blobs.
    pub dtype: DType,
    /// Folder receiving `<method>.nsb` and `summary.json`.
    pub out_dir: PathBuf,
    /// Evaluation conditions of KL(p*‖p) and pdf MSE.
    pub eval_conditions: usize,
    /// Whether the configuration is the quick one (recorded in the summary).
    pub quick: bool,
    /// Step factor relative to the defaults (recorded in the summary).
    pub steps_scale: f64,
}

/// Ground-truth resolution of the sweep's evaluation.
pub const SWEEP_EVAL_RES: usize = 64;

/// `summary.json` of a sweep.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Summary {
    /// Material name.
    pub material: String,
    /// Seed of training and evaluation.
    pub seed: u64,
    /// Whether the quick configuration was used.
    pub quick: bool,
    /// Step factor relative to the defaults.
    pub steps_scale: f64,
    /// Evaluation conditions.
    pub eval_conditions: usize,
    /// Ground-truth resolution of the evaluation.
    pub eval_res: usize,
    /// Cosine sampling first, then one row per method in order.
    pub methods: Vec<SummaryRow>,
}

/// One method of a [`Summary`]: the fit and training figures, or the error of a failed
/// method. Absent fields are omitted (cosine has no blob; a failed method has only `error`).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct SummaryRow {
    /// Method name ([`SamplerKind::name`]).
    pub method: String,
    /// The blob's fit through the runtime, its fields at the row's top level (`kl_divergence`,
    /// `chi2`, …; summaries written before it was stored whole name the KL `kl` and lack
    /// `conditions`, `chi2_worst_condition` and `mass_in_disk`, read as 0, 0 and NaN).
    #[serde(flatten, default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<eval::Fit>,
    /// Training time, seconds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub train_seconds: Option<f64>,
    /// Training steps.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps: Option<usize>,
    /// Loss of the last step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_loss: Option<f64>,
    /// Blob size in bytes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blob_bytes: Option<usize>,
    /// Largest relative pdf difference between the blob and the trained model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blob_vs_model: Option<f64>,
    /// Why the method failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Runs the sweep: each blob is written atomically and verified, then evaluated through the
/// runtime (KL(p*‖p), pdf MSE at [`SWEEP_EVAL_RES`]², the demo's evaluation seed).
/// `summary.json` is rewritten after every method; a failing method is recorded (and printed)
/// and the sweep goes on. Returns the summary; count the rows with an `error`.
pub fn sweep(material: &dyn Material, job: &SweepJob) -> Result<Summary> {
    let seed = job.config.common.seed;
    let eval_seed = Stream::Fit.of(seed);
    let fit = eval::fit(
        &CosineSampler,
        material,
        job.eval_conditions,
        SWEEP_EVAL_RES,
        eval_seed,
    );
    let mut summary = Summary {
        material: material.name().to_string(),
        seed,
        quick: job.quick,
        steps_scale: job.steps_scale,
        eval_conditions: job.eval_conditions,
        eval_res: SWEEP_EVAL_RES,
        methods: vec![SummaryRow {
            method: SamplerKind::Cosine.name().to_string(),
            fit: Some(fit),
            train_seconds: Some(0.0),
            steps: Some(0),
            ..SummaryRow::default()
        }],
    };
    for &method in &job.methods {
        let out = job.out_dir.join(format!("{}.nsb", method.name()));
        let row = train_sampler(material, method, &job.config, job.dtype, &out).and_then(
            |(trained, bytes, v)| {
                let blob = Blob::open(&bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
                let sampler = blob.sampler().map_err(|e| anyhow::anyhow!("{e}"))?;
                let fit = eval::fit(
                    &sampler,
                    material,
                    job.eval_conditions,
                    SWEEP_EVAL_RES,
                    eval_seed,
                );
                Ok(SummaryRow {
                    method: method.name().to_string(),
                    fit: Some(fit),
                    train_seconds: Some(trained.seconds),
                    steps: Some(trained.steps),
                    final_loss: trained.loss_history.last().copied().map(f64::from),
                    blob_bytes: Some(bytes.len()),
                    blob_vs_model: Some(v.max_relative),
                    error: None,
                })
            },
        );
        summary.methods.push(row.unwrap_or_else(|e| {
            eprintln!("error: {} on {}: {e:#}", method.name(), material.name());
            SummaryRow {
                method: method.name().to_string(),
                error: Some(format!("{e:#}")),
                ..SummaryRow::default()
            }
        }));
        io::atomic_write(
            &job.out_dir.join("summary.json"),
            serde_json::to_string_pretty(&summary)?.as_bytes(),
        )?;
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fit() -> eval::Fit {
        eval::Fit {
            conditions: 8,
            kl_divergence: 0.25,
            chi2: 0.5,
            chi2_worst: 2.0,
            chi2_worst_condition: 3,
            pdf_mse: 1e-3,
            mass_in_disk: 0.99,
            sampled: None,
        }
    }

    #[test]
    fn a_row_keeps_its_fit_at_the_top_level() {
        let row = SummaryRow {
            method: "flow".into(),
            fit: Some(fit()),
            steps: Some(100),
            ..SummaryRow::default()
        };
        let v = serde_json::to_value(&row).unwrap();
        assert_eq!(v["kl_divergence"], 0.25);
        assert_eq!(v["chi2_worst_condition"], 3);
        assert_eq!(v["steps"], 100);
        assert!(v.get("fit").is_none() && v.get("error").is_none());
        let back: SummaryRow = serde_json::from_value(v).unwrap();
        let f = back.fit.unwrap();
        assert_eq!(
            (f.kl_divergence, f.chi2_worst, f.mass_in_disk),
            (0.25, 2.0, 0.99)
        );
        assert_eq!(back.steps, Some(100));
    }

    #[test]
    fn rows_of_older_summaries_and_failed_rows_read() {
        let old = r#"{"method": "flow", "kl": 0.3, "chi2": 0.6, "chi2_worst": 1.5,
            "pdf_mse": 0.002, "train_seconds": 12.0, "steps": 50}"#;
        let row: SummaryRow = serde_json::from_str(old).unwrap();
        let f = row.fit.expect("an older row's fit");
        assert_eq!((f.kl_divergence, f.chi2, f.pdf_mse), (0.3, 0.6, 0.002));
        assert_eq!((f.conditions, f.chi2_worst_condition), (0, 0));
        assert!(f.mass_in_disk.is_nan());
        assert_eq!(row.train_seconds, Some(12.0));
        let failed: SummaryRow =
            serde_json::from_str(r#"{"method": "flow", "error": "diverged"}"#).unwrap();
        assert!(failed.fit.is_none());
        assert_eq!(failed.error.as_deref(), Some("diverged"));
        let v = serde_json::to_value(&failed).unwrap();
        assert_eq!(v.as_object().unwrap().len(), 2);
    }
}
