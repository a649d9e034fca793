//! The lighting of a scene (sky or map, plus the sun) and its sampling: a lat-long table over
//! `(φ, cos θ)` cells mixed with uniform sampling of the sun's cone.

use glam::{Vec2, Vec3};
use neusample::Frame;

use crate::envmap::{dir_to_latlong, EnvMap};
use crate::material::luminance;
use crate::sky::Sky;

/// A piecewise-constant 1-D distribution (f64), pbrt `PiecewiseConstant1D` style. The
/// environment table is `2n × n` cells, which core's square `Table2D` does not cover.
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
