//! Baking: a trained model → a blob, and the check that the blob reproduces the model.
//!
//! The check opens the written bytes with the runtime (`neusample::Blob::open`, the
//! same code a renderer runs) and compares its disk density with the trained model's
//! ([`crate::train::model_pdf_disk`], f64) at random conditions and points. f32 blobs must
//! agree to [`F32_TOLERANCE`] relative, compact histogram-mixture tables to
//! [`COMPACT_TOLERANCE`]; f16 blobs are reported, with a looser bound.
//!
//! A histogram mixture's tables are written in the compact layout by default
//! ([`DEFAULT_TABLE_LAYOUT`]: u16 row CDFs and f32 row totals, no values), a quarter of the
//! memory of values plus f32 CDFs; [`compact_blob`] converts an existing blob.

use anyhow::{bail, Context, Result};
use glam::Vec2;
use neusample::distrib::table2d::TableLayout;
use neusample::samplers::histogram_mixture as histogram;
use neusample::{Blob, BlobWriter, SamplerKind, TensorRole, Weights};
use neusample::{DType, Prepared, Sampler};
use rand::{RngExt, SeedableRng};

use crate::groundtruth;
use crate::materials::Material;
use crate::train::{model_pdf_disk, pole_tolerance, Trained};

/// Largest relative difference allowed between an f32 blob and the trained model.
pub const F32_TOLERANCE: f64 = 1e-3;

/// Largest relative difference allowed between an f16 blob and the trained model (f16
/// weights carry 11 significant bits; errors compound through the layers).
pub const F16_TOLERANCE: f64 = 0.25;

/// Largest relative difference allowed between a blob with compact histogram-mixture tables
/// and the trained model: each row's CDF is quantised to 1/65535 of the row, so a cell at the
/// comparison's floor (10⁻³ of the peak) may be off by a few percent.
pub const COMPACT_TOLERANCE: f64 = 0.05;

/// How [`blob_bytes`] stores a histogram mixture's tables.
pub const DEFAULT_TABLE_LAYOUT: TableLayout = TableLayout::Compact;

/// Serialises a trained model as a blob with the given storage type, histogram-mixture
/// tables in [`DEFAULT_TABLE_LAYOUT`].
pub fn blob_bytes(trained: &Trained, dtype: DType, label: &str) -> Result<Vec<u8>> {
    blob_bytes_with(trained, dtype, DEFAULT_TABLE_LAYOUT, label)
}

/// [`blob_bytes`] with the histogram-mixture table layout chosen (ignored by other kinds).
/// The compact layout stores no values and each row's CDF as u16 (a quarter of the
/// memory); `dtype` then applies to the network parameters only.
pub fn blob_bytes_with(
    trained: &Trained,
    dtype: DType,
    layout: TableLayout,
    label: &str,
) -> Result<Vec<u8>> {
    let mut w = BlobWriter::new(trained.method, dtype, label).isotropic(trained.isotropic);
    if let Some(t) = &trained.tables {
        let b = &t.baked;
        w = w.histogram_dims(b.t_levels, b.resolution, t.interpolation);
        match layout {
            TableLayout::Values => {
                let baked = t.rebake(dtype)?;
                w.tensor(TensorRole::Mass, &baked.mass)
                    .tensor(TensorRole::Table, &baked.table)
                    .tensor(TensorRole::Marginal, &baked.marginal)
                    .tensor(TensorRole::Conditional, &baked.conditional);
            }
            TableLayout::Compact => {
                let c = histogram::try_bake_compact(
                    &t.raw,
                    b.bases as usize,
                    b.t_levels as usize,
                    b.resolution as usize,
                )
                .map_err(|e| anyhow::anyhow!("baking compact tables: {e}"))?;
                write_compact(&mut w, &c);
            }
        }
    } else if trained.method == SamplerKind::HistogramMixture {
        bail!("the histogram mixture has no baked tables");
    }
    w.tensor(TensorRole::Params, &trained.params);
    Ok(w.to_bytes())
}

/// [`blob_bytes`] checked with [`verify`] (`conditions`, `seed` as there). A histogram
/// mixture whose compact tables miss [`COMPACT_TOLERANCE`] on `material` (lobes so sharp that
/// a row's u16 CDF cannot resolve the cells near the comparison's floor) is baked again with
/// value tables and f32 CDFs, which must then pass the f32 tolerance; the note on stderr
/// says so. Any other failure is an error.
pub fn checked_blob_bytes(
    trained: &Trained,
    dtype: DType,
    label: &str,
    material: &dyn Material,
    conditions: usize,
    seed: u64,
) -> Result<(Vec<u8>, Verification)> {
    checked_blob_bytes_by(trained, dtype, label, |bytes| {
        verify(trained, bytes, material, conditions, seed)
    })
}

/// [`checked_blob_bytes`] with the check given: `check` verifies a written blob (the
/// compact one first, then, if it fails, the one with value tables).
pub fn checked_blob_bytes_by(
    trained: &Trained,
    dtype: DType,
    label: &str,
    check: impl Fn(&[u8]) -> Result<Verification>,
) -> Result<(Vec<u8>, Verification)> {
    let bytes = blob_bytes(trained, dtype, label)?;
    match check(&bytes) {
        Ok(v) => Ok((bytes, v)),
        Err(e) if trained.tables.is_some() && DEFAULT_TABLE_LAYOUT == TableLayout::Compact => {
            let values = blob_bytes_with(trained, dtype, TableLayout::Values, label)?;
            let v = check(&values)
                .with_context(|| format!("value tables, after the compact ones failed: {e:#}"))?;
            eprintln!(
                "note: {e:#}; the blob keeps its tables as values and f32 CDFs instead ({} bytes, max relative difference {:.1e})",
                values.len(),
                v.max_relative
            );
            Ok((values, v))
        }
        Err(e) => Err(e),
    }
}

fn write_compact(w: &mut BlobWriter<'_>, c: &histogram::CompactTables) {
    w.tensor(TensorRole::Mass, &c.mass)
        .tensor(TensorRole::Marginal, &c.marginal)
        .tensor_u16(TensorRole::Conditional, &c.conditional);
}

/// Re-encodes a histogram-mixture blob whose tables store values ([`TableLayout::Values`])
/// in the compact layout: each slice's raw values are recovered as `table · mass` and baked
/// again with [`histogram::try_bake_compact`]; the parameters and header are kept. A blob of
/// another kind, or one already compact, is an error.
pub fn compact_blob(bytes: &[u8]) -> Result<Vec<u8>> {
    let blob = Blob::open(bytes).context("the blob does not open")?;
    let h = *blob.header();
    if h.kind != SamplerKind::HistogramMixture {
        bail!(
            "only a histogram mixture has tables to compact (this blob is {})",
            h.kind.name()
        );
    }
    if blob.is_compact() {
        bail!("the blob's tables are compact already");
    }
    let read = |role: TensorRole| -> Result<Vec<f32>> {
        let t = blob
            .tensor(role)
            .with_context(|| format!("the blob has no {} tensor", role.name()))?;
        Ok((0..t.len()).map(|i| t.at(i)).collect())
    };
    let (mass, table, params) = (
        read(TensorRole::Mass)?,
        read(TensorRole::Table)?,
        read(TensorRole::Params)?,
    );
    let (t, n) = (h.t_levels as usize, h.resolution as usize);
    let slices = mass.len();
    let raw: Vec<f32> = table
        .chunks(n * n)
        .zip(&mass)
        .flat_map(|(slice, &m)| slice.iter().map(move |&v| v * m))
        .collect();
    let c = histogram::try_bake_compact(&raw, slices / t.max(1), t, n)
        .map_err(|e| anyhow::anyhow!("baking compact tables: {e}"))?;
    let mut w = BlobWriter::new(h.kind, h.dtype, h.label)
        .histogram_dims(h.t_levels, h.resolution, h.interpolation)
        .defensive(blob.defensive())
        .isotropic(blob.isotropic());
    write_compact(&mut w, &c);
    w.tensor(TensorRole::Params, &params);
    let out = w.to_bytes();
    Blob::open(&out).context("the compacted blob does not open")?;
    Ok(out)
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
    /// The largest relative difference within 1e-2 of a pole of the disk, for a method with
    /// a tolerance of its own there ([`pole_tolerance`]; 0 for the others, whose points all
    /// count above).
    pub max_relative_pole: f64,
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
    // The learned part (a defensive weight is not part of the trained model), turned as the
    // runtime turns it where the model was trained with `wi` at azimuth 0.
    let sampler =
        neusample::Defensive::plain(*blob.sampler()?.inner()).with_isotropic(blob.isotropic());
    let tolerance = match blob.header().dtype {
        DType::F16 => F16_TOLERANCE,
        _ if blob.is_compact() => COMPACT_TOLERANCE,
        // U16 is never a header dtype (the blob would not have opened).
        DType::F32 | DType::U16 => F32_TOLERANCE,
    };
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let mut max_rel = 0f64;
    let mut max_pole = 0f64;
    let pole_tolerance = pole_tolerance(trained.method);
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
            if pole_tolerance.is_some() && 1.0 - p.y.abs() < 1e-2 {
                max_pole = max_pole.max(rel);
            } else if rel > max_rel {
                max_rel = rel;
            }
            points += 1;
        }
    }
    let v = Verification {
        points,
        max_relative: max_rel,
        tolerance,
        max_relative_pole: max_pole,
    };
    if let Some(tol) = pole_tolerance.filter(|tol| !(max_pole <= *tol)) {
        bail!(
            "the {} blob does not reproduce the trained model near the poles: max relative pdf difference {:.3e} > {:.0e}",
            trained.method.name(),
            max_pole,
            tol
        );
    }
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
