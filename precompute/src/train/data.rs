//! Training data: conditions with their ground-truth target densities p*(ω⊥ | φ, wi), a
//! pool of them refreshed during training, and the per-step batches drawn from the pool.
//!
//! The trainer draws conditions through [`TargetSource`], so that it runs on a material
//! ([`super::MaterialSource`], through `crate::groundtruth`) and on the synthetic target of
//! this module ([`SyntheticSource`], a closed-form conditional mixture tabulated the same
//! way, used by the tests and for quick experiments).
//!
//! Every random number is drawn from a PCG stream seeded by `(seed, step, index)`, so a batch
//! does not depend on how rayon schedules its construction.

use glam::{Vec2, Vec3};
use neusample::nn::{check_condition, encode_condition, raw_condition};
use neusample::nn::{CONDITION_DIM, RAW_CONDITION_DIM};
use neusample::FEATURE_DIM;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

use crate::groundtruth::TargetPdf;

/// One training condition (φ, wi) with its target density.
pub struct GtCondition {
    /// Material features φ at the condition's texel.
    pub phi: [f32; FEATURE_DIM],
    /// Incoming direction (local frame, unit length, above the horizon).
    pub wi: Vec3,
    /// p*(ω⊥ | φ, wi), tabulated.
    pub target: TargetPdf,
}

/// A source of training conditions, deterministic in its seed.
pub trait TargetSource: Sync {
    /// `n` random conditions with their targets tabulated at `res × res`, a pure function
    /// of `(n, res, seed)`.
    fn draw(&self, n: usize, res: usize, seed: u64) -> anyhow::Result<Vec<GtCondition>>;
}

/// SplitMix64 finaliser: decorrelates seeds built from small integers.
#[must_use]
pub fn mix_seed(a: u64, b: u64) -> u64 {
    let mut z = a
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(b)
        .wrapping_add(0x632B_E59B_D9B4_E019);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A PCG stream for `(seed, a, b)`.
#[must_use]
pub fn rng_for(seed: u64, a: u64, b: u64) -> Pcg64 {
    Pcg64::seed_from_u64(mix_seed(mix_seed(seed, a), b))
}

// ---------------------------------------------------------------------------------------
// Synthetic conditional target
// ---------------------------------------------------------------------------------------

/// A closed-form conditional target for tests: a Lambert floor plus two anisotropic
/// Gaussian lobes on the disk whose centres, widths and weights depend smoothly on φ and wi
/// (the main lobe follows the mirror direction `−wi⊥`, shifted by φ like a normal map).
///
/// φ is uniform in `[−1, 1]⁸`; wi is cosine-distributed with `|wi⊥| < 0.9`.
#[derive(Clone, Copy, Debug, Default)]
pub struct SyntheticSource;

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

impl SyntheticSource {
    /// The unnormalised target f(p | φ, wi).
    #[must_use]
    pub fn density(phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f32 {
        let m1 = Vec2::new(-wi.x, -wi.y) + 0.3 * Vec2::new(phi[0], phi[1]);
        let s1 = Vec2::new(
            0.04 + 0.2 * sigmoid(2.0 * phi[2]),
            0.04 + 0.2 * sigmoid(2.0 * phi[3]),
        );
        let m2 = 0.5 * Vec2::new(phi[5], phi[6]);
        let s2 = 0.15 + 0.1 * sigmoid(phi[7]);
        let w2 = 0.4 * sigmoid(3.0 * phi[4]);
        let floor = 0.05 + 0.1 * sigmoid(2.0 * phi[7]);
        let g = |m: Vec2, s: Vec2| {
            let d = (p - m) / s;
            (-0.5 * d.length_squared()).exp() / (std::f32::consts::TAU * s.x * s.y)
        };
        floor / std::f32::consts::PI + g(m1, s1) + w2 * g(m2, Vec2::splat(s2))
    }

    /// One random condition from `rng`.
    pub fn condition(rng: &mut Pcg64) -> ([f32; FEATURE_DIM], Vec3) {
        let mut phi = [0.0f32; FEATURE_DIM];
        for v in &mut phi {
            *v = rng.random_range(-1.0f32..1.0);
        }
        let wi = loop {
            let x = rng.random_range(-1.0f32..1.0);
            let y = rng.random_range(-1.0f32..1.0);
            let r2 = x * x + y * y;
            if r2 < 0.81 {
                break Vec3::new(x, y, (1.0 - r2).sqrt());
            }
        };
        (phi, wi)
    }
}

impl TargetSource for SyntheticSource {
    fn draw(&self, n: usize, res: usize, seed: u64) -> anyhow::Result<Vec<GtCondition>> {
        Ok((0..n)
            .into_par_iter()
            .map(|i| {
                let mut rng = rng_for(seed, 0x5e17, i as u64);
                let (phi, wi) = Self::condition(&mut rng);
                let h = 2.0 / res as f32;
                let mut values = vec![0.0f32; res * res];
                for r in 0..res {
                    for c in 0..res {
                        let mut acc = 0.0;
                        for i in 0..2 {
                            for j in 0..2 {
                                let p = Vec2::new(
                                    -1.0 + h * (c as f32 + 0.25 + 0.5 * j as f32),
                                    -1.0 + h * (r as f32 + 0.25 + 0.5 * i as f32),
                                );
                                acc += 0.25 * Self::density(&phi, wi, p);
                            }
                        }
                        values[r * res + c] = acc;
                    }
                }
                GtCondition {
                    phi,
                    wi,
                    target: TargetPdf::from_values(res, values),
                }
            })
            .collect())
    }
}

// ---------------------------------------------------------------------------------------
// Pool and batches
// ---------------------------------------------------------------------------------------

/// The conditions training draws its batches from. A quarter of the pool is replaced by
/// fresh conditions every `refresh_every` steps, so long runs see many more conditions than
/// the pool holds at once.
pub struct Pool<'a> {
    source: &'a dyn TargetSource,
    items: Vec<GtCondition>,
    res: usize,
    seed: u64,
    refresh_every: usize,
    round: u64,
    cursor: usize,
}

impl<'a> Pool<'a> {
    /// Draws the initial `size` conditions.
    pub fn new(
        source: &'a dyn TargetSource,
        size: usize,
        res: usize,
        seed: u64,
        refresh_every: usize,
    ) -> anyhow::Result<Self> {
        anyhow::ensure!(
            size > 0,
            "the ground-truth pool needs at least one condition"
        );
        let items = source.draw(size, res, mix_seed(seed, 0))?;
        anyhow::ensure!(
            items.len() == size,
            "the ground-truth source returned {} conditions instead of {size}",
            items.len()
        );
        Ok(Pool {
            source,
            items,
            res,
            seed,
            refresh_every,
            round: 0,
            cursor: 0,
        })
    }

    /// Replaces a quarter of the pool when `step` is a refresh step (not step 0).
    pub fn maybe_refresh(&mut self, step: usize) -> anyhow::Result<()> {
        if self.refresh_every == 0 || step == 0 || step % self.refresh_every != 0 {
            return Ok(());
        }
        self.round += 1;
        let n = self.items.len().div_ceil(4);
        let fresh = self
            .source
            .draw(n, self.res, mix_seed(self.seed, self.round))?;
        for g in fresh {
            let i = self.cursor;
            self.items[i] = g;
            self.cursor = (self.cursor + 1) % self.items.len();
        }
        Ok(())
    }

    /// The conditions.
    #[must_use]
    pub fn items(&self) -> &[GtCondition] {
        &self.items
    }
}

/// How the points of a batch are chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PointKind {
    /// Samples of p* (maximum likelihood, paper §3 "Fitting").
    FromTarget,
    /// Half uniform on the disk, half from p*, each with its target value p*(ω⊥) (the L2
    /// regression of the histogram mixture, Eq. 7).
    Regression,
}

/// One training batch, host side: `b` conditions × `s` points.
pub struct HostBatch {
    /// Number of conditions.
    pub b: usize,
    /// Points per condition.
    pub s: usize,
    /// Encoded conditions, `b × CONDITION_DIM`.
    pub cond: Vec<f32>,
    /// Raw conditions, `b × RAW_CONDITION_DIM`.
    pub raw: Vec<f32>,
    /// Point x coordinates, `b × s`.
    pub x: Vec<f32>,
    /// Point y coordinates, `b × s`.
    pub y: Vec<f32>,
    /// p* at the points (only for [`PointKind::Regression`]), `b × s`.
    pub target: Vec<f32>,
}

/// A uniform point on the open unit disk.
fn uniform_disk(rng: &mut Pcg64) -> Vec2 {
    loop {
        let p = Vec2::new(
            rng.random_range(-1.0f32..1.0),
            rng.random_range(-1.0f32..1.0),
        );
        if p.length_squared() < 1.0 {
            return p;
        }
    }
}

fn sample_target(t: &TargetPdf, rng: &mut Pcg64) -> Vec2 {
    for _ in 0..64 {
        let u = Vec2::new(rng.random(), rng.random());
        if let Some(p) = t.sample(u) {
            if p.is_finite() && p.length_squared() < 1.0 {
                return p;
            }
        }
    }
    // A target without samples: fall back to uniform points (never seen with real data).
    uniform_disk(rng)
}

/// Builds the batch of `step`: `b` pool conditions (with replacement) × `s` points.
pub fn make_batch(
    pool: &Pool<'_>,
    b: usize,
    s: usize,
    kind: PointKind,
    seed: u64,
    step: usize,
) -> HostBatch {
    let items = pool.items();
    let mut pick = rng_for(mix_seed(seed, 0xba7c), step as u64, 0);
    let chosen: Vec<usize> = (0..b).map(|_| pick.random_range(0..items.len())).collect();
    let rows: Vec<_> = chosen
        .par_iter()
        .enumerate()
        .map(|(j, &i)| {
            let g = &items[i];
            let mut rng = rng_for(mix_seed(seed, 0x9017), step as u64, j as u64);
            let wi = check_condition(&g.phi, g.wi).unwrap_or(Vec3::Z);
            let cond = encode_condition(&g.phi, wi);
            let raw = raw_condition(&g.phi, wi);
            let mut xs = Vec::with_capacity(s);
            let mut ys = Vec::with_capacity(s);
            let mut ts = Vec::new();
            for k in 0..s {
                let p = match kind {
                    PointKind::FromTarget => sample_target(&g.target, &mut rng),
                    PointKind::Regression if k % 2 == 0 => uniform_disk(&mut rng),
                    PointKind::Regression => sample_target(&g.target, &mut rng),
                };
                xs.push(p.x);
                ys.push(p.y);
                if kind == PointKind::Regression {
                    ts.push(g.target.pdf(p));
                }
            }
            (cond, raw, xs, ys, ts)
        })
        .collect();
    let mut out = HostBatch {
        b,
        s,
        cond: Vec::with_capacity(b * CONDITION_DIM),
        raw: Vec::with_capacity(b * RAW_CONDITION_DIM),
        x: Vec::with_capacity(b * s),
        y: Vec::with_capacity(b * s),
        target: Vec::new(),
    };
    for (cond, raw, xs, ys, ts) in rows {
        out.cond.extend_from_slice(&cond);
        out.raw.extend_from_slice(&raw);
        out.x.extend(xs);
        out.y.extend(ys);
        out.target.extend(ts);
    }
    out
}
