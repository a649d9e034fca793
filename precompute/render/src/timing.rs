//! Single-thread timing by repeated passes: every measurement is the median of its passes
//! (other processes on the machine only ever add time, and the median ignores a few slow
//! passes), in nanoseconds per call or per pixel sample.

use std::time::Instant;

use neusample::wavefront::BatchSampler;
use neusample::Sampler;

use crate::error::Error;
use crate::integrator::{Render, RenderOptions};
use crate::material::{Material, Surface};
use crate::scalar::render;
use crate::scene::Scene;
use crate::wavefront::render_wavefront;

/// The median of timing samples (the upper one of an even count). `v` must not be empty.
#[must_use]
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Wall time of `f` divided by `calls`, in nanoseconds (the cost of one call of a loop of
/// `calls` iterations; `calls` is taken as at least 1).
pub fn ns_per_call(calls: usize, f: impl FnOnce()) -> f64 {
    let t0 = Instant::now();
    f();
    t0.elapsed().as_nanos() as f64 / calls.max(1) as f64
}

/// Runs `pass` `passes` times (at least once); each pass returns `K` measurements, and the
/// result is the median of each over the passes.
pub fn median_of_passes<const K: usize>(
    passes: usize,
    mut pass: impl FnMut() -> [f64; K],
) -> [f64; K] {
    let mut times: [Vec<f64>; K] = std::array::from_fn(|_| Vec::with_capacity(passes.max(1)));
    for _ in 0..passes.max(1) {
        for (t, v) in times.iter_mut().zip(pass()) {
            t.push(v);
        }
    }
    times.map(median)
}

/// Renders on a private single-thread pool with the scalar integrator ([`crate::render()`])
/// and returns the render loop's wall time per pixel sample in nanoseconds (all pixels,
/// background included), **excluding** the time of reused `prepare` calls
/// ([`RenderOptions::reuse_prepared`]): the "time per sample" of equal-time comparisons. The
/// median over `passes` renders.
pub fn time_per_sample<M: Material + Sync + ?Sized, S: Sampler + Sync>(
    scene: &Scene,
    surfaces: &[Surface<'_, M, S>],
    opts: &RenderOptions,
    passes: usize,
) -> Result<f64, Error> {
    timed(scene, opts, passes, |o| render(scene, surfaces, o))
}

/// [`time_per_sample`] with the wavefront integrator ([`crate::render_wavefront()`]).
pub fn time_per_sample_wavefront<M: Material + Sync + ?Sized, S: BatchSampler + Sync>(
    scene: &Scene,
    surfaces: &[Surface<'_, M, S>],
    opts: &RenderOptions,
    passes: usize,
) -> Result<f64, Error>
where
    S::Lane: Send,
{
    timed(scene, opts, passes, |o| {
        render_wavefront(scene, surfaces, o)
    })
}

/// The median over `passes` single-thread runs of `render` (checkpoints off) of its time per
/// pixel sample, reused `prepare` time excluded.
fn timed(
    scene: &Scene,
    opts: &RenderOptions,
    passes: usize,
    render: impl Fn(&RenderOptions) -> Render + Sync,
) -> Result<f64, Error> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut o = opts.clone();
    o.checkpoints.clear();
    let samples = (scene.camera.width * scene.camera.height) as f64 * f64::from(o.spp.max(1));
    let [ns] = median_of_passes(passes, || {
        let r = pool.install(|| render(&o));
        [(r.seconds - r.prepare_seconds).max(0.0) * 1e9 / samples]
    });
    Ok(ns)
}
