//! Physically based, spatially varying target materials (the "neural materials" the samplers
//! learn to sample, issue #3).
//!
//! A material is a texture of per-texel parameters φ(uv) ∈ ℝ⁸ ([`Material::features`]) plus a
//! BRDF `f(φ, wi, wo)` ([`Material::eval`]) that depends on uv **only through φ**, exactly
//! like a NeuMIP material: a feature texture and a decoder. The samplers are conditioned on
//! the same φ, so everything a sampler needs to know about a texel is in φ.
//!
//! Conventions (shared with `neusample`): local shading frame with z = geometric normal; `wi`
//! and `wo` point away from the surface; `f` is returned **without** the cosine, in linear RGB;
//! `f = 0` when either direction is at or below the horizon.
//!
//! # Models
//!
//! | `model =`        | module          | idea                                                         |
//! |------------------|-----------------|--------------------------------------------------------------|
//! | `normal_mapped`  | [`leather`]     | GGX + diffuse under strong procedural normal mapping         |
//! | `anisotropic`    | [`anisotropic`] | anisotropic GGX with a spatially varying tangent field       |
//! | `clearcoat`      | [`clearcoat`]   | dielectric GGX coat over an attenuated rough base            |
//! | `fabric`         | [`fabric`]      | woven threads: two tilted anisotropic lobes, retro lobe, sheen |
//! | `marble`         | [`marble`]      | polished stone: spatially varying roughness + haze lobe      |
//! | `wood`           | [`wood`]        | diffuse-dominant, weak anisotropic varnish along the grain   |
//! | `tiles`          | [`tiles`]       | a different material per tile (ceramic, metal, stone, grout) |
//! | `conductor`      | [`conductor`]   | homogeneous GGX conductor, isotropic or anisotropic          |
//! | `tabulated`      | [`tabulated`]   | BRDF values read from a table file (isotropic)               |
//! | `neural`         | [`crate::neural`] | a neural material blob (`params.blob = "x.nsb"`): learned features + decoder |
//!
//! Each module documents its φ layout and ranges. The analytic models share the microfacet
//! pieces in [`microfacet`] (GGX, height-correlated Smith, Fresnel) and the "standard
//! surface" evaluator [`surface::Surface`]; the procedural textures use the tileable noise in
//! [`noise`].
//!
//! # Material files
//!
//! TOML (or JSON, chosen by the `.json` extension):
//!
//! ```toml
//! name = "goat_leather"          # required
//! model = "normal_mapped"        # required, one of the table above
//! description = "…"              # optional
//! [params]                       # model-specific, unknown fields are errors
//! …
//! ```
//!
//! Errors name the file and the field (`params.roughness`) and, for syntax and type errors,
//! the line and column.

pub mod anisotropic;
pub mod clearcoat;
pub mod conductor;
pub mod fabric;
pub mod leather;
pub mod marble;
pub mod microfacet;
pub mod noise;
pub mod surface;
pub mod tabulated;
pub mod tiles;
pub mod wood;

use std::path::Path;

use anyhow::{anyhow, bail, Context};
use glam::{Vec2, Vec3};
use serde::de::DeserializeOwned;
use serde::Deserialize;

/// Length of the per-texel feature vector φ (the same as the samplers' condition).
pub const FEATURE_DIM: usize = neusample::FEATURE_DIM;

/// A spatially varying BRDF: a feature texture φ(uv) and a decoder f(φ, wi, wo).
pub trait Material: Send + Sync {
    /// The material's name (from its file).
    fn name(&self) -> &str;

    /// Per-texel parameters φ(uv), `uv ∈ [0, 1)²` (wrapping: the texture tiles). φ alone
    /// determines f at that texel. Ranges are documented per model, roughly `[−1, 1]` or
    /// `[0, 1]`.
    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM];

    /// BRDF `f(φ, wi, wo)` in linear RGB, **without** the cosine; local frame (z = geometric
    /// normal), both directions pointing away from the surface (they need not be normalised).
    /// 0 when either direction is at or below the horizon; never NaN.
    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3];

    /// Whether `f(φ, wi, wo) = f(φ, wo, wi)` holds by construction (true for the analytic
    /// models; tables need not be reciprocal).
    fn reciprocal(&self) -> bool {
        true
    }
}

/// Rec. 709 luminance `Y = 0.2126 R + 0.7152 G + 0.0722 B` (what the target pdf is
/// proportional to, paper §3).
#[inline]
#[must_use]
pub fn luminance(rgb: [f32; 3]) -> f32 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// Names of the built-in materials (the files under `fixtures/materials/`, embedded).
#[must_use]
pub fn builtin_names() -> &'static [&'static str] {
    &BUILTIN_NAMES
}

macro_rules! builtins {
    ($($name:literal),* $(,)?) => {
        const BUILTIN_NAMES: [&str; [$($name),*].len()] = [$($name),*];
        fn builtin_source(name: &str) -> Option<&'static str> {
            match name {
                $($name => Some(include_str!(concat!(
                    env!("CARGO_MANIFEST_DIR"), "/../fixtures/materials/", $name, ".toml"))),)*
                _ => None,
            }
        }
    };
}

builtins!(
    "goat_leather",
    "cowhide_leather",
    "melted_metal",
    "brushed_metal",
    "turtle_shell",
    "car_paint",
    "victorian_fabric",
    "giallo_marble",
    "wagon_wood",
    "moroccan_tiles",
    "gold",
    "aniso_steel",
    "tabulated_satin",
);

/// Binary side files of built-ins (tables), embedded, by the name a material file uses.
fn builtin_side_file(name: &str) -> Option<&'static [u8]> {
    match name {
        "tabulated_satin.nstab" => Some(include_bytes!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../fixtures/materials/tabulated_satin.nstab"
        ))),
        _ => None,
    }
}

/// A built-in material by name (see [`builtin_names`]): parses the embedded fixture file.
pub fn builtin(name: &str) -> anyhow::Result<Box<dyn Material>> {
    let src = builtin_source(name).ok_or_else(|| {
        anyhow!(
            "unknown built-in material `{name}`; built-ins are: {}",
            BUILTIN_NAMES.join(", ")
        )
    })?;
    let origin = format!("built-in material `{name}` (fixtures/materials/{name}.toml)");
    parse(src, Format::Toml, &origin, &|file: &str| {
        builtin_side_file(file)
            .map(<[u8]>::to_vec)
            .ok_or_else(|| anyhow!("no embedded side file `{file}`"))
    })
}

/// Loads a material file (TOML, or JSON when the extension is `.json`), or a neural-material
/// blob (`.nsb` or any file starting with the blob magic, [`crate::neural`]). Side files
/// (tables, blobs) are resolved relative to the file's directory.
pub fn load(path: &Path) -> anyhow::Result<Box<dyn Material>> {
    if crate::neural::is_blob_file(path) {
        return Ok(Box::new(crate::neural::NeuralMaterialModel::load(path)?));
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read material file {}", path.display()))?;
    let format = match path.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("json") => Format::Json,
        _ => Format::Toml,
    };
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let origin = format!("material file {}", path.display());
    parse(&text, format, &origin, &|file: &str| {
        let p = dir.join(file);
        std::fs::read(&p).with_context(|| format!("cannot read side file {}", p.display()))
    })
}

/// Syntax of a material file.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Format {
    /// TOML.
    Toml,
    /// JSON.
    Json,
}

/// Reads side files named by a material file (e.g. `params.table`).
pub type SideFiles<'a> = &'a dyn Fn(&str) -> anyhow::Result<Vec<u8>>;

/// Parses material source text. `origin` names the source in error messages.
pub fn parse(
    text: &str,
    format: Format,
    origin: &str,
    side: SideFiles<'_>,
) -> anyhow::Result<Box<dyn Material>> {
    #[derive(Deserialize)]
    struct Header {
        model: Option<String>,
        name: Option<String>,
    }
    let header: Header = de(text, format).map_err(|e| anyhow!("{origin}: {e}"))?;
    let Some(model) = header.model else {
        bail!(
            "{origin}: missing field `model` (one of: {})",
            MODELS.join(", ")
        );
    };
    if header.name.is_none() {
        bail!("{origin}: missing field `name`");
    }
    let ctx = |e: anyhow::Error| anyhow!("{origin}: {e:#}");
    let m: Box<dyn Material> = match model.as_str() {
        "normal_mapped" => Box::new(
            surface::Textured::<leather::Leather>::new(file(text, format).map_err(ctx)?)
                .map_err(ctx)?,
        ),
        "anisotropic" => Box::new(
            surface::Textured::<anisotropic::Anisotropic>::new(file(text, format).map_err(ctx)?)
                .map_err(ctx)?,
        ),
        "marble" => Box::new(
            surface::Textured::<marble::Marble>::new(file(text, format).map_err(ctx)?)
                .map_err(ctx)?,
        ),
        "wood" => Box::new(
            surface::Textured::<wood::Wood>::new(file(text, format).map_err(ctx)?).map_err(ctx)?,
        ),
        "tiles" => Box::new(
            surface::Textured::<tiles::Tiles>::new(file(text, format).map_err(ctx)?)
                .map_err(ctx)?,
        ),
        "conductor" => Box::new(
            surface::Textured::<conductor::Conductor>::new(file(text, format).map_err(ctx)?)
                .map_err(ctx)?,
        ),
        "clearcoat" => Box::new(
            clearcoat::ClearCoat::new(file::<clearcoat::Params>(text, format).map_err(ctx)?)
                .map_err(ctx)?,
        ),
        "fabric" => Box::new(
            fabric::Fabric::new(file::<fabric::Params>(text, format).map_err(ctx)?).map_err(ctx)?,
        ),
        "tabulated" => Box::new(
            tabulated::Tabulated::new(file::<tabulated::Params>(text, format).map_err(ctx)?, side)
                .map_err(ctx)?,
        ),
        "neural" => {
            let f = file::<NeuralParams>(text, format).map_err(ctx)?;
            let bytes = side(&f.params.blob).map_err(ctx)?;
            Box::new(
                crate::neural::NeuralMaterialModel::from_blob(&bytes, &f.name)
                    .map(|m| m.renamed(&f.name))
                    .map_err(|e| {
                        anyhow!("{origin}: field `params.blob` ({}): {e:#}", f.params.blob)
                    })?,
            )
        }
        other => bail!(
            "{origin}: field `model`: unknown model `{other}` (one of: {})",
            MODELS.join(", ")
        ),
    };
    Ok(m)
}

/// Parameters of `model = "neural"`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NeuralParams {
    /// The neural-material blob, relative to the material file.
    pub blob: String,
}

/// The model names a file's `model` field accepts.
pub const MODELS: [&str; 10] = [
    "normal_mapped",
    "anisotropic",
    "clearcoat",
    "fabric",
    "marble",
    "wood",
    "tiles",
    "conductor",
    "tabulated",
    "neural",
];

/// A parsed material file with model parameters `P`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct File<P> {
    /// Material name.
    pub name: String,
    /// Model name (already dispatched on).
    pub model: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Model parameters.
    pub params: P,
}

fn de<T: DeserializeOwned>(text: &str, format: Format) -> anyhow::Result<T> {
    match format {
        Format::Toml => toml::from_str(text).map_err(|e| anyhow!("{}", e.to_string().trim_end())),
        Format::Json => serde_json::from_str(text).map_err(|e| anyhow!("{e}")),
    }
}

fn file<P: DeserializeOwned>(text: &str, format: Format) -> anyhow::Result<File<P>> {
    de(text, format)
}

/// Range checks that name the offending field (`params.<field>`).
pub(crate) mod check {
    use anyhow::bail;

    /// `lo ≤ v ≤ hi` and finite.
    pub fn range(field: &str, v: f32, lo: f32, hi: f32) -> anyhow::Result<()> {
        if !(v.is_finite() && v >= lo && v <= hi) {
            bail!("field `params.{field}`: must be in [{lo}, {hi}], got {v}");
        }
        Ok(())
    }

    /// Every component in `[lo, hi]`.
    pub fn range_n(field: &str, v: &[f32], lo: f32, hi: f32) -> anyhow::Result<()> {
        for (i, &x) in v.iter().enumerate() {
            if !(x.is_finite() && x >= lo && x <= hi) {
                bail!("field `params.{field}[{i}]`: must be in [{lo}, {hi}], got {x}");
            }
        }
        Ok(())
    }

    /// A `[min, max]` pair inside `[lo, hi]` with `min ≤ max`.
    pub fn interval(field: &str, v: [f32; 2], lo: f32, hi: f32) -> anyhow::Result<()> {
        range_n(field, &v, lo, hi)?;
        if v[0] > v[1] {
            bail!("field `params.{field}`: expected [min, max] with min ≤ max, got {v:?}");
        }
        Ok(())
    }

    /// An integer in `[lo, hi]`.
    pub fn count(field: &str, v: u32, lo: u32, hi: u32) -> anyhow::Result<()> {
        if v < lo || v > hi {
            bail!("field `params.{field}`: must be in [{lo}, {hi}], got {v}");
        }
        Ok(())
    }
}
