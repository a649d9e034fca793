//! Single-thread cost, nanoseconds per call, by the timing harness of [`crate::util::timing`]
//! (medians of repeated passes over random conditions): a sampler's hot path, and a
//! material's own evaluation (the denominator of the paper's Table 1 ratio).

use std::hint::black_box;

use glam::Vec2;
use neusample::{Prepared, Sampler};
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::groundtruth::{self, Condition};
use crate::materials::Material;
use crate::util::json::f64_or_nan;
use crate::util::timing::{median_of_passes, ns_per_call, timing_directions};

/// Single-thread cost of a sampler's hot path, nanoseconds per call.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Cost {
    /// `prepare(φ, wi)`.
    #[serde(deserialize_with = "f64_or_nan")]
    pub prepare_ns: f64,
    /// `sample(u)` on a prepared value.
    #[serde(deserialize_with = "f64_or_nan")]
    pub sample_ns: f64,
    /// `pdf(wo)` on a prepared value.
    #[serde(deserialize_with = "f64_or_nan")]
    pub pdf_ns: f64,
    /// One shading point: prepare + sample + pdf.
    #[serde(deserialize_with = "f64_or_nan")]
    pub total_ns: f64,
    /// `material.eval` (the material's own cost, for the Table 1 ratio).
    #[serde(deserialize_with = "f64_or_nan")]
    pub material_eval_ns: f64,
}

/// Single-thread cost of a material, nanoseconds per call.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct EvalCost {
    /// `features(uv)` (texture lookup).
    #[serde(deserialize_with = "f64_or_nan")]
    pub features_ns: f64,
    /// `eval(φ, wi, wo)` (the decoder, or the analytic BRDF).
    #[serde(deserialize_with = "f64_or_nan")]
    pub eval_ns: f64,
}

/// `n` random conditions of `m` from `rng`.
fn random_conditions(m: &dyn Material, rng: &mut impl rand::Rng, n: usize) -> Vec<Condition> {
    (0..n)
        .map(|_| groundtruth::random_condition(m, rng))
        .collect()
}

/// Measures [`Cost`] on `n` random conditions of `material`, `passes` times.
pub fn cost<S: Sampler>(sampler: &S, material: &dyn Material, n: usize, passes: usize) -> Cost {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(0xC057);
    let conds = random_conditions(material, &mut rng, n);
    let us: Vec<Vec2> = (0..n)
        .map(|_| Vec2::new(rng.random::<f32>(), rng.random::<f32>()))
        .collect();
    let wos = timing_directions(&mut rng, n);
    let [prepare_ns, sample_ns, pdf_ns, total_ns, material_eval_ns] =
        median_of_passes(passes, || {
            let prepare = ns_per_call(n, || {
                for c in &conds {
                    black_box(
                        sampler
                            .prepare(black_box(&c.phi), black_box(c.wi))
                            .is_some(),
                    );
                }
            });
            let preps: Vec<_> = conds
                .iter()
                .filter_map(|c| sampler.prepare(&c.phi, c.wi))
                .collect();
            let sample = ns_per_call(preps.len(), || {
                for (p, u) in preps.iter().zip(&us) {
                    black_box(p.sample(black_box(*u)));
                }
            });
            let pdf = ns_per_call(preps.len(), || {
                for (p, wo) in preps.iter().zip(&wos) {
                    black_box(p.pdf(black_box(*wo)));
                }
            });
            let total = ns_per_call(n, || {
                for ((c, u), wo) in conds.iter().zip(&us).zip(&wos) {
                    if let Some(p) = sampler.prepare(&c.phi, c.wi) {
                        black_box(p.sample(*u));
                        black_box(p.pdf(*wo));
                    }
                }
            });
            let eval = ns_per_call(n, || {
                for (c, wo) in conds.iter().zip(&wos) {
                    black_box(material.eval(black_box(&c.phi), c.wi, *wo));
                }
            });
            [prepare, sample, pdf, total, eval]
        });
    Cost {
        prepare_ns,
        sample_ns,
        pdf_ns,
        total_ns,
        material_eval_ns,
    }
}

/// Measures [`EvalCost`] of `material` on `n` random `(uv, wi, wo)`, `passes` times, on the
/// calling thread.
pub fn eval_cost(material: &dyn Material, n: usize, passes: usize) -> EvalCost {
    let n = n.max(1);
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(0xC057_E7A1);
    let conds = random_conditions(material, &mut rng, n);
    let wos = timing_directions(&mut rng, n);
    let [features_ns, eval_ns] = median_of_passes(passes, || {
        let features = ns_per_call(n, || {
            for c in &conds {
                black_box(material.features(black_box(c.uv)));
            }
        });
        let eval = ns_per_call(n, || {
            for (c, wo) in conds.iter().zip(&wos) {
                black_box(material.eval(black_box(&c.phi), black_box(c.wi), black_box(*wo)));
            }
        });
        [features, eval]
    });
    EvalCost {
        features_ns,
        eval_ns,
    }
}
