//! Rendering metrics of the evaluation (paper §4, Table 2 and Fig. 8): MSE against a
//! high-sample reference at equal samples per pixel and at equal time, convergence curves,
//! and the speed-up relative to the improved baseline.
//!
//! # Definitions
//!
//! * **MSE** — mean over the pixels whose primary ray hits an object and over the three
//!   channels of `(L − L_ref)²`, linear radiance. The reference is an independent render with
//!   variance `σ²_ref/N_ref` per pixel, which adds its mean to every measured MSE; it is
//!   subtracted ([`Reference::noise`]), so the reported MSE estimates the error against the
//!   true image.
//! * **Renders** — every runtime sampler renders with the wavefront integrator
//!   ([`render::render_wavefront`]: tiles of pixels, one batch per surface and path depth
//!   through the batched API, as the paper ran its samplers), a measured material's own
//!   sampler too (through its batched calls, [`MeasuredDataSampler`]); the oracle, whose
//!   `prepare` is a table build, with the scalar integrator. Both give the same image for
//!   the same sampler.
//! * **Time per sample** ([`TechniqueEval::ns_per_sample`]) — the single-thread wall time of
//!   the whole render loop (primary ray, features, `prepare`, `sample`, material evaluation,
//!   shadow ray, environment lookup, and with MIS the environment sample and `pdf`) divided by
//!   the number of pixel samples of the image (background pixels included), the median of a
//!   few passes interleaved over the techniques ([`render::time_per_sample_wavefront`];
//!   other processes on the machine only ever add time). The oracle is timed in one pass on a
//!   quarter-resolution view at 16× the spp (the same number of samples). For the oracle, the
//!   per-pixel table build is **excluded** (the table is built once per pixel and its time subtracted): the oracle is
//!   a limit of sampling quality, not a practical method.
//! * **Speed-up vs the improved baseline** (paper Table 2: the relative time the baseline
//!   needs to reach the same quality) — with MSE ∝ 1/spp for unbiased estimators, the
//!   baseline reaches the method's MSE `e_m` after `t_b · N · e_b(N)/e_m(N)`, so
//!
//!   ```text
//!   speed-up = (e_b(N) · t_b) / (e_m(N) · t_m)        (N = the equal-spp sample count)
//!   ```
//!
//!   the ratio of inverse efficiencies `1/(MSE · time)`, evaluated at the largest equal-spp
//!   count. The MSEs used are the *expected* MSEs `mean σ²/N` from the per-pixel sample
//!   variances of the equal-spp renders (unbiased estimators: MSE = variance), which are far
//!   less noisy than one image's squared error; the speed-up from the measured MSEs is
//!   reported beside it ([`speedup_measured`]) and agrees within its noise.
//! * **Equal time** — every technique gets the time the baseline needs for `N` spp:
//!   `spp_m = round(N · t_b / t_m)` (at least 1) and is rendered with a fresh seed.

use neusample::wavefront::BatchSampler;
use neusample::{BlobSampler, MeasuredMaterial, Sampler};
use neusample_render::{self as render, Estimator, Image, Render, RenderOptions, Scene, Surface};
use serde::{Deserialize, Serialize};

use super::measured_data::MeasuredDataSampler;
use super::oracle::OracleSampler;
use crate::materials::Material;
use crate::util::json::f64_or_nan;
use crate::util::rng::Stream;
use crate::util::stats::{bootstrap, median_of_means, ratio, Estimate};
use crate::util::timing::median;
use neusample::wavefront::SamplerVisitor;

/// A sampling technique of the evaluation.
#[derive(Clone, Copy, Debug)]
pub enum Technique<'a> {
    /// A runtime sampler (any blob, or cosine).
    Blob(BlobSampler<'a>),
    /// The tabulated oracle (prepared once per pixel, table time excluded).
    Oracle(OracleSampler<'a>),
    /// A measured material's own sampler (VNDF and luminance warps), through its batched
    /// path ([`MeasuredDataSampler`]).
    Measured(MeasuredMaterial<&'a Vec<f32>>),
}

impl Technique<'_> {
    fn options(&self, base: &RenderOptions) -> RenderOptions {
        let mut o = base.clone();
        o.reuse_prepared = matches!(self, Technique::Oracle(_)) && !o.jitter;
        o
    }

    /// Renders `scene` with this technique on every object: a runtime sampler with the
    /// wavefront integrator (its concrete type's batched path), the oracle with the scalar
    /// one (its `prepare` is a table build, done once per pixel).
    #[must_use]
    pub fn render(&self, scene: &Scene, material: &dyn Material, opts: &RenderOptions) -> Render {
        let o = self.options(opts);
        match self {
            Technique::Blob(s) => s.visit(Wavefront {
                scene,
                material,
                opts: &o,
            }),
            Technique::Oracle(s) => render::render(scene, &[Surface::new(material, *s)], &o),
            Technique::Measured(s) => render::render_wavefront(
                scene,
                &[Surface::new(material, MeasuredDataSampler(*s))],
                &o,
            ),
        }
    }

    /// Single-thread ns per pixel sample ([`render::time_per_sample_wavefront`] for a
    /// runtime sampler, [`render::time_per_sample`] for the oracle).
    pub fn time_per_sample(
        &self,
        scene: &Scene,
        material: &dyn Material,
        opts: &RenderOptions,
        passes: usize,
    ) -> anyhow::Result<f64> {
        let o = self.options(opts);
        Ok(match self {
            Technique::Blob(s) => s.visit(WavefrontTime {
                scene,
                material,
                opts: &o,
                passes,
            })?,
            Technique::Oracle(s) => {
                render::time_per_sample(scene, &[Surface::new(material, *s)], &o, passes)?
            }
            Technique::Measured(s) => render::time_per_sample_wavefront(
                scene,
                &[Surface::new(material, MeasuredDataSampler(*s))],
                &o,
                passes,
            )?,
        })
    }
}

/// A wavefront render of one concrete sampler.
struct Wavefront<'r> {
    scene: &'r Scene,
    material: &'r dyn Material,
    opts: &'r RenderOptions,
}

impl SamplerVisitor for Wavefront<'_> {
    type Output = Render;
    fn visit<S: Sampler + BatchSampler + Copy + Sync>(self, s: S) -> Render
    where
        S::Lane: Send,
    {
        render::render_wavefront(self.scene, &[Surface::new(self.material, s)], self.opts)
    }
}

/// The wavefront render's time per sample with one concrete sampler.
struct WavefrontTime<'r> {
    scene: &'r Scene,
    material: &'r dyn Material,
    opts: &'r RenderOptions,
    passes: usize,
}

impl SamplerVisitor for WavefrontTime<'_> {
    type Output = Result<f64, render::Error>;
    fn visit<S: Sampler + BatchSampler + Copy + Sync>(self, s: S) -> Self::Output
    where
        S::Lane: Send,
    {
        let surfaces = [Surface::new(self.material, s)];
        render::time_per_sample_wavefront(self.scene, &surfaces, self.opts, self.passes)
    }
}

/// Sizes and seeds of the rendering evaluation.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RenderSettings {
    /// Largest equal-spp sample count N (convergence checkpoints at powers of two up to it).
    pub max_spp: u32,
    /// Samples per pixel of the reference.
    pub ref_spp: u32,
    /// Table resolution of the reference's oracle.
    pub ref_res: usize,
    /// Table resolution of the oracle technique.
    pub oracle_res: usize,
    /// Samples per pixel of each timing pass.
    pub timing_spp: u32,
    /// Timing passes (interleaved over the techniques; the median is the time per sample and
    /// the intervals resample them).
    pub timing_passes: usize,
    /// Cap on the samples per pixel of an equal-time render.
    pub max_equal_time_spp: u32,
    /// Estimator of the compared renders (the reference always uses MIS).
    pub estimator: Estimator,
    /// Seed.
    pub seed: u64,
    /// Independent sample blocks of every equal-spp and equal-time render (at most its spp),
    /// the units the intervals resample ([`block_variances`]).
    #[serde(default = "default_blocks")]
    pub blocks: u32,
}

/// Sample blocks per render of the evaluation ([`RenderSettings::blocks`]).
pub const DEFAULT_BLOCKS: u32 = 16;

fn default_blocks() -> u32 {
    DEFAULT_BLOCKS
}

/// Groups of the median of means over a render's blocks ([`variance`]).
pub const MOM_GROUPS: usize = 4;

/// The reference image of a material's scene.
#[derive(Clone, Debug)]
pub struct Reference {
    /// The render (oracle at [`RenderSettings::ref_res`], MIS, [`RenderSettings::ref_spp`]).
    pub render: Render,
    /// Its own expected contribution to a measured MSE: the mean over masked pixels and
    /// channels of `σ²/N_ref`.
    pub noise: f64,
}

/// Renders the reference: the oracle with MIS at many samples per pixel, seeded
/// independently of the compared renders.
#[must_use]
pub fn reference(scene: &Scene, material: &dyn Material, s: &RenderSettings) -> Reference {
    let mut opts = RenderOptions::new(s.ref_spp.max(2), Stream::Reference.of(s.seed));
    opts.checkpoints.clear();
    opts.estimator = Estimator::Mis;
    let t = Technique::Oracle(OracleSampler::new(material, s.ref_res));
    let render = t.render(scene, material, &opts);
    let noise = mean_variance_of_mean(&render, &render.mask);
    Reference { render, noise }
}

/// Mean over masked pixels and channels of `variance / spp` (the expected squared error of
/// the pixel means of an unbiased render).
#[must_use]
pub fn mean_variance_of_mean(r: &Render, mask: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for (i, v) in r.variance.data.iter().enumerate() {
        if mask.get(i).copied().unwrap_or(false) {
            for c in v {
                s += f64::from(*c);
            }
            n += 3;
        }
    }
    if n > 0 {
        s / n as f64 / f64::from(r.spp.max(1))
    } else {
        0.0
    }
}

/// Mean over masked pixels and channels of `(a − b)²`.
#[must_use]
pub fn mse(a: &Image, b: &Image, mask: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for (i, (x, y)) in a.data.iter().zip(&b.data).enumerate() {
        if mask.get(i).copied().unwrap_or(false) {
            for c in 0..3 {
                let d = f64::from(x[c]) - f64::from(y[c]);
                s += d * d;
            }
            n += 3;
        }
    }
    if n > 0 {
        s / n as f64
    } else {
        0.0
    }
}

/// Smallest MSE reported after subtracting the reference noise (keeps logs finite).
pub const MSE_FLOOR: f64 = 1e-12;

/// The pixel-averaged radiance of a render over `mask`, with its standard error from the
/// per-pixel sample variances: `(mean, standard error)` per channel.
#[must_use]
pub fn pixel_average(r: &Render, mask: &[bool]) -> ([f64; 3], [f64; 3]) {
    let (mut m, mut v, mut n) = ([0.0f64; 3], [0.0f64; 3], 0usize);
    for (i, (c, var)) in r.image.data.iter().zip(&r.variance.data).enumerate() {
        if mask.get(i).copied().unwrap_or(false) {
            for k in 0..3 {
                m[k] += f64::from(c[k]);
                v[k] += f64::from(var[k]) / f64::from(r.spp.max(1));
            }
            n += 1;
        }
    }
    let n = n.max(1) as f64;
    let mut se = [0.0; 3];
    for k in 0..3 {
        m[k] /= n;
        se[k] = v[k].sqrt() / n;
    }
    (m, se)
}

/// Per block `k` of `r` (`n_k` samples per pixel, [`Render::block_samples`]):
/// `(MSE(block_k, reference) − reference noise) · n_k`. For an unbiased technique each is an
/// unbiased estimate of the per-sample variance `V` (mean over masked pixels and channels),
/// and the blocks are independent: every pixel's samples are.
#[must_use]
pub fn block_variances(r: &Render, reference: &Reference) -> Vec<f64> {
    let mask = &reference.render.mask;
    r.blocks
        .iter()
        .zip(r.block_samples())
        .map(|(img, n)| {
            (mse(img, &reference.render.image, mask) - reference.noise) * f64::from(n.max(1))
        })
        .collect()
}

/// The per-sample variance `V` from a render's [`block_variances`]: the median of means over
/// [`MOM_GROUPS`] groups of blocks (robust to the rare very bright samples that dominate a
/// plain mean), with a 95 % bootstrap interval over the blocks (seeded by `seed`).
#[must_use]
pub fn variance(blocks: &[f64], seed: u64) -> Estimate {
    bootstrap([blocks], seed, |[b]| robust_variance(b))
}

/// The median of means of block variances over [`MOM_GROUPS`] groups, kept above
/// [`MSE_FLOOR`] (a block's MSE minus the reference noise may come out below zero for a
/// near-exact technique): the statistic of [`variance`].
#[must_use]
pub fn robust_variance(blocks: &[f64]) -> f64 {
    median_of_means(blocks, MOM_GROUPS).max(MSE_FLOOR)
}

/// One point of a convergence curve.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ConvergencePoint {
    /// Samples per pixel.
    pub spp: u32,
    /// MSE (reference noise subtracted).
    #[serde(deserialize_with = "f64_or_nan")]
    pub mse: f64,
    /// Single-thread render time of the whole image at this spp, seconds
    /// (`spp · pixels · ns_per_sample`).
    #[serde(deserialize_with = "f64_or_nan")]
    pub seconds: f64,
}

/// The rendering results of one technique on one material.
#[derive(Clone, Debug)]
pub struct TechniqueEval {
    /// Technique name.
    pub name: String,
    /// Single-thread render-loop time per pixel sample, ns (module docs): the median of
    /// [`Self::ns_passes`].
    pub ns_per_sample: f64,
    /// The time per sample of each timing pass, ns.
    pub ns_passes: Vec<f64>,
    /// MSE at 1, 2, 4, … spp up to [`RenderSettings::max_spp`].
    pub convergence: Vec<ConvergencePoint>,
    /// The equal-spp render at [`RenderSettings::max_spp`].
    pub equal_spp: Render,
    /// MSE of [`Self::equal_spp`] against the reference (reference noise subtracted).
    pub mse_equal_spp: f64,
    /// The expected MSE at [`RenderSettings::max_spp`] estimated from the per-pixel sample
    /// variances of [`Self::equal_spp`] (`mean σ²/N`; equal to the MSE for an unbiased
    /// estimator, and a less noisy estimate of it than one realisation's squared error).
    pub mse_expected_equal_spp: f64,
    /// Samples per pixel of the equal-time render.
    pub equal_time_spp: u32,
    /// The equal-time render.
    pub equal_time: Render,
    /// MSE of [`Self::equal_time`].
    pub mse_equal_time: f64,
    /// [`block_variances`] of [`Self::equal_spp`].
    pub block_variances: Vec<f64>,
    /// The per-sample variance from them ([`variance`]).
    pub variance: Estimate,
    /// [`block_variances`] of [`Self::equal_time`].
    pub equal_time_block_variances: Vec<f64>,
}

impl TechniqueEval {
    /// The expected MSE at `spp` samples per pixel, `V / spp`, with its interval.
    #[must_use]
    pub fn mse_at(&self, spp: u32) -> Estimate {
        self.variance.scaled(1.0 / f64::from(spp.max(1)))
    }

    /// The equal-time render's MSE from its blocks (`V / spp`), with its interval (NaN with
    /// fewer than two blocks).
    #[must_use]
    pub fn mse_equal_time_estimate(&self, seed: u64) -> Estimate {
        let mut e = variance(&self.equal_time_block_variances, seed)
            .scaled(1.0 / f64::from(self.equal_time_spp.max(1)));
        if self.equal_time_block_variances.len() < 2 {
            (e.lo, e.hi) = (f64::NAN, f64::NAN);
        }
        e
    }
}

/// Renders and measures every technique against `reference`. `baseline` names the technique
/// that sets the equal-time budget (the improved baseline; the first technique if absent).
/// `progress` is called with a short message before each step.
pub fn evaluate(
    scene: &Scene,
    material: &dyn Material,
    techniques: &[(String, Technique<'_>)],
    reference: &Reference,
    baseline: &str,
    s: &RenderSettings,
    progress: &dyn Fn(&str),
) -> anyhow::Result<Vec<TechniqueEval>> {
    let mask = &reference.render.mask;
    let pixels = (scene.camera.width * scene.camera.height) as f64;
    let mut base = RenderOptions::new(s.max_spp.max(1), s.seed);
    base.estimator = s.estimator;
    base.blocks = s.blocks;

    // 1. Time per sample, single thread: passes interleaved over the techniques (so that a
    // change of machine load hits all of them alike); the median pass is the time, and the
    // intervals resample the passes. The oracle's passes mostly rebuild its (excluded) tables: one.
    // The oracle is timed once, on a quarter-resolution view of the same scene: its per-pixel
    // table builds (excluded from its time, but paid single-threaded here) would otherwise
    // dominate the whole evaluation.
    let mut passes: Vec<Vec<f64>> = vec![Vec::new(); techniques.len()];
    let mut o = base.clone();
    o.spp = s.timing_spp.max(1);
    o.blocks = 0;
    let mut small = scene.clone();
    small.camera.width = (scene.camera.width / 4).max(8);
    small.camera.height = (scene.camera.height / 4).max(6);
    for pass in 0..s.timing_passes.max(1) {
        for (i, (name, t)) in techniques.iter().enumerate() {
            let oracle = matches!(t, Technique::Oracle(_));
            if pass > 0 && oracle {
                continue;
            }
            if pass == 0 {
                progress(&format!("timing {name}"));
            }
            let timed = if oracle {
                let mut q = o.clone();
                q.spp = 16 * o.spp;
                t.time_per_sample(&small, material, &q, 1)?
            } else {
                t.time_per_sample(scene, material, &o, 1)?
            };
            passes[i].push(timed);
        }
    }
    let times: Vec<f64> = passes.iter().map(|p| median(p.clone())).collect();
    let b = techniques
        .iter()
        .position(|(n, _)| n == baseline)
        .unwrap_or(0);
    let budget_ns = times.get(b).copied().unwrap_or(1.0) * f64::from(s.max_spp.max(1));

    let mut out = Vec::with_capacity(techniques.len());
    for (((name, t), &ns), ns_passes) in techniques.iter().zip(&times).zip(passes) {
        // 2. Equal spp, with the convergence checkpoints.
        progress(&format!("equal spp {name}"));
        let r = t.render(scene, material, &base);
        let convergence = r
            .checkpoints
            .iter()
            .map(|(spp, img)| ConvergencePoint {
                spp: *spp,
                mse: (mse(img, &reference.render.image, mask) - reference.noise).max(MSE_FLOOR),
                seconds: f64::from(*spp) * pixels * ns * 1e-9,
            })
            .collect::<Vec<_>>();
        let mse_equal_spp =
            (mse(&r.image, &reference.render.image, mask) - reference.noise).max(MSE_FLOOR);
        let mse_expected_equal_spp = mean_variance_of_mean(&r, mask).max(MSE_FLOOR);

        // 3. Equal time.
        progress(&format!("equal time {name}"));
        let spp_t = if ns > 0.0 {
            (budget_ns / ns)
                .round()
                .clamp(1.0, f64::from(s.max_equal_time_spp.max(1))) as u32
        } else {
            1
        };
        let mut o = base.clone();
        o.spp = spp_t;
        o.checkpoints.clear();
        o.seed = Stream::EqualTime.of(s.seed);
        let rt = t.render(scene, material, &o);
        let mse_equal_time =
            (mse(&rt.image, &reference.render.image, mask) - reference.noise).max(MSE_FLOOR);
        let blocks = block_variances(&r, reference);
        let seed = crate::util::rng::mix_seed(s.seed, out.len() as u64);
        out.push(TechniqueEval {
            variance: variance(&blocks, seed),
            block_variances: blocks,
            equal_time_block_variances: block_variances(&rt, reference),
            name: name.clone(),
            ns_per_sample: ns,
            ns_passes,
            convergence,
            equal_spp: r,
            mse_equal_spp,
            mse_expected_equal_spp,
            equal_time_spp: spp_t,
            equal_time: rt,
            mse_equal_time,
        });
    }
    Ok(out)
}

/// Speed-up of `m` over `b` at equal quality (module docs): `(V_b · t_b) / (V_m · t_m)` with
/// the per-sample variances `V` of [`variance`] (median of means over blocks) and the times
/// `t` (medians of the timing passes), and a 95 % bootstrap interval that resamples the
/// blocks and the timing passes of both techniques independently. `seed` seeds the
/// resampling.
#[must_use]
pub fn speedup(m: &TechniqueEval, b: &TechniqueEval, seed: u64) -> Estimate {
    let sets = [
        b.block_variances.as_slice(),
        &m.block_variances,
        &b.ns_passes,
        &m.ns_passes,
    ];
    bootstrap(sets, seed, |[vb, vm, tb, tm]| {
        let t = |p: &[f64]| median(p.to_vec());
        ratio(robust_variance(vb) * t(tb), robust_variance(vm) * t(tm))
    })
}

/// The speed-up from the measured MSEs of the whole equal-spp images against the reference
/// ([`TechniqueEval::mse_equal_spp`]: plain means, no interval); it would also see a bias.
#[must_use]
pub fn speedup_measured(m: &TechniqueEval, b: &TechniqueEval) -> f64 {
    ratio(
        b.mse_equal_spp * b.ns_per_sample,
        m.mse_equal_spp * m.ns_per_sample,
    )
}

/// The MSE ratio at equal spp, `V_b / V_m`, with its interval as [`speedup`]: the speed-up if
/// every technique cost the same per sample (the paper's "sampling rate" view).
#[must_use]
pub fn variance_ratio(m: &TechniqueEval, b: &TechniqueEval, seed: u64) -> Estimate {
    bootstrap([&b.block_variances, &m.block_variances], seed, |[vb, vm]| {
        ratio(robust_variance(vb), robust_variance(vm))
    })
}

/// Which practical technique is best at equal quality: the largest speed-up, called
/// **clear** only when its interval's lower end lies above every other technique's upper end;
/// otherwise a tie with the techniques whose intervals reach its lower end.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    /// The technique with the largest speed-up.
    pub best: String,
    /// Whether its interval clears every other technique's.
    pub clear: bool,
    /// The techniques it ties with (empty when clear).
    pub tied_with: Vec<String>,
}

/// The [`Verdict`] over `(name, speed-up)` pairs (non-finite values ignored); `None` when no
/// technique has a finite speed-up.
#[must_use]
pub fn verdict(speedups: &[(String, Estimate)]) -> Option<Verdict> {
    let best = speedups
        .iter()
        .filter(|(_, e)| e.value.is_finite())
        .max_by(|a, b| a.1.value.total_cmp(&b.1.value))?;
    let lo = best.1.lo;
    let tied_with: Vec<String> = speedups
        .iter()
        .filter(|(n, e)| n != &best.0 && e.value.is_finite())
        // An unknown interval never clears: NaN bounds count as overlapping.
        .filter(|(_, e)| !(e.hi < lo))
        .map(|(n, _)| n.clone())
        .collect();
    Some(Verdict {
        best: best.0.clone(),
        clear: tied_with.is_empty(),
        tied_with,
    })
}
