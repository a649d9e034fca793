//! `measured-blob`: a measured material of the RGL database (a Mitsuba `.bsdf` tensor file)
//! converted into a neusample blob of kind `measured` (`core/BLOB.md`), which the runtime, the
//! C ABI and the Python binding open without the file reader.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use neusample::{Blob, BlobWriter, MeasuredMaterial, Weights};
use neusample_owned::measured::OwnedMeasured;
use neusample_owned::measured_label;
use serde::{Deserialize, Serialize};

use crate::materials::neural::is_blob_file;
use crate::util::io;

/// What to convert and where to write it.
#[derive(Clone, Debug)]
pub struct MeasuredBlobJob {
    /// The RGL `.bsdf` file.
    pub input: PathBuf,
    /// The blob to write (atomically).
    pub out: PathBuf,
    /// The label's `name=` field (default: the input's file stem).
    pub name: Option<String>,
}

/// What [`measured_blob`] wrote.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MeasuredBlobReport {
    /// The source file.
    pub input: String,
    /// The blob written.
    pub out: String,
    /// Its size in bytes.
    pub bytes: usize,
    /// Its label.
    pub label: String,
    /// The shape tensor: `n_phi, n_theta`, the `[width, height]` of ndf, sigma, vndf and rgb,
    /// and the jacobian flag.
    pub shape: Vec<u32>,
}

/// Reads `job.input`, writes its blob to `job.out` after checking that the blob opens and
/// holds the file's tables bit for bit.
///
/// # Errors
/// The file cannot be read or is not a measured material (the message names the file and
/// the field), the output would overwrite the input, or it cannot be written.
pub fn measured_blob(job: &MeasuredBlobJob) -> Result<MeasuredBlobReport> {
    if job.out == job.input {
        bail!(
            "the output {} would overwrite the input; choose another path with -o",
            job.out.display()
        );
    }
    if is_blob_file(&job.input) && job.input.is_file() {
        bail!(
            "{} is already a neusample blob (`neusample inspect` describes it); give the RGL \
             `.bsdf` file",
            job.input.display()
        );
    }
    let data = OwnedMeasured::open(&job.input)?;
    let name = match &job.name {
        Some(n) => n.clone(),
        None => stem(&job.input),
    };
    if name.is_empty() || name.chars().any(char::is_whitespace) {
        bail!("--name must be a non-empty word without spaces, got `{name}`");
    }
    let source = job
        .input
        .file_name()
        .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
    let label = measured_label(&name, &source, data.description());
    let bytes = measured_blob_bytes(data.material(), &label)
        .with_context(|| format!("converting {}", job.input.display()))?;
    io::atomic_write(&job.out, &bytes)?;
    let s = data.material().shape();
    Ok(MeasuredBlobReport {
        input: job.input.display().to_string(),
        out: job.out.display().to_string(),
        bytes: bytes.len(),
        label,
        shape: s
            .values()
            .into_iter()
            .chain([u32::from(data.material().jacobian())])
            .collect(),
    })
}

/// The blob of `material`, checked: it opens, and its material holds the same tables, bit for
/// bit, and the same jacobian flag.
///
/// # Errors
/// The blob does not open or differs (a bug: the writer and the reader disagree).
pub fn measured_blob_bytes<W: Weights>(
    material: &MeasuredMaterial<W>,
    label: &str,
) -> Result<Vec<u8>> {
    let bytes = BlobWriter::measured(material, label).to_bytes();
    let blob = Blob::open(&bytes).map_err(|e| anyhow::anyhow!("the written blob: {e}"))?;
    let back = blob
        .measured()
        .map_err(|e| anyhow::anyhow!("the written blob: {e}"))?;
    if back.shape() != material.shape() || back.jacobian() != material.jacobian() {
        bail!("the written blob's shape differs from the material's");
    }
    let pairs = back
        .tables()
        .as_array()
        .into_iter()
        .zip(material.tables().as_array());
    for ((name, _), (a, b)) in material.shape().lens().into_iter().zip(pairs) {
        let same =
            a.len() == b.len() && (0..a.len()).all(|i| a.at(i).to_bits() == b.at(i).to_bits());
        if !same {
            bail!("the written blob's `{name}` table differs from the material's");
        }
    }
    Ok(bytes)
}

fn stem(path: &Path) -> String {
    path.file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
}
