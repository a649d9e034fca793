//! The shape of a material file: its syntax, the `name` / `model` / `description` / `params`
//! table, the model names and the side files it may name.

use anyhow::anyhow;
use serde::de::DeserializeOwned;
use serde::Deserialize;

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

/// Parameters of `model = "neural"`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NeuralParams {
    /// The neural-material blob, relative to the material file.
    pub blob: String,
}

/// The model names a file's `model` field accepts.
pub const MODELS: [&str; 11] = [
    "normal_mapped",
    "anisotropic",
    "clearcoat",
    "fabric",
    "marble",
    "wood",
    "tiles",
    "conductor",
    "tabulated",
    "measured",
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

/// Deserialises TOML or JSON text; errors carry the parser's line and column.
pub(crate) fn de<T: DeserializeOwned>(text: &str, format: Format) -> anyhow::Result<T> {
    match format {
        Format::Toml => toml::from_str(text).map_err(|e| anyhow!("{}", e.to_string().trim_end())),
        Format::Json => serde_json::from_str(text).map_err(|e| anyhow!("{e}")),
    }
}

/// A material file with model parameters `P`.
pub(crate) fn file<P: DeserializeOwned>(text: &str, format: Format) -> anyhow::Result<File<P>> {
    de(text, format)
}
