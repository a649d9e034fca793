//! Physically based, spatially varying target materials (the "neural materials" the samplers
//! learn to sample).
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
//! | `measured`       | [`measured`]    | an RGL measured BRDF (`params.file = "x_rgb.bsdf"`), exact   |
//! | `neural`         | [`neural`]      | a neural material blob (`params.blob = "x.nsb"`): learned features + decoder |
//!
//! Each module documents its φ layout and ranges. The analytic models share the microfacet
//! pieces in [`microfacet`] (GGX, height-correlated Smith, Fresnel, the normal-tilt limit) and
//! the "standard surface" evaluator [`surface::Surface`]; the procedural textures use the
//! tileable noise in [`noise`].
//!
//! # Files of this module
//!
//! [`Material`] and [`luminance`] are in `model.rs`; the shape of a material file in
//! `format.rs`; loading (files, built-ins, `resolve`) in `load.rs`; the range checks of
//! parameters in `check.rs`; one file per model; the neural material (its runtime arrays,
//! blob and safetensors forms) in [`neural`].
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

mod check;
mod format;
mod load;
mod model;

pub mod anisotropic;
pub mod clearcoat;
pub mod conductor;
pub mod fabric;
pub mod leather;
pub mod marble;
pub mod measured;
pub mod microfacet;
pub mod neural;
pub mod noise;
pub mod surface;
pub mod tabulated;
pub mod tiles;
pub mod wood;

pub use format::{File, Format, NeuralParams, SideFiles, MODELS};
pub use load::{builtin, builtin_names, load, parse, resolve};
pub use model::{luminance, Material, FEATURE_DIM};
