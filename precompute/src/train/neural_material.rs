//! Fitting a neural material to a source material (`neusample train-material`).
//!
//! The feature texture and the decoder are trained jointly on random queries
//! `(uv, wi, wo)` of the source, with the target `f_src(φ_src(uv), wi, wo)`:
//!
//! * `uv` from a jittered grid of [`NeuralTrainConfig::uv_pool`] points whose source features
//!   are computed once (procedural textures are slow to look up); `wi` from
//!   [`groundtruth::random_wi`] (the samplers' condition distribution); `wo` half uniform on the projected disk (the rendering
//!   measure `cos θo dωo`) and half around the mirror direction (a half vector with a
//!   Gaussian slope of log-uniform width `α ∈ [0.02, 0.6]`), so that sharp highlights, which
//!   cover a tiny part of the disk but carry most of p*, are seen often.
//! * Loss: **L2 of `ln(ε + f)`** per RGB channel with `ε =` [`NeuralTrainConfig::epsilon`]
//!   (0.01). HDR BRDFs span five decades (diffuse 0.01–0.3, highlights up to 10³): the log
//!   makes the error relative, so the peak and the diffuse floor both count, and that is
//!   what sampling needs (p* is the luminance normalised per condition: a relative error of
//!   f is what moves it). ε keeps near-black values (≪ ε) from dominating with meaningless
//!   log differences. The decoder outputs `ln f` (f = exp of its last layer), so the loss
//!   is smooth in the network's output: `ln(ε + e^o)` is a softplus in `o`.
//! * The bilinear lookup is differentiable: the four texel rows are gathered (`select`) and
//!   weighted by the bilinear weights, which are computed on the host by the runtime's own
//!   [`wrap_bilinear`] (so texel indices and weights are bit-identical to core's).
//!
//! [`verify_blob`] checks that core's features and eval equal the burn forward pass;
//! `crate::eval::neural_fit` measures the fit to the source through the runtime.

use std::time::Instant;

use anyhow::{bail, Result};
use burn::module::{Module, Param};
use burn::tensor::{Device, Int, Tensor, TensorData};
use glam::{Vec2, Vec3};
use neusample::neural_material::{
    decoder_input, output_to_brdf, wrap_bilinear, DECODER_INPUTS, DECODER_OUTPUTS,
};
use rand::RngExt;
use rand_pcg::Pcg64;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::groundtruth;
use crate::materials::neural::{NeuralParts, DECODER_SIZES};
use crate::materials::{Material, FEATURE_DIM};
use crate::nn::{
    infer_device, optimise, tensor2, to_host, train_device, Activation, Mlp, OptimSettings,
};
use crate::util::rng::{mix_seed, rng_for};

/// Direction inputs of the decoder (everything after φ).
const DIRS: usize = DECODER_INPUTS - FEATURE_DIM;

/// Queries per parallel chunk of the host data (each chunk has its own PCG stream).
const CHUNK: usize = 256;

/// Hyper-parameters of [`train`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NeuralTrainConfig {
    /// Texture width (texels along u).
    pub width: u32,
    /// Texture height (texels along v).
    pub height: u32,
    /// Optimisation steps.
    pub steps: usize,
    /// Queries per step.
    pub batch: usize,
    /// Peak learning rate (AdamW; linear warm-up, cosine decay to 5 %).
    pub lr: f64,
    /// ε of the loss `(ln(ε + f̂) − ln(ε + f))²`.
    pub epsilon: f32,
    /// Fraction of queries whose `wo` is drawn around the mirror direction.
    pub lobe_fraction: f32,
    /// Initial features are uniform in `[−init_scale, init_scale]`.
    pub init_scale: f32,
    /// Texture coordinates (a jittered grid) whose source features are computed once and
    /// reused by every step: procedural feature textures cost microseconds per lookup.
    pub uv_pool: usize,
    /// Seed of every random stream.
    pub seed: u64,
    /// Threads of the training pool.
    pub threads: usize,
    /// Show a progress bar.
    pub progress: bool,
}

impl NeuralTrainConfig {
    /// The default run: 128 × 128 texels, 20 000 steps of 4096 queries (minutes on two
    /// cores).
    #[must_use]
    pub fn default_run() -> Self {
        NeuralTrainConfig {
            width: 128,
            height: 128,
            steps: 20_000,
            batch: 4096,
            lr: 1e-2,
            epsilon: 0.01,
            lobe_fraction: 0.5,
            init_scale: 0.5,
            uv_pool: 512 * 512,
            seed: 1,
            threads: 2,
            progress: false,
        }
    }

    /// A short run for tests (seconds).
    #[must_use]
    pub fn quick() -> Self {
        NeuralTrainConfig {
            width: 16,
            height: 16,
            steps: 300,
            batch: 1024,
            uv_pool: 128 * 128,
            ..Self::default_run()
        }
    }
}

/// A trained neural material.
#[derive(Clone, Debug)]
pub struct TrainedNeural {
    /// The texture and decoder in the runtime layout.
    pub parts: NeuralParts,
    /// The loss of every step.
    pub loss_history: Vec<f32>,
    /// Wall-clock training time, seconds.
    pub seconds: f64,
}

/// The burn model: the feature texture `[H·W, 8]` (row `j·W + i` = texel `(i, j)`, the
/// runtime layout) and the decoder.
#[derive(Module, Debug)]
pub struct NeuralModel {
    /// The feature texture.
    pub texture: Param<Tensor<2>>,
    /// The decoder.
    pub decoder: Mlp,
}

impl NeuralModel {
    /// A fresh model: features uniform in `[−init_scale, init_scale]`, PyTorch-initialised
    /// decoder with output bias `ln 0.1` (a dim grey start).
    pub fn init(cfg: &NeuralTrainConfig, rng: &mut Pcg64, device: &Device) -> Self {
        let n = cfg.width as usize * cfg.height as usize;
        let s = cfg.init_scale;
        let tex: Vec<f32> = (0..n * FEATURE_DIM)
            .map(|_| {
                if s > 0.0 {
                    rng.random_range(-s..s)
                } else {
                    0.0
                }
            })
            .collect();
        let bias: Vec<(usize, f32)> = (0..DECODER_OUTPUTS).map(|c| (c, 0.1f32.ln())).collect();
        NeuralModel {
            texture: Param::from_tensor(tensor2(tex, n, FEATURE_DIM, device)),
            decoder: Mlp::new_with_output_bias(&DECODER_SIZES, 1.0, &bias, rng, device),
        }
    }

    /// A model holding `parts` (for inference and checks).
    pub fn from_parts(parts: &NeuralParts, device: &Device) -> Self {
        let n = parts.width as usize * parts.height as usize;
        NeuralModel {
            texture: Param::from_tensor(tensor2(parts.texture.clone(), n, FEATURE_DIM, device)),
            decoder: Mlp::from_flat(&DECODER_SIZES, &parts.params, device),
        }
    }

    /// The arrays in the runtime layout.
    #[must_use]
    pub fn export(&self, width: u32, height: u32) -> NeuralParts {
        let mut params = Vec::new();
        self.decoder.export(&mut params);
        NeuralParts {
            width,
            height,
            texture: to_host(self.texture.val()),
            params,
        }
    }

    /// φ at the queries, `[n, 8]`: Σ over the four corners of weight × gathered texel.
    pub fn features(&self, q: &DeviceQueries) -> Tensor<2> {
        let rows = self.texture.val().select(0, q.texels.clone()); // [4n, 8]
        let weighted = rows * q.weights.clone(); // [4n, 1] broadcast
        weighted
            .reshape([4, q.n, FEATURE_DIM])
            .sum_dim(0)
            .reshape([q.n, FEATURE_DIM])
    }

    /// The decoder's raw output `ln f` at the queries, `[n, 3]` (before the runtime's clamp).
    pub fn log_f(&self, q: &DeviceQueries) -> Tensor<2> {
        let x = Tensor::cat(vec![self.features(q), q.dirs.clone()], 1);
        self.decoder.forward(x, Activation::Relu)
    }
}

/// Queries on the host: bilinear texel indices and weights (corner-major: all first
/// corners, then all second corners, …) and the direction inputs of the decoder.
#[derive(Clone, Debug, Default)]
pub struct HostQueries {
    /// Number of queries.
    pub n: usize,
    /// `4n` texel rows.
    pub texels: Vec<i64>,
    /// `4n` bilinear weights.
    pub weights: Vec<f32>,
    /// `n × 6` direction inputs `[wi.x, wi.y, wo.x, wo.y, h.x, h.y]`.
    pub dirs: Vec<f32>,
    /// Whether each query is valid (both directions above the horizon).
    pub valid: Vec<bool>,
}

impl HostQueries {
    /// Queries `(uv, wi, wo)` for a `width × height` texture. Invalid direction pairs get
    /// zero direction inputs and `valid = false` (the runtime returns 0 there).
    #[must_use]
    pub fn new(width: u32, height: u32, queries: &[(Vec2, Vec3, Vec3)]) -> Self {
        let n = queries.len();
        let mut texels = vec![0i64; 4 * n];
        let mut weights = vec![0f32; 4 * n];
        let mut dirs = vec![0f32; DIRS * n];
        let mut valid = vec![false; n];
        for (k, &(uv, wi, wo)) in queries.iter().enumerate() {
            let (i0, i1, wx) = wrap_bilinear(uv.x, width);
            let (j0, j1, wy) = wrap_bilinear(uv.y, height);
            let w = i64::from(width);
            let corners = [
                (i64::from(j0) * w + i64::from(i0), (1.0 - wx) * (1.0 - wy)),
                (i64::from(j0) * w + i64::from(i1), wx * (1.0 - wy)),
                (i64::from(j1) * w + i64::from(i0), (1.0 - wx) * wy),
                (i64::from(j1) * w + i64::from(i1), wx * wy),
            ];
            for (c, (t, a)) in corners.into_iter().enumerate() {
                texels[c * n + k] = t;
                weights[c * n + k] = a;
            }
            if let Some(x) = decoder_input(&[0.0; FEATURE_DIM], wi, wo) {
                dirs[k * DIRS..(k + 1) * DIRS].copy_from_slice(&x[FEATURE_DIM..]);
                valid[k] = true;
            }
        }
        HostQueries {
            n,
            texels,
            weights,
            dirs,
            valid,
        }
    }

    /// Uploads to `device`.
    #[must_use]
    pub fn upload(&self, device: &Device) -> DeviceQueries {
        DeviceQueries {
            n: self.n,
            texels: Tensor::<1, Int>::from_data(
                TensorData::new(self.texels.clone(), [4 * self.n]),
                device,
            ),
            weights: tensor2(self.weights.clone(), 4 * self.n, 1, device),
            dirs: tensor2(self.dirs.clone(), self.n, DIRS, device),
        }
    }
}

/// [`HostQueries`] on the training or inference device.
pub struct DeviceQueries {
    /// Number of queries.
    pub n: usize,
    /// `[4n]` texel rows.
    pub texels: Tensor<1, Int>,
    /// `[4n, 1]` weights.
    pub weights: Tensor<2>,
    /// `[n, 6]` direction inputs.
    pub dirs: Tensor<2>,
}

/// A random `wo` around the mirror direction of `wi`: a half vector with Gaussian slopes of
/// width α (log-uniform in `[0.02, 0.6]`); `None` when the reflection is below the horizon.
fn lobe_wo(wi: Vec3, rng: &mut Pcg64) -> Option<Vec3> {
    let (lo, hi) = (0.02f32.ln(), 0.6f32.ln());
    let alpha = (lo + (hi - lo) * rng.random::<f32>()).exp();
    let u1: f32 = rng.random::<f32>().max(1e-12);
    let r = (-2.0 * u1.ln()).sqrt() * alpha;
    let a = std::f32::consts::TAU * rng.random::<f32>();
    let h = Vec3::new(r * a.cos(), r * a.sin(), 1.0).normalize();
    let wo = 2.0 * wi.dot(h) * h - wi;
    (wo.z > 0.01).then_some(wo)
}

/// A uniform point of the projected disk lifted to the hemisphere (cosine-distributed `wo`).
fn disk_wo(rng: &mut Pcg64) -> Vec3 {
    let r = rng.random::<f32>().sqrt() * 0.999;
    let a = std::f32::consts::TAU * rng.random::<f32>();
    let (x, y) = (r * a.cos(), r * a.sin());
    Vec3::new(x, y, (1.0 - x * x - y * y).max(0.0).sqrt())
}

/// One training query with the source's value.
#[derive(Clone, Copy, Debug)]
pub struct Sampled {
    /// Texture coordinate.
    pub uv: Vec2,
    /// Incoming direction.
    pub wi: Vec3,
    /// Outgoing direction.
    pub wo: Vec3,
    /// The source's BRDF (non-finite and negative values set to 0).
    pub f: [f32; 3],
}

/// Texture coordinates on a jittered `s × s` grid (`s = ⌈√n⌉`) with the source's features.
#[must_use]
pub fn uv_pool(m: &dyn Material, n: usize, seed: u64) -> Vec<(Vec2, [f32; FEATURE_DIM])> {
    let side = (n.max(1) as f64).sqrt().ceil() as usize;
    (0..side * side)
        .into_par_iter()
        .map(|k| {
            let mut rng = rng_for(seed, 0x0f00, k as u64);
            let (i, j) = (k % side, k / side);
            let uv = Vec2::new(
                (i as f32 + rng.random::<f32>()) / side as f32,
                (j as f32 + rng.random::<f32>()) / side as f32,
            );
            let uv = uv.min(Vec2::splat(1.0 - f32::EPSILON));
            (uv, m.features(uv))
        })
        .collect()
}

/// `n` random queries of `m` (module docs), deterministic in `(seed, step)` whatever the
/// thread count. Texture coordinates and their features come from `pool` when given
/// ([`uv_pool`]), else are drawn uniformly and looked up.
#[must_use]
pub fn draw(
    m: &dyn Material,
    pool: Option<&[(Vec2, [f32; FEATURE_DIM])]>,
    n: usize,
    lobe_fraction: f32,
    seed: u64,
    step: u64,
) -> Vec<Sampled> {
    let chunks = n.div_ceil(CHUNK);
    (0..chunks)
        .into_par_iter()
        .flat_map_iter(|c| {
            let mut rng = rng_for(seed, step, c as u64);
            let len = CHUNK.min(n - c * CHUNK);
            (0..len)
                .map(|_| {
                    let (uv, phi) = match pool {
                        Some(p) if !p.is_empty() => p[rng.random_range(0..p.len())],
                        _ => {
                            let uv = Vec2::new(rng.random::<f32>(), rng.random::<f32>());
                            (uv, m.features(uv))
                        }
                    };
                    let wi = groundtruth::random_wi(&mut rng);
                    let wo = if rng.random::<f32>() < lobe_fraction {
                        lobe_wo(wi, &mut rng).unwrap_or_else(|| disk_wo(&mut rng))
                    } else {
                        disk_wo(&mut rng)
                    };
                    let f =
                        m.eval(&phi, wi, wo).map(
                            |v| {
                                if v.is_finite() && v > 0.0 {
                                    v
                                } else {
                                    0.0
                                }
                            },
                        );
                    Sampled { uv, wi, wo, f }
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// The loss of a batch (module docs): mean over queries and channels of
/// `(ln(ε + e^o) − ln(ε + f))²`.
fn loss(model: &NeuralModel, q: &DeviceQueries, target: Tensor<2>, ln_eps: f32) -> Tensor<1> {
    let o = model.log_f(q);
    // ln(ε + e^o) = max(o, ln ε) + ln(1 + e^{−|o − ln ε|}), stable.
    let m = o.clone().clamp_min(ln_eps);
    let d = o.sub_scalar(ln_eps).abs().neg().exp();
    let pred = m + (d + 1.0).log();
    (pred - target).square().mean()
}

/// Fits a neural material to `source` (module docs).
pub fn train(source: &dyn Material, cfg: &NeuralTrainConfig) -> Result<TrainedNeural> {
    if cfg.steps == 0 || cfg.batch == 0 || cfg.threads == 0 {
        bail!("steps, batch and threads must be positive");
    }
    if cfg.width == 0
        || cfg.height == 0
        || cfg.width > neusample::neural_material::MAX_TEXTURE_SIZE
        || cfg.height > neusample::neural_material::MAX_TEXTURE_SIZE
    {
        bail!(
            "texture {}×{} is outside 1..={} per side",
            cfg.width,
            cfg.height,
            neusample::neural_material::MAX_TEXTURE_SIZE
        );
    }
    if !(cfg.epsilon > 0.0 && cfg.epsilon.is_finite()) {
        bail!("epsilon must be positive");
    }
    let start = Instant::now();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(cfg.threads)
        .build()?;
    pool.install(|| {
        let device = train_device();
        let mut rng = rng_for(cfg.seed, 0x7e47, 0);
        let model = NeuralModel::init(cfg, &mut rng, &device);
        let settings = OptimSettings {
            name: format!("{} (neural)", source.name()),
            steps: cfg.steps,
            lr: cfg.lr,
            weight_decay: 0.0,
            grad_clip: 10.0,
            progress: cfg.progress,
            report_every: 20,
        };
        let ln_eps = cfg.epsilon.ln();
        let data_seed = mix_seed(cfg.seed, 0xda7a);
        let uvs = uv_pool(source, cfg.uv_pool, mix_seed(cfg.seed, 0x0f));
        let (model, history) = optimise(model, &settings, |model, step| {
            let samples = draw(
                source,
                Some(&uvs),
                cfg.batch,
                cfg.lobe_fraction,
                data_seed,
                step as u64,
            );
            let qs: Vec<_> = samples.iter().map(|s| (s.uv, s.wi, s.wo)).collect();
            let q = HostQueries::new(cfg.width, cfg.height, &qs).upload(&device);
            let target: Vec<f32> = samples
                .iter()
                .flat_map(|s| s.f.map(|v| (cfg.epsilon + v).ln()))
                .collect();
            let target = tensor2(target, cfg.batch, DECODER_OUTPUTS, &device);
            Ok(loss(model, &q, target, ln_eps))
        })?;
        let parts = model.export(cfg.width, cfg.height);
        parts.validate()?;
        Ok(TrainedNeural {
            parts,
            loss_history: history,
            seconds: start.elapsed().as_secs_f64(),
        })
    })
}

/// The training graph's output (burn, inference device) for `parts` at the queries:
/// φ per query and the BRDF `exp(clamp(o))` (0 for invalid direction pairs), the same
/// post-processing as the runtime ([`output_to_brdf`]).
#[must_use]
pub fn graph_eval(
    parts: &NeuralParts,
    queries: &[(Vec2, Vec3, Vec3)],
) -> (Vec<[f32; FEATURE_DIM]>, Vec<[f32; 3]>) {
    let device = infer_device();
    let model = NeuralModel::from_parts(parts, &device);
    let host = HostQueries::new(parts.width, parts.height, queries);
    let q = host.upload(&device);
    let phi = to_host(model.features(&q));
    let o = to_host(model.log_f(&q));
    let feats = phi
        .chunks_exact(FEATURE_DIM)
        .map(|c| std::array::from_fn(|k| c[k]))
        .collect();
    let rgb = o
        .chunks_exact(DECODER_OUTPUTS)
        .zip(&host.valid)
        .map(|(c, &ok)| {
            if ok {
                [
                    output_to_brdf(c[0]),
                    output_to_brdf(c[1]),
                    output_to_brdf(c[2]),
                ]
            } else {
                [0.0; 3]
            }
        })
        .collect();
    (feats, rgb)
}

/// Outcome of [`verify_blob`].
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct BlobCheck {
    /// Queries compared.
    pub queries: usize,
    /// Largest `|φ_core − φ_graph| / max(|φ_graph|, 1e−3)`.
    pub features_max_relative: f64,
    /// Largest `|f_core − f_graph| / max(f_graph, 1e−6)` over channels.
    pub eval_max_relative: f64,
    /// The tolerance applied to both.
    pub tolerance: f64,
}

/// Tolerance of [`verify_blob`].
pub const VERIFY_TOLERANCE: f64 = 1e-4;

/// Opens `bytes` with the runtime and compares its features and eval with the burn forward
/// pass of the arrays *as stored in the blob* (for an f32 blob, the trained model itself) at
/// `n` random queries. Fails above [`VERIFY_TOLERANCE`].
pub fn verify_blob(bytes: &[u8], n: usize, seed: u64) -> Result<BlobCheck> {
    let (parts, _) = NeuralParts::from_blob(bytes)?;
    let blob = neusample::Blob::open(bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
    let core = blob.neural_material().map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut rng = rng_for(seed, 0xc4ec, 0);
    let queries: Vec<(Vec2, Vec3, Vec3)> = (0..n)
        .map(|_| {
            let uv = Vec2::new(
                rng.random_range(-1.0f32..2.0),
                rng.random_range(-1.0f32..2.0),
            );
            let wi = groundtruth::random_wi(&mut rng);
            let wo = if rng.random::<bool>() {
                lobe_wo(wi, &mut rng).unwrap_or_else(|| disk_wo(&mut rng))
            } else {
                disk_wo(&mut rng)
            };
            (uv, wi, wo)
        })
        .collect();
    let (gphi, gf) = graph_eval(&parts, &queries);
    let (mut fe, mut ee) = (0f64, 0f64);
    for (k, &(uv, wi, wo)) in queries.iter().enumerate() {
        let phi = core.features(uv);
        for c in 0..FEATURE_DIM {
            let (a, b) = (f64::from(phi[c]), f64::from(gphi[k][c]));
            fe = fe.max((a - b).abs() / b.abs().max(1e-3));
        }
        // Both evaluate the decoder on the graph's φ, so the two checks are independent.
        let f = core.eval(&gphi[k], wi, wo);
        for c in 0..3 {
            let (a, b) = (f64::from(f[c]), f64::from(gf[k][c]));
            ee = ee.max((a - b).abs() / b.abs().max(1e-6));
        }
    }
    let check = BlobCheck {
        queries: n,
        features_max_relative: fe,
        eval_max_relative: ee,
        tolerance: VERIFY_TOLERANCE,
    };
    if !(fe <= VERIFY_TOLERANCE && ee <= VERIFY_TOLERANCE) {
        bail!(
            "core does not reproduce the trained model: features {fe:.2e}, eval {ee:.2e} (tolerance {VERIFY_TOLERANCE:.0e})"
        );
    }
    Ok(check)
}
