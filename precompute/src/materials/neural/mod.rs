//! Neural materials (NeuMIP-style, `NEURAL.md`): a learned `W × H × 8` feature texture and a
//! decoder MLP, evaluated by the runtime's [`neusample::neural_material::NeuralMaterial`].
//!
//! * [`NeuralParts`] — the arrays of a neural material in the runtime layout, with
//!   conversion to and from blobs ([`NeuralParts::blob_bytes`], [`NeuralParts::from_blob`]);
//! * [`NeuralMaterialModel`] — a neural material as a [`Material`] (φ = the learned features,
//!   eval = the decoder, both through core), so every sampler trains on it unchanged;
//! * [`safetensors`] — import from and export to safetensors (`neusample import-material`).
//!
//! Fitting one to another material is `crate::train::neural_material`.

pub mod safetensors;

use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use glam::{Vec2, Vec3};
use neusample::neural_material::{
    texture_len, NeuralMaterial, DECODER_HIDDEN, DECODER_INPUTS, DECODER_OUTPUTS,
    DECODER_PARAM_COUNT, MAX_TEXTURE_SIZE,
};
use neusample::wavefront::{Features, FeaturesMut, RgbMut, Vec2s, Vec3s};
use neusample::DType;
use neusample::{Blob, BlobKind, BlobWriter, TensorRole};

use super::model::{Material, FEATURE_DIM};

/// Layer sizes of the decoder (`core/ARCHITECTURES.md` §7).
pub const DECODER_SIZES: [usize; 5] = [
    DECODER_INPUTS,
    DECODER_HIDDEN,
    DECODER_HIDDEN,
    DECODER_HIDDEN,
    DECODER_OUTPUTS,
];

/// File extension of neusample blobs (samplers and neural materials).
pub const BLOB_EXTENSION: &str = "nsb";

/// The arrays of a neural material in the runtime layout (`core/ARCHITECTURES.md` §7).
#[derive(Clone, Debug, PartialEq)]
pub struct NeuralParts {
    /// Texture width (texels along u).
    pub width: u32,
    /// Texture height (texels along v).
    pub height: u32,
    /// `height × width × 8` values: texel `(i, j)` channel `c` at `(j·width + i)·8 + c`.
    pub texture: Vec<f32>,
    /// The decoder's flat parameters (input-major weights, then bias, per layer).
    pub params: Vec<f32>,
}

impl NeuralParts {
    /// Checks dimensions, lengths and finiteness.
    pub fn validate(&self) -> Result<()> {
        for (what, n) in [("width", self.width), ("height", self.height)] {
            if n == 0 || n > MAX_TEXTURE_SIZE {
                bail!("texture {what} {n} is outside 1..={MAX_TEXTURE_SIZE}");
            }
        }
        let want = texture_len(self.width, self.height);
        if self.texture.len() != want {
            bail!(
                "feature texture has {} values, expected {}×{}×{} = {want}",
                self.texture.len(),
                self.height,
                self.width,
                FEATURE_DIM
            );
        }
        if self.params.len() != DECODER_PARAM_COUNT {
            bail!(
                "decoder has {} parameters, expected {DECODER_PARAM_COUNT}",
                self.params.len()
            );
        }
        for (what, v) in [("features", &self.texture), ("decoder", &self.params)] {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                bail!("{what} value {i} is not finite ({})", v[i]);
            }
        }
        Ok(())
    }

    /// The runtime's view of these arrays.
    #[must_use]
    pub fn material(&self) -> NeuralMaterial<&[f32]> {
        NeuralMaterial::new_unchecked(&self.texture[..], &self.params[..], self.width, self.height)
    }

    /// Serialises as a neural-material blob (`core/BLOB.md`) with the given storage type.
    pub fn blob_bytes(&self, dtype: DType, label: &str) -> Result<Vec<u8>> {
        self.validate()?;
        let mut w = BlobWriter::new(BlobKind::NeuralMaterial, dtype, label)
            .texture_dims(self.width, self.height);
        w.tensor(TensorRole::Params, &self.params)
            .tensor(TensorRole::Features, &self.texture);
        let bytes = w.to_bytes();
        Blob::open(&bytes)
            .and_then(|b| b.neural_material().map(|_| ()))
            .map_err(|e| anyhow!("the neural-material blob just built does not open: {e}"))?;
        Ok(bytes)
    }

    /// The arrays of a neural-material blob (widened to f32), and its label.
    pub fn from_blob(bytes: &[u8]) -> Result<(NeuralParts, String)> {
        let blob = Blob::open(bytes).map_err(|e| anyhow!("{e}"))?;
        let m = blob.neural_material().map_err(|e| anyhow!("{e}"))?;
        let mut texture = vec![0f32; texture_len(m.width(), m.height())];
        let mut params = vec![0f32; DECODER_PARAM_COUNT];
        blob.widen_into(TensorRole::Features, &mut texture)
            .map_err(|e| anyhow!("{e}"))?;
        blob.widen_into(TensorRole::Params, &mut params)
            .map_err(|e| anyhow!("{e}"))?;
        Ok((
            NeuralParts {
                width: m.width(),
                height: m.height(),
                texture,
                params,
            },
            blob.header().label.to_string(),
        ))
    }
}

/// A neural material as a [`Material`]: `features(uv)` is the bilinear lookup of the learned
/// texture and `eval` the decoder, both computed by core's [`NeuralMaterial`] (f32 copies of
/// the stored tensors).
#[derive(Clone, Debug)]
pub struct NeuralMaterialModel {
    name: String,
    parts: NeuralParts,
}

impl NeuralMaterialModel {
    /// A material over `parts` (validated).
    pub fn new(name: impl Into<String>, parts: NeuralParts) -> Result<Self> {
        parts.validate()?;
        Ok(NeuralMaterialModel {
            name: name.into(),
            parts,
        })
    }

    /// Opens a neural-material blob. The name is the label's `name=` field, else `fallback`.
    pub fn from_blob(bytes: &[u8], fallback: &str) -> Result<Self> {
        let (parts, label) = NeuralParts::from_blob(bytes)?;
        let name = label_field(&label, "name").unwrap_or(fallback).to_string();
        Self::new(name, parts)
    }

    /// Loads a neural-material blob file; errors name the file.
    pub fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path)
            .with_context(|| format!("cannot read neural material {}", path.display()))?;
        let stem = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("neural");
        Self::from_blob(&bytes, stem).with_context(|| format!("neural material {}", path.display()))
    }

    /// The same material under another name.
    #[must_use]
    pub fn renamed(mut self, name: &str) -> Self {
        self.name = name.to_string();
        self
    }

    /// The arrays.
    #[must_use]
    pub fn parts(&self) -> &NeuralParts {
        &self.parts
    }
}

impl Material for NeuralMaterialModel {
    fn name(&self) -> &str {
        &self.name
    }
    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        self.parts.material().features(uv)
    }
    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3] {
        self.parts.material().eval(phi, wi, wo)
    }
    fn reciprocal(&self) -> bool {
        false
    }
    fn neural(&self) -> Option<NeuralMaterial<&[f32]>> {
        Some(self.parts.material())
    }
    fn features_batch(&self, uv: Vec2s<'_>, phi: FeaturesMut<'_>) {
        // Lengths agree by the trait's contract; a mismatch leaves `phi` as it was.
        let _ = self.parts.material().features_batch(uv, phi);
    }
    fn eval_batch(&self, phi: Features<'_>, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>) {
        let _ = self.parts.material().eval_batch(phi, wi, wo, out);
    }
}

/// The value of `key=value` in a space-separated label.
#[must_use]
pub fn label_field<'a>(label: &'a str, key: &str) -> Option<&'a str> {
    label
        .split_whitespace()
        .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
}

/// Whether `path` names a neusample blob: the `.nsb` extension, or a file starting with the
/// blob magic.
#[must_use]
pub fn is_blob_file(path: &Path) -> bool {
    if path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(BLOB_EXTENSION))
    {
        return true;
    }
    let mut magic = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
        .is_ok_and(|()| magic == neusample::blob::MAGIC)
}
