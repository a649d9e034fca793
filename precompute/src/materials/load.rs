//! Loading materials: material files (TOML or JSON), the embedded built-ins, neural-material
//! blobs, and `resolve` for a command-line argument that is either.

use std::path::Path;

use anyhow::{anyhow, bail, Context};
use serde::Deserialize;

use super::format::{de, file, Format, NeuralParams, SideFiles, MODELS};
use super::model::Material;
use super::neural::{is_blob_file, NeuralMaterialModel};
use super::surface::{SurfaceModel, Textured};
use super::{
    anisotropic, clearcoat, conductor, fabric, leather, marble, measured, tabulated, tiles, wood,
};

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

/// Loads a material file (TOML, or JSON when the extension is `.json`), a neural-material
/// blob (`.nsb` or any file starting with the blob magic, [`super::neural`]) or a measured
/// material (`.bsdf` or the tensor-file magic, [`super::measured`]). Side files
/// (tables, blobs) are resolved relative to the file's directory.
pub fn load(path: &Path) -> anyhow::Result<Box<dyn Material>> {
    if is_blob_file(path) {
        return Ok(Box::new(NeuralMaterialModel::load(path)?));
    }
    if is_measured_file(path) {
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("measured");
        let data = neusample_owned::measured::OwnedMeasured::open(path)?;
        return Ok(Box::new(measured::Measured::from_data(name, data)));
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

/// Whether `path` is a measured-material file: a `.bsdf` extension or the tensor-file magic.
fn is_measured_file(path: &Path) -> bool {
    let ext = path.extension().and_then(|e| e.to_str());
    if ext.is_some_and(|e| e.eq_ignore_ascii_case("bsdf")) {
        return true;
    }
    let mut magic = [0u8; 12];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
        .is_ok_and(|()| &magic == neusample_owned::measured::MAGIC)
}

/// A material given as a file path (material file or neural-material blob) or as the name of
/// a built-in material.
pub fn resolve(spec: &str) -> anyhow::Result<Box<dyn Material>> {
    let p = Path::new(spec);
    if p.exists() {
        load(p)
    } else if spec.ends_with(".toml") || spec.ends_with(".json") || spec.contains('/') {
        bail!("material file {spec} does not exist")
    } else {
        builtin(spec)
    }
}

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
        "normal_mapped" => textured::<leather::Leather>(text, format).map_err(ctx)?,
        "anisotropic" => textured::<anisotropic::Anisotropic>(text, format).map_err(ctx)?,
        "marble" => textured::<marble::Marble>(text, format).map_err(ctx)?,
        "wood" => textured::<wood::Wood>(text, format).map_err(ctx)?,
        "tiles" => textured::<tiles::Tiles>(text, format).map_err(ctx)?,
        "conductor" => textured::<conductor::Conductor>(text, format).map_err(ctx)?,
        "clearcoat" => Box::new(
            file(text, format)
                .and_then(clearcoat::ClearCoat::new)
                .map_err(ctx)?,
        ),
        "fabric" => Box::new(
            file(text, format)
                .and_then(fabric::Fabric::new)
                .map_err(ctx)?,
        ),
        "tabulated" => Box::new(
            file(text, format)
                .and_then(|f| tabulated::Tabulated::new(f, side))
                .map_err(ctx)?,
        ),
        "measured" => Box::new(
            file(text, format)
                .and_then(|f| measured::Measured::new(f, side))
                .map_err(ctx)?,
        ),
        "neural" => {
            let f = file::<NeuralParams>(text, format).map_err(ctx)?;
            let bytes = side(&f.params.blob).map_err(ctx)?;
            Box::new(
                NeuralMaterialModel::from_blob(&bytes, &f.name)
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

/// A [`SurfaceModel`] material from its file.
fn textured<M: SurfaceModel + 'static>(
    text: &str,
    format: Format,
) -> anyhow::Result<Box<dyn Material>> {
    Ok(Box::new(Textured::<M>::new(file(text, format)?)?))
}
