//! A small evaluation renderer (paper §4: Figs. 1, 8, 9 and Tables 1–2) that uses the runtime
//! **only through its public API**, exactly as a user's renderer would: per shading point
//! `sampler.prepare(φ, wi)`, then `prepared.sample(u)` for BSDF sampling and
//! `prepared.pdf(wo)` (solid angle) for multiple importance sampling.
//!
//! # Scene
//!
//! World space is z-up. A [`Scene`] is a pinhole [`Camera`], a few [`Object`]s (a square
//! planar patch and a sphere: [`Shape`]) each naming a [`Surface`] (a material and its
//! sampler), and an [`Environment`]: a procedural sky with a sun ([`Sky`]; the small, very
//! bright sun is what makes sampling quality matter) or an equirectangular EXR map
//! ([`EnvMap`]), plus the sun.
//!
//! Texture coordinates: the patch maps its square to `[0, 1)²` times its tiling scale; the
//! sphere uses `u = φ/2π` (times twice the scale, so texels stay square at the equator) and
//! `v = θ/π`. The **shading frame is the geometric one** (normal and `∂P/∂u` tangent): the
//! material applies its own normal map through φ, as a NeuMIP material does.
//!
//! # Estimators ([`Estimator`])
//!
//! By default direct lighting from the environment: a direction occluded by another object
//! contributes nothing. With [`RenderOptions::max_bounces`] `> 1`, **global illumination**: a
//! BSDF sample that hits the other object continues the path there (the sampler prepared
//! again at that vertex, throughput `f · cos θo / pdf`, the same estimator at every vertex),
//! up to that many surface interactions. The demo renders direct lighting (its reference, the
//! oracle, would tabulate p* at every secondary vertex).
//!
//! * [`Estimator::Bsdf`] — the paper's main mode: one BSDF sample per pixel sample,
//!   `L = f(φ, wi, wo) · cos θo · L_env(wo) / pdf(wo)`, pdf in solid angle.
//! * [`Estimator::Mis`] — one BSDF sample plus one environment sample, combined with the power
//!   heuristic (β = 2, Veach 1997). The environment is sampled from a tabulated lat-long sky
//!   (piecewise constant in `(φ, cos θ)`) mixed with uniform sampling of the sun's cone.
//!
//! # Sampling techniques
//!
//! Anything implementing [`neusample::Sampler`]: every blob sampler ([`AnySampler`]: cosine,
//! improved baseline, analytic, flows, histograms) and the [`OracleSampler`] — the paper's
//! "tabulated" near-optimal reference (Fig. 10): the ground truth p* tabulated per shading
//! point and sampled exactly.
//!
//! # Determinism
//!
//! Rows are rendered in parallel (rayon); every pixel draws from its own random stream seeded
//! by `(seed, pixel index)` ([`crate::groundtruth::condition_rng`]) and accumulates its samples
//! in order, so an image is bit-identical for any number of threads.

use std::time::Instant;

use glam::{Vec2, Vec3};
use neusample::warp;
use neusample::AnySampler;
use neusample::{Frame, Prepared, Sample, Sampler, Table2D, FEATURE_DIM};
use rand::RngExt;
use rayon::prelude::*;

use crate::groundtruth::condition_rng;
use crate::materials::{luminance, Material};

/// Offset of secondary-ray origins along the geometric normal (scene units ~1).
const RAY_EPSILON: f32 = 1e-4;

// ---------------------------------------------------------------------------------------
// Images
// ---------------------------------------------------------------------------------------

/// A linear RGB image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width × height` linear RGB values.
    pub data: Vec<[f32; 3]>,
}

impl Image {
    /// A black image.
    #[must_use]
    pub fn new(width: usize, height: usize) -> Image {
        Image {
            width,
            height,
            data: vec![[0.0; 3]; width * height],
        }
    }

    /// Pixel `(x, y)`.
    #[must_use]
    pub fn at(&self, x: usize, y: usize) -> [f32; 3] {
        self.data[y * self.width + x]
    }
}

// ---------------------------------------------------------------------------------------
// Camera and geometry
// ---------------------------------------------------------------------------------------

/// A ray `o + t·d` (`d` unit).
#[derive(Copy, Clone, Debug)]
pub struct Ray {
    /// Origin.
    pub o: Vec3,
    /// Unit direction.
    pub d: Vec3,
}

/// A pinhole camera.
#[derive(Copy, Clone, Debug)]
pub struct Camera {
    eye: Vec3,
    forward: Vec3,
    /// Right axis scaled by `tan(fov/2) · aspect`.
    right: Vec3,
    /// Up axis scaled by `tan(fov/2)`.
    up: Vec3,
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
}

impl Camera {
    /// A camera at `eye` looking at `target`, `up` the world's up hint, `vfov_deg` the vertical
    /// field of view in degrees.
    #[must_use]
    pub fn look_at(
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        vfov_deg: f32,
        width: usize,
        height: usize,
    ) -> Camera {
        let forward = (target - eye).normalize();
        let right = forward.cross(up).normalize();
        let true_up = right.cross(forward);
        let tan_half = (0.5 * vfov_deg.to_radians()).tan();
        let aspect = width as f32 / height.max(1) as f32;
        Camera {
            eye,
            forward,
            right: right * tan_half * aspect,
            up: true_up * tan_half,
            width,
            height,
        }
    }

    /// The ray through image position `(px, py)` in pixels (`(0, 0)` = top-left corner;
    /// pixel centres at `+0.5`).
    #[must_use]
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        let sx = 2.0 * px / self.width as f32 - 1.0;
        let sy = 1.0 - 2.0 * py / self.height as f32;
        Ray {
            o: self.eye,
            d: (self.forward + sx * self.right + sy * self.up).normalize(),
        }
    }
}

/// A primitive.
#[derive(Copy, Clone, Debug)]
pub enum Shape {
    /// A square planar patch: `center`, unit `normal`, unit `tangent` (the u axis, ⊥ normal)
    /// and half the side length.
    Patch {
        /// Centre.
        center: Vec3,
        /// Unit normal (the shaded side).
        normal: Vec3,
        /// Unit tangent (u axis).
        tangent: Vec3,
        /// Half the side length.
        half_size: f32,
    },
    /// A sphere (shaded from outside).
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius.
        radius: f32,
    },
}

/// A shape with its surface.
#[derive(Copy, Clone, Debug)]
pub struct Object {
    /// Geometry.
    pub shape: Shape,
    /// Texture tiling scale (how many times the material repeats across the object).
    pub uv_scale: f32,
    /// Index into the surfaces passed to [`render`].
    pub surface: usize,
}

/// A ray–surface intersection.
#[derive(Copy, Clone, Debug)]
pub struct Hit {
    /// Ray parameter.
    pub t: f32,
    /// Position.
    pub p: Vec3,
    /// Unit geometric normal (facing outward / up for the patch).
    pub n: Vec3,
    /// Tangent hint `∂P/∂u` (not necessarily ⊥ `n` or unit).
    pub tangent: Vec3,
    /// Texture coordinate in `[0, 1)²`.
    pub uv: Vec2,
    /// Surface index.
    pub surface: usize,
}

#[inline]
fn wrap01(x: f32) -> f32 {
    let f = x - x.floor();
    if f >= 1.0 {
        0.0
    } else {
        f
    }
}

impl Object {
    /// The nearest intersection with `t ∈ (t_min, t_max)`.
    #[must_use]
    pub fn intersect(&self, r: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        match self.shape {
            Shape::Patch {
                center,
                normal,
                tangent,
                half_size,
            } => {
                let denom = r.d.dot(normal);
                if denom.abs() < 1e-12 {
                    return None;
                }
                let t = (center - r.o).dot(normal) / denom;
                if !(t > t_min && t < t_max) {
                    return None;
                }
                let p = r.o + t * r.d;
                let l = p - center;
                let bitangent = normal.cross(tangent);
                let a = l.dot(tangent);
                let b = l.dot(bitangent);
                if a.abs() > half_size || b.abs() > half_size {
                    return None;
                }
                let s = self.uv_scale / (2.0 * half_size);
                Some(Hit {
                    t,
                    p,
                    n: normal,
                    tangent,
                    uv: Vec2::new(wrap01((a + half_size) * s), wrap01((b + half_size) * s)),
                    surface: self.surface,
                })
            }
            Shape::Sphere { center, radius } => {
                let oc = r.o - center;
                let b = oc.dot(r.d);
                let c = oc.length_squared() - radius * radius;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let sq = disc.sqrt();
                let mut t = -b - sq;
                if !(t > t_min) {
                    t = -b + sq;
                }
                if !(t > t_min && t < t_max) {
                    return None;
                }
                let p = r.o + t * r.d;
                let n = ((p - center) / radius).normalize();
                let phi = n.y.atan2(n.x);
                let theta = n.z.clamp(-1.0, 1.0).acos();
                Some(Hit {
                    t,
                    p,
                    n,
                    tangent: Vec3::new(-phi.sin(), phi.cos(), 0.0),
                    uv: Vec2::new(
                        wrap01(
                            (phi * std::f32::consts::FRAC_1_PI * 0.5 + 0.5) * 2.0 * self.uv_scale,
                        ),
                        wrap01(theta * std::f32::consts::FRAC_1_PI * self.uv_scale),
                    ),
                    surface: self.surface,
                })
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Environment
// ---------------------------------------------------------------------------------------

/// A procedural sky: a zenith-to-horizon gradient, a uniform ground below the horizon, a sun
/// disc of small angular radius and high radiance, and a soft aureole around it.
#[derive(Clone, Debug, PartialEq)]
pub struct Sky {
    /// Radiance at the zenith (linear RGB).
    pub zenith: [f32; 3],
    /// Radiance at the horizon.
    pub horizon: [f32; 3],
    /// Radiance of every direction below the horizon.
    pub ground: [f32; 3],
    /// Unit direction towards the sun (z-up world).
    pub sun_dir: Vec3,
    /// Sun colour (multiplied by `sun_radiance`).
    pub sun_color: [f32; 3],
    /// Radiance of the sun disc (0: no sun).
    pub sun_radiance: f32,
    /// Angular radius of the sun disc, degrees.
    pub sun_radius_deg: f32,
    /// Peak radiance of the aureole `a · exp(−γ² / 2w²)` (γ: angle to the sun).
    pub aureole: f32,
    /// Angular width `w` of the aureole, degrees.
    pub aureole_width_deg: f32,
}

impl Sky {
    /// A clear daylight sky with the sun at `elevation_deg` above the horizon and
    /// `azimuth_deg` (0 = +y, positive towards +x).
    #[must_use]
    pub fn daylight(
        elevation_deg: f32,
        azimuth_deg: f32,
        sun_radiance: f32,
        sun_radius_deg: f32,
    ) -> Sky {
        let (el, az) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
        Sky {
            zenith: [0.25, 0.45, 0.95],
            horizon: [0.85, 0.9, 1.0],
            ground: [0.32, 0.28, 0.24],
            sun_dir: Vec3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin()),
            sun_color: [1.0, 0.93, 0.82],
            sun_radiance,
            sun_radius_deg,
            aureole: 2.0,
            aureole_width_deg: 6.0,
        }
    }

    /// The same radiance `rgb` from every direction (no sun): the white-furnace environment.
    #[must_use]
    pub fn constant(rgb: [f32; 3]) -> Sky {
        Sky {
            zenith: rgb,
            horizon: rgb,
            ground: rgb,
            sun_dir: Vec3::Z,
            sun_color: [1.0; 3],
            sun_radiance: 0.0,
            sun_radius_deg: 0.5,
            aureole: 0.0,
            aureole_width_deg: 1.0,
        }
    }

    fn cos_sun_radius(&self) -> f32 {
        self.sun_radius_deg.to_radians().cos()
    }

    /// Sky radiance without the sun disc (gradient, ground, aureole).
    #[must_use]
    pub fn background(&self, d: Vec3) -> [f32; 3] {
        if d.z < 0.0 {
            return self.ground;
        }
        let t = d.z.sqrt();
        let mut c = [0.0; 3];
        for k in 0..3 {
            c[k] = self.horizon[k] + (self.zenith[k] - self.horizon[k]) * t;
        }
        if self.aureole > 0.0 {
            let gamma = d.dot(self.sun_dir).clamp(-1.0, 1.0).acos();
            let w = self.aureole_width_deg.to_radians().max(1e-4);
            let a = self.aureole * (-0.5 * gamma * gamma / (w * w)).exp();
            for k in 0..3 {
                c[k] += a * self.sun_color[k];
            }
        }
        c
    }
}

/// An equirectangular environment map, **z-up**: row 0 is the zenith (+z), the last row the
/// nadir; column 0 is azimuth −π (the −x direction) and the azimuth `atan2(y, x)` increases
/// with the column. Looked up with nearest-pixel filtering.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvMap {
    /// The image (linear RGB).
    pub image: Image,
    /// Multiplier applied to every texel.
    pub scale: f32,
}

impl EnvMap {
    /// Loads the first RGB(A) layer of an OpenEXR file.
    pub fn load_exr(path: &std::path::Path) -> anyhow::Result<EnvMap> {
        use exr::prelude::{read_first_rgba_layer_from_file, Vec2 as ExrVec2};
        let img = read_first_rgba_layer_from_file(
            path,
            |res: ExrVec2<usize>, _| Image::new(res.width(), res.height()),
            |im: &mut Image, pos: ExrVec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
                let w = im.width;
                let clean = |v: f32| if v.is_finite() && v > 0.0 { v } else { 0.0 };
                im.data[pos.y() * w + pos.x()] = [clean(r), clean(g), clean(b)];
            },
        )
        .map_err(|e| anyhow::anyhow!("cannot read environment map {}: {e}", path.display()))?;
        let image = img.layer_data.channel_data.pixels;
        anyhow::ensure!(
            image.width > 0 && image.height > 0,
            "environment map {} is empty",
            path.display()
        );
        Ok(EnvMap { image, scale: 1.0 })
    }

    /// Radiance towards `d`.
    #[must_use]
    pub fn lookup(&self, d: Vec3) -> [f32; 3] {
        let (u, v) = dir_to_latlong(d);
        let x = ((u * self.image.width as f32) as usize).min(self.image.width - 1);
        let y = ((v * self.image.height as f32) as usize).min(self.image.height - 1);
        let c = self.image.at(x, y);
        [c[0] * self.scale, c[1] * self.scale, c[2] * self.scale]
    }
}

/// Lat-long coordinates `(u, v) ∈ [0, 1]²` of a unit direction (see [`EnvMap`]).
fn dir_to_latlong(d: Vec3) -> (f32, f32) {
    let phi = d.y.atan2(d.x);
    let theta = d.z.clamp(-1.0, 1.0).acos();
    (
        (phi + std::f32::consts::PI) * (0.5 * std::f32::consts::FRAC_1_PI),
        theta * std::f32::consts::FRAC_1_PI,
    )
}

/// A piecewise-constant 1-D distribution (f64), pbrt `PiecewiseConstant1D` style.
#[derive(Clone, Debug)]
struct Distribution1D {
    func: Vec<f64>,
    /// `cdf[i]` = mass of cells `< i`; `cdf[n]` = total.
    cdf: Vec<f64>,
}

impl Distribution1D {
    fn new(func: Vec<f64>) -> Distribution1D {
        let mut cdf = Vec::with_capacity(func.len() + 1);
        let mut acc = 0.0;
        cdf.push(0.0);
        for &f in &func {
            acc += f;
            cdf.push(acc);
        }
        Distribution1D { func, cdf }
    }

    fn total(&self) -> f64 {
        self.cdf[self.cdf.len() - 1]
    }

    /// Cell index, fraction within the cell, probability of the cell.
    fn sample(&self, u: f64) -> Option<(usize, f64, f64)> {
        let total = self.total();
        if !(total > 0.0) {
            return None;
        }
        let target = u * total;
        // First i with cdf[i + 1] > target.
        let i = self.cdf[1..]
            .partition_point(|&c| c <= target)
            .min(self.func.len() - 1);
        let f = self.func[i];
        if !(f > 0.0) {
            return None;
        }
        let frac = ((target - self.cdf[i]) / f).clamp(0.0, 1.0 - 1e-12);
        Some((i, frac, f / total))
    }

    fn prob(&self, i: usize) -> f64 {
        let total = self.total();
        if total > 0.0 {
            self.func.get(i).copied().unwrap_or(0.0) / total
        } else {
            0.0
        }
    }
}

/// Environment sampling: a lat-long table over `(φ, cos θ)` cells, mixed with uniform
/// sampling of the sun's cone.
#[derive(Clone, Debug)]
struct EnvSampling {
    nu: usize,
    nv: usize,
    /// Marginal over rows (θ bands).
    rows: Distribution1D,
    /// Conditional over columns, per row.
    cols: Vec<Distribution1D>,
    /// Probability of picking the sun cone.
    sun_prob: f32,
}

/// The lighting: a procedural [`Sky`] (or an [`EnvMap`] with the sky's sun added) and the
/// tables for environment sampling.
#[derive(Clone, Debug)]
pub struct Environment {
    /// Sky (sun parameters are used with a map too).
    pub sky: Sky,
    /// Optional map replacing the sky's background.
    pub map: Option<EnvMap>,
    sampling: EnvSampling,
}

impl Environment {
    /// Builds the environment and its sampling tables (`2n × n` lat-long cells, `n` rows).
    #[must_use]
    pub fn new(sky: Sky, map: Option<EnvMap>, n: usize) -> Environment {
        let nv = n.max(2);
        let nu = 2 * nv;
        let mut env = Environment {
            sky,
            map,
            sampling: EnvSampling {
                nu,
                nv,
                rows: Distribution1D::new(vec![]),
                cols: vec![],
                sun_prob: 0.0,
            },
        };
        // Cell (i, j): φ ∈ [−π + 2π j/nu, …), θ ∈ [π i/nv, …). Value: mean luminance of the
        // background (2 × 2 points) times the cell's solid angle, so that sampling a cell and
        // then uniformly in (φ, cos θ) inside it has the solid-angle density P_cell / Ω_cell.
        let mut row_mass = Vec::with_capacity(nv);
        let mut cols = Vec::with_capacity(nv);
        let mut sky_power = 0.0f64;
        for i in 0..nv {
            let (c0, c1) = env.cell_cos_bounds(i);
            let omega = (c0 - c1) * (2.0 * std::f64::consts::PI / nu as f64);
            let mut func = Vec::with_capacity(nu);
            for j in 0..nu {
                let mut acc = 0.0f64;
                for a in 0..2 {
                    for b in 0..2 {
                        let ct = c0 + (c1 - c0) * (0.25 + 0.5 * a as f64);
                        let phi = -std::f64::consts::PI
                            + 2.0 * std::f64::consts::PI * (j as f64 + 0.25 + 0.5 * b as f64)
                                / nu as f64;
                        let st = (1.0 - ct * ct).max(0.0).sqrt();
                        let d =
                            Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, ct as f32);
                        acc += f64::from(luminance(env.background(d)).max(0.0));
                    }
                }
                // A small floor keeps every direction sampleable (MIS stays unbiased anyway,
                // but a zero table would make env sampling useless for black maps).
                func.push((acc * 0.25 + 1e-6) * omega);
            }
            let d = Distribution1D::new(func);
            sky_power += d.total();
            row_mass.push(d.total());
            cols.push(d);
        }
        let sun_power = f64::from(luminance(env.sky.sun_color) * env.sky.sun_radiance.max(0.0))
            * env.sun_solid_angle();
        env.sampling.rows = Distribution1D::new(row_mass);
        env.sampling.cols = cols;
        env.sampling.sun_prob = if sun_power > 0.0 {
            (sun_power / (sun_power + sky_power)).clamp(0.05, 0.95) as f32
        } else {
            0.0
        };
        env
    }

    /// `(cos θ at the top, cos θ at the bottom)` of table row `i`.
    fn cell_cos_bounds(&self, i: usize) -> (f64, f64) {
        let nv = self.sampling.nv as f64;
        let t0 = std::f64::consts::PI * i as f64 / nv;
        let t1 = std::f64::consts::PI * (i + 1) as f64 / nv;
        (t0.cos(), t1.cos())
    }

    fn sun_solid_angle(&self) -> f64 {
        2.0 * std::f64::consts::PI * (1.0 - f64::from(self.sky.cos_sun_radius()))
    }

    fn in_sun(&self, d: Vec3) -> bool {
        self.sky.sun_radiance > 0.0 && d.dot(self.sky.sun_dir) >= self.sky.cos_sun_radius()
    }

    /// Background radiance without the sun disc.
    fn background(&self, d: Vec3) -> [f32; 3] {
        match &self.map {
            Some(m) => m.lookup(d),
            None => self.sky.background(d),
        }
    }

    /// Radiance arriving from direction `d` (unit, world space).
    #[must_use]
    pub fn radiance(&self, d: Vec3) -> [f32; 3] {
        let mut c = self.background(d);
        if self.in_sun(d) {
            for k in 0..3 {
                c[k] += self.sky.sun_radiance * self.sky.sun_color[k];
            }
        }
        c
    }

    /// Density (solid angle) with which [`Environment::sample`] draws `d`.
    #[must_use]
    pub fn pdf(&self, d: Vec3) -> f32 {
        let s = &self.sampling;
        let mut p = 0.0f64;
        if s.sun_prob > 0.0 && self.in_sun(d) {
            p += f64::from(s.sun_prob) / self.sun_solid_angle();
        }
        let (u, v) = dir_to_latlong(d);
        let i = ((v * s.nv as f32) as usize).min(s.nv - 1);
        let j = ((u * s.nu as f32) as usize).min(s.nu - 1);
        let (c0, c1) = self.cell_cos_bounds(i);
        let omega = (c0 - c1) * (2.0 * std::f64::consts::PI / s.nu as f64);
        if omega > 0.0 {
            let pc = s.rows.prob(i) * s.cols[i].prob(j);
            p += f64::from(1.0 - s.sun_prob) * pc / omega;
        }
        p as f32
    }

    /// A direction drawn with `pick` (sun or table) and `u`, with its density ([`Self::pdf`]).
    #[must_use]
    pub fn sample(&self, pick: f32, u: Vec2) -> Option<(Vec3, f32)> {
        let s = &self.sampling;
        let d = if pick < s.sun_prob {
            // Uniform in the sun's cone.
            let cos_a = self.sky.cos_sun_radius();
            let ct = 1.0 - u.x * (1.0 - cos_a);
            let st = (1.0 - ct * ct).max(0.0).sqrt();
            let ph = std::f32::consts::TAU * u.y;
            let f = Frame::from_normal(self.sky.sun_dir);
            f.from_local(Vec3::new(st * ph.cos(), st * ph.sin(), ct))
                .normalize()
        } else {
            let (i, fy, _) = s.rows.sample(f64::from(u.x))?;
            let (j, fx, _) = s.cols[i].sample(f64::from(u.y))?;
            let (c0, c1) = self.cell_cos_bounds(i);
            let ct = c0 + (c1 - c0) * fy;
            let st = (1.0 - ct * ct).max(0.0).sqrt();
            let phi =
                -std::f64::consts::PI + 2.0 * std::f64::consts::PI * (j as f64 + fx) / s.nu as f64;
            Vec3::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, ct as f32)
        };
        let pdf = self.pdf(d);
        (pdf > 0.0 && pdf.is_finite()).then_some((d, pdf))
    }
}

/// A scene: camera, objects and lighting.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Camera (fixes the image size).
    pub camera: Camera,
    /// Objects.
    pub objects: Vec<Object>,
    /// Lighting.
    pub env: Environment,
}

impl Scene {
    /// Nearest hit along `r`.
    #[must_use]
    pub fn intersect(&self, r: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for o in &self.objects {
            let t_max = best.map_or(f32::INFINITY, |h| h.t);
            if let Some(h) = o.intersect(r, RAY_EPSILON, t_max) {
                best = Some(h);
            }
        }
        best
    }

    /// Whether anything blocks the ray `o + t·d`, `t > ε`.
    #[must_use]
    pub fn occluded(&self, o: Vec3, d: Vec3) -> bool {
        let r = Ray { o, d };
        self.objects
            .iter()
            .any(|ob| ob.intersect(&r, RAY_EPSILON, f32::INFINITY).is_some())
    }
}

/// Parameters of [`demo_scene`].
#[derive(Clone, Debug)]
pub struct SceneParams {
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Radiance of the sun disc.
    pub sun_radiance: f32,
    /// Angular radius of the sun, degrees.
    pub sun_radius_deg: f32,
    /// Optional environment map (replaces the procedural sky; the sun is added unless its
    /// radiance is 0).
    pub env_map: Option<EnvMap>,
    /// Texture tiling of the patch.
    pub patch_tiling: f32,
    /// Uniform white lighting (radiance 1 from every direction, no sun) instead of the sky:
    /// BSDF-sampling variance then depends on the sampler alone.
    pub uniform_light: bool,
}

impl Default for SceneParams {
    fn default() -> Self {
        SceneParams {
            width: 160,
            height: 120,
            sun_radiance: 60.0,
            sun_radius_deg: 4.0,
            env_map: None,
            patch_tiling: 2.0,
            uniform_light: false,
        }
    }
}

/// The evaluation scene: a textured square patch with a sphere standing on it, seen from
/// above at about 27°, under a daylight sky whose sun (elevation 27°, in front of the camera)
/// reflects in both objects (or under uniform light). Both objects use surface 0.
#[must_use]
pub fn demo_scene(p: &SceneParams) -> Scene {
    let camera = Camera::look_at(
        Vec3::new(0.0, -3.3, 1.75),
        Vec3::new(0.0, 0.15, 0.2),
        Vec3::Z,
        34.0,
        p.width.max(1),
        p.height.max(1),
    );
    let sky = if p.uniform_light {
        Sky::constant([1.0; 3])
    } else {
        Sky::daylight(27.0, -12.0, p.sun_radiance, p.sun_radius_deg)
    };
    Scene {
        camera,
        objects: vec![
            Object {
                shape: Shape::Patch {
                    center: Vec3::ZERO,
                    normal: Vec3::Z,
                    tangent: Vec3::X,
                    half_size: 1.6,
                },
                uv_scale: p.patch_tiling,
                surface: 0,
            },
            Object {
                shape: Shape::Sphere {
                    center: Vec3::new(0.62, 0.45, 0.5),
                    radius: 0.5,
                },
                uv_scale: 1.0,
                surface: 0,
            },
        ],
        env: Environment::new(sky, p.env_map.clone(), 128),
    }
}

// ---------------------------------------------------------------------------------------
// The oracle
// ---------------------------------------------------------------------------------------

/// The "tabulated" near-optimal sampler (paper Fig. 10): at each shading point, the ground
/// truth p*(ω⊥ | φ, wi) ∝ Y(f(φ, wi, ω)) is tabulated on a `res × res` grid over the projected
/// disk and sampled exactly through the runtime's [`Table2D`]. Its `prepare` is expensive
/// (`res² · s²` material evaluations), which is why it is a limit, not a method.
///
/// It follows [`crate::groundtruth::TargetPdf`] (cell value = mean of `Y(f)` over `s × s`
/// stratified points) with two changes that make it **unbiased** for rendering: cells that
/// straddle the circle are kept (the points of a cell outside the disk count as 0; a sample
/// falling outside the disk is refused, as in the runtime's histograms) and there is no
/// grazing cut-off; and a small defensive share of cosine sampling
/// (`p = (1 − d)·p_table + d/π`) covers any sliver the table misses.
#[derive(Clone, Copy)]
pub struct OracleSampler<'m> {
    /// The material.
    pub material: &'m dyn Material,
    /// Grid resolution per side (≤ [`neusample::samplers::histogram_mixture::MAX_N`]).
    pub res: usize,
    /// Stratified points per cell and axis.
    pub supersample: usize,
    /// Share `d` of cosine sampling.
    pub defensive: f32,
}

impl std::fmt::Debug for OracleSampler<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OracleSampler")
            .field("material", &self.material.name())
            .field("res", &self.res)
            .field("supersample", &self.supersample)
            .field("defensive", &self.defensive)
            .finish()
    }
}

impl<'m> OracleSampler<'m> {
    /// An oracle with 2 × 2 points per cell and a 2 % defensive share.
    #[must_use]
    pub fn new(material: &'m dyn Material, res: usize) -> Self {
        OracleSampler {
            material,
            res: res.clamp(1, neusample::samplers::histogram_mixture::MAX_N),
            supersample: 2,
            defensive: 0.02,
        }
    }
}

/// The prepared state of [`OracleSampler`]: the tabulated density and its running sums.
#[derive(Clone, Debug)]
pub struct OraclePrepared {
    values: Vec<f32>,
    marginal: Vec<f32>,
    conditional: Vec<f32>,
    res: u32,
    defensive: f32,
}

impl OraclePrepared {
    fn table(&self) -> Option<Table2D<&[f32]>> {
        Table2D::new(
            &self.values[..],
            &self.marginal[..],
            &self.conditional[..],
            self.res,
            0,
        )
    }
}

impl Sampler for OracleSampler<'_> {
    type Prepared<'s>
        = OraclePrepared
    where
        Self: 's;

    fn prepare(&self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<OraclePrepared> {
        let wi = neusample::nn::check_condition(phi, wi)?;
        let res = self
            .res
            .clamp(1, neusample::samplers::histogram_mixture::MAX_N);
        let s = self.supersample.max(1);
        let h = 2.0 / res as f32;
        let hs = h / s as f32;
        let mut values = vec![0f32; res * res];
        let mut total = 0.0f64;
        for r in 0..res {
            for c in 0..res {
                if neusample::distrib::table2d::cell_outside_disk(r as u32, c as u32, res as u32) {
                    continue;
                }
                let mut acc = 0.0f32;
                for i in 0..s {
                    let y = -1.0 + r as f32 * h + (i as f32 + 0.5) * hs;
                    for j in 0..s {
                        let x = -1.0 + c as f32 * h + (j as f32 + 0.5) * hs;
                        let r2 = x * x + y * y;
                        if r2 >= 1.0 {
                            continue;
                        }
                        let wo = Vec3::new(x, y, (1.0 - r2).sqrt());
                        let l = luminance(self.material.eval(phi, wi, wo));
                        if l > 0.0 && l.is_finite() {
                            acc += l;
                        }
                    }
                }
                let v = acc / (s * s) as f32;
                values[r * res + c] = v;
                total += f64::from(v);
            }
        }
        let mut defensive = self.defensive.clamp(0.0, 1.0);
        if !(total > 0.0 && total.is_finite()) {
            // Nothing reflects: cosine sampling only.
            defensive = 1.0;
            values.iter_mut().for_each(|v| *v = 0.0);
            values[0] = 1.0;
        }
        let mut marginal = vec![0f32; res];
        let mut conditional = vec![0f32; res * res];
        neusample::distrib::table2d::running_sums(
            &values,
            res as u32,
            &mut marginal,
            &mut conditional,
        );
        Some(OraclePrepared {
            values,
            marginal,
            conditional,
            res: res as u32,
            defensive,
        })
    }
}

impl Prepared for OraclePrepared {
    fn sample(&self, u: Vec2) -> Option<Sample> {
        if !(u.x >= 0.0 && u.x <= 1.0 && u.y >= 0.0 && u.y <= 1.0) {
            return None;
        }
        let u = u.min(Vec2::splat(neusample::ONE_MINUS_EPSILON));
        let d = self.defensive;
        let p = if u.x < d {
            warp::sample_uniform_disk_concentric(Vec2::new(u.x / d, u.y))
        } else {
            let ux = ((u.x - d) / (1.0 - d)).min(neusample::ONE_MINUS_EPSILON);
            self.table()?.sample(Vec2::new(ux, u.y))?.0
        };
        Sample::from_disk(p, self.pdf_disk(p))
    }

    fn pdf_disk(&self, p: Vec2) -> f32 {
        if !(p.length_squared() < 1.0) {
            return 0.0;
        }
        let d = self.defensive;
        let t = if d < 1.0 {
            self.table().map_or(0.0, |t| t.pdf(p))
        } else {
            0.0
        };
        (1.0 - d) * t + d * warp::uniform_disk_pdf(p)
    }
}

// ---------------------------------------------------------------------------------------
// The renderer
// ---------------------------------------------------------------------------------------

/// A material with the sampler used for it.
pub struct Surface<'a, S> {
    /// The material (features and BRDF).
    pub material: &'a dyn Material,
    /// Its sampler.
    pub sampler: S,
}

/// How a pixel sample estimates direct lighting (module docs).
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Estimator {
    /// BSDF sampling only.
    Bsdf,
    /// BSDF sampling + environment sampling, power heuristic.
    Mis,
}

/// Options of [`render`].
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Samples per pixel.
    pub spp: u32,
    /// Sample counts at which the running mean image is kept, e.g. 1, 2, 4, … (sorted and
    /// limited to `1..=spp` by [`render`]).
    pub checkpoints: Vec<u32>,
    /// Seed of the per-pixel random streams.
    pub seed: u64,
    /// Estimator.
    pub estimator: Estimator,
    /// Jitter the primary ray inside the pixel (box filter). Off by default: every sample of
    /// a pixel then shades the same point, so the measured variance is that of the BRDF
    /// sampling alone.
    pub jitter: bool,
    /// Prepare once per pixel and reuse it for all its samples (only without `jitter`; the
    /// same point is shaded). Meant for the expensive [`OracleSampler`]; the time spent in
    /// `prepare` is then reported separately ([`Render::prepare_seconds`]).
    pub reuse_prepared: bool,
    /// Path length in surface interactions: 1 = direct lighting only (the paper's main
    /// mode); `k > 1` = global illumination: a BSDF sample that hits another surface
    /// continues the path there (the sampler is prepared at every vertex, the throughput is
    /// `f · cos θo / pdf`), up to `k` interactions. Unbiased for the light carried by paths of
    /// at most `k` interactions; no Russian roulette.
    pub max_bounces: u32,
}

impl RenderOptions {
    /// `spp` samples, BSDF sampling, no jitter, checkpoints at powers of two.
    #[must_use]
    pub fn new(spp: u32, seed: u64) -> Self {
        RenderOptions {
            spp,
            checkpoints: powers_of_two(spp),
            seed,
            estimator: Estimator::Bsdf,
            jitter: false,
            reuse_prepared: false,
            max_bounces: 1,
        }
    }
}

/// `1, 2, 4, …` up to and including `max` (and `max` itself).
#[must_use]
pub fn powers_of_two(max: u32) -> Vec<u32> {
    let mut v = Vec::new();
    let mut k = 1u32;
    while k < max {
        v.push(k);
        k = k.saturating_mul(2);
    }
    if max > 0 {
        v.push(max);
    }
    v
}

/// The result of [`render`].
#[derive(Clone, Debug)]
pub struct Render {
    /// Mean of all samples.
    pub image: Image,
    /// Per pixel and channel, the unbiased sample variance of one pixel sample (0 for one
    /// sample); the variance of the pixel mean is this divided by `spp`.
    pub variance: Image,
    /// The running mean at each checkpoint, ascending.
    pub checkpoints: Vec<(u32, Image)>,
    /// Whether the pixel's primary ray hits an object (from its first sample).
    pub mask: Vec<bool>,
    /// Samples per pixel.
    pub spp: u32,
    /// Wall time of the render.
    pub seconds: f64,
    /// Time spent in `prepare` when it was reused per pixel (summed over threads), else 0.
    pub prepare_seconds: f64,
}

struct Ctx<'r, 'a, S> {
    scene: &'r Scene,
    surfaces: &'r [Surface<'a, S>],
    opts: &'r RenderOptions,
}

struct RowOut {
    mean: Vec<[f32; 3]>,
    var: Vec<[f32; 3]>,
    checkpoints: Vec<Vec<[f32; 3]>>,
    mask: Vec<bool>,
    prepare_seconds: f64,
}

#[inline]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 && (a2 + b2).is_finite() {
        a2 / (a2 + b2)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

impl<'r, 'a, S: Sampler> Ctx<'r, 'a, S> {
    /// The surface at a path vertex, its shading frame, the local direction towards the
    /// previous vertex and φ; `None` off every surface or seen from below.
    #[allow(clippy::type_complexity)]
    fn vertex(
        &self,
        ray: &Ray,
        hit: &Hit,
    ) -> Option<(&'r Surface<'a, S>, Frame, Vec3, [f32; FEATURE_DIM])> {
        let surface = self.surfaces.get(hit.surface)?;
        let frame = Frame::from_normal_tangent(hit.n, hit.tangent);
        let wi = frame.to_local(-ray.d);
        if !(wi.z > 0.0) {
            return None;
        }
        let phi = surface.material.features(hit.uv);
        Some((surface, frame, wi, phi))
    }

    /// Radiance leaving a secondary path vertex `hit` towards `-ray.d`, the vertex being the
    /// `depth`-th surface interaction of the path.
    fn radiance_at(
        &self,
        ray: &Ray,
        hit: &Hit,
        depth: u32,
        rng: &mut rand_pcg::Pcg64Mcg,
    ) -> [f32; 3] {
        let Some((surface, frame, wi, phi)) = self.vertex(ray, hit) else {
            return [0.0; 3];
        };
        match surface.sampler.prepare(&phi, wi) {
            Some(p) => self.shade(surface.material, &phi, hit, &frame, wi, &p, depth, rng),
            None => [0.0; 3],
        }
    }

    /// Lighting at a shading point, one pixel sample: direct lighting, plus (while `depth <
    /// max_bounces`) the light the BSDF sample brings from the surface it hits.
    #[allow(clippy::too_many_arguments)]
    fn shade<P: Prepared>(
        &self,
        material: &dyn Material,
        phi: &[f32; FEATURE_DIM],
        hit: &Hit,
        frame: &Frame,
        wi: Vec3,
        prep: &P,
        depth: u32,
        rng: &mut rand_pcg::Pcg64Mcg,
    ) -> [f32; 3] {
        let env = &self.scene.env;
        let origin = hit.p + hit.n * RAY_EPSILON;
        let mis = self.opts.estimator == Estimator::Mis;
        let mut out = [0.0f32; 3];
        // BSDF sample.
        let u = Vec2::new(rng.random::<f32>(), rng.random::<f32>());
        if let Some(s) = prep.sample(u) {
            let wo_w = frame.from_local(s.wo).normalize();
            // Does the sample see the environment? With bounces left, a surface it hits
            // instead continues the path (surfaces do not emit: no MIS weight there).
            let escaped = if depth < self.opts.max_bounces {
                let ray = Ray { o: origin, d: wo_w };
                match self.scene.intersect(&ray) {
                    None => true,
                    Some(next) => {
                        let l = self.radiance_at(&ray, &next, depth + 1, rng);
                        if l != [0.0; 3] {
                            let f = material.eval(phi, wi, s.wo);
                            let k = s.wo.z / s.pdf;
                            for c in 0..3 {
                                out[c] += f[c] * l[c] * k;
                            }
                        }
                        false
                    }
                }
            } else {
                !self.scene.occluded(origin, wo_w)
            };
            if escaped {
                let l = env.radiance(wo_w);
                let f = material.eval(phi, wi, s.wo);
                let w = if mis {
                    power_heuristic(s.pdf, env.pdf(wo_w))
                } else {
                    1.0
                };
                let k = s.wo.z * w / s.pdf;
                for c in 0..3 {
                    out[c] += f[c] * l[c] * k;
                }
            }
        }
        if mis {
            let pick: f32 = rng.random();
            let u = Vec2::new(rng.random::<f32>(), rng.random::<f32>());
            if let Some((d, pe)) = env.sample(pick, u) {
                let wo = frame.to_local(d);
                if wo.z > 0.0 && !self.scene.occluded(origin, d) {
                    let f = material.eval(phi, wi, wo);
                    let l = env.radiance(d);
                    let w = power_heuristic(pe, prep.pdf(wo));
                    let k = wo.z * w / pe;
                    for c in 0..3 {
                        out[c] += f[c] * l[c] * k;
                    }
                }
            }
        }
        for v in &mut out {
            if !v.is_finite() {
                *v = 0.0;
            }
        }
        out
    }

    fn row(&self, y: usize) -> RowOut {
        let cam = &self.scene.camera;
        let w = cam.width;
        let spp = self.opts.spp.max(1);
        let reuse = self.opts.reuse_prepared && !self.opts.jitter;
        let mut out = RowOut {
            mean: vec![[0.0; 3]; w],
            var: vec![[0.0; 3]; w],
            checkpoints: vec![vec![[0.0; 3]; w]; self.opts.checkpoints.len()],
            mask: vec![false; w],
            prepare_seconds: 0.0,
        };
        for x in 0..w {
            let mut rng = condition_rng(self.opts.seed, y * w + x);
            let (mut sum, mut sq) = ([0.0f64; 3], [0.0f64; 3]);
            // Outer None: not prepared yet (reuse mode).
            let mut cached: Option<Option<S::Prepared<'_>>> = None;
            let mut next_cp = 0;
            for s in 1..=spp {
                let (jx, jy) = if self.opts.jitter {
                    (rng.random::<f32>(), rng.random::<f32>())
                } else {
                    (0.5, 0.5)
                };
                let ray = cam.ray(x as f32 + jx, y as f32 + jy);
                let v = match self.scene.intersect(&ray) {
                    None => self.scene.env.radiance(ray.d),
                    Some(hit) => {
                        if s == 1 {
                            out.mask[x] = true;
                        }
                        self.sample_hit(&ray, &hit, reuse, &mut cached, &mut rng, &mut out)
                    }
                };
                for c in 0..3 {
                    let vc = f64::from(v[c]);
                    sum[c] += vc;
                    sq[c] += vc * vc;
                }
                while next_cp < self.opts.checkpoints.len() && self.opts.checkpoints[next_cp] <= s {
                    if self.opts.checkpoints[next_cp] == s {
                        for c in 0..3 {
                            out.checkpoints[next_cp][x][c] = (sum[c] / f64::from(s)) as f32;
                        }
                    }
                    next_cp += 1;
                }
            }
            let n = f64::from(spp);
            for c in 0..3 {
                let mean = sum[c] / n;
                out.mean[x][c] = mean as f32;
                out.var[x][c] = if spp > 1 {
                    ((sq[c] - n * mean * mean) / (n - 1.0)).max(0.0) as f32
                } else {
                    0.0
                };
            }
        }
        out
    }

    fn sample_hit<'s>(
        &'s self,
        ray: &Ray,
        hit: &Hit,
        reuse: bool,
        cached: &mut Option<Option<S::Prepared<'s>>>,
        rng: &mut rand_pcg::Pcg64Mcg,
        out: &mut RowOut,
    ) -> [f32; 3] {
        let Some((surface, frame, wi, phi)) = self.vertex(ray, hit) else {
            return [0.0; 3];
        };
        if reuse {
            if cached.is_none() {
                let t0 = Instant::now();
                *cached = Some(surface.sampler.prepare(&phi, wi));
                out.prepare_seconds += t0.elapsed().as_secs_f64();
            }
            match cached {
                Some(Some(p)) => self.shade(surface.material, &phi, hit, &frame, wi, p, 1, rng),
                _ => [0.0; 3],
            }
        } else {
            match surface.sampler.prepare(&phi, wi) {
                Some(p) => self.shade(surface.material, &phi, hit, &frame, wi, &p, 1, rng),
                None => [0.0; 3],
            }
        }
    }
}

/// Renders `scene` with `surfaces` (indexed by [`Object::surface`]) on the current rayon pool.
pub fn render<S: Sampler + Sync>(
    scene: &Scene,
    surfaces: &[Surface<'_, S>],
    opts: &RenderOptions,
) -> Render {
    let t0 = Instant::now();
    let mut opts = opts.clone();
    opts.spp = opts.spp.max(1);
    let spp = opts.spp;
    opts.checkpoints.retain(|&s| s >= 1 && s <= spp);
    opts.checkpoints.sort_unstable();
    opts.checkpoints.dedup();
    let opts = &opts;
    let ctx = Ctx {
        scene,
        surfaces,
        opts,
    };
    let (w, h) = (scene.camera.width, scene.camera.height);
    let rows: Vec<RowOut> = (0..h).into_par_iter().map(|y| ctx.row(y)).collect();
    let seconds = t0.elapsed().as_secs_f64();
    let mut image = Image::new(w, h);
    let mut variance = Image::new(w, h);
    let mut mask = vec![false; w * h];
    let mut cps: Vec<(u32, Image)> = opts
        .checkpoints
        .iter()
        .map(|&s| (s, Image::new(w, h)))
        .collect();
    let mut prepare_seconds = 0.0;
    for (y, r) in rows.into_iter().enumerate() {
        image.data[y * w..(y + 1) * w].copy_from_slice(&r.mean);
        variance.data[y * w..(y + 1) * w].copy_from_slice(&r.var);
        mask[y * w..(y + 1) * w].copy_from_slice(&r.mask);
        for (k, cp) in r.checkpoints.iter().enumerate() {
            cps[k].1.data[y * w..(y + 1) * w].copy_from_slice(cp);
        }
        prepare_seconds += r.prepare_seconds;
    }
    Render {
        image,
        variance,
        checkpoints: cps,
        mask,
        spp: opts.spp.max(1),
        seconds,
        prepare_seconds,
    }
}

/// Renders on a private single-thread pool and returns the render loop's wall time per pixel
/// sample in nanoseconds (all pixels, background included), **excluding** the time of reused
/// `prepare` calls ([`RenderOptions::reuse_prepared`]): the "time per sample" of the
/// equal-time comparisons. Returns the median over `passes` renders.
pub fn time_per_sample<S: Sampler + Sync>(
    scene: &Scene,
    surfaces: &[Surface<'_, S>],
    opts: &RenderOptions,
    passes: usize,
) -> anyhow::Result<f64> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut o = opts.clone();
    o.checkpoints.clear();
    let samples = (scene.camera.width * scene.camera.height) as f64 * f64::from(o.spp.max(1));
    let mut times: Vec<f64> = (0..passes.max(1))
        .map(|_| {
            let r = pool.install(|| render(scene, surfaces, &o));
            (r.seconds - r.prepare_seconds).max(0.0) * 1e9 / samples
        })
        .collect();
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}

/// Convenience: a blob sampler surface.
#[must_use]
pub fn surface<'a>(
    material: &'a dyn Material,
    sampler: AnySampler<'a>,
) -> Surface<'a, AnySampler<'a>> {
    Surface { material, sampler }
}
