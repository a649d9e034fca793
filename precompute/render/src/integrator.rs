//! The path-tracing integrator: BSDF sampling, optionally combined with environment sampling
//! (MIS), direct lighting or multi-bounce global illumination, per-pixel statistics and
//! convergence checkpoints.

use std::time::Instant;

use glam::{Vec2, Vec3};
use neusample::{Frame, Prepared, Sampler, FEATURE_DIM};
use rand::RngExt;
use rayon::prelude::*;

use crate::geometry::{Hit, Ray};
use crate::image::Image;
use crate::material::{Material, Surface};
use crate::rng::{indexed_rng, StreamRng};
use crate::scene::{Scene, RAY_EPSILON};

/// How a pixel sample estimates the light arriving from the environment.
///
/// * [`Estimator::Bsdf`] — the paper's main mode: one BSDF sample per pixel sample,
///   `L = f(φ, wi, wo) · cos θo · L_env(wo) / pdf(wo)`, pdf in solid angle.
/// * [`Estimator::Mis`] — one BSDF sample plus one environment sample, combined with the
///   power heuristic (β = 2, Veach 1997).
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
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
    /// same point is shaded). Meant for samplers whose `prepare` is expensive (a tabulated oracle); the time spent in
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

struct Ctx<'r, 'a, M: ?Sized, S> {
    scene: &'r Scene,
    surfaces: &'r [Surface<'a, M, S>],
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

impl<'r, 'a, M: Material + ?Sized, S: Sampler> Ctx<'r, 'a, M, S> {
    /// The surface at a path vertex, its shading frame, the local direction towards the
    /// previous vertex and φ; `None` off every surface or seen from below.
    #[allow(clippy::type_complexity)]
    fn vertex(
        &self,
        ray: &Ray,
        hit: &Hit,
    ) -> Option<(&'r Surface<'a, M, S>, Frame, Vec3, [f32; FEATURE_DIM])> {
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
    fn radiance_at(&self, ray: &Ray, hit: &Hit, depth: u32, rng: &mut StreamRng) -> [f32; 3] {
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
        material: &M,
        phi: &[f32; FEATURE_DIM],
        hit: &Hit,
        frame: &Frame,
        wi: Vec3,
        prep: &P,
        depth: u32,
        rng: &mut StreamRng,
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
            let mut rng = indexed_rng(self.opts.seed, y * w + x);
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
        rng: &mut StreamRng,
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

/// Renders `scene` with `surfaces` (indexed by [`crate::Object::surface`]) on the current
/// rayon pool. Every pixel draws from its own stream ([`indexed_rng`] of the seed and the
/// pixel index) and accumulates its samples in order, so the image is bit-identical for any
/// number of threads.
pub fn render<M: Material + Sync + ?Sized, S: Sampler + Sync>(
    scene: &Scene,
    surfaces: &[Surface<'_, M, S>],
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
