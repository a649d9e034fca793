//! What both integrators share: the estimator, the options, the result, the random numbers a
//! path vertex draws, the MIS weight, per-pixel accumulation and the assembly of the image.
//!
//! The scalar integrator ([`crate::render()`], one shading point at a time) and the wavefront
//! integrator ([`crate::render_wavefront()`], a wavefront of shading points per call) follow
//! the same per-pixel recipe, so that they give the same image bit for bit:
//!
//! 1. pixel `i` draws from its own stream ([`indexed_rng`] of the seed and `i`), samples in
//!    order `1..=spp`;
//! 2. a sample draws the pixel jitter (with [`RenderOptions::jitter`]), then every surface
//!    interaction of its path, in path order, draws its [`VertexRandoms`] (the BSDF sample's
//!    `u`, and with MIS the environment sample's `pick` and `u`) **before** anything else is
//!    decided there — so a stream's position never depends on a sampler's answer;
//! 3. a vertex's radiance is `0 + bsdf term + environment term` in that order, non-finite
//!    values set to 0, and the pixel sums are kept in f64 in sample order.

use std::time::Instant;

use glam::Vec2;
use rand::RngExt;

use crate::image::Image;
use crate::rng::{indexed_rng, StreamRng};

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

/// Default number of pixels per wavefront ([`RenderOptions::wavefront_pixels`]).
pub const WAVEFRONT_PIXELS: usize = 256;

/// Options of [`crate::render()`] and [`crate::render_wavefront()`].
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Samples per pixel.
    pub spp: u32,
    /// Sample counts at which the running mean image is kept, e.g. 1, 2, 4, … (sorted and
    /// limited to `1..=spp` by the integrators).
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
    /// same point is shaded). Meant for samplers whose `prepare` is expensive (a tabulated
    /// oracle); the time spent in `prepare` is then reported separately
    /// ([`Render::prepare_seconds`]).
    pub reuse_prepared: bool,
    /// Path length in surface interactions: 1 = direct lighting only (the paper's main
    /// mode); `k > 1` = global illumination: a BSDF sample that hits another surface
    /// continues the path there (the sampler is prepared at every vertex, the throughput is
    /// `f · cos θo / pdf`), up to `k` interactions. Unbiased for the light carried by paths of
    /// at most `k` interactions; no Russian roulette.
    pub max_bounces: u32,
    /// Pixels per wavefront of [`crate::render_wavefront()`] (consecutive pixels in row-major
    /// order, one sample each per step); ignored by the scalar integrator.
    pub wavefront_pixels: usize,
    /// Independent blocks of consecutive samples whose mean images are kept
    /// ([`Render::blocks`]; at most `spp`); 0 keeps none. Every pixel's samples are
    /// independent, so block images are independent renders of `spp / blocks` samples: the
    /// evaluation's intervals resample them.
    pub blocks: u32,
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
            wavefront_pixels: WAVEFRONT_PIXELS,
            blocks: 0,
        }
    }

    /// A copy with `spp ≥ 1` and the checkpoints sorted, deduplicated and within `1..=spp`.
    pub(crate) fn normalised(&self) -> RenderOptions {
        let mut o = self.clone();
        o.spp = o.spp.max(1);
        let spp = o.spp;
        o.checkpoints.retain(|&s| s >= 1 && s <= spp);
        o.checkpoints.sort_unstable();
        o.checkpoints.dedup();
        o.wavefront_pixels = o.wavefront_pixels.max(1);
        o.blocks = o.blocks.min(spp);
        o
    }

    /// Whether `prepare` is kept per pixel ([`RenderOptions::reuse_prepared`] without jitter).
    pub(crate) fn reuses_prepared(&self) -> bool {
        self.reuse_prepared && !self.jitter
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

/// The result of a render.
#[derive(Clone, Debug)]
pub struct Render {
    /// Mean of all samples.
    pub image: Image,
    /// Per pixel and channel, the unbiased sample variance of one pixel sample (0 for one
    /// sample); the variance of the pixel mean is this divided by `spp`.
    pub variance: Image,
    /// The running mean at each checkpoint, ascending.
    pub checkpoints: Vec<(u32, Image)>,
    /// With [`RenderOptions::blocks`] = B: the mean image of each block of samples, block k
    /// holding the samples `s` (1-based) with `⌊(s − 1) · B / spp⌋ = k` of every pixel.
    pub blocks: Vec<Image>,
    /// Whether the pixel's primary ray hits an object (from its first sample).
    pub mask: Vec<bool>,
    /// Samples per pixel.
    pub spp: u32,
    /// Wall time of the render.
    pub seconds: f64,
    /// Time spent in `prepare` when it was reused per pixel (summed over threads), else 0.
    pub prepare_seconds: f64,
}

impl Render {
    /// Samples per pixel of each of [`Render::blocks`].
    #[must_use]
    pub fn block_samples(&self) -> Vec<u32> {
        block_counts(self.spp, self.blocks.len() as u32)
    }
}

/// Samples in each of `blocks` blocks of `spp` samples ([`block_of`]).
fn block_counts(spp: u32, blocks: u32) -> Vec<u32> {
    let mut counts = vec![0u32; blocks as usize];
    if blocks > 0 {
        for s in 1..=spp {
            counts[block_of(s, spp, blocks)] += 1;
        }
    }
    counts
}

/// The power heuristic's weight of a technique with density `a` against one with `b`.
#[inline]
pub(crate) fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 && (a2 + b2).is_finite() {
        a2 / (a2 + b2)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// The random numbers one surface interaction draws, all at once (module docs, step 2).
#[derive(Copy, Clone, Debug)]
pub(crate) struct VertexRandoms {
    /// The BSDF sample's `u`.
    pub(crate) bsdf: Vec2,
    /// With MIS: which part of the environment to sample.
    pub(crate) env_pick: f32,
    /// With MIS: the environment sample's `u`.
    pub(crate) env: Vec2,
}

impl VertexRandoms {
    pub(crate) fn draw(rng: &mut StreamRng, mis: bool) -> VertexRandoms {
        let bsdf = Vec2::new(rng.random::<f32>(), rng.random::<f32>());
        let (env_pick, env) = if mis {
            let pick = rng.random::<f32>();
            (pick, Vec2::new(rng.random::<f32>(), rng.random::<f32>()))
        } else {
            (0.0, Vec2::ZERO)
        };
        VertexRandoms {
            bsdf,
            env_pick,
            env,
        }
    }
}

/// The pixel jitter of one sample (`(0.5, 0.5)` without jitter: nothing is drawn).
pub(crate) fn jitter(rng: &mut StreamRng, on: bool) -> (f32, f32) {
    if on {
        (rng.random::<f32>(), rng.random::<f32>())
    } else {
        (0.5, 0.5)
    }
}

/// `out += f · l · k` per channel, in the scalar integrator's operation order.
#[inline]
pub(crate) fn add_term(out: &mut [f32; 3], f: [f32; 3], l: [f32; 3], k: f32) {
    for c in 0..3 {
        out[c] += f[c] * l[c] * k;
    }
}

/// Sets the non-finite channels of a vertex's radiance to 0.
#[inline]
pub(crate) fn finite_or_zero(mut v: [f32; 3]) -> [f32; 3] {
    for x in &mut v {
        if !x.is_finite() {
            *x = 0.0;
        }
    }
    v
}

/// The results of a run of consecutive pixels (a row, a wavefront tile).
pub(crate) struct Span {
    /// Index of the first pixel (row-major).
    pub(crate) start: usize,
    pub(crate) mean: Vec<[f32; 3]>,
    pub(crate) var: Vec<[f32; 3]>,
    pub(crate) checkpoints: Vec<Vec<[f32; 3]>>,
    pub(crate) mask: Vec<bool>,
    pub(crate) prepare_seconds: f64,
    /// Per block, the block mean of each pixel (filled by [`Span::finish`]).
    pub(crate) blocks: Vec<Vec<[f32; 3]>>,
    sums: Vec<([f64; 3], [f64; 3], usize)>,
    /// Per block and pixel, the sum of the block's samples.
    block_sums: Vec<Vec<[f64; 3]>>,
}

impl Span {
    pub(crate) fn new(start: usize, len: usize, opts: &RenderOptions) -> Span {
        let blocks = opts.blocks as usize;
        Span {
            start,
            mean: vec![[0.0; 3]; len],
            var: vec![[0.0; 3]; len],
            checkpoints: vec![vec![[0.0; 3]; len]; opts.checkpoints.len()],
            mask: vec![false; len],
            prepare_seconds: 0.0,
            blocks: vec![vec![[0.0; 3]; len]; blocks],
            sums: vec![([0.0; 3], [0.0; 3], 0); len],
            block_sums: vec![vec![[0.0; 3]; len]; blocks],
        }
    }

    /// The streams of the span's pixels.
    pub(crate) fn streams(&self, seed: u64) -> Vec<StreamRng> {
        (0..self.mean.len())
            .map(|p| indexed_rng(seed, self.start + p))
            .collect()
    }

    /// Adds sample `s` (1-based, of `opts.spp`) of pixel `p` of the span.
    pub(crate) fn add(&mut self, p: usize, s: u32, v: [f32; 3], opts: &RenderOptions) {
        let checkpoints = &opts.checkpoints;
        let (sum, sq, next_cp) = &mut self.sums[p];
        for c in 0..3 {
            let vc = f64::from(v[c]);
            sum[c] += vc;
            sq[c] += vc * vc;
        }
        if !self.block_sums.is_empty() {
            let k = block_of(s, opts.spp, opts.blocks);
            for c in 0..3 {
                self.block_sums[k][p][c] += f64::from(v[c]);
            }
        }
        while *next_cp < checkpoints.len() && checkpoints[*next_cp] <= s {
            if checkpoints[*next_cp] == s {
                for c in 0..3 {
                    self.checkpoints[*next_cp][p][c] = (sum[c] / f64::from(s)) as f32;
                }
            }
            *next_cp += 1;
        }
    }

    /// Writes every pixel's mean and sample variance after `opts.spp` samples, and the
    /// block means.
    pub(crate) fn finish(&mut self, opts: &RenderOptions) {
        let spp = opts.spp;
        let counts = block_counts(spp, self.blocks.len() as u32);
        for ((means, sums), &count) in self.blocks.iter_mut().zip(&self.block_sums).zip(&counts) {
            let count = f64::from(count.max(1));
            for (m, s) in means.iter_mut().zip(sums) {
                *m = s.map(|x| (x / count) as f32);
            }
        }
        let n = f64::from(spp);
        for (p, (sum, sq, _)) in self.sums.iter().enumerate() {
            for c in 0..3 {
                let mean = sum[c] / n;
                self.mean[p][c] = mean as f32;
                self.var[p][c] = if spp > 1 {
                    ((sq[c] - n * mean * mean) / (n - 1.0)).max(0.0) as f32
                } else {
                    0.0
                };
            }
        }
    }
}

/// The block of sample `s` (1-based) of `spp` samples in `blocks ≥ 1` blocks:
/// `⌊(s − 1) · blocks / spp⌋`.
#[inline]
fn block_of(s: u32, spp: u32, blocks: u32) -> usize {
    (u64::from(s - 1) * u64::from(blocks) / u64::from(spp)) as usize
}

/// The image of a render from its spans (`seconds` measured from `t0`).
pub(crate) fn assemble(
    width: usize,
    height: usize,
    opts: &RenderOptions,
    spans: Vec<Span>,
    t0: Instant,
) -> Render {
    let seconds = t0.elapsed().as_secs_f64();
    let mut image = Image::new(width, height);
    let mut variance = Image::new(width, height);
    let mut mask = vec![false; width * height];
    let mut cps: Vec<(u32, Image)> = opts
        .checkpoints
        .iter()
        .map(|&s| (s, Image::new(width, height)))
        .collect();
    let mut blocks = vec![Image::new(width, height); opts.blocks as usize];
    let mut prepare_seconds = 0.0;
    for r in spans {
        let range = r.start..r.start + r.mean.len();
        image.data[range.clone()].copy_from_slice(&r.mean);
        variance.data[range.clone()].copy_from_slice(&r.var);
        mask[range.clone()].copy_from_slice(&r.mask);
        for (k, cp) in r.checkpoints.iter().enumerate() {
            cps[k].1.data[range.clone()].copy_from_slice(cp);
        }
        for (img, b) in blocks.iter_mut().zip(&r.blocks) {
            img.data[range.clone()].copy_from_slice(b);
        }
        prepare_seconds += r.prepare_seconds;
    }
    Render {
        image,
        variance,
        checkpoints: cps,
        blocks,
        mask,
        spp: opts.spp,
        seconds,
        prepare_seconds,
    }
}
