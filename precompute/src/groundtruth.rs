//! Ground-truth target densities: for a condition (φ, wi) of a material, the tabulated
//! projected-disk density
//!
//! ```text
//! p*(ω⊥ | φ, wi) ∝ Y(f(φ, wi, ω(ω⊥)))        (Y = luminance, ω(ω⊥) = (x, y, √(1 − |ω⊥|²)))
//! ```
//!
//! which is the density of sampling ∝ BRDF·cos on the hemisphere, expressed on the disk
//! (paper §3; `p_ω = p*·cos θo`). It is what the samplers are trained against and compared to
//! (KL divergence, paper Fig. 7), and sampling it exactly gives the paper's "tabulated"
//! near-optimal reference sampler (Fig. 10).
//!
//! # Discretisation (a choice, documented here)
//!
//! * An `R × R` grid of square cells over `[−1, 1]²`, row-major with rows = y (cell `(r, c)`
//!   spans `x ∈ [−1 + c·h, −1 + (c+1)·h)`, `y` likewise with `r`, `h = 2/R`).
//! * A cell's value is the mean of `Y(f)` over `s × s` stratified cell-centred points
//!   (`s = 2` by default: the midpoints of the four quarter cells).
//! * Following the release, `f` is set to 0 at points with `|ω⊥|² > 0.98` (grazing
//!   directions, [`GRAZING_CUTOFF`]).
//! * Only cells lying **entirely inside** the unit disk (farthest corner at radius ≤ 1) get a
//!   non-zero density: the piecewise-constant density is then exactly 0 outside the disk,
//!   every sample lands strictly inside it (nothing is refused for lying outside, unlike the
//!   release), and the density a sample reports is `pdf` at its point. With the 0.98 cut-off
//!   this drops only the sliver of cells straddling the circle (radius > 0.98).
//! * Values are normalised so that `Σ density·h² = 1` (∫ over the disk = 1). If the function
//!   is 0 everywhere (possible only at pathological conditions), the density is uniform over
//!   the active cells and [`TargetPdf::degenerate`] says so.
//!
//! The table is stored in the layout of the runtime's baked histograms
//! (`neusample::samplers::histogram_mixture`: normalised cell densities plus unnormalised running sums, a
//! marginal over rows and a conditional within each row), and sampling, density and inverse
//! go through [`neusample::Table2D`] — the very code that samples baked tables:
//! a row from the marginal with `u.x`, a column from the row's conditional with `u.y`, the
//! remainders as the offset inside the cell, so `u ↦ ω⊥` is a bijection with an inverse
//! ([`TargetPdf::invert`]). `Table2D` supports `R ≤` [`neusample::samplers::histogram_mixture::MAX_N`] (128);
//! larger tables still give [`TargetPdf::density`], [`TargetPdf::pdf`] and
//! [`TargetPdf::kl_from`], but `sample` and `invert` return `None`.

use glam::{Vec2, Vec3};
use rand::RngExt;
use rayon::prelude::*;

use neusample::Table2D;

use crate::materials::{luminance, Material, FEATURE_DIM};
use crate::util::rng::indexed_rng;

/// The release's grazing cut-off: `f = 0` where `|ω⊥|² >` this value.
pub const GRAZING_CUTOFF: f32 = 0.98;

/// Smallest `wi.z` drawn by [`random_condition`].
pub const MIN_WI_Z: f32 = 0.05;

/// Density floor used by [`TargetPdf::kl_from`] where `q` is 0 or not finite.
pub const KL_Q_FLOOR: f64 = 1e-12;

/// A condition `(uv, φ(uv), wi)` (local frame, `wi` unit, `wi.z ≥ MIN_WI_Z` when drawn by
/// [`random_condition`]).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Condition {
    /// Texture coordinate in `[0, 1)²`.
    pub uv: Vec2,
    /// The material's features at `uv`.
    pub phi: [f32; FEATURE_DIM],
    /// Incident direction (unit, above the horizon).
    pub wi: Vec3,
}

/// A random incident direction: with probability 0.7 cosine-distributed, otherwise uniform in
/// solid angle (so grazing directions are well covered), both restricted to
/// `wi.z ≥` [`MIN_WI_Z`].
pub fn random_wi(rng: &mut impl rand::Rng) -> Vec3 {
    let pick: f32 = rng.random();
    let u: f32 = rng.random();
    let phi = std::f32::consts::TAU * rng.random::<f32>();
    let zmin = MIN_WI_Z;
    let z = if pick < 0.7 {
        // Cosine-distributed on the cap z ≥ zmin: |ω⊥|² uniform in [0, 1 − zmin²].
        (1.0 - u * (1.0 - zmin * zmin)).max(zmin * zmin).sqrt()
    } else {
        zmin + (1.0 - zmin) * u
    };
    let s = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(s * phi.cos(), s * phi.sin(), z)
}

/// A random condition: `uv` uniform in `[0, 1)²`, `φ = m.features(uv)`, `wi` from
/// [`random_wi`].
pub fn random_condition(m: &dyn Material, rng: &mut impl rand::Rng) -> Condition {
    let uv = Vec2::new(rng.random::<f32>(), rng.random::<f32>());
    let wi = random_wi(rng);
    Condition {
        uv,
        phi: m.features(uv),
        wi,
    }
}

/// A training condition: [`random_condition`], with `wi` turned to azimuth 0 on an
/// isotropic material ([`Material::isotropic`]), where samplers see only its elevation.
pub fn training_condition(m: &dyn Material, rng: &mut impl rand::Rng) -> Condition {
    let mut c = random_condition(m, rng);
    if m.isotropic() {
        c.wi = neusample::samplers::Turn::aligning(c.wi).1;
    }
    c
}

/// Options of [`TargetPdf::with_options`].
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct TargetOptions {
    /// Stratified points per cell and axis (`s × s` per cell), ≥ 1.
    pub supersample: usize,
    /// `f = 0` where `|ω⊥|² >` this (the release uses 0.98).
    pub grazing_cutoff: f32,
    /// Tabulate up to the horizon: cells straddling the circle keep the mean of `Y(f)` over
    /// their points inside the disk (with `2s × 2s` points), so that the target has mass
    /// wherever the material reflects. For training targets; the fit metrics keep the
    /// default (cells wholly inside the disk). See [`TargetOptions::horizon`].
    pub to_horizon: bool,
}

impl Default for TargetOptions {
    fn default() -> Self {
        TargetOptions {
            supersample: 2,
            grazing_cutoff: GRAZING_CUTOFF,
            to_horizon: false,
        }
    }
}

impl TargetOptions {
    /// Training targets up to the horizon: no grazing cut-off, straddling cells kept
    /// ([`TargetOptions::to_horizon`]). A sampler trained on the default targets never sees
    /// the outer ring of the disk (the cut-off at `|ω⊥|² = 0.98` and the cells straddling the
    /// circle), where the materials still reflect and its weights then explode.
    #[must_use]
    pub fn horizon() -> Self {
        TargetOptions {
            grazing_cutoff: 1.0,
            to_horizon: true,
            ..TargetOptions::default()
        }
    }
}

/// The tabulated target density p*(ω⊥ | φ, wi) on the projected disk (module docs).
#[derive(Clone, Debug)]
pub struct TargetPdf {
    res: usize,
    /// Per cell, density w.r.t. disk area; rows = y.
    density: Vec<f32>,
    /// Running sums of the row totals of `density` (`R` entries, core layout).
    marginal: Vec<f32>,
    /// Running sums of `density` within each row (`R²` entries, core layout).
    conditional: Vec<f32>,
    /// `∫ Y(f) dω⊥` before normalisation (the luminance albedo `∫ Y(f) cos θo dωo`).
    integral: f64,
    /// [`TargetPdf::pdf`]'s factor on `density`: 1, or with cells straddling the circle
    /// (sampled by rejection, so only their part inside the disk counts) the table's total
    /// over the total inside the disk.
    pdf_scale: f32,
    degenerate: bool,
}

/// Marginal and conditional running sums of a `res × res` table of cell
/// values (row-major), as [`neusample::distrib::table2d::running_sums`]
/// fills them.
#[must_use]
pub fn running_sums(values: &[f32], res: usize) -> (Vec<f32>, Vec<f32>) {
    let mut marginal = vec![0f32; res];
    let mut conditional = vec![0f32; res * res];
    neusample::distrib::table2d::running_sums(values, res as u32, &mut marginal, &mut conditional);
    (marginal, conditional)
}

/// The sum of `Y(f(φ, wi, ω(p)))` over the `s × s` stratified points `p` of cell
/// `(row, col)` of an `res × res` grid over `[−1, 1]²` (module docs), skipping the points
/// whose `|p|²` fails `keep` (and values that are not positive and finite). The caller divides
/// by `s²`; [`TargetPdf`] and the tabulated oracle of `crate::eval` share it.
#[must_use]
pub fn cell_luminance_sum(
    m: &dyn Material,
    phi: &[f32; FEATURE_DIM],
    wi: Vec3,
    res: usize,
    (row, col): (usize, usize),
    s: usize,
    keep: impl Fn(f32) -> bool,
) -> f32 {
    let mut acc = 0.0f32;
    for (x, y) in cell_points(res, (row, col), s) {
        let r2 = x * x + y * y;
        if !keep(r2) {
            continue;
        }
        let wo = Vec3::new(x, y, (1.0 - r2).max(0.0).sqrt());
        let l = luminance(m.eval(phi, wi, wo));
        if l > 0.0 && l.is_finite() {
            acc += l;
        }
    }
    acc
}

/// How many of the `s × s` stratified points of cell `(row, col)` (as in
/// [`cell_luminance_sum`]) lie strictly inside the unit disk.
#[must_use]
pub fn cell_points_inside(res: usize, cell: (usize, usize), s: usize) -> usize {
    cell_points(res, cell, s)
        .filter(|(x, y)| x * x + y * y < 1.0)
        .count()
}

/// The `s × s` stratified points `(x, y)` of cell `(row, col)` of an `res × res` grid over
/// `[−1, 1]²` (module docs), row by row.
fn cell_points(
    res: usize,
    (row, col): (usize, usize),
    s: usize,
) -> impl Iterator<Item = (f32, f32)> {
    let h = 2.0 / res as f32;
    let hs = h / s as f32;
    (0..s).flat_map(move |i| {
        let y = -1.0 + row as f32 * h + (i as f32 + 0.5) * hs;
        (0..s).map(move |j| (-1.0 + col as f32 * h + (j as f32 + 0.5) * hs, y))
    })
}

/// Whether cell `(r, c)` of an `res × res` grid lies entirely inside the closed unit disk.
#[inline]
#[must_use]
pub fn cell_inside_disk(res: usize, r: usize, c: usize) -> bool {
    let h = 2.0 / res as f64;
    let far = |i: usize| {
        let a = -1.0 + i as f64 * h;
        let b = a + h;
        if a.abs() > b.abs() {
            a
        } else {
            b
        }
    };
    let (x, y) = (far(c), far(r));
    x * x + y * y <= 1.0
}

impl TargetPdf {
    /// Tabulates p* at resolution `res` with the default options (2 × 2 points per cell,
    /// cut-off 0.98).
    #[must_use]
    pub fn new(m: &dyn Material, c: &Condition, res: usize) -> TargetPdf {
        Self::with_options(m, c, res, &TargetOptions::default())
    }

    /// Tabulates p* with explicit options.
    #[must_use]
    pub fn with_options(
        m: &dyn Material,
        c: &Condition,
        res: usize,
        opts: &TargetOptions,
    ) -> TargetPdf {
        let res = res.max(1);
        let s = opts.supersample.max(1);
        let inv_ss = 1.0 / (s * s) as f32;
        let mut values = vec![0f32; res * res];
        let mut inside = vec![0f32; res * res];
        for r in 0..res {
            for col in 0..res {
                let i = r * res + col;
                if cell_inside_disk(res, r, col) {
                    let acc = cell_luminance_sum(m, &c.phi, c.wi, res, (r, col), s, |r2| {
                        !(r2 > opts.grazing_cutoff)
                    });
                    values[i] = acc * inv_ss;
                    inside[i] = 1.0;
                } else if opts.to_horizon {
                    let s2 = 2 * s;
                    let n_in = cell_points_inside(res, (r, col), s2);
                    if n_in > 0 {
                        let acc = cell_luminance_sum(m, &c.phi, c.wi, res, (r, col), s2, |r2| {
                            r2 < 1.0 && !(r2 > opts.grazing_cutoff)
                        });
                        values[i] = acc / n_in as f32;
                        inside[i] = n_in as f32 / (s2 * s2) as f32;
                    }
                }
            }
        }
        Self::from_cells(res, values, &inside)
    }

    /// A table from cell values (unnormalised means of `Y(f)` over each cell's part inside the
    /// disk) and the fraction `inside[i] ∈ [0, 1]` of each cell that lies inside the disk:
    /// cells with fraction 0 get density 0. The sampled density inside the disk is
    /// proportional to the values (samples in the outer part of a straddling cell are
    /// refused), so the normaliser is `Σ value·fraction·h²`, and [`TargetPdf::pdf`] rescales
    /// the table's own densities by it.
    #[must_use]
    pub fn from_cells(res: usize, mut values: Vec<f32>, inside: &[f32]) -> TargetPdf {
        let res = res.max(1);
        values.resize(res * res, 0.0);
        let frac = |i: usize| inside.get(i).copied().unwrap_or(0.0).clamp(0.0, 1.0);
        for (i, v) in values.iter_mut().enumerate() {
            if !(v.is_finite() && *v > 0.0 && frac(i) > 0.0) {
                *v = 0.0;
            }
        }
        let mut degenerate = false;
        let total_in: f64 = values
            .iter()
            .enumerate()
            .map(|(i, &v)| f64::from(v) * f64::from(frac(i)))
            .sum();
        if !(total_in > 0.0 && total_in.is_finite()) {
            degenerate = true;
            for (i, v) in values.iter_mut().enumerate() {
                *v = if frac(i) > 0.0 { 1.0 } else { 0.0 };
            }
        }
        let mut t = Self::from_values_kept(res, values, |r, c| frac(r * res + c) > 0.0);
        let area = (2.0 / res as f64).powi(2);
        let table_total: f64 = t.density.iter().map(|&d| f64::from(d) * area).sum();
        let in_total: f64 = t
            .density
            .iter()
            .enumerate()
            .map(|(i, &d)| f64::from(d) * f64::from(frac(i)) * area)
            .sum();
        if in_total > 0.0 {
            t.pdf_scale = (table_total / in_total) as f32;
            t.integral *= in_total / table_total;
        }
        if degenerate {
            t.degenerate = true;
            t.integral = 0.0;
        }
        t
    }

    /// A table from non-negative cell values (unnormalised; rows = y). Values of cells not
    /// entirely inside the disk, negative or non-finite values are set to 0.
    #[must_use]
    pub fn from_values(res: usize, values: Vec<f32>) -> TargetPdf {
        Self::from_values_kept(res, values, |r, c| cell_inside_disk(res, r, c))
    }

    /// [`TargetPdf::from_values`] keeping the cells where `kept(row, col)`.
    fn from_values_kept(
        res: usize,
        mut values: Vec<f32>,
        kept: impl Fn(usize, usize) -> bool,
    ) -> TargetPdf {
        let res = res.max(1);
        values.resize(res * res, 0.0);
        let area = (2.0 / res as f64).powi(2);
        let mut total = 0.0f64;
        for r in 0..res {
            for c in 0..res {
                let v = &mut values[r * res + c];
                if !(v.is_finite() && *v > 0.0 && kept(r, c)) {
                    *v = 0.0;
                }
                total += f64::from(*v);
            }
        }
        let degenerate = !(total > 0.0 && total.is_finite());
        if degenerate {
            for r in 0..res {
                for c in 0..res {
                    values[r * res + c] = if kept(r, c) { 1.0 } else { 0.0 };
                }
            }
            total = values.iter().map(|&v| f64::from(v)).sum();
        }
        let integral = if degenerate { 0.0 } else { total * area };
        // Density: value / (total · area), so Σ density · area = 1.
        let scale = 1.0 / (total * area);
        let density: Vec<f32> = values
            .iter()
            .map(|&v| (f64::from(v) * scale) as f32)
            .collect();
        let (marginal, conditional) = running_sums(&density, res);
        TargetPdf {
            res,
            density,
            marginal,
            conditional,
            integral,
            pdf_scale: 1.0,
            degenerate,
        }
    }

    /// Grid resolution R.
    #[must_use]
    pub fn res(&self) -> usize {
        self.res
    }

    /// Per-cell density w.r.t. **area on the projected disk**, `R²` values, row-major with
    /// rows = y; `Σ density · (2/R)² = 1`.
    #[must_use]
    pub fn density(&self) -> &[f32] {
        &self.density
    }

    /// `∫_disk Y(f(φ, wi, ω(ω⊥))) dω⊥ = ∫ Y(f) cos θo dωo` of the discretised function before
    /// normalisation (the luminance albedo at this condition); 0 when degenerate.
    #[must_use]
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// True when the function was 0 everywhere and the density is uniform instead.
    #[must_use]
    pub fn degenerate(&self) -> bool {
        self.degenerate
    }

    /// Row-major cell index of a point, `None` outside `[−1, 1)²` or for non-finite input.
    #[inline]
    #[must_use]
    pub fn cell_of(&self, p: Vec2) -> Option<usize> {
        if !(p.x >= -1.0 && p.x < 1.0 && p.y >= -1.0 && p.y < 1.0) {
            return None;
        }
        let n = self.res as f32;
        let c = (((p.x + 1.0) * 0.5 * n) as usize).min(self.res - 1);
        let r = (((p.y + 1.0) * 0.5 * n) as usize).min(self.res - 1);
        Some(r * self.res + c)
    }

    /// The runtime's view of the table (`None` when `R >` [`neusample::samplers::histogram_mixture::MAX_N`]).
    #[must_use]
    pub fn table(&self) -> Option<Table2D<&[f32]>> {
        Table2D::new(
            &self.density[..],
            &self.marginal[..],
            &self.conditional[..],
            self.res as u32,
            0,
        )
    }

    /// The table in the runtime's layout: `(density, marginal, conditional)` with `R²`, `R` and
    /// `R²` values (module docs of `neusample::samplers::histogram_mixture`), e.g. to bake it into a blob.
    #[must_use]
    pub fn tensors(&self) -> (&[f32], &[f32], &[f32]) {
        (&self.density, &self.marginal, &self.conditional)
    }

    /// Piecewise-constant density at disk point `p` w.r.t. disk area; 0 outside the open unit
    /// disk and for non-finite `p`. Equal to the density [`TargetPdf::sample`] reports.
    #[inline]
    #[must_use]
    pub fn pdf(&self, p: Vec2) -> f32 {
        if p.length_squared() >= 1.0 || !p.is_finite() {
            return 0.0;
        }
        let d = match self.table() {
            Some(t) => t.pdf(p),
            None => self.cell_of(p).map_or(0.0, |i| self.density[i]),
        };
        d * self.pdf_scale
    }

    /// Exact sample for `u ∈ [0, 1)²` through `Table2D::sample` (`u.x` picks the row, `u.y`
    /// the column). `None` for `u` outside `[0, 1]²` or non-finite, for `R > 128`, and in the
    /// rare event that rounding puts the point on the edge of an empty neighbouring cell.
    #[must_use]
    pub fn sample(&self, u: Vec2) -> Option<Vec2> {
        let (p, _) = self.table()?.sample(u)?;
        (p.length_squared() < 1.0).then_some(p)
    }

    /// The `u` that [`TargetPdf::sample`] maps to `p` (up to rounding); `None` where the
    /// density is 0 or for `R > 128`.
    #[must_use]
    pub fn invert(&self, p: Vec2) -> Option<Vec2> {
        if self.pdf(p) <= 0.0 {
            return None;
        }
        self.table()?.invert(p)
    }

    /// `KL(p* ‖ q) = Σ_cells p*_c log(p*_c / q(m_c)) · h²` with `m_c` the cell midpoints and `q`
    /// a density on the disk (area measure). `q ≤ 0` or non-finite counts as
    /// [`KL_Q_FLOOR`]. In nats.
    pub fn kl_from(&self, q: impl Fn(Vec2) -> f32) -> f64 {
        self.cell_sum(q, |p, qv| p * (p / qv).ln())
    }

    /// The χ² divergence `χ²(p* ‖ q) = ∫ p*² / q − 1 = Σ_cells p*_c² / q(m_c) · h² − 1`: the
    /// relative variance of the one-sample estimator `p*/q` with samples from `q`, i.e. the
    /// render's variance per sample relative to perfect importance sampling (the measure that
    /// KL does not see where `q ≪ p*` on little mass). `q ≤ 0` or non-finite counts as
    /// [`KL_Q_FLOOR`]. Over the table's cells only, which stop short of the horizon;
    /// [`rim_moments`] integrates over the whole disk.
    pub fn chi2_from(&self, q: impl Fn(Vec2) -> f32) -> f64 {
        self.cell_sum(q, |p, qv| p * p / qv) - 1.0
    }

    /// `Σ_cells term(p*_c, q(m_c)) · h²` over the cells where p* > 0, `q` floored at
    /// [`KL_Q_FLOOR`] (≤ 0 or non-finite counts as the floor).
    fn cell_sum(&self, q: impl Fn(Vec2) -> f32, term: impl Fn(f64, f64) -> f64) -> f64 {
        let res = self.res;
        let h = 2.0 / res as f64;
        let mut sum = 0.0f64;
        for r in 0..res {
            for c in 0..res {
                let p = f64::from(self.density[r * res + c]);
                if p <= 0.0 {
                    continue;
                }
                sum += term(p, floored(f64::from(q(cell_midpoint(res, r, c)))));
            }
        }
        sum * h * h
    }
}

/// Nodes of [`rim_quadrature`] along the radius and around it.
pub const RIM_RADIAL: usize = 64;
/// See [`RIM_RADIAL`].
pub const RIM_ANGULAR: usize = 256;

/// A quadrature of the whole open disk that resolves the rim: polar midpoints with
/// `r = 1 − s²` (s uniform), so that the outermost ring lies within `1/(4·radial²)` of the
/// horizon — where a tabulated target (cells wholly inside the disk, the release's 0.98
/// cut-off) sees nothing, but a material that reflects at grazing angles puts mass and a
/// sampler with thin tails puts its largest weights. Returns `(point, area weight)` pairs;
/// the weights sum to π up to the midpoint rule's error.
#[must_use]
pub fn rim_quadrature(radial: usize, angular: usize) -> Vec<(Vec2, f64)> {
    let mut q = Vec::with_capacity(radial * angular);
    let ds = 1.0 / radial as f64;
    let dphi = std::f64::consts::TAU / angular as f64;
    for i in 0..radial {
        let s = (i as f64 + 0.5) * ds;
        let r = 1.0 - s * s;
        // dA = r dr dφ, dr = 2s ds.
        let w = r * 2.0 * s * ds * dphi;
        for j in 0..angular {
            let phi = (j as f64 + 0.5) * dphi;
            q.push((Vec2::new((r * phi.cos()) as f32, (r * phi.sin()) as f32), w));
        }
    }
    q
}

/// `Y(f)` at each of the [`rim_quadrature`] nodes `nodes` (0 where it is not finite and
/// positive).
#[must_use]
pub fn rim_luminance(m: &dyn Material, c: &Condition, nodes: &[(Vec2, f64)]) -> Vec<f64> {
    nodes
        .iter()
        .map(|&(p, _)| {
            neusample::warp::from_disk(p).map_or(0.0, |wo| {
                let y = f64::from(luminance(m.eval(&c.phi, c.wi, wo)));
                if y > 0.0 && y.is_finite() {
                    y
                } else {
                    0.0
                }
            })
        })
        .collect()
}

/// `∫ Y(f)` and `∫ Y(f)²/q` over the disk with [`rim_quadrature`] nodes `nodes`, `q` a disk
/// density (≤ 0 or non-finite counts as [`KL_Q_FLOOR`]). `χ²(p* ‖ q) = m2 / a² − 1`, and `m2`
/// is the second moment of the one-bounce estimator `Y(f)·cos/p_ω` under uniform light.
#[must_use]
pub fn rim_moments(
    m: &dyn Material,
    c: &Condition,
    nodes: &[(Vec2, f64)],
    q: impl Fn(Vec2) -> f32,
) -> (f64, f64) {
    let (mut a, mut m2) = (0.0f64, 0.0f64);
    for (&(p, w), f) in nodes.iter().zip(rim_luminance(m, c, nodes)) {
        if f > 0.0 {
            a += f * w;
            m2 += f * f / floored(f64::from(q(p))) * w;
        }
    }
    (a, m2)
}

/// `q`, or [`KL_Q_FLOOR`] where `q` is below it or not finite.
pub(crate) fn floored(q: f64) -> f64 {
    if q.is_finite() && q > KL_Q_FLOOR {
        q
    } else {
        KL_Q_FLOOR
    }
}

/// The midpoint of cell `(r, c)` of an `res × res` grid over `[−1, 1]²` (rows = y).
#[must_use]
pub fn cell_midpoint(res: usize, r: usize, c: usize) -> Vec2 {
    let h = 2.0 / res as f64;
    Vec2::new(
        (-1.0 + (c as f64 + 0.5) * h) as f32,
        (-1.0 + (r as f64 + 0.5) * h) as f32,
    )
}

impl neusample::Prepared for TargetPdf {
    fn sample(&self, u: Vec2) -> Option<neusample::Sample> {
        let (p, pdf) = self.table()?.sample(u)?;
        neusample::Sample::from_disk(p, pdf)
    }

    fn pdf_disk(&self, p: Vec2) -> f32 {
        TargetPdf::pdf(self, p)
    }

    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        let w = neusample::warp::upper_hemisphere(wo)?;
        TargetPdf::invert(self, neusample::warp::to_disk(w))
    }
}

/// `n_conditions` random conditions, without target densities; condition `i` draws from
/// [`indexed_rng`]`(seed, i)`, so the result does not depend on the thread count and a batch of
/// n is a prefix of a batch of m > n with the same seed.
#[must_use]
pub fn conditions(m: &dyn Material, n_conditions: usize, seed: u64) -> Vec<Condition> {
    (0..n_conditions)
        .into_par_iter()
        .map(|i| random_condition(m, &mut indexed_rng(seed, i)))
        .collect()
}

/// `n_conditions` random conditions with their target densities at resolution `res`, in
/// parallel (rayon); deterministic per seed whatever the thread count.
#[must_use]
pub fn batch(
    m: &dyn Material,
    n_conditions: usize,
    res: usize,
    seed: u64,
) -> Vec<(Condition, TargetPdf)> {
    batch_with(m, n_conditions, res, seed, &TargetOptions::default())
}

/// [`batch`] with explicit tabulation options.
#[must_use]
pub fn batch_with(
    m: &dyn Material,
    n_conditions: usize,
    res: usize,
    seed: u64,
    opts: &TargetOptions,
) -> Vec<(Condition, TargetPdf)> {
    (0..n_conditions)
        .into_par_iter()
        .map(|i| {
            let c = random_condition(m, &mut indexed_rng(seed, i));
            let t = TargetPdf::with_options(m, &c, res, opts);
            (c, t)
        })
        .collect()
}
