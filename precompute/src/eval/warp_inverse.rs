//! The reparameterization sampler's exact sampling density anywhere on the disk, by inverting
//! its warp: `q(x) = Σ N(z)/det ∂T/∂z` over the latent points `z` with `T(z) = x` and
//! `det > 0` (the runtime rejects samples where `det ≤ 0`). The runtime only knows `q` at its
//! own samples and reports a pdf network `p̂` for MIS; with `q` at any point the study can
//! measure what the samples never show: the integrand's mass where the warp puts no density
//! (a bias), the second moment there, and `p̂`'s true mismatch to `q`.
//!
//! [`WarpInverse::new`] evaluates the warp on a grid of `z` cells covering the standard normal
//! out to [`Z_EXTENT`] and files each cell under the disk bins its image's bounding box
//! touches; [`WarpInverse::density`] runs Newton's method from the centre of every cell whose
//! (padded) box holds the query and sums the distinct roots. A root outside every candidate
//! cell's neighbourhood is missed, so the inverse can only under-count; the tests compare
//! `∫ q` and per-bin masses with the sampler's own samples.

use std::time::Instant;

use anyhow::{bail, ensure, Context, Result};
use glam::Vec3;
use neusample::nn::encode_condition;
use neusample::{Blob, Prepared, Sampler, SamplerKind, TensorRole, FEATURE_DIM};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::defend::ALPHA_GRID;
use crate::groundtruth;
use crate::materials::Material;
use crate::train::reparam::{jacobian_det, warp_jacobian_f64};

/// Half-width of the latent square the grid covers (the normal's mass outside it is below
/// 3·10⁻⁶).
pub const Z_EXTENT: f64 = 4.75;
/// Default cells per side of the latent grid.
pub const DEFAULT_Z_CELLS: usize = 128;
/// Disk bins per side of the lookup grid.
const BINS: usize = 96;
/// Newton iterations at most, and the residual below which a root is accepted.
const NEWTON_ITERATIONS: usize = 24;
const NEWTON_TOLERANCE: f64 = 1e-11;
/// Two roots closer than this in `z` are one.
const SAME_ROOT: f64 = 1e-7;
/// A cell's image box is padded by this fraction of its size on every side (the image of a
/// cell is curved; its corners' box can miss a sliver).
const BOX_PAD: f64 = 0.25;

/// The lookup bin of a disk coordinate in `[−1, 1]` (clamped to the grid).
fn disk_bin(v: f64) -> usize {
    (((v + 1.0) * 0.5 * BINS as f64).floor().max(0.0) as usize).min(BINS - 1)
}

/// The standard normal density at `z`.
fn standard_normal(z: [f64; 2]) -> f64 {
    (-0.5 * (z[0] * z[0] + z[1] * z[1])).exp() / std::f64::consts::TAU
}

/// A reparameterization blob's parameter tensor, widened to f32.
fn reparam_params(blob: &Blob<'_>) -> Result<Vec<f32>> {
    let n = blob
        .entry(TensorRole::Params)
        .context("the blob has no parameters")?
        .count as usize;
    let mut params = vec![0.0f32; n];
    blob.widen_into(TensorRole::Params, &mut params)?;
    Ok(params)
}

/// One condition's warp, inverted on demand.
pub struct WarpInverse<'a> {
    params: &'a [f32],
    cond: Vec<f64>,
    cells: usize,
    h: f64,
    /// Per disk bin, the latent cells whose padded image box touches it.
    bins: Vec<Vec<u32>>,
    /// Per latent cell, its padded image box `(min x, min y, max x, max y)`.
    boxes: Vec<[f64; 4]>,
}

/// What [`WarpInverse::density`] found at one point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inverted {
    /// `q(x)` on the projected disk (area measure), from the roots with `det > 0`.
    pub density: f64,
    /// Distinct roots found (all signs of `det`).
    pub roots: usize,
    /// Roots with `det ≤ 0` (folds: samples there are rejected).
    pub folded_roots: usize,
    /// Warp evaluations spent.
    pub evaluations: usize,
}

impl<'a> WarpInverse<'a> {
    /// The inverse of the warp of reparameterization parameters `params` (the blob's
    /// tensor) at condition `(phi, wi)` (`wi` normalised), on `cells²` latent cells.
    #[must_use]
    pub fn new(params: &'a [f32], phi: &[f32; FEATURE_DIM], wi: Vec3, cells: usize) -> Self {
        let cond: Vec<f64> = encode_condition(phi, wi)
            .iter()
            .map(|&v| f64::from(v))
            .collect();
        let cells = cells.max(1);
        let h = 2.0 * Z_EXTENT / cells as f64;
        let corners: Vec<[f64; 2]> = (0..=cells)
            .flat_map(|r| (0..=cells).map(move |c| (r, c)))
            .map(|(r, c)| {
                let z = [-Z_EXTENT + c as f64 * h, -Z_EXTENT + r as f64 * h];
                warp_jacobian_f64(params, &cond, z).0
            })
            .collect();
        let mut bins = vec![Vec::new(); BINS * BINS];
        let mut boxes = Vec::with_capacity(cells * cells);
        for r in 0..cells {
            for c in 0..cells {
                let k = [
                    corners[r * (cells + 1) + c],
                    corners[r * (cells + 1) + c + 1],
                    corners[(r + 1) * (cells + 1) + c],
                    corners[(r + 1) * (cells + 1) + c + 1],
                ];
                let mut b = [
                    f64::INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::NEG_INFINITY,
                ];
                for p in k {
                    b = [
                        b[0].min(p[0]),
                        b[1].min(p[1]),
                        b[2].max(p[0]),
                        b[3].max(p[1]),
                    ];
                }
                let pad = BOX_PAD * (b[2] - b[0]).max(b[3] - b[1]) + 1e-9;
                let b = [b[0] - pad, b[1] - pad, b[2] + pad, b[3] + pad];
                let id = (r * cells + c) as u32;
                if b.iter().all(|v| v.is_finite()) {
                    for by in disk_bin(b[1])..=disk_bin(b[3]) {
                        for bx in disk_bin(b[0])..=disk_bin(b[2]) {
                            bins[by * BINS + bx].push(id);
                        }
                    }
                }
                boxes.push(b);
            }
        }
        WarpInverse {
            params,
            cond,
            cells,
            h,
            bins,
            boxes,
        }
    }

    /// `q(x)` and how it was found (module docs); `x` on the projected disk.
    #[must_use]
    pub fn density(&self, x: [f64; 2]) -> Inverted {
        let mut out = Inverted::default();
        if !(x[0] * x[0] + x[1] * x[1] < 1.0) {
            return out;
        }
        let mut roots: Vec<[f64; 2]> = Vec::new();
        for &id in &self.bins[disk_bin(x[1]) * BINS + disk_bin(x[0])] {
            let b = self.boxes[id as usize];
            if !(x[0] >= b[0] && x[0] <= b[2] && x[1] >= b[1] && x[1] <= b[3]) {
                continue;
            }
            let (r, c) = (id as usize / self.cells, id as usize % self.cells);
            let mut z = [
                -Z_EXTENT + (c as f64 + 0.5) * self.h,
                -Z_EXTENT + (r as f64 + 0.5) * self.h,
            ];
            for _ in 0..NEWTON_ITERATIONS {
                let (p, j) = warp_jacobian_f64(self.params, &self.cond, z);
                out.evaluations += 1;
                let e = [p[0] - x[0], p[1] - x[1]];
                let det = jacobian_det(&j);
                if e[0] * e[0] + e[1] * e[1] < NEWTON_TOLERANCE * NEWTON_TOLERANCE {
                    if !roots
                        .iter()
                        .any(|q| (q[0] - z[0]).abs() < SAME_ROOT && (q[1] - z[1]).abs() < SAME_ROOT)
                    {
                        roots.push(z);
                        out.roots += 1;
                        if det > 0.0 {
                            out.density += standard_normal(z) / det;
                        } else {
                            out.folded_roots += 1;
                        }
                    }
                    break;
                }
                if !(det.abs() > 1e-300) {
                    break;
                }
                // z − J⁻¹ e, each step held to a few cells so that it cannot jump far.
                let mut d = [
                    (j[1][1] * e[0] - j[0][1] * e[1]) / det,
                    (-j[1][0] * e[0] + j[0][0] * e[1]) / det,
                ];
                let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
                let cap = 4.0 * self.h;
                if len > cap {
                    d = [d[0] * cap / len, d[1] * cap / len];
                }
                z = [z[0] - d[0], z[1] - d[1]];
                if !(z[0].abs() <= Z_EXTENT + self.h && z[1].abs() <= Z_EXTENT + self.h) {
                    break;
                }
            }
        }
        out
    }
}

/// The exact-density study of one reparameterization blob on a material, means over
/// conditions (`*_worst`: the condition farthest from the ideal). Integrals on the
/// [`groundtruth::rim_quadrature`] of the whole disk; `f` the material's luminance ×
/// `cos θo` on the disk, `a = ∫ f`.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
pub struct ExactFit {
    /// Conditions evaluated.
    pub conditions: usize,
    /// `∫ q`: the fraction of samples the runtime keeps (the rest fall where `det ≤ 0`).
    pub mass: f64,
    /// `∫_{q=0} f / a`: the integrand's share where the warp puts no density, which its
    /// sample weights never see (their estimate of `a` is low by this fraction).
    pub missed: f64,
    /// Its largest value over the conditions.
    pub missed_worst: f64,
    /// `∫_{q>0} f²/q / a² − 1`: the second moment of the sample weights (what
    /// [`super::SampledFit::chi2`] estimates from samples), exact.
    pub chi2: f64,
    /// Its largest value over the conditions.
    pub chi2_worst: f64,
    /// `∫ q ln(q/p̂) / ∫ q`: KL of the pdf network `p̂` from the samples' density.
    pub mis_kl: f64,
    /// `∫ q²/p̂ / ∫ q − 1`: χ²(q ‖ p̂).
    pub mis_chi2: f64,
    /// The share of `q`'s mass at points reached from more than one latent point.
    pub overlap: f64,
    /// Warp evaluations per density query (Newton steps over all candidate cells).
    pub evaluations_per_query: f64,
    /// Warp evaluations of the latent grid, per condition.
    pub grid_evaluations: usize,
    /// Wall time of one exact density query (f64, one thread), ns.
    pub query_ns: f64,
    /// Wall time of the latent grid of one condition (f64, one thread), ms.
    pub grid_ms: f64,
    /// Wall time of one pdf network query `p̂` (the runtime's scalar path), ns.
    pub network_ns: f64,
    /// Per defensive weight α of [`ALPHA_GRID`], the second moment of the runtime's
    /// defensive estimator (`neusample::Defensive`: one-sample MIS of the warp and cosine
    /// sampling over `p̂`), summed over conditions, relative to α = 0; exact where the
    /// sampled estimate of `neusample defend` does not see the warp's thin regions.
    pub alpha_second_moment: [f64; ALPHA_GRID.len()],
}

/// [`ExactFit`] of the reparameterization blob `bytes` on `material` at `conditions`
/// conditions of [`groundtruth::conditions`] (seed `seed`), `cells²` latent cells, the
/// quadrature at `radial × angular` nodes.
pub fn exact_fit(
    bytes: &[u8],
    material: &dyn Material,
    conditions: usize,
    seed: u64,
    cells: usize,
    (radial, angular): (usize, usize),
) -> Result<ExactFit> {
    let blob = Blob::open(bytes).context("the reparameterization blob")?;
    if blob.kind() != SamplerKind::Reparam {
        bail!(
            "a {} blob, not a reparameterization blob",
            blob.kind().name()
        );
    }
    let params = reparam_params(&blob)?;
    // The MIS density a renderer uses (with the blob's defensive weight, if any).
    let sampler = blob.sampler_as::<neusample::samplers::ReparamSampler<_>>()?;
    let conds = groundtruth::conditions(material, conditions, seed);
    let nodes = groundtruth::rim_quadrature(radial, angular);
    let per: Vec<ExactFit> = conds
        .par_iter()
        .filter_map(|c| {
            let prep = sampler.prepare(&c.phi, c.wi)?;
            let t0 = Instant::now();
            let inv = WarpInverse::new(&params, &c.phi, c.wi, cells);
            let grid_ms = t0.elapsed().as_secs_f64() * 1e3;
            let f = groundtruth::rim_luminance(material, c, &nodes);
            let t0 = Instant::now();
            let exact: Vec<Inverted> = nodes
                .iter()
                .map(|&(p, _)| inv.density([f64::from(p.x), f64::from(p.y)]))
                .collect();
            let query_ns = t0.elapsed().as_secs_f64() * 1e9 / nodes.len() as f64;
            let t0 = Instant::now();
            let network: Vec<f64> = nodes
                .iter()
                .map(|&(p, _)| f64::from(std::hint::black_box(&prep).pdf_disk(p)))
                .collect();
            let network_ns = t0.elapsed().as_secs_f64() * 1e9 / nodes.len() as f64;
            let (mut a, mut mass, mut missed, mut m2) = (0.0, 0.0, 0.0, 0.0);
            let (mut kl, mut x2, mut overlap, mut evals) = (0.0, 0.0, 0.0, 0usize);
            let mut m2_alpha = [0.0f64; ALPHA_GRID.len()];
            let c_cos = std::f64::consts::FRAC_1_PI;
            for (((&(_, w), f), r), ph) in nodes.iter().zip(f).zip(exact).zip(network) {
                evals += r.evaluations;
                let q = r.density;
                // Cosine samples are divided by D = (1 − α)·p̂ + α/π, warp samples by D·q/p̂.
                for (m2a, &alpha) in m2_alpha.iter_mut().zip(&ALPHA_GRID) {
                    let alpha = f64::from(alpha);
                    let d = (1.0 - alpha) * ph + alpha * c_cos;
                    if d > 0.0 {
                        let mut g = alpha * c_cos;
                        if q > 0.0 {
                            g += (1.0 - alpha) * ph * ph / q;
                        }
                        *m2a += f * f / (d * d) * g * w;
                    } else if q > 0.0 {
                        *m2a += f * f / q * w;
                    }
                }
                a += f * w;
                mass += q * w;
                if q > 0.0 {
                    m2 += f * f / q * w;
                    if r.roots - r.folded_roots > 1 {
                        overlap += q * w;
                    }
                    if ph > 0.0 {
                        kl += q * (q / ph).ln() * w;
                        x2 += q * q / ph * w;
                    }
                } else {
                    missed += f * w;
                }
            }
            (a > 0.0 && mass > 0.0).then(|| ExactFit {
                conditions: 1,
                mass,
                missed: missed / a,
                missed_worst: missed / a,
                chi2: m2 / (a * a) - 1.0,
                chi2_worst: m2 / (a * a) - 1.0,
                mis_kl: kl / mass,
                mis_chi2: x2 / mass - 1.0,
                overlap: overlap / mass,
                evaluations_per_query: evals as f64 / nodes.len() as f64,
                grid_evaluations: (cells + 1) * (cells + 1),
                query_ns,
                grid_ms,
                network_ns,
                alpha_second_moment: m2_alpha,
            })
        })
        .collect();
    ensure!(!per.is_empty(), "no condition with a positive integrand");
    let k = per.len() as f64;
    let mean = |g: fn(&ExactFit) -> f64| per.iter().map(g).sum::<f64>() / k;
    let max = |g: fn(&ExactFit) -> f64| per.iter().map(g).fold(f64::NEG_INFINITY, f64::max);
    Ok(ExactFit {
        conditions: per.len(),
        mass: mean(|e| e.mass),
        missed: mean(|e| e.missed),
        missed_worst: max(|e| e.missed),
        chi2: mean(|e| e.chi2),
        chi2_worst: max(|e| e.chi2),
        mis_kl: mean(|e| e.mis_kl),
        mis_chi2: mean(|e| e.mis_chi2),
        overlap: mean(|e| e.overlap),
        evaluations_per_query: mean(|e| e.evaluations_per_query),
        grid_evaluations: per[0].grid_evaluations,
        query_ns: mean(|e| e.query_ns),
        grid_ms: mean(|e| e.grid_ms),
        network_ns: mean(|e| e.network_ns),
        alpha_second_moment: std::array::from_fn(|k| {
            let at = |k: usize| per.iter().map(|e| e.alpha_second_moment[k]).sum::<f64>();
            at(k) / at(0)
        }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials::neural::NeuralMaterialModel;
    use glam::Vec2;
    use std::path::Path;

    fn fixture(material: &str) -> (NeuralMaterialModel, Vec<u8>) {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let m = NeuralMaterialModel::load(
            &root.join(format!("fixtures/materials/neural/{material}_neural.nsb")),
        )
        .expect("committed neural material");
        let bytes =
            std::fs::read(root.join(format!("fixtures/blobs/{material}_neural/reparam.nsb")))
                .expect("committed reparameterization blob");
        (m, bytes)
    }

    fn params(bytes: &[u8]) -> Vec<f32> {
        reparam_params(&Blob::open(bytes).unwrap()).unwrap()
    }

    /// At `x = T(z)` the inverse finds `z` among the roots: `q(x) ≥ N(z)/det` (other roots
    /// may add to it) where `det > 0`.
    #[test]
    fn every_image_point_has_its_preimage() {
        let (m, bytes) = fixture("goat_leather");
        let p = params(&bytes);
        let c = groundtruth::conditions(&m, 3, 7);
        let mut rng = crate::util::rng::rng_for(3, 0, 0);
        for c in &c {
            let inv = WarpInverse::new(&p, &c.phi, c.wi, 64);
            let cond: Vec<f64> = encode_condition(&c.phi, c.wi)
                .iter()
                .map(|&v| f64::from(v))
                .collect();
            for _ in 0..40 {
                use rand::RngExt;
                let z = [
                    rng.random::<f64>() * 4.0 - 2.0,
                    rng.random::<f64>() * 4.0 - 2.0,
                ];
                let (x, j) = warp_jacobian_f64(&p, &cond, z);
                let det = jacobian_det(&j);
                let r = inv.density(x);
                assert!(r.roots >= 1, "no root found at T({z:?}) = {x:?}");
                if det > 0.0 {
                    let n = standard_normal(z);
                    assert!(
                        r.density >= n / det * (1.0 - 1e-6),
                        "q = {} below N/det = {} at {x:?}",
                        r.density,
                        n / det
                    );
                }
            }
        }
    }

    /// The inverted density agrees with the runtime's samples: its mass is the share of
    /// samples kept, and each bin of a grid on the disk holds the share of samples that its
    /// integral of `q` predicts (within five standard deviations).
    #[test]
    fn inverted_density_matches_the_samples() {
        let (m, bytes) = fixture("goat_leather");
        let p = params(&bytes);
        let blob = Blob::open(&bytes).unwrap();
        let sampler = blob
            .sampler_as::<neusample::samplers::ReparamSampler<_>>()
            .unwrap();
        let c = groundtruth::conditions(&m, 1, 11)[0];
        let prep = sampler.prepare(&c.phi, c.wi).unwrap();
        let inv = WarpInverse::new(&p, &c.phi, c.wi, 96);
        const B: usize = 4;
        const G: usize = 48;
        let mut predicted = [0.0f64; B * B];
        let h = 2.0 / G as f64;
        for r in 0..G {
            for col in 0..G {
                let x = [-1.0 + (col as f64 + 0.5) * h, -1.0 + (r as f64 + 0.5) * h];
                predicted[(r * B / G) * B + col * B / G] += inv.density(x).density * h * h;
            }
        }
        let k = 256usize;
        let n = k * k;
        let mut counts = [0usize; B * B];
        let mut kept = 0usize;
        for i in 0..n {
            let u = Vec2::new(
                ((i % k) as f32 + 0.5) / k as f32,
                ((i / k) as f32 + 0.5) / k as f32,
            );
            if let Some(s) = prep.sample(u) {
                let (x, y) = (f64::from(s.wo.x), f64::from(s.wo.y));
                let b = |v: f64| (((v + 1.0) * 0.5 * B as f64) as usize).min(B - 1);
                counts[b(y) * B + b(x)] += 1;
                kept += 1;
            }
        }
        let total: f64 = predicted.iter().sum();
        let kept_share = kept as f64 / n as f64;
        assert!(
            (total - kept_share).abs() < 0.01,
            "∫q = {total}, samples kept {kept_share}"
        );
        for (i, (&q, &c)) in predicted.iter().zip(&counts).enumerate() {
            let share = c as f64 / n as f64;
            let sd = (share.max(1e-4) * (1.0 - share) / n as f64).sqrt();
            // The midpoint rule's error on the bins' curved share of the disk, plus sampling.
            assert!(
                (q - share).abs() < 5.0 * sd + 0.01 * share.max(q) + 2e-3,
                "bin {i}: ∫q {q}, samples {share}"
            );
        }
    }
}
