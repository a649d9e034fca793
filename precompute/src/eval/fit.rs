//! Fit to the ground truth, measured through the runtime's public API: a sampler's density
//! against p* (KL(p* ‖ p), pdf MSE, mass), and a neural material against its source (RGB
//! error, KL between the two p*, albedo).

use glam::Vec2;
use neusample::{Prepared, Sampler};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::groundtruth::{self, TargetPdf};
use crate::materials::Material;
use crate::train::neural_material::draw;
use crate::util::json::{f64_or_nan, nan};
use crate::util::rng::mix_seed;

/// Fit of a sampler's density to the ground truth, averaged over conditions.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Fit {
    /// Conditions evaluated (0 in reports written before the demo report stored it).
    #[serde(default)]
    pub conditions: usize,
    /// Mean KL(p* ‖ p) in nats over the conditions (p* tabulated at `res`², p at cell
    /// midpoints). Read as `kl` too (the name in sweep summaries before they stored a `Fit`).
    #[serde(alias = "kl", deserialize_with = "f64_or_nan")]
    pub kl_divergence: f64,
    /// Mean χ²(p* ‖ p) = ∫ p*²/p − 1 over the conditions: the render's relative variance per
    /// sample. Integrated over the whole disk up to the horizon
    /// ([`groundtruth::rim_moments`]), not on the KL's table, whose cells stop short of the
    /// rim where thin-tailed samplers put their largest weights.
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub chi2: f64,
    /// The largest χ²(p* ‖ p) of the conditions.
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub chi2_worst: f64,
    /// Index of that condition in [`groundtruth::conditions`] with the fit's seed.
    #[serde(default)]
    pub chi2_worst_condition: usize,
    /// Mean over conditions of the mean squared difference of the disk densities.
    #[serde(deserialize_with = "f64_or_nan")]
    pub pdf_mse: f64,
    /// Mean probability mass the sampler puts inside the disk (NaN in sweep summaries written
    /// before they stored a `Fit`).
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub mass_in_disk: f64,
    /// Samplers whose samples are drawn with a density other than their `pdf` (their MIS
    /// density: [`samples_carry_pdf`] false, the reparameterization sampler), measured on
    /// their own samples ([`SampledFit`]); `None` for the others, whose fields above say it
    /// all.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampled: Option<SampledFit>,
}

/// A sampler measured on its own samples, for kinds whose `pdf` (the MIS density) is not
/// the density of their samples: [`FIT_SAMPLES`] stratified samples per condition, `w =
/// Y(f)/(a·pdf_disk)` with `a` the quadrature albedo `∫ Y(f)` of [`groundtruth::rim_moments`]
/// (`pdf_disk` of a sample: the density it is divided by). Means over the conditions.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct SampledFit {
    /// `E[w]`: the sample-weight estimate of `∫ f cos θo dωo` over the quadrature albedo, 1
    /// for an unbiased sampler (a warp that folds or misses part of the disk moves it).
    pub weight_mean: f64,
    /// Its worst (farthest from 1) condition.
    pub weight_mean_worst: f64,
    /// `E[w²] − 1`: χ²(p* ‖ q) of the density the samples are drawn with (the render's
    /// relative variance per sample; the [`Fit::chi2`] above is the pdf network's).
    pub chi2: f64,
    /// `E_q[ln(q/p̂)]` over the samples: KL(q ‖ p̂) of the MIS density `p̂` (`Prepared::pdf`)
    /// to the samples' density `q`.
    pub mis_kl: f64,
    /// `E_q[q/p̂] − 1`: χ²(q ‖ p̂).
    pub mis_chi2: f64,
}

/// Samples per condition of [`SampledFit`].
pub const FIT_SAMPLES: usize = 16384;

/// Whether `prep`'s samples are drawn with their MIS density, the sampler's `pdf`
/// ([`neusample::Sample::mis_pdf`] equal to [`neusample::Sample::pdf`]), on 16 stratified
/// samples: true for every kind but the reparameterization sampler, whose warp's density
/// and pdf network agree only approximately.
pub fn samples_carry_pdf<P: Prepared>(prep: &P) -> bool {
    (0..16).all(|i| {
        let u = Vec2::new((i % 4) as f32 * 0.25 + 0.125, (i / 4) as f32 * 0.25 + 0.125);
        prep.sample(u).is_none_or(|s| s.mis_pdf == s.pdf)
    })
}

/// [`SampledFit`]'s figures at one condition: `(E[w], E[w²] − 1, KL, χ²)`; `a` is the
/// condition's quadrature albedo.
fn sampled_fit<P: Prepared>(
    prep: &P,
    m: &dyn Material,
    c: &groundtruth::Condition,
    a: f64,
    seed: u64,
) -> (f64, f64, f64, f64) {
    let k = (FIT_SAMPLES as f64).sqrt() as usize;
    let n = k * k;
    let mut rng = crate::util::rng::rng_for(seed, 0x5a3f, 0);
    let (mut w1, mut w2, mut kl, mut x2, mut kept) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0usize);
    for i in 0..n {
        use rand::RngExt;
        let u = Vec2::new(
            (((i % k) as f32 + rng.random::<f32>()) / k as f32).min(neusample::ONE_MINUS_EPSILON),
            (((i / k) as f32 + rng.random::<f32>()) / k as f32).min(neusample::ONE_MINUS_EPSILON),
        );
        let Some(s) = prep.sample(u) else { continue };
        let f = f64::from(crate::materials::luminance(m.eval(&c.phi, c.wi, s.wo)));
        let q = f64::from(s.pdf_disk);
        if f > 0.0 && f.is_finite() && a > 0.0 {
            let w = f / (a * q);
            w1 += w;
            w2 += w * w;
        }
        let p_mis = f64::from(s.mis_pdf) / f64::from(s.wo.z);
        if p_mis > 0.0 && p_mis.is_finite() {
            kl += (q / p_mis).ln();
            x2 += q / p_mis;
            kept += 1;
        }
    }
    let kept = kept.max(1) as f64;
    (
        w1 / n as f64,
        w2 / n as f64 - 1.0,
        kl / kept,
        x2 / kept - 1.0,
    )
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
    let conds = groundtruth::conditions(material, conditions, seed);
    let nodes = groundtruth::rim_quadrature(groundtruth::RIM_RADIAL, groundtruth::RIM_ANGULAR);
    type Sampled = Option<(f64, f64, f64, f64)>;
    let per: Vec<(f64, f64, f64, f64, Sampled)> = conds
        .par_iter()
        .enumerate()
        .map(|(ci, c)| {
            let (target_material, tc) = match reference {
                None => (material, *c),
                Some(r) => (
                    r,
                    groundtruth::Condition {
                        phi: r.features(c.uv),
                        ..*c
                    },
                ),
            };
            let target = TargetPdf::new(target_material, &tc, res);
            let Some(prep) = sampler.prepare(&c.phi, c.wi) else {
                return (f64::INFINITY, f64::INFINITY, 0.0, f64::INFINITY, None);
            };
            let kl = target.kl_from(|p| prep.pdf_disk(p));
            let (a, m2) =
                groundtruth::rim_moments(target_material, &tc, &nodes, |p| prep.pdf_disk(p));
            let chi2 = if a > 0.0 { m2 / (a * a) - 1.0 } else { 0.0 };
            let sampled = (!samples_carry_pdf(&prep))
                .then(|| sampled_fit(&prep, target_material, &tc, a, mix_seed(seed, ci as u64)));
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
            (kl, se / n as f64, mass, chi2, sampled)
        })
        .collect();
    let with: Vec<(f64, f64, f64, f64)> = per.iter().filter_map(|p| p.4).collect();
    let sampled = (!with.is_empty()).then(|| {
        let k = with.len() as f64;
        SampledFit {
            weight_mean: with.iter().map(|s| s.0).sum::<f64>() / k,
            weight_mean_worst: with.iter().map(|s| s.0).fold(1.0, |w, x| {
                if (x - 1.0).abs() > (w - 1.0).abs() {
                    x
                } else {
                    w
                }
            }),
            chi2: with.iter().map(|s| s.1).sum::<f64>() / k,
            mis_kl: with.iter().map(|s| s.2).sum::<f64>() / k,
            mis_chi2: with.iter().map(|s| s.3).sum::<f64>() / k,
        }
    });
    let n = per.len().max(1) as f64;
    let (chi2_worst_condition, chi2_worst) =
        per.iter()
            .map(|p| p.3)
            .enumerate()
            .fold(
                (0, f64::NEG_INFINITY),
                |a, (i, c)| if c > a.1 { (i, c) } else { a },
            );
    Fit {
        conditions: per.len(),
        kl_divergence: per.iter().map(|p| p.0).sum::<f64>() / n,
        chi2: per.iter().map(|p| p.3).sum::<f64>() / n,
        chi2_worst,
        chi2_worst_condition,
        pdf_mse: per.iter().map(|p| p.1).sum::<f64>() / n,
        mass_in_disk: per.iter().map(|p| p.2).sum::<f64>() / n,
        sampled,
    }
}

/// How well a neural material reproduces its source, measured through the runtime.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct FitReport {
    /// Random queries of the RGB error.
    pub points: usize,
    /// `Σ|f̂ − f| / Σ|f|` over RGB channels and queries with `wo` uniform on the projected
    /// disk (the rendering measure): the relative L1 error of `f·cos`.
    #[serde(deserialize_with = "f64_or_nan")]
    pub relative_rgb_error: f64,
    /// The same with `wo` around the mirror direction (the highlight region).
    #[serde(deserialize_with = "f64_or_nan")]
    pub relative_rgb_error_lobe: f64,
    /// RMS of `ln(ε + f̂) − ln(ε + f)` (the training loss, square-rooted) on fresh queries.
    #[serde(deserialize_with = "f64_or_nan")]
    pub log_rmse: f64,
    /// Conditions `(uv, wi)` of the KL and albedo measures.
    pub conditions: usize,
    /// Mean `KL(p*_source ‖ p*_neural)` in nats (tables at `res²`, same uv and wi).
    #[serde(deserialize_with = "f64_or_nan")]
    pub kl_pstar: f64,
    /// Mean `KL(p*_source ‖ uniform disk)`: the KL of cosine sampling, for scale.
    #[serde(deserialize_with = "f64_or_nan")]
    pub kl_pstar_vs_cosine: f64,
    /// `Σ|a_neural − a_source| / Σ a_source` over the conditions, `a` the luminance albedo
    /// `∫ Y(f) cos θo dωo` at the condition.
    #[serde(deserialize_with = "f64_or_nan")]
    pub albedo_relative_error: f64,
}

/// Measures a neural material (any [`Material`], typically a
/// [`crate::materials::neural::NeuralMaterialModel`])
/// against its source: `points` random queries and `conditions` tabulated p* at `res²`.
pub fn fit_report(
    source: &dyn Material,
    neural: &dyn Material,
    points: usize,
    conditions: usize,
    res: usize,
    epsilon: f32,
    seed: u64,
) -> FitReport {
    let rel = |lobe: f32, s: u64| {
        let q = draw(source, None, points, lobe, mix_seed(seed, s), 0);
        let (num, den, se) = q
            .par_iter()
            .map(|s| {
                let g = neural.eval(&neural.features(s.uv), s.wi, s.wo);
                let (mut num, mut den, mut se) = (0f64, 0f64, 0f64);
                for c in 0..3 {
                    num += f64::from((g[c] - s.f[c]).abs());
                    den += f64::from(s.f[c].abs());
                    let d = f64::from((epsilon + g[c]).ln() - (epsilon + s.f[c]).ln());
                    se += d * d;
                }
                (num, den, se)
            })
            .reduce(|| (0.0, 0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
        (
            num / den.max(1e-30),
            (se / (3 * q.len().max(1)) as f64).sqrt(),
        )
    };
    let (disk, log_rmse) = rel(0.0, 1);
    let (lobe, _) = rel(1.0, 2);
    let conds = groundtruth::conditions(source, conditions, mix_seed(seed, 3));
    let per: Vec<(f64, f64, f64, f64)> = conds
        .par_iter()
        .map(|c| {
            let src = TargetPdf::new(source, c, res);
            let nc = groundtruth::Condition {
                phi: neural.features(c.uv),
                ..*c
            };
            let neu = TargetPdf::new(neural, &nc, res);
            let kl = src.kl_from(|p| neu.pdf(p));
            let kl_cos = src.kl_from(|_| std::f32::consts::FRAC_1_PI);
            (
                kl,
                kl_cos,
                (neu.integral() - src.integral()).abs(),
                src.integral(),
            )
        })
        .collect();
    let n = per.len().max(1) as f64;
    FitReport {
        points,
        relative_rgb_error: disk,
        relative_rgb_error_lobe: lobe,
        log_rmse,
        conditions: per.len(),
        kl_pstar: per.iter().map(|p| p.0).sum::<f64>() / n,
        kl_pstar_vs_cosine: per.iter().map(|p| p.1).sum::<f64>() / n,
        albedo_relative_error: per.iter().map(|p| p.2).sum::<f64>()
            / per.iter().map(|p| p.3).sum::<f64>().max(1e-30),
    }
}
