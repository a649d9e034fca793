//! Baking: a trained model → a blob, and the check that the blob reproduces the model.
//!
//! The check opens the written bytes with the runtime (`neusample::Blob::open`, the
//! same code a renderer runs) and compares its disk density with the trained model's
//! ([`crate::train::model_pdf_disk`], f64) at random conditions and points. f32 blobs must
//! agree to [`F32_TOLERANCE`] relative; f16 blobs are reported, with a looser bound.

use anyhow::{bail, Context, Result};
use glam::Vec2;
use neusample::{Blob, BlobWriter, SamplerKind, TensorRole};
use neusample::{DType, Prepared, Sampler};
use rand::{RngExt, SeedableRng};

use crate::groundtruth;
use crate::materials::Material;
use crate::train::{model_pdf_disk, Trained};

/// Largest relative difference allowed between an f32 blob and the trained model.
pub const F32_TOLERANCE: f64 = 1e-3;
/// Largest relative difference allowed between an f16 blob and the trained model (f16
/// weights carry 11 significant bits; errors compound through the layers).
pub const F16_TOLERANCE: f64 = 0.25;

/// Serialises a trained model as a blob with the given storage type.
pub fn blob_bytes(trained: &Trained, dtype: DType, label: &str) -> Result<Vec<u8>> {
    let mut w = BlobWriter::new(trained.method, dtype, label);
    if let Some(t) = &trained.tables {
        let baked = t.rebake(dtype)?;
        let n = baked.resolution;
        let levels = baked.t_levels;
        w = w.histogram_dims(levels, n, t.interpolation);
        w.tensor(TensorRole::Mass, &baked.mass)
            .tensor(TensorRole::Table, &baked.table)
            .tensor(TensorRole::Marginal, &baked.marginal)
            .tensor(TensorRole::Conditional, &baked.conditional);
    } else if trained.method == SamplerKind::HistogramMixture {
        bail!("the histogram mixture has no baked tables");
    }
    w.tensor(TensorRole::Params, &trained.params);
    Ok(w.to_bytes())
}

/// Outcome of [`verify`].
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Verification {
    /// Points compared.
    pub points: usize,
    /// Largest relative difference `|p_blob − p_model| / max(p_model, floor)`.
    pub max_relative: f64,
    /// The tolerance applied.
    pub tolerance: f64,
}

/// Opens `bytes` with the runtime and compares its density with the trained model at
/// `conditions` random conditions of `material` (× 64 points: uniform in the disk and
/// samples of the blob itself). Fails when the difference exceeds the tolerance.
pub fn verify(
    trained: &Trained,
    bytes: &[u8],
    material: &dyn Material,
    conditions: usize,
    seed: u64,
) -> Result<Verification> {
    let blob = Blob::open(bytes).context("the written blob does not open")?;
    let sampler = blob.sampler()?;
    let tolerance = match blob.header().dtype {
        DType::F16 => F16_TOLERANCE,
        // U16 is never a header dtype (the blob would not have opened).
        DType::F32 | DType::U16 => F32_TOLERANCE,
    };
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let mut max_rel = 0f64;
    let mut points = 0;
    for _ in 0..conditions {
        let c = groundtruth::random_condition(material, &mut rng);
        let Some(prep) = sampler.prepare(&c.phi, c.wi) else {
            bail!(
                "the blob refused a valid condition (φ {:?}, wi {})",
                c.phi,
                c.wi
            );
        };
        // A density floor relative to the condition's peak keeps the comparison meaningful
        // where both densities are ~0.
        let mut pts = Vec::with_capacity(64);
        for _ in 0..32 {
            let r = rng.random::<f32>().sqrt() * 0.999;
            let a = rng.random::<f32>() * std::f32::consts::TAU;
            pts.push(Vec2::new(r * a.cos(), r * a.sin()));
        }
        for _ in 0..32 {
            let u = Vec2::new(rng.random::<f32>(), rng.random::<f32>());
            if let Some(s) = prep.sample(u) {
                pts.push(Vec2::new(s.wo.x, s.wo.y));
            }
        }
        let model: Vec<f64> = pts
            .iter()
            .map(|&p| f64::from(model_pdf_disk(trained, &c.phi, c.wi, p)))
            .collect();
        let peak = model.iter().cloned().fold(0.0, f64::max);
        let floor = (peak * 1e-3).max(1e-6);
        for (p, m) in pts.iter().zip(&model) {
            let b = f64::from(prep.pdf_disk(*p));
            let rel = (b - m).abs() / m.max(floor);
            if rel > max_rel {
                max_rel = rel;
            }
            points += 1;
        }
    }
    let v = Verification {
        points,
        max_relative: max_rel,
        tolerance,
    };
    if !(max_rel <= tolerance) {
        bail!(
            "the blob does not reproduce the trained model: max relative pdf difference {:.3e} > {:.0e} over {} points",
            max_rel,
            tolerance,
            points
        );
    }
    Ok(v)
}
