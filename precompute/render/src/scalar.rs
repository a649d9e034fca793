//! The scalar integrator, one shading point at a time through the runtime's scalar API
//! (`prepare`, `sample`, `pdf`): the reference the wavefront integrator is tested against.

use std::time::Instant;

use glam::Vec3;
use neusample::{Frame, Prepared, Sampler, FEATURE_DIM};
use rayon::prelude::*;

use crate::geometry::{Hit, Ray};
use crate::integrator::{
    add_term, assemble, finite_or_zero, jitter, power_heuristic, Estimator, Render, RenderOptions,
    Span, VertexRandoms,
};
use crate::material::{Material, Surface};
use crate::rng::StreamRng;
use crate::scene::{Scene, RAY_EPSILON};

struct Ctx<'r, 'a, M: ?Sized, S> {
    scene: &'r Scene,
    surfaces: &'r [Surface<'a, M, S>],
    opts: &'r RenderOptions,
}

/// A shading point: its surface, shading frame, local direction towards the previous vertex
/// and φ.
struct Vertex<'r, 'a, M: ?Sized, S> {
    surface: &'r Surface<'a, M, S>,
    frame: Frame,
    wi: Vec3,
    phi: [f32; FEATURE_DIM],
}

impl<'r, 'a, M: Material + ?Sized, S: Sampler> Ctx<'r, 'a, M, S> {
    /// The shading point at `hit`; `None` off every surface or seen from below.
    fn vertex(&self, ray: &Ray, hit: &Hit) -> Option<Vertex<'r, 'a, M, S>> {
        let surface = self.surfaces.get(hit.surface)?;
        let frame = Frame::from_normal_tangent(hit.n, hit.tangent);
        let wi = frame.to_local(-ray.d);
        if !(wi.z > 0.0) {
            return None;
        }
        let phi = surface.material.features(hit.uv);
        Some(Vertex {
            surface,
            frame,
            wi,
            phi,
        })
    }

    /// Radiance leaving a secondary path vertex `hit` towards `-ray.d`, the vertex being the
    /// `depth`-th surface interaction of the path.
    fn radiance_at(&self, ray: &Ray, hit: &Hit, depth: u32, rng: &mut StreamRng) -> [f32; 3] {
        let r = VertexRandoms::draw(rng, self.opts.estimator == Estimator::Mis);
        let Some(v) = self.vertex(ray, hit) else {
            return [0.0; 3];
        };
        match v.surface.sampler.prepare(&v.phi, v.wi) {
            Some(p) => self.shade(&v, hit, &p, depth, &r, rng),
            None => [0.0; 3],
        }
    }

    /// Lighting at a shading point, one pixel sample: direct lighting, plus (while `depth <
    /// max_bounces`) the light the BSDF sample brings from the surface it hits.
    fn shade<P: Prepared>(
        &self,
        v: &Vertex<'r, 'a, M, S>,
        hit: &Hit,
        prep: &P,
        depth: u32,
        r: &VertexRandoms,
        rng: &mut StreamRng,
    ) -> [f32; 3] {
        let env = &self.scene.env;
        let material = v.surface.material;
        let origin = hit.p + hit.n * RAY_EPSILON;
        let mis = self.opts.estimator == Estimator::Mis;
        let mut out = [0.0f32; 3];
        // BSDF sample.
        if let Some(s) = prep.sample(r.bsdf) {
            let wo_w = v.frame.from_local(s.wo).normalize();
            // Does the sample see the environment? With bounces left, a surface it hits
            // instead continues the path (surfaces do not emit: no MIS weight there).
            let escaped = if depth < self.opts.max_bounces {
                let ray = Ray { o: origin, d: wo_w };
                match self.scene.intersect(&ray) {
                    None => true,
                    Some(next) => {
                        let l = self.radiance_at(&ray, &next, depth + 1, rng);
                        if l != [0.0; 3] {
                            let f = material.eval(&v.phi, v.wi, s.wo);
                            add_term(&mut out, f, l, s.wo.z / s.pdf);
                        }
                        false
                    }
                }
            } else {
                !self.scene.occluded(origin, wo_w)
            };
            if escaped {
                let l = env.radiance(wo_w);
                let f = material.eval(&v.phi, v.wi, s.wo);
                let w = if mis {
                    power_heuristic(s.mis_pdf, env.pdf(wo_w))
                } else {
                    1.0
                };
                add_term(&mut out, f, l, s.wo.z * w / s.pdf);
            }
        }
        if mis {
            if let Some((d, pe)) = env.sample(r.env_pick, r.env) {
                let wo = v.frame.to_local(d);
                if wo.z > 0.0 && !self.scene.occluded(origin, d) {
                    let f = material.eval(&v.phi, v.wi, wo);
                    let l = env.radiance(d);
                    let w = power_heuristic(pe, prep.pdf(wo));
                    add_term(&mut out, f, l, wo.z * w / pe);
                }
            }
        }
        finite_or_zero(out)
    }

    fn row(&self, y: usize) -> Span {
        let cam = &self.scene.camera;
        let w = cam.width;
        let spp = self.opts.spp;
        let reuse = self.opts.reuses_prepared();
        let mis = self.opts.estimator == Estimator::Mis;
        let mut out = Span::new(y * w, w, self.opts);
        let mut streams = out.streams(self.opts.seed);
        for (x, rng) in streams.iter_mut().enumerate() {
            // Outer None: not prepared yet (reuse mode).
            let mut cached: Option<Option<S::Prepared<'_>>> = None;
            for s in 1..=spp {
                let (jx, jy) = jitter(rng, self.opts.jitter);
                let ray = cam.ray(x as f32 + jx, y as f32 + jy);
                let v = match self.scene.intersect(&ray) {
                    None => self.scene.env.radiance(ray.d),
                    Some(hit) => {
                        if s == 1 {
                            out.mask[x] = true;
                        }
                        let r = VertexRandoms::draw(rng, mis);
                        match self.vertex(&ray, &hit) {
                            None => [0.0; 3],
                            Some(v) if reuse => {
                                if cached.is_none() {
                                    let t0 = Instant::now();
                                    cached = Some(v.surface.sampler.prepare(&v.phi, v.wi));
                                    out.prepare_seconds += t0.elapsed().as_secs_f64();
                                }
                                match &cached {
                                    Some(Some(p)) => self.shade(&v, &hit, p, 1, &r, rng),
                                    _ => [0.0; 3],
                                }
                            }
                            Some(v) => match v.surface.sampler.prepare(&v.phi, v.wi) {
                                Some(p) => self.shade(&v, &hit, &p, 1, &r, rng),
                                None => [0.0; 3],
                            },
                        }
                    }
                };
                out.add(x, s, v, self.opts);
            }
        }
        out.finish(self.opts);
        out
    }
}

/// Renders `scene` with `surfaces` (indexed by [`crate::Object::surface`]) on the current
/// rayon pool, one shading point at a time through the scalar sampler API (the reference of
/// [`crate::render_wavefront()`]). Every pixel draws from its own stream and accumulates its
/// samples in order, so the image is bit-identical for any number of threads.
pub fn render<M: Material + Sync + ?Sized, S: Sampler + Sync>(
    scene: &Scene,
    surfaces: &[Surface<'_, M, S>],
    opts: &RenderOptions,
) -> Render {
    let t0 = Instant::now();
    let opts = opts.normalised();
    let ctx = Ctx {
        scene,
        surfaces,
        opts: &opts,
    };
    let (w, h) = (scene.camera.width, scene.camera.height);
    let rows: Vec<Span> = (0..h).into_par_iter().map(|y| ctx.row(y)).collect();
    assemble(w, h, &opts, rows, t0)
}
