//! `inspect`: what a blob holds, as a typed description (`inspect --json`, schema in
//! `docs/usage.md`) and as text.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use neusample::Weights;
use neusample::{Blob, BlobKind, TensorRole};
use serde::{Deserialize, Serialize};

use crate::util::io;

/// A blob's description (`inspect --json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Inspection {
    /// The file.
    pub file: String,
    /// File size in bytes.
    pub bytes: usize,
    /// The blob's format version (1; 2 with a defensive weight; 3 when isotropic).
    pub format_version: u32,
    /// The sampler's defensive weight α (`Defensive`; 0 in version-1 blobs).
    #[serde(default)]
    pub defensive: f32,
    /// Whether the sampler sees `wi` at azimuth 0 (`Defensive::with_isotropic`).
    #[serde(default)]
    pub isotropic: bool,
    /// Kind name ([`neusample::BlobKind::name`]).
    pub kind: String,
    /// Storage type of the parameters (`f32`, `f16`).
    pub dtype: String,
    /// Length of φ.
    pub feature_dim: u32,
    /// Number of network parameters.
    pub param_count: u32,
    /// Histogram mixture: bases K.
    pub basis: u32,
    /// Histogram mixture: latent levels T; neural material: texture height.
    pub t_levels: u32,
    /// Histogram grid N; neural material: texture width.
    pub resolution: u32,
    /// Histogram mixture: `nearest` or `linear`.
    pub interpolation: String,
    /// The blob's label.
    pub label: String,
    /// Always `ok` (a blob whose checksum fails does not open).
    pub checksum: String,
    /// The tensors in role order.
    pub tensors: Vec<TensorInfo>,
    /// A measured material's table sizes (absent for every other kind).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measured: Option<MeasuredInfo>,
}

/// The table sizes of a measured-material blob (its `shape` tensor, read).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MeasuredInfo {
    /// Number of `φi` nodes (1 or 2 for isotropic data).
    pub n_phi: u32,
    /// Number of `θi` nodes.
    pub n_theta: u32,
    /// Whether the data is isotropic.
    pub isotropic: bool,
    /// Whether the RGB values are multiplied by `D / (4σ)`.
    pub jacobian: bool,
    /// `[width, height]` of the NDF table.
    pub ndf: [u32; 2],
    /// `[width, height]` of the projected-area table.
    pub sigma: [u32; 2],
    /// `[width, height]` of each VNDF slice.
    pub vndf: [u32; 2],
    /// `[width, height]` of each luminance and RGB slice.
    pub rgb: [u32; 2],
    /// The element count of each of the 11 tables inside the `tables` tensor, in order.
    pub tables: Vec<(String, u32)>,
}

/// One tensor of an [`Inspection`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TensorInfo {
    /// Role name.
    pub role: String,
    /// Element type (`f32`, `f16`).
    pub dtype: String,
    /// Byte offset in the blob.
    pub offset: u32,
    /// Number of elements.
    pub count: u32,
    /// Smallest element (the stored value, widened).
    pub min: f64,
    /// Largest element.
    pub max: f64,
    /// Mean of the elements.
    pub mean: f64,
}

/// Reads, validates and describes the blob at `path`.
pub fn inspect(path: &Path) -> Result<Inspection> {
    let bytes = io::read_blob(path)?;
    let blob = Blob::open(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let h = blob.header();
    let lower = |v: &dyn std::fmt::Debug| format!("{v:?}").to_lowercase();
    let mut tensors = Vec::new();
    for role in TensorRole::ALL {
        if let (Some(e), Some(t)) = (blob.entry(role), blob.tensor(role)) {
            let n = t.len();
            let (mut lo, mut hi, mut sum) = (f32::INFINITY, f32::NEG_INFINITY, 0f64);
            for i in 0..n {
                let v = t.at(i);
                lo = lo.min(v);
                hi = hi.max(v);
                sum += f64::from(v);
            }
            tensors.push(TensorInfo {
                role: role.name().to_string(),
                dtype: lower(&e.dtype),
                offset: e.offset,
                count: e.count,
                min: f64::from(lo),
                max: f64::from(hi),
                mean: if n > 0 { sum / f64::from(n) } else { 0.0 },
            });
        }
    }
    let measured = if h.kind == BlobKind::Measured {
        let m = blob
            .measured()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        let sh = m.shape();
        Some(MeasuredInfo {
            n_phi: sh.n_phi,
            n_theta: sh.n_theta,
            isotropic: m.isotropic(),
            jacobian: m.jacobian(),
            ndf: sh.ndf,
            sigma: sh.sigma,
            vndf: sh.vndf,
            rgb: sh.rgb,
            tables: sh
                .lens()
                .iter()
                .map(|&(name, n)| (name.to_string(), n))
                .collect(),
        })
    } else {
        None
    };
    Ok(Inspection {
        file: path.display().to_string(),
        bytes: bytes.len(),
        format_version: blob.version(),
        defensive: blob.defensive(),
        isotropic: blob.isotropic(),
        kind: h.kind.name().to_string(),
        dtype: lower(&h.dtype),
        feature_dim: h.feature_dim,
        param_count: h.param_count,
        basis: h.basis,
        t_levels: h.t_levels,
        resolution: h.resolution,
        interpolation: lower(&h.interpolation),
        label: h.label.to_string(),
        checksum: "ok".to_string(),
        tensors,
        measured,
    })
}

impl Inspection {
    /// The human-readable description `inspect` prints.
    #[must_use]
    pub fn text(&self) -> String {
        let mut s = String::new();
        let kind = BlobKind::from_name(&self.kind);
        let _ = writeln!(
            s,
            "{}: {} {}, {} bytes, format v{}, checksum ok",
            self.file,
            self.kind,
            if kind.and_then(BlobKind::sampler).is_some() {
                "sampler"
            } else {
                "blob"
            },
            self.bytes,
            self.format_version
        );
        if self.defensive > 0.0 {
            let _ = writeln!(
                s,
                "  defensive mixture: (1 − α)·p + α·cos/π with α = {}",
                self.defensive
            );
        }
        if self.isotropic {
            let _ = writeln!(s, "  isotropic: conditions turned to wi's azimuth 0");
        }
        if self.measured.is_none() {
            let _ = writeln!(
                s,
                "  storage {}, φ dim {}, {} params",
                self.dtype.to_uppercase(),
                self.feature_dim,
                self.param_count
            );
        }
        if let Some(m) = &self.measured {
            let _ = writeln!(
                s,
                "  measured material: {}×{} incident nodes (φi × θi, {}), jacobian {}",
                m.n_phi,
                m.n_theta,
                if m.isotropic {
                    "isotropic"
                } else {
                    "anisotropic"
                },
                if m.jacobian { "yes" } else { "no" }
            );
            let _ = writeln!(
                s,
                "  table sizes (w×h): ndf {}×{}, sigma {}×{}, vndf {}×{}, rgb {}×{}",
                m.ndf[0],
                m.ndf[1],
                m.sigma[0],
                m.sigma[1],
                m.vndf[0],
                m.vndf[1],
                m.rgb[0],
                m.rgb[1]
            );
            let parts: Vec<String> = m.tables.iter().map(|(n, c)| format!("{n} {c}")).collect();
            let _ = writeln!(s, "  tables tensor: {}", parts.join(", "));
        } else if kind == Some(BlobKind::NeuralMaterial) {
            let _ = writeln!(
                s,
                "  neural material: feature texture {}×{}×8 (NEURAL.md)",
                self.resolution, self.t_levels
            );
        } else if self.t_levels > 0 {
            let _ = writeln!(
                s,
                "  tables: K={} T={} N={} ({} in t)",
                self.basis,
                self.t_levels,
                self.resolution,
                capitalised(&self.interpolation)
            );
        }
        let _ = writeln!(s, "  label: {}", self.label);
        for t in &self.tensors {
            let _ = writeln!(
                s,
                "  tensor {:<12} {:>4} {:>8} elements at {:>7}  min {:.4} max {:.4} mean {:.4}",
                t.role, t.dtype, t.count, t.offset, t.min, t.max, t.mean
            );
        }
        s
    }
}

/// `linear` → `Linear` (the Debug spelling the text output always used).
fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}
