//! # neusample-render — a small path tracer over neusample's public API
//!
//! The evaluation renderer of *NeuSample* (paper §4: Figs. 1, 8, 9 and Tables 1–2). It links
//! the runtime `neusample` and nothing of the training stack, and uses the runtime exactly as
//! a user's renderer would. Two integrators give the same image:
//!
//! * [`render_wavefront`] — the one the evaluation uses: tiles of pixels, one sample per
//!   pixel per step, and at every path depth the tile's shading points go to the material and
//!   the sampler as one batch per surface (`features_batch`, `prepare_batch`, `sample_batch`,
//!   `eval_batch`, `pdf_batch`: core's [`neusample::wavefront`] API), as the paper ran its
//!   samplers on a wavefront of rays;
//! * [`render`] — one shading point at a time through the scalar API (`prepare`, `sample`,
//!   `pdf`), the reference the wavefront is tested against, and the integrator for samplers
//!   without a batched path (a tabulated oracle).
//!
//! ```text
//! image ─┐
//! geometry (Ray, Camera, Shape, Object) ─┐
//! sky, envmap → environment (lighting + its sampling) ─┴→ scene (Scene, demo_scene,
//!                                                          showcase_scene)
//! material (Material, Surface) ──→ integrator (options, per-pixel recipe, Render)
//!                                    → scalar (render), wavefront (render_wavefront) → timing
//! rng (per-item streams) ───────────┘
//! ```
//!
//! # Scene
//!
//! World space is z-up. A [`Scene`] is a pinhole [`Camera`], a few [`Object`]s (a square
//! planar patch and a sphere: [`Shape`]) each naming a [`Surface`] (a [`Material`] and its
//! [`neusample::Sampler`]), and an [`Environment`]: a procedural sky with a sun ([`Sky`]; the
//! small, very bright sun is what makes sampling quality matter) or an equirectangular map
//! ([`EnvMap`]), plus the sun. Two presets: [`demo_scene`] (a patch and a sphere of one
//! material, the evaluation scene) and [`showcase_scene`] (a floor and four spheres, each
//! object with its own surface, close enough to light each other).
//!
//! Texture coordinates: the patch maps its square to `[0, 1)²` times its tiling scale; the
//! sphere uses `u = φ/2π` (times twice the scale, so texels stay square at the equator) and
//! `v = θ/π`. The **shading frame is the geometric one** (normal and `∂P/∂u` tangent): the
//! material applies its own normal map through φ, as a NeuMIP material does.
//!
//! # Estimators
//!
//! [`Estimator::Bsdf`] (the paper's main mode) or [`Estimator::Mis`] (BSDF and environment
//! sampling, power heuristic; the environment is sampled from a tabulated lat-long sky mixed
//! with uniform sampling of the sun's cone). By default direct lighting: a direction occluded
//! by another object contributes nothing. With [`RenderOptions::max_bounces`] `> 1`, global
//! illumination: a BSDF sample that hits the other object continues the path there (the
//! sampler prepared again at that vertex, throughput `f · cos θo / pdf`).
//!
//! # Example
//!
//! ```
//! use neusample::samplers::CosineSampler;
//! use neusample_render::{demo_scene, render, Material, RenderOptions, SceneParams, Surface};
//! use neusample_render::glam::{Vec2, Vec3};
//!
//! /// A white Lambertian material (φ unused).
//! struct White;
//! impl Material for White {
//!     fn features(&self, _uv: Vec2) -> [f32; 8] {
//!         [0.0; 8]
//!     }
//!     fn eval(&self, _phi: &[f32; 8], wi: Vec3, wo: Vec3) -> [f32; 3] {
//!         let lit = wi.z > 0.0 && wo.z > 0.0;
//!         [if lit { std::f32::consts::FRAC_1_PI } else { 0.0 }; 3]
//!     }
//! }
//!
//! let scene = demo_scene(&SceneParams { width: 16, height: 12, ..SceneParams::default() });
//! let image = render(&scene, &[Surface::new(&White, CosineSampler)], &RenderOptions::new(4, 1));
//! assert!(image.image.data.iter().all(|c| c.iter().all(|v| v.is_finite())));
//! ```
//!
//! # Determinism
//!
//! Rows are rendered in parallel (rayon); every pixel draws from its own random stream
//! ([`rng::indexed_rng`] of the seed and the pixel index) and accumulates its samples in
//! order, so an image is bit-identical for any number of threads.

mod environment;
mod envmap;
mod error;
mod geometry;
mod image;
mod integrator;
mod material;
pub mod rng;
mod scalar;
mod scene;
mod sky;
pub mod timing;
mod wavefront;

pub use environment::Environment;
pub use envmap::EnvMap;
pub use error::Error;
pub use geometry::{Camera, Hit, Object, Ray, Shape};
pub use glam;
pub use image::Image;
pub use integrator::{powers_of_two, Estimator, Render, RenderOptions, WAVEFRONT_PIXELS};
pub use material::{eval_per_lane, features_per_lane, luminance, Material, Surface};
pub use scalar::render;
pub use scene::{demo_scene, showcase_scene, Scene, SceneParams, ShowcaseParams, SHOWCASE_OBJECTS};
pub use sky::Sky;
pub use timing::{time_per_sample, time_per_sample_wavefront};
pub use wavefront::render_wavefront;
