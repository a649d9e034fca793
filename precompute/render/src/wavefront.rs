//! The wavefront integrator: the image is cut into tiles of consecutive pixels, and every
//! step of a tile traces one sample of each of its pixels, path vertex by path vertex. At
//! each depth the tile's shading points are grouped by surface and handed to the material and
//! the sampler as one batch (`features_batch`, `prepare_batch`, `sample_batch`, `eval_batch`,
//! and with MIS `pdf_batch`), as the paper ran its samplers on a wavefront of rays. Ray
//! casting and the environment stay per lane.
//!
//! It follows the per-pixel recipe of [`crate::integrator`], so its image equals the scalar
//! integrator's bit for bit whenever the batched calls equal the scalar ones (which core
//! guarantees for every sampler and the neural material): a vertex's terms are kept per
//! depth and folded from the deepest vertex back, in the scalar integrator's operation
//! order.

use std::time::Instant;

use glam::{Vec2, Vec3};
use neusample::wavefront::{
    BatchSampler, Features, FeaturesMut, LaneState, RgbMut, SamplesMut, Scratch, Vec2s, Vec3s,
    Vec3sMut,
};
use neusample::{Frame, FEATURE_DIM};
use rayon::prelude::*;

use crate::geometry::{Hit, Ray};
use crate::integrator::{
    add_term, assemble, finite_or_zero, jitter, power_heuristic, Estimator, Render, RenderOptions,
    Span, VertexRandoms,
};
use crate::material::{Material, Surface};
use crate::rng::StreamRng;
use crate::scene::{Scene, RAY_EPSILON};

/// One `out += f · l · k` of a vertex (`on`: whether it is added).
#[derive(Copy, Clone, Default)]
struct Term {
    f: [f32; 3],
    l: [f32; 3],
    k: f32,
    on: bool,
}

/// What a path vertex contributes, kept until the path ends.
#[derive(Copy, Clone, Default)]
struct VertexTerms {
    /// The path has a shading point at this depth.
    present: bool,
    /// The BSDF sample continues the path (its term's `l` is the next vertex's radiance).
    continues: bool,
    /// The BSDF sample's term.
    bsdf: Term,
    /// With MIS, the environment sample's term.
    env: Term,
}

impl VertexTerms {
    /// The vertex's radiance given the radiance `next` of the vertex after it, in the scalar
    /// integrator's order: BSDF term, then environment term, then non-finite channels to 0.
    fn radiance(&self, next: [f32; 3]) -> [f32; 3] {
        if !self.present {
            return [0.0; 3];
        }
        let mut out = [0.0f32; 3];
        if self.continues {
            if next != [0.0; 3] {
                add_term(&mut out, self.bsdf.f, next, self.bsdf.k);
            }
        } else if self.bsdf.on {
            add_term(&mut out, self.bsdf.f, self.bsdf.l, self.bsdf.k);
        }
        if self.env.on {
            add_term(&mut out, self.env.f, self.env.l, self.env.k);
        }
        finite_or_zero(out)
    }
}

/// Structure-of-arrays buffers of `n` components, sized once per tile.
struct Rows<const K: usize>([Vec<f32>; K]);

impl<const K: usize> Rows<K> {
    fn new(cap: usize) -> Self {
        Rows(std::array::from_fn(|_| vec![0.0; cap]))
    }

    fn set(&mut self, i: usize, v: [f32; K]) {
        for (c, x) in self.0.iter_mut().zip(v) {
            c[i] = x;
        }
    }

    fn at(&self, i: usize) -> [f32; K] {
        std::array::from_fn(|c| self.0[c][i])
    }
}

impl Rows<2> {
    fn view(&self, n: usize) -> Vec2s<'_> {
        Vec2s {
            x: &self.0[0][..n],
            y: &self.0[1][..n],
        }
    }
}

impl Rows<3> {
    fn view(&self, n: usize) -> Vec3s<'_> {
        Vec3s {
            x: &self.0[0][..n],
            y: &self.0[1][..n],
            z: &self.0[2][..n],
        }
    }

    fn view_mut(&mut self, n: usize) -> Vec3sMut<'_> {
        let [x, y, z] = &mut self.0;
        Vec3sMut {
            x: &mut x[..n],
            y: &mut y[..n],
            z: &mut z[..n],
        }
    }

    fn rgb_mut(&mut self, n: usize) -> RgbMut<'_> {
        let [r, g, b] = &mut self.0;
        RgbMut {
            r: &mut r[..n],
            g: &mut g[..n],
            b: &mut b[..n],
        }
    }

    fn vec3(&self, i: usize) -> Vec3 {
        Vec3::from_array(self.at(i))
    }
}

impl Rows<FEATURE_DIM> {
    fn features(&self, n: usize) -> Features<'_> {
        Features {
            channels: std::array::from_fn(|c| &self.0[c][..n]),
        }
    }

    fn features_mut(&mut self, n: usize) -> FeaturesMut<'_> {
        let mut it = self.0.iter_mut();
        FeaturesMut {
            channels: std::array::from_fn(|_| match it.next() {
                Some(c) => &mut c[..n],
                None => &mut [],
            }),
        }
    }
}

/// One surface's batch at one depth: the shading points of the tile that lie on it.
struct Batch<L> {
    /// Tile slot of each lane.
    slots: Vec<usize>,
    frames: Vec<Frame>,
    uv: Rows<2>,
    wi: Rows<3>,
    phi: Rows<FEATURE_DIM>,
    lanes: Vec<L>,
    u: Rows<2>,
    wo: Rows<3>,
    pdf: Vec<f32>,
    /// The density the BSDF sample's MIS weight uses ([`neusample::Sample::mis_pdf`]).
    mis_pdf: Vec<f32>,
    f: Rows<3>,
    /// With MIS: the environment sample per lane (world direction, density), its local
    /// direction, the sampler's density there and the BRDF there.
    env: Vec<Option<(Vec3, f32)>>,
    env_wo: Rows<3>,
    env_pdf: Vec<f32>,
    env_f: Rows<3>,
}

impl<L: LaneState> Batch<L> {
    fn new(cap: usize) -> Self {
        Batch {
            slots: Vec::with_capacity(cap),
            frames: Vec::with_capacity(cap),
            uv: Rows::new(cap),
            wi: Rows::new(cap),
            phi: Rows::new(cap),
            lanes: vec![L::default(); cap],
            u: Rows::new(cap),
            wo: Rows::new(cap),
            pdf: vec![0.0; cap],
            mis_pdf: vec![0.0; cap],
            f: Rows::new(cap),
            env: vec![None; cap],
            env_wo: Rows::new(cap),
            env_pdf: vec![0.0; cap],
            env_f: Rows::new(cap),
        }
    }

    /// Gathers the shading points on surface `surface_index`: the slots whose vertex lies
    /// on it with `wi` above it, with their frames, texture coordinates, `wi` and BSDF
    /// random numbers. Returns how many.
    fn gather(
        &mut self,
        surface_index: usize,
        hits: &[Option<Hit>],
        rays: &[Ray],
        randoms: &[VertexRandoms],
    ) -> usize {
        self.slots.clear();
        self.frames.clear();
        for (slot, hit) in hits.iter().enumerate() {
            let Some(hit) = hit else { continue };
            if hit.surface != surface_index {
                continue;
            }
            let frame = Frame::from_normal_tangent(hit.n, hit.tangent);
            let wi = frame.to_local(-rays[slot].d);
            if !(wi.z > 0.0) {
                continue;
            }
            let i = self.slots.len();
            self.slots.push(slot);
            self.frames.push(frame);
            self.uv.set(i, hit.uv.to_array());
            self.wi.set(i, wi.to_array());
            self.u.set(i, randoms[slot].bsdf.to_array());
        }
        self.slots.len()
    }
}

/// The per-tile state of the integrator.
struct Tile<'r, 'a, M: ?Sized, S: BatchSampler> {
    scene: &'r Scene,
    surfaces: &'r [Surface<'a, M, S>],
    opts: &'r RenderOptions,
    /// Per slot: the ray that reached the current vertex, the vertex, its random numbers.
    rays: Vec<Ray>,
    hits: Vec<Option<Hit>>,
    randoms: Vec<VertexRandoms>,
    /// Per depth and slot.
    terms: Vec<Vec<VertexTerms>>,
    /// Per slot: where a continuing path goes next (filled while a depth is shaded, taken
    /// when it ends, so `None` between depths).
    next: Vec<Option<(Ray, Hit)>>,
    batch: Batch<S::Lane>,
    /// The sampler's working memory, kept across its calls.
    scratch: Box<S::Scratch>,
}

impl<M: Material + ?Sized, S: BatchSampler> Tile<'_, '_, M, S> {
    /// Shades every slot with a vertex at `depth`, one batch per surface, and moves each
    /// continuing path to its next vertex.
    fn shade_depth(&mut self, depth: u32, streams: &mut [StreamRng]) {
        let Tile {
            scene,
            surfaces,
            opts,
            rays,
            hits,
            randoms,
            terms,
            next,
            batch: b,
            scratch,
            ..
        } = self;
        let mis = opts.estimator == Estimator::Mis;
        let terms = &mut terms[depth as usize - 1];
        // Every vertex draws its random numbers first (the recipe's step 2).
        for (slot, hit) in hits.iter().enumerate() {
            terms[slot] = VertexTerms::default();
            if hit.is_some() {
                randoms[slot] = VertexRandoms::draw(&mut streams[slot], mis);
            }
        }
        for (surface_index, surface) in surfaces.iter().enumerate() {
            let n = b.gather(surface_index, hits, rays, randoms);
            if n == 0 {
                continue;
            }
            // The batched calls. Every buffer is sliced to `n`, so the lengths agree and
            // the calls cannot fail.
            let lanes = &mut b.lanes[..n];
            surface
                .material
                .features_batch(b.uv.view(n), b.phi.features_mut(n));
            let _ = surface
                .sampler
                .prepare_batch(b.phi.features(n), b.wi.view(n), lanes);
            let _ = surface.sampler.sample_batch_in(
                lanes,
                b.u.view(n),
                SamplesMut {
                    wo: b.wo.view_mut(n),
                    pdf: &mut b.pdf[..n],
                    mis_pdf: &mut b.mis_pdf[..n],
                },
                scratch,
            );
            surface.material.eval_batch(
                b.phi.features(n),
                b.wi.view(n),
                b.wo.view(n),
                b.f.rgb_mut(n),
            );
            if mis {
                for i in 0..n {
                    let r = &randoms[b.slots[i]];
                    let s = scene.env.sample(r.env_pick, r.env);
                    b.env[i] = s;
                    let wo = s.map_or(Vec3::ZERO, |(dir, _)| b.frames[i].to_local(dir));
                    b.env_wo.set(i, wo.to_array());
                }
                let _ = surface.sampler.pdf_batch_in(
                    lanes,
                    b.env_wo.view(n),
                    &mut b.env_pdf[..n],
                    scratch,
                );
                surface.material.eval_batch(
                    b.phi.features(n),
                    b.wi.view(n),
                    b.env_wo.view(n),
                    b.env_f.rgb_mut(n),
                );
            }
            // Per lane: shadow rays, the environment, the next vertex.
            for i in 0..n {
                let slot = b.slots[i];
                let Some(hit) = &hits[slot] else { continue };
                if !b.lanes[i].is_prepared() {
                    continue;
                }
                let origin = hit.p + hit.n * RAY_EPSILON;
                let t = &mut terms[slot];
                t.present = true;
                let (bsdf, cont) = bsdf_term(scene, opts, b, i, origin, depth);
                t.bsdf = bsdf;
                if let Some(c) = cont {
                    t.continues = true;
                    next[slot] = Some(c);
                }
                if mis {
                    t.env = env_term(scene, b, i, origin);
                }
            }
        }
        // The paths that continue move to their next vertex; the others end here.
        for slot in 0..hits.len() {
            match next[slot].take() {
                Some((ray, hit)) => {
                    rays[slot] = ray;
                    hits[slot] = Some(hit);
                }
                None => hits[slot] = None,
            }
        }
    }

    /// Renders pixels `start .. start + len` (row-major).
    fn run(&mut self, start: usize, len: usize) -> Span {
        let cam = &self.scene.camera;
        let w = cam.width;
        let opts = self.opts;
        let depths = opts.max_bounces.max(1);
        let mut out = Span::new(start, len, opts);
        let mut streams = out.streams(opts.seed);
        let mut values = vec![[0.0f32; 3]; len];
        let mut primary = vec![false; len];
        for s in 1..=opts.spp {
            // Primary rays.
            for slot in 0..len {
                let p = start + slot;
                let (jx, jy) = jitter(&mut streams[slot], opts.jitter);
                let ray = cam.ray((p % w) as f32 + jx, (p / w) as f32 + jy);
                let hit = self.scene.intersect(&ray);
                primary[slot] = hit.is_some();
                values[slot] = if hit.is_some() {
                    if s == 1 {
                        out.mask[slot] = true;
                    }
                    [0.0; 3]
                } else {
                    self.scene.env.radiance(ray.d)
                };
                self.rays[slot] = ray;
                self.hits[slot] = hit;
            }
            // Vertices, depth by depth, until no path continues.
            let mut deepest = 0;
            for depth in 1..=depths {
                if self.hits.iter().all(Option::is_none) {
                    break;
                }
                self.shade_depth(depth, &mut streams);
                deepest = depth as usize;
            }
            // Fold each path's vertices from the deepest back.
            for slot in 0..len {
                if primary[slot] {
                    let mut l = [0.0f32; 3];
                    for d in (0..deepest).rev() {
                        l = self.terms[d][slot].radiance(l);
                    }
                    values[slot] = l;
                }
                out.add(slot, s, values[slot], opts);
            }
        }
        out.finish(opts);
        out
    }
}

/// The BSDF sample's term of lane `i` of `b`, and the ray and vertex that continue the path
/// when the sample hits a surface with bounces left (the scalar integrator's `shade`).
fn bsdf_term<L>(
    scene: &Scene,
    opts: &RenderOptions,
    b: &Batch<L>,
    i: usize,
    origin: Vec3,
    depth: u32,
) -> (Term, Option<(Ray, Hit)>) {
    let pdf = b.pdf[i];
    if !(pdf > 0.0) {
        return (Term::default(), None);
    }
    let wo = b.wo.vec3(i);
    let f = b.f.at(i);
    let wo_w = b.frames[i].from_local(wo).normalize();
    let escaped = if depth < opts.max_bounces {
        let ray = Ray { o: origin, d: wo_w };
        match scene.intersect(&ray) {
            None => true,
            Some(next) => {
                let t = Term {
                    f,
                    l: [0.0; 3],
                    k: wo.z / pdf,
                    on: false,
                };
                return (t, Some((ray, next)));
            }
        }
    } else {
        !scene.occluded(origin, wo_w)
    };
    if !escaped {
        return (Term::default(), None);
    }
    let env = &scene.env;
    let w = if opts.estimator == Estimator::Mis {
        power_heuristic(b.mis_pdf[i], env.pdf(wo_w))
    } else {
        1.0
    };
    let t = Term {
        f,
        l: env.radiance(wo_w),
        k: wo.z * w / pdf,
        on: true,
    };
    (t, None)
}

/// The environment sample's term of lane `i` of `b` (MIS).
fn env_term<L>(scene: &Scene, b: &Batch<L>, i: usize, origin: Vec3) -> Term {
    let Some((dir, pe)) = b.env[i] else {
        return Term::default();
    };
    let wo = b.env_wo.vec3(i);
    if !(wo.z > 0.0) || scene.occluded(origin, dir) {
        return Term::default();
    }
    let w = power_heuristic(pe, b.env_pdf[i]);
    Term {
        f: b.env_f.at(i),
        l: scene.env.radiance(dir),
        k: wo.z * w / pe,
        on: true,
    }
}

/// Renders `scene` with `surfaces` (indexed by [`crate::Object::surface`]) on the current
/// rayon pool through the batched API: tiles of [`RenderOptions::wavefront_pixels`]
/// consecutive pixels render in parallel, and each step of a tile shades one sample of each
/// of its pixels as one batch per surface and depth. The image equals
/// [`crate::render()`]'s bit for bit (same streams, same operations per lane); it is
/// bit-identical for any number of threads. [`RenderOptions::reuse_prepared`] is ignored
/// (every vertex is prepared): render a sampler whose `prepare` is a table build with the
/// scalar integrator.
pub fn render_wavefront<M: Material + Sync + ?Sized, S: BatchSampler + Sync>(
    scene: &Scene,
    surfaces: &[Surface<'_, M, S>],
    opts: &RenderOptions,
) -> Render
where
    S::Lane: Send,
{
    let t0 = Instant::now();
    let opts = opts.normalised();
    let (w, h) = (scene.camera.width, scene.camera.height);
    let pixels = w * h;
    let tile = opts.wavefront_pixels;
    let spans: Vec<Span> = (0..pixels.div_ceil(tile))
        .into_par_iter()
        .map(|k| {
            let start = k * tile;
            let len = tile.min(pixels - start);
            let mut t = Tile {
                scene,
                surfaces,
                opts: &opts,
                rays: vec![
                    Ray {
                        o: Vec3::ZERO,
                        d: Vec3::Z
                    };
                    len
                ],
                hits: vec![None; len],
                randoms: vec![
                    VertexRandoms {
                        bsdf: Vec2::ZERO,
                        env_pick: 0.0,
                        env: Vec2::ZERO,
                    };
                    len
                ],
                terms: vec![vec![VertexTerms::default(); len]; opts.max_bounces.max(1) as usize],
                next: vec![None; len],
                batch: Batch::new(len),
                scratch: Box::new(Scratch::NEW),
            };
            t.run(start, len)
        })
        .collect();
    assemble(w, h, &opts, spans, t0)
}
