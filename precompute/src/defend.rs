//! The defensive weight α of a blob's sampler ([`neusample::Defensive`]): the runtime samples
//! `p = (1 − α)·p_learned + α·cos θ/π`, which bounds every sample weight by `π·f/α`.
//!
//! α is chosen in the render's measure, not in KL: with the material's own light transport at
//! one bounce under uniform light, the estimator of a shading point is `f·cos/p = a·p*/p`
//! (`a` the albedo), whose second moment is `a²·(1 + χ²(p* ‖ p))`. [`choose_alpha`] evaluates
//! the material and the learned density once per condition on a disk quadrature that reaches
//! the horizon ([`rim_quadrature`]: thin-tailed samplers put their largest weights in the
//! outermost fraction of a percent of the radius, which a table of p* does not see) and that
//! second moment in closed form for every α of [`ALPHA_GRID`], averaged over random
//! conditions of the material (drawn with their own seed, not the evaluation's). The smallest
//! α within [`ALPHA_TOLERANCE`] of the best second moment wins: the learned part keeps as
//! much of the samples as the variance allows.
//! [`with_defensive`] rewrites a blob with the chosen α, its tensors unchanged.
//!
//! A sampler whose samples carry a density other than its `pdf` (the reparameterization
//! sampler: the warp's exact `q`, a pdf network for MIS) has no closed form on a quadrature:
//! its mixture divides each sample by a one-sample-MIS density (`neusample::Defensive`).
//! There the second moment is estimated from [`SAMPLED_PER_CONDITION`] stratified samples of
//! each mixture, the same uniforms for every α (common random numbers, so the comparison
//! between α is far less noisy than each estimate).

use anyhow::{bail, Context, Result};
use neusample::{Blob, BlobWriter, Prepared, Sampler, SamplerKind};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::groundtruth::{self, rim_quadrature, RIM_ANGULAR, RIM_RADIAL};
use crate::materials::Material;

/// The weights [`choose_alpha`] tries. Capped at 0.2: the expectation is dominated by rare
/// directions at the horizon, and beyond 0.2 it buys little there while every typical shading
/// point loses a fifth of its learned samples (the measured cost of a higher cap:
/// `docs/results.md`, "Defensive mixture").
pub const ALPHA_GRID: [f32; 7] = [0.0, 0.01, 0.02, 0.05, 0.1, 0.15, 0.2];

/// How much above the smallest second moment a smaller α may be and still be chosen.
pub const ALPHA_TOLERANCE: f64 = 0.1;

/// Samples per condition and α of the sampled estimate (module docs).
pub const SAMPLED_PER_CONDITION: usize = 4096;

/// Conditions [`choose_alpha`] averages over by default.
pub const DEFAULT_CONDITIONS: usize = 128;
/// Radial nodes of [`choose_alpha`]'s quadrature by default ([`RIM_RADIAL`]).
pub const DEFAULT_RADIAL: usize = RIM_RADIAL;

/// One α of the search.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct AlphaScore {
    /// The defensive weight.
    pub alpha: f32,
    /// Mean over conditions of `a²·(1 + χ²(p* ‖ p_α))`, relative to the same with α = 0.
    pub relative_second_moment: f64,
    /// Mean χ²(p* ‖ p_α).
    pub chi2: f64,
    /// Largest χ²(p* ‖ p_α) of the conditions.
    pub chi2_worst: f64,
}

/// The result of [`choose_alpha`].
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct AlphaChoice {
    /// The smallest α within [`ALPHA_TOLERANCE`] of the smallest second moment.
    pub alpha: f32,
    /// Conditions averaged over.
    pub conditions: usize,
    /// Every α tried, in [`ALPHA_GRID`] order.
    pub scores: Vec<AlphaScore>,
}

/// Chooses the defensive weight of `bytes`' sampler for `material` (module docs): its
/// learned part is evaluated at `conditions` random conditions (seeded by `seed`) on the
/// disk quadrature [`rim_quadrature`] with `radial` rings, which reaches the horizon.
pub fn choose_alpha(
    bytes: &[u8],
    material: &dyn Material,
    conditions: usize,
    radial: usize,
    seed: u64,
) -> Result<AlphaChoice> {
    let blob = Blob::open(bytes).context("the blob does not open")?;
    let sampler = *blob.sampler()?.inner();
    let mut conds = groundtruth::conditions(material, conditions, seed);
    if blob.isotropic() {
        // The learned part sees `wi` at azimuth 0; the material looks the same from there.
        for c in &mut conds {
            c.wi = neusample::samplers::Turn::aligning(c.wi).1;
        }
    }
    let nodes = rim_quadrature(radial, RIM_ANGULAR);
    let carries_pdf = conds.iter().all(|c| {
        sampler
            .prepare(&c.phi, c.wi)
            .is_none_or(|p| crate::eval::samples_carry_pdf(&p))
    });
    if !carries_pdf {
        let per = sampled_moments(&sampler, material, &conds, &nodes, seed);
        return Ok(choice(&per));
    }
    // Per condition: albedo² and, per α, ∫ Y(f)²/p_α over the disk (rim included).
    let per: Vec<(f64, Vec<f64>)> = conds
        .par_iter()
        .map(|c| {
            let prep = sampler.prepare(&c.phi, c.wi);
            let f = groundtruth::rim_luminance(material, c, &nodes);
            let a: f64 = f.iter().zip(&nodes).map(|(y, n)| y * n.1).sum();
            let mut m2 = vec![0.0f64; ALPHA_GRID.len()];
            for (&(p, w), &y) in nodes.iter().zip(&f) {
                if y <= 0.0 {
                    continue;
                }
                let q = prep.as_ref().map_or(0.0, |pr| f64::from(pr.pdf_disk(p)));
                let q = if q.is_finite() { q.max(0.0) } else { 0.0 };
                for (k, &alpha) in ALPHA_GRID.iter().enumerate() {
                    let alpha = f64::from(alpha);
                    let qa = (1.0 - alpha) * q + alpha * std::f64::consts::FRAC_1_PI;
                    m2[k] += y * y / groundtruth::floored(qa) * w;
                }
            }
            // Normalised: χ² + 1 = m2 / a².
            let a2 = a * a;
            if a2 > 0.0 {
                (a2, m2.iter().map(|m| m / a2).collect())
            } else {
                (0.0, vec![1.0; ALPHA_GRID.len()])
            }
        })
        .collect();
    if per.is_empty() {
        bail!("no conditions to choose the defensive weight on");
    }
    Ok(choice(&per))
}

/// Per condition, albedo² and per α of [`ALPHA_GRID`] `E[w²]/a²` of the mixture's samples
/// (`w = Y(f)/pdf_disk`, `pdf_disk` the density a sample is divided by; refused samples
/// count as 0), the same stratified uniforms for every α.
fn sampled_moments(
    sampler: &neusample::AnySampler<'_>,
    material: &dyn Material,
    conds: &[groundtruth::Condition],
    nodes: &[(glam::Vec2, f64)],
    seed: u64,
) -> Vec<(f64, Vec<f64>)> {
    use rand::RngExt;
    let k = (SAMPLED_PER_CONDITION as f64).sqrt() as usize;
    conds
        .par_iter()
        .enumerate()
        .map(|(ci, c)| {
            let f = groundtruth::rim_luminance(material, c, nodes);
            let a: f64 = f.iter().zip(nodes).map(|(y, n)| y * n.1).sum();
            let a2 = a * a;
            if !(a2 > 0.0) {
                return (0.0, vec![1.0; ALPHA_GRID.len()]);
            }
            let mut rng = crate::util::rng::rng_for(seed, 0xde5a, ci as u64);
            let us: Vec<glam::Vec2> = (0..k * k)
                .map(|i| {
                    let mut cell = |j: usize| {
                        ((j as f32 + rng.random::<f32>()) / k as f32)
                            .min(neusample::ONE_MINUS_EPSILON)
                    };
                    glam::Vec2::new(cell(i % k), cell(i / k))
                })
                .collect();
            let m2 = ALPHA_GRID
                .iter()
                .map(|&alpha| {
                    let d = neusample::Defensive::new_unchecked(*sampler, alpha);
                    let Some(prep) = d.prepare(&c.phi, c.wi) else {
                        return 1.0;
                    };
                    let mut sum = 0.0f64;
                    for &u in &us {
                        let Some(s) = prep.sample(u) else { continue };
                        let y = f64::from(crate::materials::luminance(
                            material.eval(&c.phi, c.wi, s.wo),
                        ));
                        if y > 0.0 && y.is_finite() {
                            let w = y / f64::from(s.pdf_disk);
                            sum += w * w;
                        }
                    }
                    sum / us.len() as f64 / a2
                })
                .collect();
            (a2, m2)
        })
        .collect()
}

/// The α of per-condition `(a², E[w²]/a² per α)` (module docs).
fn choice(per: &[(f64, Vec<f64>)]) -> AlphaChoice {
    let n = per.len().max(1) as f64;
    let weighted = |k: usize| per.iter().map(|(a2, m)| a2 * m[k]).sum::<f64>() / n;
    let base = weighted(0).max(f64::MIN_POSITIVE);
    let scores: Vec<AlphaScore> = ALPHA_GRID
        .iter()
        .enumerate()
        .map(|(k, &alpha)| AlphaScore {
            alpha,
            relative_second_moment: weighted(k) / base,
            chi2: per.iter().map(|(_, m)| m[k] - 1.0).sum::<f64>() / n,
            chi2_worst: per
                .iter()
                .map(|(_, m)| m[k] - 1.0)
                .fold(f64::NEG_INFINITY, f64::max),
        })
        .collect();
    let least = scores
        .iter()
        .map(|s| s.relative_second_moment)
        .fold(f64::INFINITY, f64::min);
    let best = scores
        .iter()
        .find(|s| s.relative_second_moment <= least * (1.0 + ALPHA_TOLERANCE))
        .map_or(0.0, |s| s.alpha);
    AlphaChoice {
        alpha: best,
        conditions: per.len(),
        scores,
    }
}

/// `bytes` rewritten with the defensive weight `alpha` (format version 2, or version 1 when
/// α = 0), every tensor and header field kept; the result is opened before it is returned.
pub fn with_defensive(bytes: &[u8], alpha: f32) -> Result<Vec<u8>> {
    let blob = Blob::open(bytes).context("the blob does not open")?;
    if blob.kind().sampler().is_none() {
        bail!("a {} blob has no sampler to defend", blob.kind().name());
    }
    if !(alpha >= 0.0 && alpha < 1.0) {
        bail!("the defensive weight must be in [0, 1), not {alpha}");
    }
    let out = BlobWriter::from_blob(&blob).defensive(alpha).to_bytes();
    let check = Blob::open(&out).context("the rewritten blob does not open")?;
    if check.defensive().to_bits() != alpha.to_bits() {
        bail!("the rewritten blob does not hold α = {alpha}");
    }
    Ok(out)
}

/// Whether the pipeline gives `kind` a defensive weight: every learned sampler, not cosine
/// (already the defensive part) and not the improved baseline (the paper's reference, kept
/// as published so that every speed-up is against the same thing).
#[must_use]
pub fn is_defended(kind: SamplerKind) -> bool {
    !matches!(kind, SamplerKind::Cosine | SamplerKind::ImprovedBaseline)
}

/// The pipeline's step after baking: for a kind that [`is_defended`], `bytes` with the α that
/// [`choose_alpha`] picks on `material` (default conditions, `seed`), and the search;
/// otherwise `bytes` unchanged.
pub fn defend_baked(
    bytes: Vec<u8>,
    material: &dyn Material,
    seed: u64,
) -> Result<(Vec<u8>, Option<AlphaChoice>)> {
    let kind = Blob::open(&bytes).context("the blob does not open")?.kind();
    if !kind.sampler().is_some_and(is_defended) {
        return Ok((bytes, None));
    }
    let c = choose_alpha(&bytes, material, DEFAULT_CONDITIONS, DEFAULT_RADIAL, seed)?;
    Ok((with_defensive(&bytes, c.alpha)?, Some(c)))
}
