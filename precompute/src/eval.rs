//! Evaluation of samplers through the runtime's public API only, as a renderer uses them:
//! pdf fit against the ground truth (KL(p* ‖ p), pdf MSE) and single-thread cost.

use std::hint::black_box;
use std::time::Instant;

use glam::{Vec2, Vec3};
use neusample::{Prepared, Sampler};
use rand::{RngExt, SeedableRng};
use serde::Serialize;

use crate::groundtruth::{self, TargetPdf};
use crate::materials::Material;

/// Fit of a sampler's density to the ground truth, averaged over conditions.
#[derive(Clone, Debug, Serialize)]
pub struct Fit {
    /// Conditions evaluated.
    pub conditions: usize,
    /// Mean KL(p* ‖ p) in nats over the conditions (p* tabulated at `res`², p at cell
    /// midpoints).
    pub kl_divergence: f64,
    /// Mean over conditions of the mean squared difference of the disk densities.
    pub pdf_mse: f64,
    /// Mean probability mass the sampler puts inside the disk.
    pub mass_in_disk: f64,
}

/// Mean fit of `sampler` to `material`'s ground truth at `conditions` random conditions.
pub fn fit<S: Sampler + Sync>(
    sampler: &S,
    material: &dyn Material,
    conditions: usize,
    res: usize,
    seed: u64,
) -> Fit {
    fit_to(sampler, material, None, conditions, res, seed)
}

/// [`fit`] with the target taken from `reference` instead of `material`: the sampler is
/// conditioned on `material`'s φ(uv) and `wi`, the ground truth p* is `reference`'s at the
/// same uv and wi. For a neural material and its source this measures the samplers against
/// the material the neural one approximates (the same conditions as [`fit`] with the same
/// seed, so the two are comparable).
pub fn fit_to<S: Sampler + Sync>(
    sampler: &S,
    material: &dyn Material,
    reference: Option<&dyn Material>,
    conditions: usize,
    res: usize,
    seed: u64,
) -> Fit {
    use rayon::prelude::*;
    let conds = groundtruth::conditions(material, conditions, seed);
    let per: Vec<(f64, f64, f64)> = conds
        .par_iter()
        .map(|c| {
            let target = match reference {
                None => TargetPdf::new(material, c, res),
                Some(r) => {
                    let rc = groundtruth::Condition {
                        phi: r.features(c.uv),
                        ..*c
                    };
                    TargetPdf::new(r, &rc, res)
                }
            };
            let Some(prep) = sampler.prepare(&c.phi, c.wi) else {
                return (f64::INFINITY, f64::INFINITY, 0.0);
            };
            let kl = target.kl_from(|p| prep.pdf_disk(p));
            let h = 2.0 / res as f64;
            let (mut se, mut mass, mut n) = (0.0, 0.0, 0usize);
            for r in 0..res {
                for col in 0..res {
                    let p = Vec2::new(
                        (-1.0 + (col as f64 + 0.5) * h) as f32,
                        (-1.0 + (r as f64 + 0.5) * h) as f32,
                    );
                    let q = f64::from(prep.pdf_disk(p));
                    let t = f64::from(target.pdf(p));
                    se += (q - t) * (q - t);
                    mass += q * h * h;
                    n += 1;
                }
            }
            (kl, se / n as f64, mass)
        })
        .collect();
    let n = per.len().max(1) as f64;
    Fit {
        conditions: per.len(),
        kl_divergence: per.iter().map(|p| p.0).sum::<f64>() / n,
        pdf_mse: per.iter().map(|p| p.1).sum::<f64>() / n,
        mass_in_disk: per.iter().map(|p| p.2).sum::<f64>() / n,
    }
}

/// Single-thread cost of the hot path, nanoseconds per call (medians of repeated passes).
#[derive(Clone, Debug, Serialize)]
pub struct Cost {
    /// `prepare(φ, wi)`.
    pub prepare_ns: f64,
    /// `sample(u)` on a prepared value.
    pub sample_ns: f64,
    /// `pdf(wo)` on a prepared value.
    pub pdf_ns: f64,
    /// One shading point: prepare + sample + pdf.
    pub total_ns: f64,
    /// `material.eval` (the material's own cost, for the Table 1 ratio).
    pub material_eval_ns: f64,
}

/// Measures [`Cost`] on `n` random conditions of `material`, `passes` times.
pub fn cost<S: Sampler>(sampler: &S, material: &dyn Material, n: usize, passes: usize) -> Cost {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(0xC057);
    let conds: Vec<_> = (0..n)
        .map(|_| groundtruth::random_condition(material, &mut rng))
        .collect();
    let us: Vec<Vec2> = (0..n)
        .map(|_| Vec2::new(rng.random::<f32>(), rng.random::<f32>()))
        .collect();
    let wos = timing_directions(&mut rng, n);
    let (mut tp, mut ts, mut tq, mut tt, mut te) = (vec![], vec![], vec![], vec![], vec![]);
    for _ in 0..passes {
        let t0 = Instant::now();
        for c in &conds {
            black_box(
                sampler
                    .prepare(black_box(&c.phi), black_box(c.wi))
                    .is_some(),
            );
        }
        tp.push(t0.elapsed().as_nanos() as f64 / n as f64);

        let preps: Vec<_> = conds
            .iter()
            .filter_map(|c| sampler.prepare(&c.phi, c.wi))
            .collect();
        let m = preps.len().max(1) as f64;
        let t0 = Instant::now();
        for (p, u) in preps.iter().zip(&us) {
            black_box(p.sample(black_box(*u)));
        }
        ts.push(t0.elapsed().as_nanos() as f64 / m);
        let t0 = Instant::now();
        for (p, wo) in preps.iter().zip(&wos) {
            black_box(p.pdf(black_box(*wo)));
        }
        tq.push(t0.elapsed().as_nanos() as f64 / m);

        let t0 = Instant::now();
        for ((c, u), wo) in conds.iter().zip(&us).zip(&wos) {
            if let Some(p) = sampler.prepare(&c.phi, c.wi) {
                black_box(p.sample(*u));
                black_box(p.pdf(*wo));
            }
        }
        tt.push(t0.elapsed().as_nanos() as f64 / n as f64);

        let t0 = Instant::now();
        for (c, wo) in conds.iter().zip(&wos) {
            black_box(material.eval(black_box(&c.phi), c.wi, *wo));
        }
        te.push(t0.elapsed().as_nanos() as f64 / n as f64);
    }
    Cost {
        prepare_ns: median(tp),
        sample_ns: median(ts),
        pdf_ns: median(tq),
        total_ns: median(tt),
        material_eval_ns: median(te),
    }
}

/// `n` random directions for timing `eval` (polar angle uniform in [0, 1.4], azimuth uniform).
pub(crate) fn timing_directions(rng: &mut impl rand::Rng, n: usize) -> Vec<Vec3> {
    (0..n)
        .map(|_| {
            crate::bake::direction(
                rng.random::<f32>() * 1.4,
                rng.random::<f32>() * std::f32::consts::TAU,
            )
        })
        .collect()
}

/// The median of timing samples (the upper one of an even count); `v` is non-empty.
pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
