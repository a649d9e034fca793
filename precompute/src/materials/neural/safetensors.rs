//! Neural materials in the safetensors format, to import models trained elsewhere (PyTorch)
//! and to export ours (`NEURAL.md` documents the format).
//!
//! | tensor               | shape                  | meaning                                         |
//! |----------------------|------------------------|-------------------------------------------------|
//! | `features`           | `[H, W, 8]`            | feature texture, rows along v, channels last     |
//! | `decoder.{l}.weight` | `[out_l, in_l]`        | layer `l` weight, PyTorch `nn.Linear` layout     |
//! | `decoder.{l}.bias`   | `[out_l]`              | layer `l` bias                                   |
//!
//! with `l = 0..4` and `(in, out)` = (14, 64), (64, 64), (64, 64), (64, 3) (the decoder of
//! `core/ARCHITECTURES.md` §7). Element types F32, F16, BF16 or F64 are accepted (widened to
//! f32); other tensors in the file are ignored and reported.

use std::collections::HashMap;

use anyhow::{anyhow, bail, Context, Result};
use neusample::neural_material::{DECODER_PARAM_COUNT, MAX_TEXTURE_SIZE};
use safetensors::tensor::{Dtype, SafeTensors, TensorView};

use super::{NeuralParts, DECODER_SIZES};
use crate::materials::FEATURE_DIM;

/// Name of the feature texture tensor.
pub const FEATURES: &str = "features";
/// Value of the `format` metadata entry written by [`write()`].
pub const FORMAT: &str = "neusample-neural-material";
/// Number of decoder layers.
pub const LAYERS: usize = DECODER_SIZES.len() - 1;

/// Names of the weight and bias tensors of decoder layer `l`.
#[must_use]
pub fn layer_names(l: usize) -> (String, String) {
    (format!("decoder.{l}.weight"), format!("decoder.{l}.bias"))
}

/// A one-line description of the decoder, written as the `architecture` metadata entry.
#[must_use]
pub fn architecture() -> String {
    let sizes: Vec<String> = DECODER_SIZES.iter().map(ToString::to_string).collect();
    format!(
        "decoder {} relu; input [phi(8), wi.xy, wo.xy, h.xy]; f = exp(clamp(out, {}, {}))",
        sizes.join("-"),
        neusample::neural_material::LOG_F_MIN,
        neusample::neural_material::LOG_F_MAX
    )
}

/// Element type of exported tensors.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum ExportDtype {
    /// IEEE binary32.
    F32,
    /// IEEE binary16.
    F16,
}

/// A neural material read from safetensors.
#[derive(Clone, Debug)]
pub struct Imported {
    /// The arrays in the runtime layout.
    pub parts: NeuralParts,
    /// Tensors present in the file but not used (sorted).
    pub ignored: Vec<String>,
    /// The file's metadata (`__metadata__`).
    pub metadata: HashMap<String, String>,
}

fn shape_str(s: &[usize]) -> String {
    format!(
        "[{}]",
        s.iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join(", ")
    )
}

/// The values of a tensor as f32, checked finite.
fn values(name: &str, t: &TensorView<'_>) -> Result<Vec<f32>> {
    let d = t.data();
    let v: Vec<f32> = match t.dtype() {
        Dtype::F32 => d
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect(),
        Dtype::F16 => d
            .chunks_exact(2)
            .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
            .collect(),
        Dtype::BF16 => d
            .chunks_exact(2)
            .map(|b| half::bf16::from_le_bytes([b[0], b[1]]).to_f32())
            .collect(),
        Dtype::F64 => d
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32)
            .collect(),
        other => {
            bail!("tensor `{name}` has element type {other:?}; expected F32, F16, BF16 or F64")
        }
    };
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        bail!(
            "tensor `{name}` has a non-finite value at flat index {i} ({})",
            v[i]
        );
    }
    Ok(v)
}

fn tensor<'a>(st: &SafeTensors<'a>, name: &str, expected: &str) -> Result<TensorView<'a>> {
    st.tensor(name).map_err(|_| {
        let mut have: Vec<_> = st.names().into_iter().map(str::to_string).collect();
        have.sort();
        anyhow!(
            "missing tensor `{name}` (expected shape {expected}); the file has: {}",
            if have.is_empty() {
                "no tensors".to_string()
            } else {
                have.join(", ")
            }
        )
    })
}

/// Reads a neural material from safetensors bytes (module docs). Errors name the tensor and
/// the expected and actual shapes.
pub fn read(bytes: &[u8]) -> Result<Imported> {
    let st = SafeTensors::deserialize(bytes)
        .map_err(|e| anyhow!("not a valid safetensors file: {e}"))?;
    let (_, meta) = SafeTensors::read_metadata(bytes)
        .map_err(|e| anyhow!("not a valid safetensors file: {e}"))?;
    let metadata = meta.metadata().clone().unwrap_or_default();

    let f = tensor(&st, FEATURES, "[H, W, 8]")?;
    let s = f.shape();
    if s.len() != 3
        || s[2] != FEATURE_DIM
        || s[0] == 0
        || s[1] == 0
        || s[0] > MAX_TEXTURE_SIZE as usize
        || s[1] > MAX_TEXTURE_SIZE as usize
    {
        bail!(
            "tensor `{FEATURES}` has shape {}, expected [H, W, {FEATURE_DIM}] (rows along v, \
             columns along u, channels last; 1 ≤ H, W ≤ {MAX_TEXTURE_SIZE}). From a PyTorch \
             [1, {FEATURE_DIM}, H, W] parameter: `t[0].permute(1, 2, 0).contiguous()`",
            shape_str(s)
        );
    }
    let (height, width) = (s[0] as u32, s[1] as u32);
    let texture = values(FEATURES, &f)?;

    let mut params = Vec::with_capacity(DECODER_PARAM_COUNT);
    let mut used = vec![FEATURES.to_string()];
    for l in 0..LAYERS {
        let (i, o) = (DECODER_SIZES[l], DECODER_SIZES[l + 1]);
        let (wn, bn) = layer_names(l);
        let w = tensor(&st, &wn, &shape_str(&[o, i]))?;
        if w.shape() != [o, i] {
            bail!(
                "tensor `{wn}` has shape {}, expected {} ([out, in], the PyTorch nn.Linear \
                 layout, of decoder layer {l}: {i} → {o})",
                shape_str(w.shape()),
                shape_str(&[o, i])
            );
        }
        let b = tensor(&st, &bn, &shape_str(&[o]))?;
        if b.shape() != [o] {
            bail!(
                "tensor `{bn}` has shape {}, expected {} (bias of decoder layer {l})",
                shape_str(b.shape()),
                shape_str(&[o])
            );
        }
        let wv = values(&wn, &w)?;
        // PyTorch [out, in] → runtime input-major W[i][o].
        for r in 0..i {
            for c in 0..o {
                params.push(wv[c * i + r]);
            }
        }
        params.extend(values(&bn, &b)?);
        used.push(wn);
        used.push(bn);
    }
    let mut ignored: Vec<String> = st
        .names()
        .into_iter()
        .filter(|n| !used.iter().any(|u| u == n))
        .map(str::to_string)
        .collect();
    ignored.sort();
    let parts = NeuralParts {
        width,
        height,
        texture,
        params,
    };
    parts.validate()?;
    Ok(Imported {
        parts,
        ignored,
        metadata,
    })
}

/// Reads a safetensors file (errors name the file).
pub fn read_file(path: &std::path::Path) -> Result<Imported> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    read(&bytes).with_context(|| format!("safetensors file {}", path.display()))
}

fn encode(v: &[f32], dtype: ExportDtype) -> Vec<u8> {
    match dtype {
        ExportDtype::F32 => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
        ExportDtype::F16 => v
            .iter()
            .flat_map(|x| half::f16::from_f32(*x).to_le_bytes())
            .collect(),
    }
}

/// Serialises `parts` as safetensors (module docs), with metadata `format`, `name` and
/// `architecture` plus `extra`.
pub fn write(
    parts: &NeuralParts,
    dtype: ExportDtype,
    name: &str,
    extra: &[(&str, String)],
) -> Result<Vec<u8>> {
    parts.validate()?;
    let st_dtype = match dtype {
        ExportDtype::F32 => Dtype::F32,
        ExportDtype::F16 => Dtype::F16,
    };
    let mut buffers: Vec<(String, Vec<usize>, Vec<u8>)> = vec![(
        FEATURES.to_string(),
        vec![parts.height as usize, parts.width as usize, FEATURE_DIM],
        encode(&parts.texture, dtype),
    )];
    let mut at = 0;
    for l in 0..LAYERS {
        let (i, o) = (DECODER_SIZES[l], DECODER_SIZES[l + 1]);
        let w = &parts.params[at..at + i * o];
        let b = &parts.params[at + i * o..at + i * o + o];
        at += i * o + o;
        // Runtime input-major W[i][o] → PyTorch [out, in].
        let mut t = Vec::with_capacity(i * o);
        for c in 0..o {
            for r in 0..i {
                t.push(w[r * o + c]);
            }
        }
        let (wn, bn) = layer_names(l);
        buffers.push((wn, vec![o, i], encode(&t, dtype)));
        buffers.push((bn, vec![o], encode(b, dtype)));
    }
    let views = buffers
        .iter()
        .map(|(n, s, d)| Ok((n.clone(), TensorView::new(st_dtype, s.clone(), d)?)))
        .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()
        .map_err(|e| anyhow!("{e}"))?;
    let mut meta: HashMap<String, String> = HashMap::new();
    meta.insert("format".into(), FORMAT.into());
    meta.insert("name".into(), name.into());
    meta.insert("architecture".into(), architecture());
    for (k, v) in extra {
        meta.insert((*k).to_string(), v.clone());
    }
    safetensors::tensor::serialize(views, Some(meta)).map_err(|e| anyhow!("{e}"))
}
