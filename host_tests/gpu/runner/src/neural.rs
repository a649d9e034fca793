//! The neural material's cases: `neural_features` and `neural_eval` on the device against the
//! same entry points compiled for the host (tolerances: the crate docs in `main.rs`).

use std::time::Instant;

use neusample::neural_material::{DECODER_OUTPUTS, LOG_F_MAX, LOG_F_MIN};
use neusample::{Blob, BlobKind, NeuralMaterial, TensorRole, Vec2, FEATURE_DIM};
use neusample_gpu_shader::kernel::{
    Params, IN_STRIDE, NM_IN_PHI, NM_IN_UV, NM_IN_WI, NM_IN_WO, NM_OUT_EVAL, NM_OUT_EVAL_UV,
    OUT_STRIDE,
};
use neusample_gpu_shader::{UVec3, WORKGROUP_SIZE};

use crate::{mlp_params, push_bytes, vk, Rng, EVAL_REL, FEAT_EPS};

/// A neural material as the GPU sees it: flat f32 texture and decoder buffers.
pub struct Material {
    pub label: &'static str,
    pub texture: Vec<f32>,
    pub decoder: Vec<f32>,
    pub width: u32,
    pub height: u32,
}

impl Material {
    /// The committed blob at `path`, decoded (and widened to f32) into flat buffers, as a
    /// renderer's host would fill storage buffers.
    pub fn from_blob(label: &'static str, path: &str) -> Result<Self, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("reading {path}: {e}"))?;
        let blob = Blob::open(&bytes).map_err(|e| format!("{path}: {e}"))?;
        if blob.kind() != BlobKind::NeuralMaterial {
            return Err(format!("{path}: not a neural material ({:?})", blob.kind()));
        }
        // Validates the shape (texture = width·height·8, decoder = 9475) on the host.
        let m = blob.neural_material().map_err(|e| format!("{path}: {e}"))?;
        let (width, height) = (m.width(), m.height());
        let mut texture = vec![0.0f32; neusample::neural_material::texture_len(width, height)];
        blob.widen_into(TensorRole::Features, &mut texture)
            .map_err(|e| format!("{path}: {e}"))?;
        let mut decoder = vec![0.0f32; neusample::neural_material::DECODER_PARAM_COUNT];
        blob.widen_into(TensorRole::Params, &mut decoder)
            .map_err(|e| format!("{path}: {e}"))?;
        Ok(Material {
            label,
            texture,
            decoder,
            width,
            height,
        })
    }

    /// A seeded random material: an odd, non-square `width × height` texture (so `t·n` is
    /// rounded and both wraps are exercised) with values in ±2, and a decoder with
    /// PyTorch-style init times `gain`, large enough that some outputs reach the `ln f`
    /// clamps.
    pub fn random(label: &'static str, seed: u64, width: u32, height: u32, gain: f32) -> Self {
        let mut rng = Rng(seed);
        let texture = (0..neusample::neural_material::texture_len(width, height))
            .map(|_| rng.range(-2.0, 2.0))
            .collect();
        let mut decoder = Vec::new();
        mlp_params(
            &mut rng,
            &[(14, 64), (64, 64), (64, 64), (64, 3)],
            gain,
            &mut decoder,
        );
        assert_eq!(
            decoder.len(),
            neusample::neural_material::DECODER_PARAM_COUNT
        );
        Material {
            label,
            texture,
            decoder,
            width,
            height,
        }
    }

    fn host(&self) -> NeuralMaterial<&[f32]> {
        NeuralMaterial::new(
            &self.texture[..],
            &self.decoder[..],
            self.width,
            self.height,
        )
        .expect("material buffers have the right lengths")
    }

    /// Largest |texture value|: the scale of the features' tolerance.
    fn scale(&self) -> f32 {
        self.texture.iter().fold(0.0f32, |a, v| a.max(v.abs()))
    }

    /// Allowed |Δφ| / max|T| (main.rs): rounding of both sides plus one ulp of
    /// `x = t'·n − 0.5`.
    fn feat_tol(&self) -> f32 {
        FEAT_EPS * (16.0 + 2.0 * self.width.max(self.height) as f32)
    }

    /// One line: texture size, scale, the features' tolerance.
    pub fn describe(&self) {
        println!(
            "{}: {} × {} × 8 texture, max|T| {:.3}, φ tolerance {:.1e}·max|T|; {} decoder params",
            self.label,
            self.width,
            self.height,
            self.scale(),
            self.feat_tol(),
            self.decoder.len()
        );
    }

    fn params(&self, n: usize) -> Params {
        Params {
            n: n as u32,
            width: self.width,
            height: self.height,
            ..Params::default()
        }
    }
}

/// Record positions (`i % 64`) whose `eval(φ, …)` and `eval(φ(uv), …)` must both be refused
/// (`[0, 0, 0]`): a direction below, on the horizon, zero, non-finite, or overflowing.
const REFUSED_BOTH: [usize; 8] = [1, 2, 3, 4, 5, 6, 25, 26];
/// Record positions where only `eval(φ, …)` must be refused (non-finite φ).
const REFUSED_PHI: [usize; 2] = [7, 8];

/// Input records: uv (half in [0, 1), half in [−2.5, 3.5)), φ (even records: the material's
/// own features at another uv, i.e. in distribution; odd records: uniform in ±1.5 × the
/// texture's scale), wi (z ≥ 0.02) and wo (z ≥ 10⁻⁴), with edge cases at fixed positions.
fn make_input(n: usize, seed: u64, mat: &Material) -> Vec<f32> {
    let m = mat.host();
    let scale = mat.scale();
    let (w, h) = (mat.width as f32, mat.height as f32);
    let mut rng = Rng(seed);
    let mut v = vec![0.0f32; n * IN_STRIDE];
    for i in 0..n {
        let r = &mut v[i * IN_STRIDE..(i + 1) * IN_STRIDE];
        let uv = if i % 2 == 0 {
            [rng.f32(), rng.f32()]
        } else {
            [rng.range(-2.5, 3.5), rng.range(-2.5, 3.5)]
        };
        r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&uv);
        if i % 2 == 0 {
            let phi = m.features(Vec2::new(rng.f32(), rng.f32()));
            r[NM_IN_PHI..NM_IN_PHI + FEATURE_DIM].copy_from_slice(&phi);
        } else {
            for k in 0..FEATURE_DIM {
                r[NM_IN_PHI + k] = rng.range(-1.5, 1.5) * scale;
            }
        }
        let wi = rng.hemisphere(0.02);
        let wo = rng.hemisphere(1e-4);
        r[NM_IN_WI..NM_IN_WI + 3].copy_from_slice(&wi);
        r[NM_IN_WO..NM_IN_WO + 3].copy_from_slice(&wo);
        let (ci, cj) = (
            (rng.f32() * w).floor().min(w - 1.0),
            (rng.f32() * h).floor().min(h - 1.0),
        );
        match i % 64 {
            // Refused directions (REFUSED_BOTH).
            1 => r[NM_IN_WI + 2] = -0.3, // wi below
            2 => r[NM_IN_WO + 2] = -0.5, // wo below
            3 => r[NM_IN_WI + 2] = 0.0,  // wi on the horizon
            4 => r[NM_IN_WO..NM_IN_WO + 3].copy_from_slice(&[0.0; 3]), // zero wo
            5 => r[NM_IN_WI] = f32::NAN, // NaN wi
            6 => r[NM_IN_WO + 1] = f32::INFINITY, // ∞ wo
            25 => r[NM_IN_WI..NM_IN_WI + 3].copy_from_slice(&wi.map(|c| c * 1e20)), // |wi|² = ∞
            26 => r[NM_IN_WO..NM_IN_WO + 3].copy_from_slice(&wo.map(|c| c * 1e-25)), // |wo|² = 0
            // Non-finite φ (REFUSED_PHI); eval(φ(uv)) still valid.
            7 => r[NM_IN_PHI + 2] = f32::NAN,
            8 => r[NM_IN_PHI + 5] = f32::NEG_INFINITY,
            // Valid but unusual directions.
            9 => r[NM_IN_WI + 2] = 1e-3, // grazing wi (renormalised)
            10 => r[NM_IN_WO..NM_IN_WO + 3].copy_from_slice(&wi.map(|c| c * 3.7)), // wo ∥ wi, unnormalised
            11 => r[NM_IN_WO..NM_IN_WO + 3].copy_from_slice(&[-wi[0], -wi[1], wi[2]]), // mirror: h = n
            12 => {
                r[NM_IN_WI..NM_IN_WI + 3].copy_from_slice(&[0.0, 0.0, 1.0]);
                r[NM_IN_WO..NM_IN_WO + 3].copy_from_slice(&[0.0, 0.0, 1.0]);
            }
            24 => {
                r[NM_IN_WI + 2] = 1e-3; // both grazing
                r[NM_IN_WO + 2] = 1e-3;
            }
            // Texture coordinates: non-finite (read as 0), far outside, wrap, texel grid.
            13 => r[NM_IN_UV] = f32::NAN,
            14 => r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&[f32::INFINITY, f32::NEG_INFINITY]),
            15 => r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&[1e4 + 0.3, -1e4 - 0.7]),
            16 => r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&[1.5e7, -3e9]), // integers
            17 => r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&[-1e-30, -1e-9]), // t − ⌊t⌋ → 1
            18 => r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&[1.0, 0.0]),
            19 => r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&[-0.0, 1.0 - f32::EPSILON / 2.0]),
            20 => r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&[(ci + 0.5) / w, (cj + 0.5) / h]),
            21 => r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&[ci / w, cj / h]), // texel edges
            22 => r[NM_IN_UV..NM_IN_UV + 2]
                .copy_from_slice(&[(ci + 0.5) / w - 3.0, (cj + 0.5) / h + 5.0]),
            23 => r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&[0.5 / w - 1e-7, 0.5 / h + 1e-7]), // around the first centre
            27 => r[NM_IN_UV..NM_IN_UV + 2].copy_from_slice(&[-1.0 / w, 1.0 + 0.5 / h]), // wrap
            _ => {}
        }
    }
    v
}

/// Per-case figures.
#[derive(Default)]
struct Stats {
    /// `neural_features`: max |Δφ| / texture scale.
    max_feat: f32,
    /// `neural_eval`: max relative difference of `eval(φ, …)`, and of `eval(φ(uv), …)`.
    max_eval_rel: f32,
    max_eval_uv_rel: f32,
    /// CPU `eval(φ, …)` refused (all zero), and `eval(φ(uv), …)` refused.
    refused: usize,
    refused_uv: usize,
    /// CPU channels of `eval(φ, …)` at a clamp of `ln f`.
    clamped: usize,
    failures: usize,
}

fn rel(a: f32, b: f32) -> f32 {
    let d = (a - b).abs();
    if d == 0.0 {
        0.0
    } else {
        d / a.abs().max(b.abs())
    }
}

/// One RGB triple: refused (exactly zero) on both sides or on neither, every channel
/// finite and within `EVAL_REL`. Returns the largest relative difference, or `None`.
fn rgb_close(g: &[f32], c: &[f32]) -> Option<f32> {
    let gz = g.iter().all(|&x| x == 0.0);
    let cz = c.iter().all(|&x| x == 0.0);
    if gz != cz {
        return None;
    }
    let mut m = 0.0f32;
    for k in 0..DECODER_OUTPUTS {
        if !g[k].is_finite() || !c[k].is_finite() || (!cz && !(c[k] > 0.0 && g[k] > 0.0)) {
            return None;
        }
        let r = rel(g[k], c[k]);
        if r > EVAL_REL {
            return None;
        }
        m = m.max(r);
    }
    Some(m)
}

/// Runs both entry points of one material; prints one row per entry point. Returns the
/// labels that failed.
pub fn run(ctx: &vk::Context, mat: &Material, n: usize, seed: u64, verbose: bool) -> Vec<String> {
    let mut failed = Vec::new();
    let input = make_input(n, seed, mat);
    let params = mat.params(n);
    let push = push_bytes(&params);
    let groups = (n as u32).div_ceil(WORKGROUP_SIZE);
    let scale = mat.scale();
    let feat_tol = mat.feat_tol();
    let (tex, dec): (&[f32], &[f32]) = (&mat.texture, &mat.decoder);
    let out_init = vec![0.0f32; n * OUT_STRIDE];
    let bufs: Vec<&[f32]> = vec![&input, &out_init, tex, dec];

    for entry in ["neural_features", "neural_eval"] {
        let label = format!("{}:{}", mat.label, entry.trim_start_matches("neural_"));
        let d = match ctx.dispatch(entry, &bufs, 1, n * OUT_STRIDE, &push, groups) {
            Ok(d) => d,
            Err(e) => {
                println!("{label:<24} DISPATCH FAILED: {e}");
                failed.push(label);
                continue;
            }
        };
        // The CPU reference: the same entry point compiled for the host.
        let t = Instant::now();
        let mut cpu = vec![0.0f32; n * OUT_STRIDE];
        for i in 0..n {
            let id = UVec3::new(i as u32, 0, 0);
            if entry == "neural_features" {
                neusample_gpu_shader::neural_features(id, &params, &input, &mut cpu, tex, dec);
            } else {
                neusample_gpu_shader::neural_eval(id, &params, &input, &mut cpu, tex, dec);
            }
        }
        let cpu_ms = t.elapsed().as_secs_f64() * 1e3;

        let mut s = Stats::default();
        let mut shown = 0;
        for i in 0..n {
            let rec = &input[i * IN_STRIDE..(i + 1) * IN_STRIDE];
            let g = &d.output[i * OUT_STRIDE..(i + 1) * OUT_STRIDE];
            let c = &cpu[i * OUT_STRIDE..(i + 1) * OUT_STRIDE];
            let mut ok = true;
            if entry == "neural_features" {
                for k in 0..FEATURE_DIM {
                    let e = (g[k] - c[k]).abs() / scale;
                    if !(e <= feat_tol) || !c[k].is_finite() {
                        ok = false;
                    } else {
                        s.max_feat = s.max_feat.max(e);
                    }
                }
            } else {
                let (ge, ce) = (
                    &g[NM_OUT_EVAL..NM_OUT_EVAL + 3],
                    &c[NM_OUT_EVAL..NM_OUT_EVAL + 3],
                );
                let (gu, cu) = (
                    &g[NM_OUT_EVAL_UV..NM_OUT_EVAL_UV + 3],
                    &c[NM_OUT_EVAL_UV..NM_OUT_EVAL_UV + 3],
                );
                let refused = ce.iter().all(|&x| x == 0.0);
                let refused_uv = cu.iter().all(|&x| x == 0.0);
                s.refused += refused as usize;
                s.refused_uv += refused_uv as usize;
                let (lo, hi) = (LOG_F_MIN.exp(), LOG_F_MAX.exp());
                s.clamped += ce
                    .iter()
                    .filter(|&&x| x != 0.0 && (rel(x, lo) < 1e-6 || rel(x, hi) < 1e-6))
                    .count();
                match (rgb_close(ge, ce), rgb_close(gu, cu)) {
                    (Some(a), Some(b)) => {
                        s.max_eval_rel = s.max_eval_rel.max(a);
                        s.max_eval_uv_rel = s.max_eval_uv_rel.max(b);
                    }
                    _ => ok = false,
                }
                // The documented refusals hold (on the CPU; the GPU matched it above).
                let pos = i % 64;
                if REFUSED_BOTH.contains(&pos) && !(refused && refused_uv) {
                    ok = false;
                }
                if REFUSED_PHI.contains(&pos) && !(refused && !refused_uv) {
                    ok = false;
                }
                if !REFUSED_BOTH.contains(&pos)
                    && !REFUSED_PHI.contains(&pos)
                    && (refused || refused_uv)
                {
                    ok = false;
                }
            }
            if !ok {
                s.failures += 1;
            }
            if (!ok || (verbose && i % 64 < 28)) && shown < 8 {
                shown += 1;
                eprintln!(
                    "  {label} record {i}: {}\n    input {rec:?}\n    gpu {g:?}\n    cpu {c:?}",
                    if ok { "ok" } else { "MISMATCH" }
                );
            }
        }
        if entry == "neural_features" {
            println!(
                "{label:<24} {n:>6} {:>9.1e} {:>9} {:>9} {:>6} {:>6} {:>7} {:>5} {:>7.1} {:>7.1} {:>7.1} {:>7.1}",
                s.max_feat, "", "", "", "", "", s.failures, cpu_ms,
                d.first.as_secs_f64() * 1e3, d.second.as_secs_f64() * 1e3, d.compile.as_secs_f64() * 1e3,
            );
        } else {
            println!(
                "{label:<24} {n:>6} {:>9} {:>9.1e} {:>9.1e} {:>6} {:>6} {:>7} {:>5} {:>7.1} {:>7.1} {:>7.1} {:>7.1}",
                "", s.max_eval_rel, s.max_eval_uv_rel, s.refused, s.refused_uv, s.clamped, s.failures,
                cpu_ms, d.first.as_secs_f64() * 1e3, d.second.as_secs_f64() * 1e3, d.compile.as_secs_f64() * 1e3,
            );
        }
        if s.failures > 0 {
            failed.push(label);
        }
    }
    failed
}

/// Header of the neural material's table.
pub fn header() {
    println!(
        "{:<24} {:>6} {:>9} {:>9} {:>9} {:>6} {:>6} {:>7} {:>5} {:>7} {:>7} {:>7} {:>7}",
        "material:entry",
        "recs",
        "φ abs/s",
        "eval rel",
        "f(uv) rel",
        "refus",
        "ref uv",
        "clamped",
        "bad",
        "cpu ms",
        "gpu1 ms",
        "gpu2 ms",
        "pipe ms"
    );
}
