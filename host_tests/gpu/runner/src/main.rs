//! Runs the neusample compute shaders on a Vulkan device (lavapipe on CI) and compares every
//! output record with the CPU.
//!
//! The CPU reference is the *same* entry-point function of `neusample-gpu-shader`, compiled
//! for the host: identical wrapper, core's code on both sides (on the host core takes its
//! slice fast paths, on SPIR-V the portable loops).
//!
//! Usage: `neusample-gpu-runner <module.spv> [records per sampler]`. Exit status 0 when every
//! sampler and the neural material match, 1 on a mismatch, 2 when Vulkan is unusable.
//!
//! # Tolerances (per record)
//!
//! * flags (prepared / sampled / inverted) identical;
//! * directions: `wo⊥ = wo.xy` (the samplers' native domain, the projected disk) within
//!   `wo_abs` (1e-5) per component; `wo.z = √(1 − |wo⊥|²)` within `wo_abs·(1 + 1.5/z)`,
//!   since z amplifies an error of `wo⊥` by `|wo⊥|/z`;
//! * densities (`pdf_disk`, `pdf(wo2)`, `pdf_disk(wo2)`, and the solid-angle `pdf`, `pdf(wo)`
//!   divided by their side's z, which removes the same conditioning):
//!   `|a − b| ≤ pdf_rel·max(|a|, |b|) + PDF_ABS` with `pdf_rel` 1e-4, `PDF_ABS` 1e-6;
//! * per side, `pdf(wo)` at the sample equals the sample's `pdf` ("self" column, reported).
//! * `invert(wo2)`: absolute `U_TOL` (1e-5) per component.
//!
//! Records outside these are accepted only in three documented situations:
//!
//! * **edge**: a sample within `EDGE_COS` of the horizon (the rim of the projected disk,
//!   reached by u = 0 or 1 and by far tails) on either side. There `wo.z = √(1 − |wo⊥|²)`
//!   is ill-conditioned and `from_disk` may refuse the point on one side only; `wo.xy` and
//!   `pdf_disk` are still compared when both sides sampled. Counted with them: a **fold** of
//!   the reparameterization warp (`Tol::fold_pdf`: both sides' sample density above 1e5,
//!   `det J` within ~1e-6 of 0), where `wo.xy` is compared and the density is not.
//! * **u-match** (samplers with `invert`): the GPU's sample is the CPU's sample map at a
//!   `u'` with `|u' − u| ≤ U_TOL` — the CPU's `invert(wo_gpu)` is within `U_TOL` of `u` and
//!   its density at `wo_gpu` equals the GPU's. Inverting a CDF in f32 amplifies last-ulp
//!   differences by the inverse of a cell's mass (histograms) or a spline's slope (flows),
//!   so the direction can move by more than `wo_abs` while the computation is right.
//! * **crossing** (at most `MAX_CROSSING_FRACTION` of the records): a discrete choice
//!   (mixture component, histogram cell, disk rim) taken differently because of a last-ulp
//!   difference. Accepted when the CPU reproduces the GPU's values (within the tolerances)
//!   for an input (u for sample values, wo2 for densities at wo2) moved by at most
//!   `CROSSING_DELTA`.
//!
//! # Neural material (`neural_features`, `neural_eval`; [`neural`])
//!
//! Run on the committed `fixtures/materials/neural/goat_leather_neural.nsb` (decoded on the
//! host into flat f32 texture and decoder buffers) and on a seeded random 13 × 7 material
//! whose decoder reaches the `ln f` clamps. Both functions are continuous away from the
//! horizon test (bilinear weights go to 0/1 where a texel index changes; ReLU and the clamp
//! are continuous), and the inputs keep clear of that test, so there is no edge / crossing
//! class: every record must match.
//!
//! * `features(uv)`: `|Δφ_k| ≤ FEAT_EPS·(16 + 2·max(W, H))·max|T|` (`FEAT_EPS` = f32 ε).
//!   φ is a convex combination of four texels computed by the same formula on both sides;
//!   the driver may fuse `a·b + c` into an FMA or reorder, which moves each side
//!   by ≤ ~4ε·max|T| (products and three sums, weights summing to 1), and the texel weight
//!   `w = x − ⌊x⌋`, `x = t'·n − 0.5`, by up to one ulp of `x` (≤ n·ε), which moves φ by
//!   ≤ n·ε·|T₁ − T₀| ≤ 2n·ε·max|T|. (For power-of-two n, `t'·n` is exact and the second
//!   term does not arise.) The report gives max |Δφ| / max|T|.
//! * `eval(φ, wi, wo)` and `eval(φ(uv), wi, wo)` (RGB, no cosine): refused (exactly
//!   `[0, 0, 0]`) on both sides or on neither, and per channel `|Δf| ≤ EVAL_REL·max(f_gpu,
//!   f_cpu)` with `EVAL_REL` 1e-4. The decoder's output is `ln f`, so a relative error of f
//!   is an absolute error of `ln f`: four dense layers (≤ 64-term f32 dot products, any
//!   order or fusion on the driver) plus `exp` give ~1e-6 on the committed material; 1e-4
//!   is the densities' tolerance and leaves room for the φ(uv) error propagated through
//!   `∂ ln f/∂φ`. Refused records must be exactly the documented edge positions (below /
//!   on the horizon, zero, non-finite or overflowing directions; non-finite φ for
//!   `eval(φ, …)` only), and no other record may be refused.
//!
//! # Measured material (`measured`; [`measured`])
//!
//! Run on the committed `fixtures/measured/chm_mint_rgb.bsdf` (read and checked on the host by
//! `neusample-owned`'s reader; its eleven tables bound as storage buffers), with
//! [`make_input`]'s records and wo2 next to the mirror direction on every fourth ordinary one.
//! Per record: `f(wi, wo2)` (RGB), `pdf(wo2)` and the sample's density and weight (RGB) within
//! `MS_REL` (1e-2) relative + `MS_ABS` (1e-6); the sampled `wo` within `MS_WO_ABS` (1e-3)
//! per component; the prepared and sampled flags identical. These are looser than the
//! samplers' because the data is steep: the driver's `atan2`, `sin` and `cos` (GLSL.std.450,
//! not libm's) and its fused multiply-adds move the half vector's table coordinates by a few
//! ulps, which a glossy material's tables turn into far larger relative changes of `f` and
//! the densities. Three situations are accepted and counted: **grazing** (`MS_GRAZING`: wi
//! or wo2 with cos θ < 0.05), where `f` or `pdf(wo2)` may be 0 on one side only; **edge**
//! (`MS_EDGE_Z`), a sample at the horizon that one side refuses; **corner**
//! (`MS_CORNER_REL`, 1e-1): where a component of u is 0 or 1 both warps start in a corner
//! cell and invert its CDF as `v0 − √(v0² + δ)` with a tiny δ (Mitsuba's arithmetic, kept
//! bit for bit on the CPU): the sample's position inside the cell, and with it the density
//! where a corner value is 0, is ill-conditioned there; `wo` is compared as everywhere.
//!
//! The measured material's angles are core's f32 polynomials (`math::poly`), the same
//! operations on the CPU and on SPIR-V: Mesa's own `Asin` is a coarse cubic above ½, which
//! the mint's tables amplify far beyond these tolerances (figures: `docs/measured/README.md`).

mod measured;
mod neural;
mod vk;

use std::time::Instant;

use neusample_gpu_shader::kernel::{self, Params, IN_STRIDE, OUT_STRIDE};
use neusample_gpu_shader::UVec3;
use neusample_gpu_shader::WORKGROUP_SIZE;

/// Largest allowed fraction of discontinuity crossings.
const MAX_CROSSING_FRACTION: f64 = 5e-3;
/// Input perturbations searched for a discontinuity crossing (largest = `CROSSING_DELTA`).
const CROSSING_STEPS: [f32; 7] = [1e-8, 3e-8, 1e-7, 3e-7, 1e-6, 3e-6, CROSSING_DELTA];
/// Largest input perturbation searched for a discontinuity crossing.
const CROSSING_DELTA: f32 = 1e-5;
/// `wo.z` below which a sample counts as at the disk edge.
const EDGE_COS: f32 = 1e-3;
/// Absolute part of the density tolerance.
const PDF_ABS: f32 = 1e-6;
/// Tolerance on `invert` results and on the u of a u-match.
const U_TOL: f32 = 1e-5;
/// Neural material: unit of the features' tolerance (`FEAT_EPS·(16 + 2·max(W, H))·max|T|`).
const FEAT_EPS: f32 = f32::EPSILON;
/// Neural material: relative tolerance per RGB channel of `eval`.
const EVAL_REL: f32 = 1e-4;
/// Neural material: gain of the random decoder's init (some outputs reach the `ln f` clamps).
const RANDOM_DECODER_GAIN: f32 = 4.0;
/// Measured material: relative tolerance of `f`, the densities and the sample's weight.
const MS_REL: f32 = 1e-2;
/// Measured material: absolute part of those tolerances.
const MS_ABS: f32 = 1e-6;
/// Measured material: tolerance of the sampled direction, per component.
const MS_WO_ABS: f32 = 1e-3;
/// Measured material: `cos θ` of wi or wo2 below which a zero on one side only is accepted.
const MS_GRAZING: f32 = 0.05;
/// Measured material: `wo.z` below which a sample may exist on one side only.
const MS_EDGE_Z: f32 = 2.0 * MS_WO_ABS;
/// Measured material: relative tolerance of the sample's density and weight where a
/// component of u is 0 or 1 (the corners of the square, where both warps invert a cell's
/// CDF by cancellation).
const MS_CORNER_REL: f32 = 1e-1;

/// Tolerances of one sampler.
#[derive(Copy, Clone, Debug)]
struct Tol {
    wo_abs: f32,
    pdf_rel: f32,
    /// Sample densities (`pdf_disk`, both sides) above which a record is a **fold** of the
    /// reparameterization warp: `q = N(z)/det J` with `det J`, a difference of products of
    /// O(1) Jacobian entries, within ~1e-6 of 0, so its f32 rounding (~1e-8 absolute) is
    /// ~1 % of it. The directions are compared there, the densities not. Infinite (no
    /// folds) for every other sampler.
    fold_pdf: f32,
}

/// A CPU evaluation of the entry point over all records of `input`.
type CpuFn<'a> = Box<dyn Fn(&[f32], &mut [f32]) + 'a>;

struct Case<'a> {
    label: &'static str,
    entry: &'static str,
    /// Extra buffers bound at 2, 3, …
    buffers: Vec<&'a [f32]>,
    params: Params,
    tol: Tol,
    cpu: CpuFn<'a>,
}

/// SplitMix64 → uniform f32 in [0, 1).
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
    /// A cosine-distributed direction with z ≥ `min_z`.
    fn hemisphere(&mut self, min_z: f32) -> [f32; 3] {
        loop {
            let x = self.range(-1.0, 1.0);
            let y = self.range(-1.0, 1.0);
            let r2 = x * x + y * y;
            if r2 < 1.0 {
                let z = (1.0 - r2).sqrt();
                if z >= min_z {
                    return [x, y, z];
                }
            }
        }
    }
}

/// Random parameters for an MLP with the given `(inputs, outputs)` layers, in core's layout
/// (input-major weights then bias), PyTorch's default init `U(±1/√inputs)`, times `gain`.
fn mlp_params(rng: &mut Rng, layers: &[(usize, usize)], gain: f32, out: &mut Vec<f32>) {
    for &(i, o) in layers {
        let a = gain / (i as f32).sqrt();
        for _ in 0..i * o + o {
            out.push(rng.range(-a, a));
        }
    }
}

/// Latent levels T of the test histogram mixture.
const HM_LEVELS: u32 = 8;
/// Cells per side N of the test histogram mixture.
const HM_CELLS: u32 = 32;

/// Baked histogram-mixture tables from random raw slices: per (basis, level) a sum of two
/// Gaussian bumps with random centres and widths plus a little noise, so the densities have
/// structure (and cell edges) everywhere, baked by core's own `bake_slices`.
fn histogram_tables(
    rng: &mut Rng,
    levels: u32,
    cells: u32,
) -> neusample::samplers::histogram_mixture::BakedTables {
    let (k, t, n) = (
        neusample::samplers::histogram_mixture::BASES,
        levels as usize,
        cells as usize,
    );
    let mut raw = Vec::with_capacity(k * t * n * n);
    for _ in 0..k * t {
        let mut bumps = [[0.0f32; 4]; 2];
        for b in &mut bumps {
            *b = [
                rng.range(-0.7, 0.7),
                rng.range(-0.7, 0.7),
                rng.range(0.05, 0.5),
                rng.range(0.2, 1.0),
            ];
        }
        for r in 0..n {
            for c in 0..n {
                let x = -1.0 + (c as f32 + 0.5) * 2.0 / n as f32;
                let y = -1.0 + (r as f32 + 0.5) * 2.0 / n as f32;
                let mut v = 0.02 * rng.f32();
                for b in &bumps {
                    let d2 = (x - b[0]).powi(2) + (y - b[1]).powi(2);
                    v += b[3] * (-0.5 * d2 / (b[2] * b[2])).exp();
                }
                raw.push(v);
            }
        }
    }
    neusample::samplers::histogram_mixture::bake_slices(&raw, k, t, n, neusample::DType::F32)
}

/// Input records: random conditions, u and second directions, with edge cases mixed in at
/// fixed positions (invalid wi, φ, u, wo2; u at 0 and 1; grazing wi).
fn make_input(n: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let mut v = vec![0.0f32; n * IN_STRIDE];
    for i in 0..n {
        let r = &mut v[i * IN_STRIDE..(i + 1) * IN_STRIDE];
        for v in &mut r[..8] {
            *v = rng.range(-1.5, 1.5);
        }
        let wi = rng.hemisphere(0.05);
        r[kernel::IN_WI..kernel::IN_WI + 3].copy_from_slice(&wi);
        r[kernel::IN_U] = rng.f32();
        r[kernel::IN_U + 1] = rng.f32();
        let wo2 = rng.hemisphere(0.0);
        r[kernel::IN_WO2..kernel::IN_WO2 + 3].copy_from_slice(&wo2);
        match i % 64 {
            1 => r[kernel::IN_WI + 2] = -0.3, // wi below the horizon
            2 => r[kernel::IN_WI + 2] = 1e-3, // grazing wi (renormalised)
            3 => r[3] = f32::INFINITY,        // bad φ
            4 => r[kernel::IN_U] = f32::NAN,  // bad u
            5 => r[kernel::IN_U + 1] = 1.5,   // u out of range
            6 => {
                r[kernel::IN_U] = 1.0; // u = 1 (clamped)
                r[kernel::IN_U + 1] = 1.0;
            }
            7 => {
                r[kernel::IN_U] = 0.0; // u = 0
                r[kernel::IN_U + 1] = 0.0;
            }
            8 => r[kernel::IN_WO2 + 2] = -0.5, // wo2 below the horizon
            9 => r[kernel::IN_WO2] = f32::NAN, // bad wo2
            10 => r[kernel::IN_WI..kernel::IN_WI + 3].copy_from_slice(&[0.0, 0.0, 2.0]),
            _ => {}
        }
    }
    v
}

/// Relative difference for the report, with a floor of 1e-3 on the scale (tiny densities
/// are judged by `PDF_ABS`).
fn rel_diff(a: f32, b: f32) -> f32 {
    let d = (a - b).abs();
    if d == 0.0 {
        return 0.0;
    }
    d / a.abs().max(b.abs()).max(1e-3)
}

fn pdf_close(a: f32, b: f32, tol: Tol) -> bool {
    (a - b).abs() <= tol.pdf_rel * a.abs().max(b.abs()) + PDF_ABS
}

fn flags(r: &[f32]) -> u32 {
    r[5] as u32
}

#[derive(Default, Debug)]
struct Stats {
    prepared: usize,
    sampled: usize,
    inverted: usize,
    max_wo_abs: f32,
    max_pdf_rel: f32,
    max_wo2_rel: f32,
    max_inv_abs: f32,
    /// max over both sides of |pdf(wo) − sample pdf| (relative), internal consistency.
    max_self_rel: f32,
    edge: usize,
    umatch: usize,
    crossings: usize,
    failures: usize,
}

/// Runs the CPU entry point on a single record.
fn cpu_one(cpu: &CpuFn, rec: &[f32]) -> [f32; OUT_STRIDE] {
    let mut out = [0.0f32; OUT_STRIDE];
    cpu(rec, &mut out);
    out
}

/// The sample part of two records agrees: the sampled bit, `wo⊥ = wo.xy` within `wo_abs`,
/// `wo.z` within `wo_abs·(1 + 1.5/z)` (z = √(1 − |wo⊥|²) amplifies an error of `wo⊥` by
/// |wo⊥|/z), `pdf_disk`, and the solid-angle densities `pdf` and `pdf(wo)` divided by each
/// side's own z (the same conditioning; `pdf = pdf_disk·z` is checked per side by "self").
fn sample_close(g: &[f32], c: &[f32], tol: Tol) -> bool {
    let gs = flags(g) & kernel::FLAG_SAMPLED;
    if gs != flags(c) & kernel::FLAG_SAMPLED {
        return false;
    }
    if gs == 0 {
        return true;
    }
    let z = g[2].min(c[2]).max(1e-6);
    (g[0] - c[0]).abs() <= tol.wo_abs
        && (g[1] - c[1]).abs() <= tol.wo_abs
        && (g[2] - c[2]).abs() <= tol.wo_abs * (1.0 + 1.5 / z)
        && pdf_close(g[4], c[4], tol)
        && pdf_close(g[3] / g[2], c[3] / c[2], tol)
        && pdf_close(g[7] / g[2], c[7] / c[2], tol)
}

/// The wo2 part of two records agrees: pdf(wo2), pdf_disk(wo2), invert(wo2).
fn wo2_close(g: &[f32], c: &[f32], tol: Tol) -> bool {
    let inv = kernel::FLAG_INVERTED;
    (flags(g) & inv) == (flags(c) & inv)
        && pdf_close(g[6], c[6], tol)
        && pdf_close(g[10], c[10], tol)
        && (flags(g) & inv == 0 || ((g[8] - c[8]).abs() <= U_TOL && (g[9] - c[9]).abs() <= U_TOL))
}

/// Does the CPU reproduce the GPU record `g` (its sample part, or its wo2 part) for an input
/// moved by at most `CROSSING_DELTA` (u, or wo2's x and y)?
fn crossing(cpu: &CpuFn, rec: &[f32], g: &[f32], tol: Tol, sample_part: bool) -> bool {
    let (a, b) = if sample_part {
        (kernel::IN_U, kernel::IN_U + 1)
    } else {
        (kernel::IN_WO2, kernel::IN_WO2 + 1)
    };
    for &d in &CROSSING_STEPS {
        for (dx, dy) in [
            (-1.0f32, -1.0f32),
            (-1.0, 0.0),
            (-1.0, 1.0),
            (0.0, -1.0),
            (0.0, 1.0),
            (1.0, -1.0),
            (1.0, 0.0),
            (1.0, 1.0),
        ] {
            let mut r = rec.to_vec();
            r[a] += dx * d;
            r[b] += dy * d;
            let c = cpu_one(cpu, &r);
            let ok = if sample_part {
                sample_close(g, &c, tol)
            } else {
                wo2_close(g, &c, tol)
            };
            if ok {
                return true;
            }
        }
    }
    false
}

/// Is the GPU's sample the CPU's sample map at a `u'` with `|u' − u| ≤ U_TOL`?
///
/// Tried two ways: the CPU's `invert(wo_gpu)` (samplers with a unique inverse), then two
/// Newton steps on `u` with a finite-difference Jacobian of the CPU's sample map (any
/// sampler, within one mixture component / cell). Either way the CPU's values at `u'` must
/// match the GPU's within the tolerances.
fn u_match(cpu: &CpuFn, rec: &[f32], g: &[f32], tol: Tol) -> bool {
    if flags(g) & kernel::FLAG_SAMPLED == 0 || !pdf_close(g[3], g[7], tol) {
        return false;
    }
    let u = [
        rec[kernel::IN_U].min(1.0 - f32::EPSILON / 2.0),
        rec[kernel::IN_U + 1].min(1.0 - f32::EPSILON / 2.0),
    ];
    // 1. Through the CPU's inverse.
    let mut r = rec.to_vec();
    r[kernel::IN_WO2..kernel::IN_WO2 + 3].copy_from_slice(&g[0..3]);
    let c = cpu_one(cpu, &r);
    if flags(&c) & kernel::FLAG_INVERTED != 0
        && (c[8] - u[0]).abs() <= U_TOL
        && (c[9] - u[1]).abs() <= U_TOL
        && pdf_close(c[6], g[7], tol)
    {
        return true;
    }
    // 2. Newton on the CPU's sample map.
    let at = |uu: [f32; 2]| {
        let mut r = rec.to_vec();
        r[kernel::IN_U] = uu[0];
        r[kernel::IN_U + 1] = uu[1];
        cpu_one(cpu, &r)
    };
    let mut uu = u;
    for _ in 0..3 {
        let c0 = at(uu);
        if flags(&c0) & kernel::FLAG_SAMPLED == 0 {
            return false;
        }
        if (uu[0] - u[0]).abs() <= U_TOL
            && (uu[1] - u[1]).abs() <= U_TOL
            && sample_close(g, &c0, tol)
        {
            return true;
        }
        let h = 1e-5f32;
        let cx = at([uu[0] - h, uu[1]]);
        let cy = at([uu[0], uu[1] - h]);
        if flags(&cx) & flags(&cy) & kernel::FLAG_SAMPLED == 0 {
            return false;
        }
        let (a, b) = ((c0[0] - cx[0]) / h, (c0[0] - cy[0]) / h);
        let (cc, d) = ((c0[1] - cx[1]) / h, (c0[1] - cy[1]) / h);
        let det = a * d - b * cc;
        if det.abs().partial_cmp(&1e-12) != Some(std::cmp::Ordering::Greater) {
            return false;
        }
        let (ex, ey) = (g[0] - c0[0], g[1] - c0[1]);
        uu[0] += (d * ex - b * ey) / det;
        uu[1] += (-cc * ex + a * ey) / det;
        if !((uu[0] - u[0]).abs() <= 2.0 * U_TOL && (uu[1] - u[1]).abs() <= 2.0 * U_TOL) {
            return false;
        }
    }
    false
}

fn compare(case: &Case, input: &[f32], gpu: &[f32], cpu_out: &[f32], verbose: bool) -> Stats {
    let n = input.len() / IN_STRIDE;
    let tol = case.tol;
    let mut s = Stats::default();
    let mut shown = 0;
    for i in 0..n {
        let rec = &input[i * IN_STRIDE..(i + 1) * IN_STRIDE];
        let g = &gpu[i * OUT_STRIDE..(i + 1) * OUT_STRIDE];
        let c = &cpu_out[i * OUT_STRIDE..(i + 1) * OUT_STRIDE];
        let (gf, cf) = (flags(g), flags(c));
        if cf & kernel::FLAG_PREPARED != 0 {
            s.prepared += 1;
        }
        if cf & kernel::FLAG_SAMPLED != 0 {
            s.sampled += 1;
        }
        if cf & kernel::FLAG_INVERTED != 0 {
            s.inverted += 1;
        }
        // 0 ok, 1 edge, 2 u-match, 3 crossing, 4 bad
        let mut class = 0;
        if (gf ^ cf) & kernel::FLAG_PREPARED != 0 {
            class = 4;
        } else if cf & kernel::FLAG_PREPARED != 0 {
            // The sample part.
            let gs = gf & kernel::FLAG_SAMPLED != 0;
            let cs = cf & kernel::FLAG_SAMPLED != 0;
            let edge = (gs && g[2] < EDGE_COS) || (cs && c[2] < EDGE_COS);
            if gs && cs {
                s.max_self_rel = s
                    .max_self_rel
                    .max(rel_diff(g[3], g[7]))
                    .max(rel_diff(c[3], c[7]));
            }
            if edge {
                let xy_ok = !(gs && cs)
                    || ((g[0] - c[0]).abs() <= tol.wo_abs
                        && (g[1] - c[1]).abs() <= tol.wo_abs
                        && pdf_close(g[4], c[4], tol));
                class = if xy_ok || crossing(&case.cpu, rec, g, tol, true) {
                    1
                } else {
                    4
                };
            } else if gs
                && cs
                && g[4] > tol.fold_pdf
                && c[4] > tol.fold_pdf
                && (g[0] - c[0]).abs() <= tol.wo_abs
                && (g[1] - c[1]).abs() <= tol.wo_abs
            {
                class = 1;
            } else if sample_close(g, c, tol) {
                if gs {
                    let wo = (g[0] - c[0]).abs().max((g[1] - c[1]).abs());
                    s.max_wo_abs = s.max_wo_abs.max(wo);
                    s.max_pdf_rel = s
                        .max_pdf_rel
                        .max(rel_diff(g[4], c[4]))
                        .max(rel_diff(g[3] / g[2], c[3] / c[2]))
                        .max(rel_diff(g[7] / g[2], c[7] / c[2]));
                    s.max_self_rel = s.max_self_rel.max(rel_diff(g[3], g[4] * g[2]));
                }
            } else if u_match(&case.cpu, rec, g, tol) {
                class = 2;
            } else if crossing(&case.cpu, rec, g, tol, true) {
                class = 3;
            } else {
                class = 4;
            }
            // The wo2 part.
            if wo2_close(g, c, tol) {
                s.max_wo2_rel = s
                    .max_wo2_rel
                    .max(rel_diff(g[6], c[6]))
                    .max(rel_diff(g[10], c[10]));
                if gf & kernel::FLAG_INVERTED != 0 {
                    s.max_inv_abs = s
                        .max_inv_abs
                        .max((g[8] - c[8]).abs())
                        .max((g[9] - c[9]).abs());
                }
            } else if crossing(&case.cpu, rec, g, tol, false) {
                class = class.max(3);
            } else {
                class = 4;
            }
        }
        match class {
            1 => s.edge += 1,
            2 => s.umatch += 1,
            3 => s.crossings += 1,
            4 => s.failures += 1,
            _ => {}
        }
        if (class == 4 || (class > 0 && verbose)) && shown < 8 {
            shown += 1;
            eprintln!(
                "  {} record {i}: {}\n    input {:?}\n    gpu {:?}\n    cpu {:?}",
                case.label,
                ["ok", "edge", "u-match", "crossing", "MISMATCH"][class],
                rec,
                g,
                c
            );
        }
    }
    s
}

/// The push-constant bytes of `p` (`Params` is `#[repr(C)]`, all `u32`).
fn push_bytes(p: &Params) -> Vec<u8> {
    let mut push = Vec::new();
    for v in [
        p.n,
        p.levels,
        p.cells,
        p.interpolate,
        p.width,
        p.height,
        p.n_phi,
        p.n_theta,
        p.ndf_w,
        p.ndf_h,
        p.sigma_w,
        p.sigma_h,
        p.vndf_w,
        p.vndf_h,
        p.rgb_w,
        p.rgb_h,
        p.jacobian,
    ] {
        push.extend_from_slice(&v.to_le_bytes());
    }
    assert_eq!(push.len(), std::mem::size_of::<Params>());
    push
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let Some(spv_path) = args.get(1) else {
        eprintln!("usage: neusample-gpu-runner <module.spv> [records]");
        std::process::exit(2);
    };
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1 << 14);
    let verbose = std::env::var_os("NEUSAMPLE_GPU_VERBOSE").is_some();
    let spv = match std::fs::read(spv_path) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("reading {spv_path}: {e}");
            std::process::exit(2);
        }
    };
    let t = Instant::now();
    let ctx = match vk::Context::new(&spv, true) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("Vulkan unusable: {e}");
            std::process::exit(2);
        }
    };
    println!(
        "device: {} (init {:.0} ms); module {} bytes; {n} records per sampler",
        ctx.device_name,
        t.elapsed().as_secs_f64() * 1e3,
        spv.len()
    );

    // Weights: fixed seeds, shared by the GPU buffers and the CPU reference.
    let mut rng = Rng(0x5eed_0001);
    let mut flow_w = Vec::new();
    mlp_params(&mut rng, &[(30, 32), (32, 4)], 1.0, &mut flow_w);
    for _ in 0..2 {
        mlp_params(&mut rng, &[(39, 32), (32, 32), (32, 59)], 1.0, &mut flow_w);
    }
    assert_eq!(flow_w.len(), neusample::samplers::SplineFlowSampler::<&[f32]>::PARAM_COUNT);
    let mut affine_w = Vec::new();
    for _ in 0..4 {
        mlp_params(&mut rng, &[(39, 32), (32, 32), (32, 2)], 1.0, &mut affine_w);
    }
    assert_eq!(
        affine_w.len(),
        neusample::samplers::AffineFlowSampler::<&[f32]>::PARAM_COUNT
    );

    let mut baseline_w = Vec::new();
    mlp_params(
        &mut rng,
        &[(30, 32), (32, 32), (32, 32), (32, 5)],
        1.0,
        &mut baseline_w,
    );
    assert_eq!(
        baseline_w.len(),
        neusample::samplers::ImprovedBaselineSampler::<&[f32]>::PARAM_COUNT
    );
    let mut analytic_w = Vec::new();
    mlp_params(&mut rng, &[(30, 32), (32, 11)], 1.0, &mut analytic_w);
    assert_eq!(
        analytic_w.len(),
        neusample::samplers::AnalyticMixtureSampler::<&[f32]>::PARAM_COUNT
    );
    let mut direct_w = Vec::new();
    mlp_params(
        &mut rng,
        &[(30, 64), (64, 64), (64, 256)],
        1.0,
        &mut direct_w,
    );
    assert_eq!(
        direct_w.len(),
        neusample::samplers::DirectHistogramSampler::<&[f32]>::PARAM_COUNT
    );
    let mut hm_w = Vec::new();
    mlp_params(
        &mut rng,
        &[(10, 32), (32, 32), (32, 32), (32, 40)],
        1.0,
        &mut hm_w,
    );
    assert_eq!(
        hm_w.len(),
        neusample::samplers::HistogramMixtureSampler::<&[f32]>::PARAM_COUNT
    );
    let (levels, cells) = (HM_LEVELS, HM_CELLS);
    let tables = histogram_tables(&mut rng, levels, cells);
    tables.validate().expect("baked tables are valid");
    // Drawn after every earlier case's inputs, so that those keep theirs.
    let mut reparam_w = Vec::new();
    mlp_params(
        &mut rng,
        &[(32, 16), (16, 16), (16, 3), (32, 16), (16, 1)],
        1.0,
        &mut reparam_w,
    );
    assert_eq!(
        reparam_w.len(),
        neusample::samplers::ReparamSampler::<&[f32]>::PARAM_COUNT
    );
    // Drawn last, for the same reason.
    let mut disk_w = Vec::new();
    for _ in 0..2 {
        mlp_params(&mut rng, &[(39, 32), (32, 32), (32, 61)], 1.0, &mut disk_w);
    }
    assert_eq!(
        disk_w.len(),
        neusample::samplers::DiskFlowSampler::<&[f32]>::PARAM_COUNT
    );

    let p = |n: usize| Params {
        n: n as u32,
        ..Params::default()
    };
    let tight = Tol {
        wo_abs: 1e-5,
        pdf_rel: 1e-4,
        fold_pdf: f32::INFINITY,
    };
    // The spline flow's density is exp of a sum of ~10 logs through two coupling networks;
    // its GPU/CPU differences reach ~1e-4 relative.
    let flow_tol = Tol {
        wo_abs: 1e-5,
        pdf_rel: 5e-4,
        fold_pdf: f32::INFINITY,
    };
    // The reparameterization warp: the flow's tolerances away from its folds.
    let reparam_tol = Tol {
        fold_pdf: 1e5,
        ..flow_tol
    };

    /// A CPU closure calling the host build of an entry point over every record.
    macro_rules! cpu {
        ($entry:path $(, $buf:expr)*) => {
            Box::new(move |input: &[f32], output: &mut [f32]| {
                let n = input.len() / IN_STRIDE;
                let params = Params { n: n as u32, ..Params::default() };
                for i in 0..n {
                    $entry(UVec3::new(i as u32, 0, 0), &params, input, output $(, $buf)*);
                }
            }) as CpuFn
        };
    }

    let fw: &[f32] = &flow_w;
    let aw: &[f32] = &affine_w;
    let bw: &[f32] = &baseline_w;
    let anw: &[f32] = &analytic_w;
    let dw: &[f32] = &direct_w;
    let hw: &[f32] = &hm_w;
    let rw: &[f32] = &reparam_w;
    let dfw: &[f32] = &disk_w;
    let (tm, tt, tmg, tc): (&[f32], &[f32], &[f32], &[f32]) = (
        &tables.mass,
        &tables.table,
        &tables.marginal,
        &tables.conditional,
    );
    let hm_cpu = |interpolate: u32| -> CpuFn {
        Box::new(move |input: &[f32], output: &mut [f32]| {
            let n = input.len() / IN_STRIDE;
            let params = Params {
                n: n as u32,
                levels,
                cells,
                interpolate,
                ..Params::default()
            };
            for i in 0..n {
                neusample_gpu_shader::histogram_mixture(
                    UVec3::new(i as u32, 0, 0),
                    &params,
                    input,
                    output,
                    hw,
                    tm,
                    tt,
                    tmg,
                    tc,
                );
            }
        })
    };
    let hm_params = |interpolate: u32| Params {
        n: n as u32,
        levels,
        cells,
        interpolate,
        ..Params::default()
    };
    let cases = [
        Case {
            label: "cosine",
            entry: "cosine",
            buffers: vec![],
            params: p(n),
            tol: tight,
            cpu: cpu!(neusample_gpu_shader::cosine),
        },
        Case {
            label: "baseline",
            entry: "baseline",
            buffers: vec![bw],
            params: p(n),
            tol: tight,
            cpu: cpu!(neusample_gpu_shader::baseline, bw),
        },
        Case {
            label: "analytic",
            entry: "analytic",
            buffers: vec![anw],
            params: p(n),
            tol: tight,
            cpu: cpu!(neusample_gpu_shader::analytic, anw),
        },
        Case {
            label: "flow",
            entry: "flow",
            buffers: vec![fw],
            params: p(n),
            tol: flow_tol,
            cpu: cpu!(neusample_gpu_shader::flow, fw),
        },
        Case {
            label: "affine_flow",
            entry: "affine_flow",
            buffers: vec![aw],
            params: p(n),
            tol: tight,
            cpu: cpu!(neusample_gpu_shader::affine_flow, aw),
        },
        Case {
            label: "direct_histogram",
            entry: "direct_histogram",
            buffers: vec![dw],
            params: p(n),
            tol: tight,
            cpu: cpu!(neusample_gpu_shader::direct_histogram, dw),
        },
        Case {
            label: "hist_mix_nearest",
            entry: "histogram_mixture",
            buffers: vec![hw, tm, tt, tmg, tc],
            params: hm_params(0),
            tol: tight,
            cpu: hm_cpu(0),
        },
        Case {
            label: "hist_mix_linear",
            entry: "histogram_mixture",
            buffers: vec![hw, tm, tt, tmg, tc],
            params: hm_params(1),
            tol: tight,
            cpu: hm_cpu(1),
        },
        // Last, so that the cases before it keep their inputs (seeded by position).
        Case {
            label: "defensive_flow",
            entry: "defensive_flow",
            buffers: vec![fw],
            params: p(n),
            tol: flow_tol,
            cpu: cpu!(neusample_gpu_shader::defensive_flow, fw),
        },
        // After the cases above, for the same reason. The warp's density runs through a
        // Jacobian of three layers (tolerance as the flow's, folds aside).
        Case {
            label: "reparam",
            entry: "reparam",
            buffers: vec![rw],
            params: p(n),
            tol: reparam_tol,
            cpu: cpu!(neusample_gpu_shader::reparam, rw),
        },
        Case {
            label: "defensive_reparam",
            entry: "defensive_reparam",
            buffers: vec![rw],
            params: p(n),
            tol: reparam_tol,
            cpu: cpu!(neusample_gpu_shader::defensive_reparam, rw),
        },
        // Last, for the same reason; the flow's tolerances (the same couplings).
        Case {
            label: "disk_flow",
            entry: "disk_flow",
            buffers: vec![dfw],
            params: p(n),
            tol: flow_tol,
            cpu: cpu!(neusample_gpu_shader::disk_flow, dfw),
        },
    ];

    // Debugging aid: `NEUSAMPLE_GPU_SMOKE=<entry>` only creates and dispatches that entry
    // point with the flow weights at binding 2 and prints the first output record.
    if let Ok(entry) = std::env::var("NEUSAMPLE_GPU_SMOKE") {
        let input = make_input(n, 1);
        let out = vec![0.0f32; n * OUT_STRIDE];
        let push = push_bytes(&p(n));
        let bufs: Vec<&[f32]> = vec![&input, &out, fw];
        let groups = (n as u32).div_ceil(WORKGROUP_SIZE);
        match ctx.dispatch(&entry, &bufs, 1, n * OUT_STRIDE, &push, groups) {
            Ok(d) => println!("{entry}: ok, first record {:?}", &d.output[..OUT_STRIDE]),
            Err(e) => println!("{entry}: {e}"),
        }
        return;
    }

    let only: Option<Vec<String>> = std::env::var("NEUSAMPLE_GPU_ONLY")
        .ok()
        .map(|s| s.split(',').map(str::to_string).collect());
    let mut failed: Vec<String> = Vec::new();
    println!(
        "{:<17} {:>5} {:>5} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>5} {:>5} {:>5} {:>4} {:>7} {:>7} {:>7} {:>7} {:>7}",
        "sampler", "prep", "sampl", "inv", "wo abs", "pdf rel", "wo2 rel", "inv abs", "self rel",
        "edge", "u-mat", "cross", "bad", "cpu ms", "cmp ms", "gpu1 ms", "gpu2 ms", "pipe ms"
    );
    for (ci, case) in cases.iter().enumerate() {
        if let Some(only) = &only {
            if !only.iter().any(|o| o == case.label) {
                continue;
            }
        }
        let input = make_input(n, 0x1234_5678 + ci as u64);
        let mut bufs: Vec<&[f32]> = vec![&input, &[]];
        let out_init = vec![0.0f32; n * OUT_STRIDE];
        bufs[1] = &out_init;
        bufs.extend(case.buffers.iter().copied());
        let push = push_bytes(&case.params);
        let groups = (n as u32).div_ceil(WORKGROUP_SIZE);
        let d = match ctx.dispatch(case.entry, &bufs, 1, n * OUT_STRIDE, &push, groups) {
            Ok(d) => d,
            Err(e) => {
                println!("{:<20} DISPATCH FAILED: {e}", case.label);
                failed.push(case.label.to_string());
                continue;
            }
        };
        let t = Instant::now();
        let mut cpu_out = vec![0.0f32; n * OUT_STRIDE];
        (case.cpu)(&input, &mut cpu_out);
        let cpu_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let s = compare(case, &input, &d.output, &cpu_out, verbose);
        let compare_ms = t.elapsed().as_secs_f64() * 1e3;
        println!(
            "{:<17} {:>5} {:>5} {:>5} {:>8.1e} {:>8.1e} {:>8.1e} {:>8.1e} {:>8.1e} {:>5} {:>5} {:>5} {:>4} {:>7.1} {:>7.1} {:>7.1} {:>7.1} {:>7.1}",
            case.label,
            s.prepared,
            s.sampled,
            s.inverted,
            s.max_wo_abs,
            s.max_pdf_rel,
            s.max_wo2_rel,
            s.max_inv_abs,
            s.max_self_rel,
            s.edge,
            s.umatch,
            s.crossings,
            s.failures,
            cpu_ms,
            compare_ms,
            d.first.as_secs_f64() * 1e3,
            d.second.as_secs_f64() * 1e3,
            d.compile.as_secs_f64() * 1e3,
        );
        let too_many_crossings = s.crossings as f64 > MAX_CROSSING_FRACTION * n as f64;
        if s.failures > 0 || too_many_crossings || s.sampled == 0 {
            failed.push(case.label.to_string());
        }
    }
    // The neural material: the committed goat leather and a seeded random one.
    let material_path = std::env::var("NEUSAMPLE_GPU_MATERIAL").unwrap_or_else(|_| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../../fixtures/materials/neural/goat_leather_neural.nsb"
        )
        .to_string()
    });
    let wanted = |label: &str| only.as_ref().is_none_or(|o| o.iter().any(|x| x == label));
    let mut materials = Vec::new();
    if wanted("goat_leather") {
        match neural::Material::from_blob("goat_leather", &material_path) {
            Ok(m) => materials.push(m),
            Err(e) => {
                println!("goat_leather: cannot load the committed material: {e}");
                failed.push("goat_leather".to_string());
            }
        }
    }
    if wanted("random_material") {
        materials.push(neural::Material::random(
            "random_material",
            0x5eed_0002,
            13,
            7,
            RANDOM_DECODER_GAIN,
        ));
    }
    let mut failed_neural = Vec::new();
    for m in &materials {
        m.describe();
    }
    if !materials.is_empty() {
        neural::header();
    }
    for (mi, m) in materials.iter().enumerate() {
        failed_neural.extend(neural::run(&ctx, m, n, 0x9abc_def0 + mi as u64, verbose));
    }
    failed.extend(failed_neural);

    // The measured material: a committed RGL file's tables.
    if wanted("measured") {
        let path = std::env::var("NEUSAMPLE_GPU_MEASURED").unwrap_or_else(|_| {
            concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../../fixtures/measured/chm_mint_rgb.bsdf"
            )
            .to_string()
        });
        match measured::Material::open(&path) {
            Ok(m) => {
                m.describe();
                measured::header();
                failed.extend(measured::run(&ctx, &m, n, 0x3ea5_0001, verbose));
            }
            Err(e) => {
                println!("measured: cannot load {e}");
                failed.push("measured".to_string());
            }
        }
    }

    println!(
        "tolerances: wo ±{:.0e} abs, densities {:.0e} rel (flow 5e-4) + {PDF_ABS:.0e} abs, invert ±{U_TOL:.0e}; \
         edge = sample within {EDGE_COS:.0e} of the horizon; u-match = GPU sample is the CPU's at \
         |u' − u| ≤ {U_TOL:.0e}; crossings ≤ {:.1}% of records (input moved ≤ {CROSSING_DELTA:.0e})",
        tight.wo_abs,
        tight.pdf_rel,
        MAX_CROSSING_FRACTION * 100.0
    );
    println!(
        "neural material: φ ±{FEAT_EPS:.1e}·(16 + 2·max(W, H))·max|T| abs; eval {EVAL_REL:.0e} rel per \
         channel, refusals identical and only at the documented edge cases"
    );
    println!(
        "measured material: f, densities, weight {MS_REL:.0e} rel + {MS_ABS:.0e} abs \
         ({MS_CORNER_REL:.0e} where u is at a corner of the square); sampled wo ±{MS_WO_ABS:.0e}; \
         a zero on one side only where wi or wo2 has cos θ < {MS_GRAZING}; sampled on one side \
         only where wo.z < {MS_EDGE_Z:.0e}"
    );
    if failed.is_empty() {
        println!(
            "GPU CHECK PASSED: every sampler, the neural material and the measured material match the CPU"
        );
    } else {
        println!("GPU CHECK FAILED: {}", failed.join(", "));
        std::process::exit(1);
    }
}
