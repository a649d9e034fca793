//! `model = "measured"`: a measured BRDF of the RGL material database (Dupuy & Jakob 2018),
//! read from its `.bsdf` file (Mitsuba's `tensor_file` format, RGB; the reader is
//! `neusample_owned::measured`) and evaluated by the runtime's [`neusample::MeasuredMaterial`]
//! exactly as Mitsuba 3's `measured` BSDF does.
//!
//! ```toml
//! name = "chm_mint"
//! model = "measured"
//! [params]
//! file = "chm_mint_rgb.bsdf"     # relative to the material file
//! ```
//!
//! A `.bsdf` path given where a material is expected loads the same way, named after the
//! file's stem.
//!
//! # φ layout
//!
//! The data is homogeneous: φ is 0 everywhere, so samplers learn the (wi, wo) dependence
//! only. Measured tables need not be reciprocal ([`Material::reciprocal`] is false).

use anyhow::Context;
use glam::{Vec2, Vec3};
use neusample_owned::measured::OwnedMeasured;
use serde::Deserialize;

use super::format::{File, SideFiles};
use super::model::{Material, FEATURE_DIM};

/// `[params]` of a `measured` material.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// The `.bsdf` file, relative to the material file.
    pub file: String,
}

/// A `measured` material.
#[derive(Clone, Debug)]
pub struct Measured {
    name: String,
    data: OwnedMeasured,
}

impl Measured {
    /// Loads the file a parsed material file names through `side`.
    pub fn new(file: File<Params>, side: SideFiles<'_>) -> anyhow::Result<Self> {
        let bytes = side(&file.params.file).context("field `params.file`")?;
        let data = OwnedMeasured::from_bytes(&bytes)
            .with_context(|| format!("field `params.file`: `{}`", file.params.file))?;
        Ok(Measured {
            name: file.name,
            data,
        })
    }

    /// A measured material from data already read.
    #[must_use]
    pub fn from_data(name: &str, data: OwnedMeasured) -> Self {
        Measured {
            name: name.to_string(),
            data,
        }
    }

    /// The data and its own sampler.
    #[must_use]
    pub fn data(&self) -> &OwnedMeasured {
        &self.data
    }
}

impl Material for Measured {
    fn name(&self) -> &str {
        &self.name
    }

    fn features(&self, _uv: Vec2) -> [f32; FEATURE_DIM] {
        [0.0; FEATURE_DIM]
    }

    fn eval(&self, _phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3] {
        match self.data.material().prepare(wi) {
            Some(p) => p.eval(wo),
            None => [0.0; 3],
        }
    }

    fn reciprocal(&self) -> bool {
        false
    }

    fn isotropic(&self) -> bool {
        self.data.material().isotropic()
    }

    fn measured(&self) -> Option<&OwnedMeasured> {
        Some(&self.data)
    }
}
