//! Where training conditions come from: a material (through [`crate::groundtruth`]) or the
//! closed-form synthetic target of the tests ([`SyntheticSource`], a conditional mixture
//! tabulated the same way). Both are deterministic in their seed.

use burn::tensor::{Device, Tensor};
use glam::{Vec2, Vec3};
use neusample::FEATURE_DIM;
use rand::RngExt;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::integrand::{ConditionRows, Integrand, MeasuredIntegrand, NeuralIntegrand};
use crate::groundtruth::{self, TargetOptions, TargetPdf};
use crate::materials::Material;
use crate::util::rng::{indexed_rng, rng_for};

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
    /// Random condition `i` of the draw with `seed`, with its target tabulated at `res × res`
    /// with `opts`: a pure function of `(i, res, seed, opts)`.
    fn draw_one(&self, i: usize, res: usize, seed: u64, opts: &TargetOptions) -> GtCondition;

    /// `n` random conditions with their targets tabulated at `res × res` with `opts`, a pure
    /// function of `(n, res, seed, opts)`: conditions `0 .. n` of [`TargetSource::draw_one`],
    /// drawn in parallel (so a draw of `n` is a prefix of a draw of `m > n`).
    fn draw_with(
        &self,
        n: usize,
        res: usize,
        seed: u64,
        opts: &TargetOptions,
    ) -> anyhow::Result<Vec<GtCondition>> {
        Ok((0..n)
            .into_par_iter()
            .map(|i| self.draw_one(i, res, seed, opts))
            .collect())
    }

    /// [`TargetSource::draw_with`] with the default options (the fit metrics' targets).
    fn draw(&self, n: usize, res: usize, seed: u64) -> anyhow::Result<Vec<GtCondition>> {
        self.draw_with(n, res, seed, &TargetOptions::default())
    }

    /// The unnormalised target with a differentiable training graph, which the
    /// reparameterization sampler trains on; `None` where the source has none (a material
    /// that is not a neural material).
    fn integrand(&self) -> Option<&dyn Integrand> {
        None
    }

    /// Whether the conditions' `wi` lie at azimuth 0 (an isotropic material, see
    /// [`Material::isotropic`]): the trained sampler's blob says so, and the runtime turns
    /// every condition there.
    fn isotropic(&self) -> bool {
        false
    }
}

/// Draws training conditions of a material ([`groundtruth::training_condition`]).
pub struct MaterialSource<'a> {
    material: &'a dyn Material,
    integrand: Option<Box<dyn Integrand + 'a>>,
}

impl<'a> MaterialSource<'a> {
    /// The source of `material`, with the integrand of a neural or a measured material.
    #[must_use]
    pub fn new(material: &'a dyn Material) -> Self {
        MaterialSource {
            material,
            integrand: material_integrand(material),
        }
    }
}

/// The integrand the reparameterization sampler trains on, for the materials that have one:
/// a neural material (its decoder) and a measured one (its tables).
#[must_use]
pub fn material_integrand<'a>(material: &'a dyn Material) -> Option<Box<dyn Integrand + 'a>> {
    if let Some(n) = material.neural() {
        return Some(Box::new(NeuralIntegrand::new(n)));
    }
    material
        .measured()
        .map(|m| Box::new(MeasuredIntegrand::new(m.material())) as Box<dyn Integrand + 'a>)
}

/// Whether `material` has an integrand to train the reparameterization sampler on
/// ([`material_integrand`] is `Some`).
#[must_use]
pub fn has_integrand(material: &dyn Material) -> bool {
    material_integrand(material).is_some()
}

impl TargetSource for MaterialSource<'_> {
    fn draw_one(&self, i: usize, res: usize, seed: u64, opts: &TargetOptions) -> GtCondition {
        let c = groundtruth::training_condition(self.material, &mut indexed_rng(seed, i));
        GtCondition {
            phi: c.phi,
            wi: c.wi,
            target: TargetPdf::with_options(self.material, &c, res, opts),
        }
    }

    fn integrand(&self) -> Option<&dyn Integrand> {
        self.integrand.as_deref()
    }

    fn isotropic(&self) -> bool {
        self.material.isotropic()
    }
}

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
    /// The lobes of condition `(φ, wi)`: `[m1.x, m1.y, s1.x, s1.y, m2.x, m2.y, s2, w2,
    /// floor]` (means, widths, the second lobe's weight and the Lambert floor).
    #[must_use]
    pub fn lobes(phi: &[f32; FEATURE_DIM], wi: Vec3) -> [f32; 9] {
        let m1 = Vec2::new(-wi.x, -wi.y) + 0.3 * Vec2::new(phi[0], phi[1]);
        let s1 = Vec2::new(
            0.04 + 0.2 * sigmoid(2.0 * phi[2]),
            0.04 + 0.2 * sigmoid(2.0 * phi[3]),
        );
        let m2 = 0.5 * Vec2::new(phi[5], phi[6]);
        let s2 = 0.15 + 0.1 * sigmoid(phi[7]);
        let w2 = 0.4 * sigmoid(3.0 * phi[4]);
        let floor = 0.05 + 0.1 * sigmoid(2.0 * phi[7]);
        [m1.x, m1.y, s1.x, s1.y, m2.x, m2.y, s2, w2, floor]
    }

    /// The unnormalised target f(p | φ, wi).
    #[must_use]
    pub fn density(phi: &[f32; FEATURE_DIM], wi: Vec3, p: Vec2) -> f32 {
        let [m1x, m1y, s1x, s1y, m2x, m2y, s2, w2, floor] = Self::lobes(phi, wi);
        let (m1, s1, m2) = (
            Vec2::new(m1x, m1y),
            Vec2::new(s1x, s1y),
            Vec2::new(m2x, m2y),
        );
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

    /// The target of condition `(φ, wi)` tabulated at `res × res`: the mean of the density
    /// over each cell's 2 × 2 stratified points, with `opts.to_horizon` over those inside the
    /// disk of the cells straddling the circle.
    #[must_use]
    pub fn target(
        phi: &[f32; FEATURE_DIM],
        wi: Vec3,
        res: usize,
        opts: &TargetOptions,
    ) -> TargetPdf {
        let h = 2.0 / res as f32;
        let mut values = vec![0.0f32; res * res];
        let mut inside = vec![0.0f32; res * res];
        for r in 0..res {
            for c in 0..res {
                let (mut acc, mut n_in) = (0.0, 0);
                for i in 0..2 {
                    for j in 0..2 {
                        let p = Vec2::new(
                            -1.0 + h * (c as f32 + 0.25 + 0.5 * j as f32),
                            -1.0 + h * (r as f32 + 0.25 + 0.5 * i as f32),
                        );
                        if p.length_squared() < 1.0 || !opts.to_horizon {
                            acc += Self::density(phi, wi, p);
                            n_in += 1;
                        }
                    }
                }
                let i = r * res + c;
                if groundtruth::cell_inside_disk(res, r, c) {
                    (values[i], inside[i]) = (acc / 4.0, 1.0);
                } else if opts.to_horizon && n_in > 0 {
                    (values[i], inside[i]) = (acc / n_in as f32, n_in as f32 / 4.0);
                }
            }
        }
        TargetPdf::from_cells(res, values, &inside)
    }
}

impl TargetSource for SyntheticSource {
    fn integrand(&self) -> Option<&dyn Integrand> {
        Some(&SyntheticIntegrand)
    }

    fn draw_one(&self, i: usize, res: usize, seed: u64, opts: &TargetOptions) -> GtCondition {
        let (phi, wi) = Self::condition(&mut rng_for(seed, 0x5e17, i as u64));
        GtCondition {
            phi,
            wi,
            target: Self::target(&phi, wi, res, opts),
        }
    }
}

/// [`SyntheticSource::density`] as an integrand.
pub struct SyntheticIntegrand;

impl Integrand for SyntheticIntegrand {
    fn log_f(&self, rows: ConditionRows<'_>, wo: Tensor<2>, device: &Device) -> Tensor<2> {
        let l = rows.per_condition(9, device, |phi, wi, row| {
            row.extend(SyntheticSource::lobes(phi, wi));
        });
        let c = |j: usize| l.clone().narrow(1, j, 1);
        let (px, py) = (wo.clone().narrow(1, 0, 1), wo.narrow(1, 1, 1));
        let tau = std::f32::consts::TAU;
        let g = |mx: Tensor<2>, my: Tensor<2>, sx: Tensor<2>, sy: Tensor<2>| {
            let dx = (px.clone() - mx) / sx.clone();
            let dy = (py.clone() - my) / sy.clone();
            ((dx.powi_scalar(2) + dy.powi_scalar(2)) * (-0.5)).exp() / (sx * sy * tau)
        };
        let f = c(8) / std::f32::consts::PI
            + g(c(0), c(1), c(2), c(3))
            + c(7) * g(c(4), c(5), c(6), c(6));
        f.log()
    }

    fn f(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> f32 {
        if !(wo.z > 0.0) {
            return 0.0;
        }
        SyntheticSource::density(phi, wi, Vec2::new(wo.x, wo.y))
    }
}
