//! The "tabulated" near-optimal sampler of the paper (Fig. 10): the ground truth p* tabulated
//! at each shading point and sampled exactly. It plugs into the renderer and the evaluation
//! like any runtime sampler, through the public [`Sampler`] / [`Prepared`] traits.

use glam::{Vec2, Vec3};
use neusample::distrib::table2d::MAX_N;
use neusample::{warp, Prepared, Sample, Sampler, Table2D, FEATURE_DIM, ONE_MINUS_EPSILON};

use crate::groundtruth::{cell_luminance_sum, running_sums};
use crate::materials::Material;

/// The "tabulated" near-optimal sampler (paper Fig. 10): at each shading point, the ground
/// truth p*(ω⊥ | φ, wi) ∝ Y(f(φ, wi, ω)) is tabulated on a `res × res` grid over the projected
/// disk and sampled exactly through the runtime's [`Table2D`]. Its `prepare` is expensive
/// (`res² · s²` material evaluations), which is why it is a limit, not a method.
///
/// It follows [`crate::groundtruth::TargetPdf`] (cell value = mean of `Y(f)` over `s × s`
/// stratified points, [`cell_luminance_sum`]) with two changes that make it **unbiased** for rendering: cells that
/// straddle the circle are kept (the points of a cell outside the disk count as 0; a sample
/// falling outside the disk is refused, as in the runtime's histograms) and there is no
/// grazing cut-off; and a small defensive share of cosine sampling
/// (`p = (1 − d)·p_table + d/π`) covers any sliver the table misses.
#[derive(Clone, Copy)]
pub struct OracleSampler<'m> {
    /// The material.
    pub material: &'m dyn Material,
    /// Grid resolution per side (≤ [`MAX_N`]).
    pub res: usize,
    /// Stratified points per cell and axis.
    pub supersample: usize,
    /// Share `d` of cosine sampling.
    pub defensive: f32,
}

impl std::fmt::Debug for OracleSampler<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OracleSampler")
            .field("material", &self.material.name())
            .field("res", &self.res)
            .field("supersample", &self.supersample)
            .field("defensive", &self.defensive)
            .finish()
    }
}

impl<'m> OracleSampler<'m> {
    /// An oracle with 2 × 2 points per cell and a 2 % defensive share.
    #[must_use]
    pub fn new(material: &'m dyn Material, res: usize) -> Self {
        OracleSampler {
            material,
            res: res.clamp(1, MAX_N),
            supersample: 2,
            defensive: 0.02,
        }
    }
}

/// The prepared state of [`OracleSampler`]: the tabulated density and its running sums.
#[derive(Clone, Debug)]
pub struct OraclePrepared {
    values: Vec<f32>,
    marginal: Vec<f32>,
    conditional: Vec<f32>,
    res: u32,
    defensive: f32,
}

impl OraclePrepared {
    fn table(&self) -> Option<Table2D<&[f32]>> {
        Table2D::new(
            &self.values[..],
            &self.marginal[..],
            &self.conditional[..],
            self.res,
            0,
        )
    }
}

impl Sampler for OracleSampler<'_> {
    type Prepared<'s>
        = OraclePrepared
    where
        Self: 's;

    fn prepare(&self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<OraclePrepared> {
        let wi = neusample::nn::check_condition(phi, wi)?;
        let res = self.res.clamp(1, MAX_N);
        let s = self.supersample.max(1);
        let mut values = vec![0f32; res * res];
        let mut total = 0.0f64;
        for r in 0..res {
            for c in 0..res {
                if neusample::distrib::table2d::cell_outside_disk(r as u32, c as u32, res as u32) {
                    continue;
                }
                let acc = cell_luminance_sum(self.material, phi, wi, res, (r, c), s, |r2| r2 < 1.0);
                let v = acc / (s * s) as f32;
                values[r * res + c] = v;
                total += f64::from(v);
            }
        }
        let mut defensive = self.defensive.clamp(0.0, 1.0);
        if !(total > 0.0 && total.is_finite()) {
            // Nothing reflects: cosine sampling only.
            defensive = 1.0;
            values.iter_mut().for_each(|v| *v = 0.0);
            values[0] = 1.0;
        }
        let (marginal, conditional) = running_sums(&values, res);
        Some(OraclePrepared {
            values,
            marginal,
            conditional,
            res: res as u32,
            defensive,
        })
    }
}

impl Prepared for OraclePrepared {
    fn sample(&self, u: Vec2) -> Option<Sample> {
        // u outside [0, 1]² (or NaN) is refused; u = 1 is moved just below 1.
        if !(u.x >= 0.0 && u.x <= 1.0 && u.y >= 0.0 && u.y <= 1.0) {
            return None;
        }
        let u = u.min(Vec2::splat(ONE_MINUS_EPSILON));
        let d = self.defensive;
        let p = if u.x < d {
            warp::sample_uniform_disk_concentric(Vec2::new(u.x / d, u.y))
        } else {
            let ux = ((u.x - d) / (1.0 - d)).min(ONE_MINUS_EPSILON);
            self.table()?.sample(Vec2::new(ux, u.y))?.0
        };
        Sample::from_disk(p, self.pdf_disk(p))
    }

    fn pdf_disk(&self, p: Vec2) -> f32 {
        if !(p.length_squared() < 1.0) {
            return 0.0;
        }
        let d = self.defensive;
        let t = if d < 1.0 {
            self.table().map_or(0.0, |t| t.pdf(p))
        } else {
            0.0
        };
        (1.0 - d) * t + d * warp::uniform_disk_pdf(p)
    }
}
