//! Histogram samplers: piecewise-constant densities on an `N × N` grid over `[−1, 1]²`.
//!
//! * [`Table2D`] — a read-only view of one tabulated 2-D distribution (or of the linear blend
//!   of two), stored pbrt/Mitsuba style as density values plus unnormalised running sums
//!   (a *marginal* over rows and a *conditional* within each row), with `sample`, `pdf` and
//!   `invert`. Generic over [`Weights`], so the same code reads blob tensors (f32 or f16),
//!   host slices, GPU storage buffers and the fixed arrays of a prepared sampler.
//! * [`DirectHistogramSampler`] — the direct histogram baseline (Zhu et al. 2021): an MLP
//!   predicts the 16 × 16 grid per condition (`ARCHITECTURES.md` §5).
//! * [`HistogramMixtureSampler`] — the paper's histogram mixture (Eq. 5–6): an MLP predicts
//!   per-basis weights, rotations and latent codes, the bases are baked tables
//!   (`ARCHITECTURES.md` §6).
//! * [`validate_tables`] — the checks a blob's baked tables must pass before use;
//!   [`running_sums`] builds the CDFs of stored values, and (with the `alloc` feature)
//!   [`bake_slices`] / [`try_bake_slices`] build whole tables from raw slice values.
//!
//! # Layout and measure
//!
//! Rows are y, columns x: cell `(r, c)` covers `[−1 + c·h, −1 + (c+1)·h] × [−1 + r·h,
//! −1 + (r+1)·h]` with `h = 2/N`, and has flat index `r·N + c` within its slice. A slice holds
//! densities with respect to **area on the projected disk**; a normalised slice integrates to
//! 1 over the square (`Σ value · h² = 1`), and cells lying entirely outside the unit disk hold
//! 0 ([`cell_outside_disk`]). With `S(r, c) = Σ_{c' ≤ c} value[r][c']`:
//!
//! ```text
//! conditional[r][c] = S(r, c)                      (running sum within row r)
//! marginal[r]       = Σ_{r' ≤ r} S(r', N − 1)      (running sum of row totals)
//! ```
//!
//! # Linear interpolation between slices
//!
//! A [`Table2D`] can blend two slices with weights `(1 − a, a)` (Mitsuba 3 `Marginal2D`
//! style): values, marginal and conditional are all blended with the same weights. Running
//! sums are linear, so the blended running sums are exactly the running sums of the blended
//! values, and a blend of normalised slices is normalised. The blend is evaluated on the fly
//! (two reads instead of one); nothing is rebuilt per condition.
//!
//! Densities are divided by the (blended) stored total `marginal[N − 1] · h²`, which is 1 for
//! a validated table up to rounding; dividing keeps `pdf` exactly consistent with what
//! `sample` draws even for tables that are only normalised to within the validation
//! tolerance (e.g. after f16 rounding).

// Negated comparisons (`!(x > 0.0)`) are deliberate throughout: they send NaN to the
// refusing branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::{Vec2, Vec3};

use crate::error::Error;
use crate::gaussian;
use crate::math;
use crate::mlp::{self, Activation};
use crate::sampler::{
    check_condition, encode_condition, raw_condition, sanitize_u2, Prepared, Sample, Sampler,
    CONDITION_DIM, FEATURE_DIM, RAW_CONDITION_DIM,
};
use crate::warp;
use crate::weights::Weights;

/// Largest number of latent-code levels T a histogram mixture may have.
pub const MAX_T: usize = 256;
/// Largest grid resolution N a histogram mixture may have.
pub const MAX_N: usize = 128;
/// Number of basis histograms K of the histogram mixture (paper §3.3: K = 10).
pub const BASES: usize = 10;
/// Grid resolution of the direct histogram baseline (16 × 16 cells).
pub const DIRECT_N: usize = 16;

/// Number of cells of the direct histogram baseline.
const DIRECT_CELLS: usize = DIRECT_N * DIRECT_N;

/// Iterations of the fixed-length binary searches: enough for any `N ≤ MAX_N`.
const SEARCH_STEPS: u32 = 7;
const _: () = assert!(1usize << SEARCH_STEPS >= MAX_N);

/// Resolutions above this are clamped by [`cell_outside_disk`] (keeps its integer test exact
/// and overflow-free).
const MAX_MASK_N: u32 = 16384;

/// Relative tolerance of [`validate_tables`] on each slice's integral.
pub const INTEGRAL_TOLERANCE: f64 = 1e-3;
/// Relative tolerance of [`validate_tables`] on the running sums (see there).
pub const CDF_TOLERANCE: f64 = 1e-4;

// ---------------------------------------------------------------------------------------
// Grid helpers
// ---------------------------------------------------------------------------------------

/// Area `h² = (2/N)²` of one cell of an `N × N` grid over `[−1, 1]²`.
#[inline(always)]
#[must_use]
pub fn cell_area(n: u32) -> f32 {
    let h = 2.0 / n as f32;
    h * h
}

/// Distance, in half-cell units, from the disk centre to the nearest point of cell
/// `i` along one axis (0 when the cell spans the axis).
#[inline(always)]
fn half_cell_gap(i: u32, n: u32) -> u32 {
    let lo = 2 * i; // 2·(cell start + 1)/h
    if lo >= n {
        lo - n
    } else if lo + 2 <= n {
        n - lo - 2
    } else {
        0
    }
}

/// `true` when cell `(row, col)` of an `n × n` grid over `[−1, 1]²` lies entirely outside
/// the open unit disk: its nearest point is at distance ≥ 1 from the origin. Such cells carry
/// no density in any table of this crate.
///
/// Evaluated exactly in integers (`n ≤ 16384`; larger `n` is clamped), so the baker, the
/// validator and the samplers agree on every cell.
#[inline]
#[must_use]
pub fn cell_outside_disk(row: u32, col: u32, n: u32) -> bool {
    let n = if n > MAX_MASK_N { MAX_MASK_N } else { n };
    let r = if row < n { row } else { n - 1 };
    let c = if col < n { col } else { n - 1 };
    let dx = half_cell_gap(c, n);
    let dy = half_cell_gap(r, n);
    // dist² = (dx² + dy²)·(h/2)² ≥ 1  ⇔  dx² + dy² ≥ (2/h)² = n².
    dx * dx + dy * dy >= n * n
}

/// The cell index of coordinate `x ∈ [−1, 1]` on an `n`-cell axis, clamped to `[0, n − 1]`
/// (x = 1 falls in the last cell): `⌊(x + 1)·n/2⌋`. No `floor` call is needed: the clamp
/// to `[0, n − 1]` and the truncating conversion give the floor for every input (NaN → 0).
#[inline(always)]
fn cell_index(x: f32, n: u32) -> u32 {
    math::clamp_index((x + 1.0) * (0.5 * n as f32), n)
}

/// The coordinate `x` moved by whole ulps until [`cell_index`] puts it in cell `cell`: the
/// position `cell·h − 1 + d·h` of a sample can round onto a neighbouring cell's edge, and the
/// density must then be read from the cell the sample was drawn in. Bounded loop; the
/// caller's `x` is already within a few ulps of the cell.
#[inline(always)]
fn snap_into_cell(mut x: f32, cell: u32, n: u32) -> f32 {
    let mut k = 0;
    while k < 16 {
        let i = cell_index(x, n);
        if i == cell {
            break;
        }
        x = if i > cell { next_down(x) } else { next_up(x) };
        k += 1;
    }
    x
}

/// The largest f32 below finite `x`.
#[inline(always)]
fn next_down(x: f32) -> f32 {
    if x == 0.0 {
        -f32::from_bits(1)
    } else if x > 0.0 {
        f32::from_bits(x.to_bits() - 1)
    } else {
        f32::from_bits(x.to_bits() + 1)
    }
}

/// The smallest f32 above finite `x`.
#[inline(always)]
fn next_up(x: f32) -> f32 {
    -next_down(-x)
}

/// `true` for points of the closed square `[−1, 1]²` (false for NaN).
#[inline(always)]
fn in_square(p: Vec2) -> bool {
    p.x >= -1.0 && p.x <= 1.0 && p.y >= -1.0 && p.y <= 1.0
}

/// The first index `i ∈ [0, n)` with `f(i) > target`, for non-decreasing `f`; `n − 1` when
/// there is none. A fixed number of halvings ([`SEARCH_STEPS`]), so the loop has a static trip
/// count (rust-gpu friendly); the result is always in range.
#[inline(always)]
fn search<F: Fn(u32) -> f32>(n: u32, target: f32, f: F) -> u32 {
    let mut lo = 0u32;
    let mut hi = if n > 0 { n - 1 } else { 0 };
    let mut step = 0;
    while step < SEARCH_STEPS {
        if lo < hi {
            let mid = lo + (hi - lo) / 2;
            if f(mid) > target {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        step += 1;
    }
    lo
}

/// Makes a density safe to return: non-finite or negative values become 0.
#[inline(always)]
fn finite_density(p: f32) -> f32 {
    if p >= 0.0 && math::is_finite(p) {
        p
    } else {
        0.0
    }
}

/// Bound applied to logits before a softmax (NaN → −bound): keeps ±∞/NaN out of it.
const LOGIT_BOUND: f32 = 1.0e30;

#[inline(always)]
fn logit(x: f32) -> f32 {
    math::clamp(x, -LOGIT_BOUND, LOGIT_BOUND)
}

// ---------------------------------------------------------------------------------------
// Table2D
// ---------------------------------------------------------------------------------------

/// A read-only view of a piecewise-constant 2-D distribution on an `N × N` grid over
/// `[−1, 1]²`: one slice, or the linear blend `(1 − a)·slice0 + a·slice1` of two, inside
/// three flat tensors (values `T`, marginal `M`, conditional `C`; see the
/// [module docs](self) for the layout).
///
/// Sampling picks a row by binary search of the marginal and a column by binary search of the
/// row's conditional, with a continuous offset inside the cell (pbrt `PiecewiseConstant1D`
/// style); cells of zero density are never chosen. A positive cell smaller than the f32
/// resolution of its row's running sum (≲ 6·10⁻⁸ of the row total) is absorbed by the sum and
/// never drawn although its density is reported — the pbrt/Mitsuba behaviour, a bias below
/// `N · 6·10⁻⁸` of the row's mass. Nothing allocates, and an index past the end of a tensor
/// reads 0 ([`Weights`]), so no input can make it panic.
#[derive(Debug)]
pub struct Table2D<T, M = T, C = T> {
    values: T,
    marginal: M,
    conditional: C,
    n: u32,
    slice0: u32,
    slice1: u32,
    /// Weight of `slice1` (0 for a single slice).
    a: f32,
    /// Blended `marginal[N − 1]`.
    total: f32,
    /// `1 / (total · h²)`, or 0 when the total is not positive.
    inv_integral: f32,
}

impl<T: Copy, M: Copy, C: Copy> Clone for Table2D<T, M, C> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T: Copy, M: Copy, C: Copy> Copy for Table2D<T, M, C> {}

impl<T: Weights, M: Weights, C: Weights> Table2D<T, M, C> {
    /// A view of slice `slice` (the `slice`-th block of `N²` values, `N²` conditional and `N`
    /// marginal entries). `None` when `n` is 0 or above [`MAX_N`], or a tensor is too short.
    #[inline]
    #[must_use]
    pub fn new(values: T, marginal: M, conditional: C, n: u32, slice: u32) -> Option<Self> {
        Self::lerp(values, marginal, conditional, n, slice, slice, 0.0)
    }

    /// A view of the blend `(1 − a)·slice0 + a·slice1` (`a ∈ [0, 1]`). `None` when `n` is 0
    /// or above [`MAX_N`], `a` is outside `[0, 1]` (or NaN), or a tensor is too short.
    #[inline]
    #[must_use]
    pub fn lerp(
        values: T,
        marginal: M,
        conditional: C,
        n: u32,
        slice0: u32,
        slice1: u32,
        a: f32,
    ) -> Option<Self> {
        if n == 0 || n as usize > MAX_N || !(0.0..=1.0).contains(&a) {
            return None;
        }
        let nn = n * n;
        // Written as divisions so that nothing can overflow.
        let slices_v = values.len() / nn;
        let slices_c = conditional.len() / nn;
        let slices_m = marginal.len() / n;
        let last = if slice0 > slice1 { slice0 } else { slice1 };
        if last >= slices_v || last >= slices_c || last >= slices_m {
            return None;
        }
        Some(Self::from_parts(
            values,
            marginal,
            conditional,
            n,
            slice0,
            slice1,
            a,
        ))
    }

    /// A view without the size checks (reads past the end give 0, so this is safe; callers
    /// check sizes once, at construction of the sampler).
    #[inline(always)]
    fn from_parts(
        values: T,
        marginal: M,
        conditional: C,
        n: u32,
        slice0: u32,
        slice1: u32,
        a: f32,
    ) -> Self {
        let mut t = Table2D {
            values,
            marginal,
            conditional,
            n,
            slice0,
            slice1,
            a,
            total: 0.0,
            inv_integral: 0.0,
        };
        let total = t.marginal_at(n - 1);
        let integral = total * cell_area(n);
        if total > 0.0 && math::is_finite(total) && integral > 0.0 {
            t.total = total;
            t.inv_integral = 1.0 / integral;
        }
        t
    }

    /// Grid resolution N.
    #[inline]
    #[must_use]
    pub fn resolution(&self) -> u32 {
        self.n
    }

    /// The stored integral `marginal[N − 1] · h²` of the (blended) slice; 1 for a validated
    /// table up to rounding, 0 when it is not positive and finite.
    #[inline]
    #[must_use]
    pub fn integral(&self) -> f32 {
        self.total * cell_area(self.n)
    }

    /// Reads `w[base0 + i]` and `w[base1 + i]` blended with weights `(1 − a, a)`.
    #[inline(always)]
    fn blend<W: Weights + ?Sized>(&self, w: &W, stride: u32, i: u32) -> f32 {
        let v0 = w.at(self.slice0 * stride + i);
        if self.a > 0.0 {
            (1.0 - self.a) * v0 + self.a * w.at(self.slice1 * stride + i)
        } else {
            v0
        }
    }

    /// Blended `marginal[r]`.
    #[inline(always)]
    fn marginal_at(&self, r: u32) -> f32 {
        self.blend(&self.marginal, self.n, r)
    }

    /// Blended `conditional[r][c]`.
    #[inline(always)]
    fn conditional_at(&self, r: u32, c: u32) -> f32 {
        self.blend(&self.conditional, self.n * self.n, r * self.n + c)
    }

    /// Blended stored value of cell `(r, c)` (indices clamped into the grid).
    #[inline]
    #[must_use]
    pub fn value(&self, row: u32, col: u32) -> f32 {
        let r = if row < self.n { row } else { self.n - 1 };
        let c = if col < self.n { col } else { self.n - 1 };
        self.blend(&self.values, self.n * self.n, r * self.n + c)
    }

    /// Draws a point of `[−1, 1]²` from `u ∈ [0, 1)²`: `u.x` picks the row, `u.y` the column
    /// and the offsets within the cell are continuous. Returns the point and its density
    /// ([`Table2D::pdf`] at the point, area measure). `None` for invalid `u` or a table whose
    /// total is not positive.
    #[inline]
    #[must_use]
    pub fn sample(&self, u: Vec2) -> Option<(Vec2, f32)> {
        let u = sanitize_u2(u)?;
        let n = self.n;
        let total = self.total;
        if !(total > 0.0) {
            return None;
        }
        // Row: the first r with marginal[r] > u.x·total. For u.x < 1, u.x·total < total, so
        // such a row exists and marginal[r] > marginal[r − 1]: it has positive mass.
        let ty = u.x * total;
        if !(ty < total) {
            return None;
        }
        let r = search(n, ty, |i| self.marginal_at(i));
        let m0 = if r > 0 { self.marginal_at(r - 1) } else { 0.0 };
        let dm = self.marginal_at(r) - m0;
        if !(dm > 0.0) {
            return None;
        }
        let dy = math::clamp((ty - m0) / dm, 0.0, math::ONE_MINUS_EPSILON);
        // Column, within row r, the same way.
        let row_total = self.conditional_at(r, n - 1);
        let tx = u.y * row_total;
        if !(row_total > 0.0) || !(tx < row_total) {
            return None;
        }
        let c = search(n, tx, |i| self.conditional_at(r, i));
        let c0 = if c > 0 {
            self.conditional_at(r, c - 1)
        } else {
            0.0
        };
        let dc = self.conditional_at(r, c) - c0;
        if !(dc > 0.0) {
            return None;
        }
        let dx = math::clamp((tx - c0) / dc, 0.0, math::ONE_MINUS_EPSILON);
        let h = 2.0 / n as f32;
        let p = Vec2::new(
            snap_into_cell((c as f32 * h - 1.0) + dx * h, c, n),
            snap_into_cell((r as f32 * h - 1.0) + dy * h, r, n),
        );
        let pdf = self.pdf(p);
        if pdf > 0.0 {
            Some((p, pdf))
        } else {
            None
        }
    }

    /// Density at `p` with respect to area on `[−1, 1]²`: the (blended) cell value divided by
    /// the stored integral. 0 outside the closed square and for non-finite `p`.
    #[inline]
    #[must_use]
    pub fn pdf(&self, p: Vec2) -> f32 {
        if !in_square(p) {
            return 0.0;
        }
        let r = cell_index(p.y, self.n);
        let c = cell_index(p.x, self.n);
        finite_density(self.value(r, c) * self.inv_integral)
    }

    /// The `u` that [`Table2D::sample`] maps to `p` (up to rounding). `None` for points
    /// outside the square or in a cell of zero density (where no `u` lands).
    #[inline]
    #[must_use]
    pub fn invert(&self, p: Vec2) -> Option<Vec2> {
        if !in_square(p) || !(self.total > 0.0) {
            return None;
        }
        let n = self.n;
        let r = cell_index(p.y, n);
        let c = cell_index(p.x, n);
        if !(self.value(r, c) > 0.0) {
            return None;
        }
        let half_n = 0.5 * n as f32;
        let fy = math::clamp((p.y + 1.0) * half_n - r as f32, 0.0, 1.0);
        let fx = math::clamp((p.x + 1.0) * half_n - c as f32, 0.0, 1.0);
        let m0 = if r > 0 { self.marginal_at(r - 1) } else { 0.0 };
        let m1 = self.marginal_at(r);
        let ux = (m0 + fy * (m1 - m0)) / self.total;
        let row_total = self.conditional_at(r, n - 1);
        if !(row_total > 0.0) {
            return None;
        }
        let c0 = if c > 0 {
            self.conditional_at(r, c - 1)
        } else {
            0.0
        };
        let c1 = self.conditional_at(r, c);
        let uy = (c0 + fx * (c1 - c0)) / row_total;
        if !(math::is_finite(ux) && math::is_finite(uy)) {
            return None;
        }
        Some(Vec2::new(
            math::clamp(ux, 0.0, math::ONE_MINUS_EPSILON),
            math::clamp(uy, 0.0, math::ONE_MINUS_EPSILON),
        ))
    }
}

// ---------------------------------------------------------------------------------------
// Direct histogram (Zhu et al. 2021)
// ---------------------------------------------------------------------------------------

const DIRECT_HIDDEN: usize = 64;
const DIRECT_L0: usize = 0;
const DIRECT_L1: usize = DIRECT_L0 + mlp::dense_len(CONDITION_DIM, DIRECT_HIDDEN);
const DIRECT_L2: usize = DIRECT_L1 + mlp::dense_len(DIRECT_HIDDEN, DIRECT_HIDDEN);
const DIRECT_END: usize = DIRECT_L2 + mlp::dense_len(DIRECT_HIDDEN, DIRECT_CELLS);

/// The direct histogram baseline (Zhu et al. 2021; "histogram (baseline)" in the paper's
/// Table 2): an MLP `30 → 64 → 64 → 256` (ReLU hidden) maps `encode_condition(φ, wi)` to
/// the logits of a 16 × 16 grid over `[−1, 1]²`. Cells entirely outside the disk are masked,
/// the others get `softmax` probabilities `P_rc`, and the density on the projected disk is
/// `P_rc / h²` (`ARCHITECTURES.md` §5).
#[derive(Copy, Clone, Debug)]
pub struct DirectHistogramSampler<W> {
    params: W,
}

impl<W: Weights> DirectHistogramSampler<W> {
    /// Number of parameters: `dense(30,64) dense(64,64) dense(64,256)` = 22784.
    pub const PARAM_COUNT: usize = DIRECT_END;

    /// A sampler over `params` without the length check of [`Self::new`], for GPU shaders
    /// (`Option<Self>` with a borrowed `W` cannot be tested by rust-gpu). Not `unsafe`:
    /// reads past the end of a short array give 0.0, so wrong densities but never a panic
    /// or NaN. Check `params.len() == PARAM_COUNT` on the host.
    #[inline]
    #[must_use]
    pub const fn new_unchecked(params: W) -> Self {
        DirectHistogramSampler { params }
    }

    /// A sampler over the flat parameter array `params`, or `None` when it does not hold
    /// exactly [`Self::PARAM_COUNT`] values.
    #[must_use]
    pub fn new(params: W) -> Option<Self> {
        if params.len() as usize == Self::PARAM_COUNT {
            Some(Self::new_unchecked(params))
        } else {
            None
        }
    }

    /// The parameter array.
    #[must_use]
    pub fn params(&self) -> &W {
        &self.params
    }

    /// The raw network outputs (cell logits, index `r·16 + c`) for an encoded condition.
    #[inline]
    #[must_use]
    pub fn forward(&self, c: &[f32; CONDITION_DIM]) -> [f32; DIRECT_CELLS] {
        let w = &self.params;
        let h: [f32; DIRECT_HIDDEN] = mlp::dense(w, DIRECT_L0 as u32, c, Activation::Relu);
        let h: [f32; DIRECT_HIDDEN] = mlp::dense(w, DIRECT_L1 as u32, &h, Activation::Relu);
        mlp::dense(w, DIRECT_L2 as u32, &h, Activation::Identity)
    }
}

/// The direct histogram at one shading point: densities and running sums in fixed arrays
/// (2 KiB, no allocation).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DirectHistogramPrepared {
    table: [f32; DIRECT_CELLS],
    marginal: [f32; DIRECT_N],
    conditional: [f32; DIRECT_CELLS],
}

impl DirectHistogramPrepared {
    /// The histogram from the 256 raw logits (index `r·16 + c`): masked softmax, densities
    /// `P_rc / h²`, and their running sums. Non-finite logits are clamped (NaN → very
    /// negative), so the result is always a valid distribution.
    #[must_use]
    pub fn from_logits(logits: &[f32; DIRECT_CELLS]) -> Self {
        let n = DIRECT_N as u32;
        // `cell_outside_disk` per cell, from the squared half-cell gaps of each row and
        // column (computed once): the same integer test, in a loop that vectorises.
        let mut gap2 = [0u32; DIRECT_N];
        let mut i = 0;
        while i < DIRECT_N {
            let g = half_cell_gap(i as u32, n);
            gap2[i] = g * g;
            i += 1;
        }
        let mut p = [0.0f32; DIRECT_CELLS];
        i = 0;
        while i < DIRECT_CELLS {
            // −∞ gets softmax weight exactly 0.
            p[i] = if gap2[i / DIRECT_N] + gap2[i % DIRECT_N] >= n * n {
                f32::NEG_INFINITY
            } else {
                logit(logits[i])
            };
            i += 1;
        }
        gaussian::softmax(&mut p);
        let inv_area = 1.0 / cell_area(n);
        let mut out = DirectHistogramPrepared {
            table: [0.0; DIRECT_CELLS],
            marginal: [0.0; DIRECT_N],
            conditional: [0.0; DIRECT_CELLS],
        };
        let mut m = 0.0f32;
        let mut r = 0;
        while r < DIRECT_N {
            let mut s = 0.0f32;
            let mut c = 0;
            while c < DIRECT_N {
                let k = r * DIRECT_N + c;
                let v = p[k] * inv_area;
                out.table[k] = v;
                s += v;
                out.conditional[k] = s;
                c += 1;
            }
            m += s;
            out.marginal[r] = m;
            r += 1;
        }
        out
    }

    /// The grid as a [`Table2D`] view.
    #[inline]
    #[must_use]
    pub fn table(&self) -> Table2D<&[f32; DIRECT_CELLS], &[f32; DIRECT_N]> {
        Table2D::from_parts(
            &self.table,
            &self.marginal,
            &self.conditional,
            DIRECT_N as u32,
            0,
            0,
            0.0,
        )
    }
}

impl<W: Weights> Sampler for DirectHistogramSampler<W> {
    type Prepared<'s>
        = DirectHistogramPrepared
    where
        Self: 's;

    #[inline]
    fn prepare(&self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<DirectHistogramPrepared> {
        let wi = check_condition(phi, wi)?;
        let logits = self.forward(&encode_condition(phi, wi));
        Some(DirectHistogramPrepared::from_logits(&logits))
    }
}

impl Prepared for DirectHistogramPrepared {
    /// Row by the marginal, column by the conditional, uniform within the cell; `None` when
    /// the point lands in the part of a boundary cell outside the disk.
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let (p, _) = self.table().sample(u)?;
        Sample::from_disk(p, self.pdf_disk(p))
    }

    /// `P_rc / h²` for points inside the open unit disk (area measure), 0 elsewhere.
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        if !(p.x * p.x + p.y * p.y < 1.0) {
            return 0.0;
        }
        self.table().pdf(p)
    }

    /// The unique `u` that `sample` maps to `wo` ([`Table2D::invert`]).
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        let w = warp::upper_hemisphere(wo)?;
        self.table().invert(warp::to_disk(w))
    }
}

// ---------------------------------------------------------------------------------------
// Histogram mixture (Eq. 5–6)
// ---------------------------------------------------------------------------------------

/// How the histogram mixture reads the latent-code axis of its tables.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default)]
pub enum Interpolation {
    /// The nearest level `round(t·(T − 1))` (the paper's rounding).
    #[default]
    Nearest,
    /// Linear interpolation between levels `⌊s⌋` and `⌊s⌋ + 1`, `s = t·(T − 1)`; exactly
    /// normalised because each slice is.
    Linear,
}

const MIX_HIDDEN: usize = 32;
const MIX_OUTPUTS: usize = 4 * BASES;
const MIX_L0: usize = 0;
const MIX_L1: usize = MIX_L0 + mlp::dense_len(RAW_CONDITION_DIM, MIX_HIDDEN);
const MIX_L2: usize = MIX_L1 + mlp::dense_len(MIX_HIDDEN, MIX_HIDDEN);
const MIX_L3: usize = MIX_L2 + mlp::dense_len(MIX_HIDDEN, MIX_HIDDEN);
const MIX_END: usize = MIX_L3 + mlp::dense_len(MIX_HIDDEN, MIX_OUTPUTS);

/// [`BASES`] rounded up to a multiple of 4 (per-basis scratch arrays that vectorise).
const PADDED_BASES: usize = BASES.div_ceil(4) * 4;

/// `|ρ|²` below which a predicted rotation vector counts as zero (identity rotation).
const MIN_ROTATION_NORM2: f32 = 1e-24;

/// The paper's histogram mixture (§3.3, Eq. 5–6): `p(ω⊥) = Σ_k w_k · H_k(Rᵀ_k ω⊥)` over
/// [`BASES`] baked basis histograms (`ARCHITECTURES.md` §6).
///
/// An MLP `10 → 32 → 32 → 32 → 40` (ReLU hidden) maps the raw condition `(φ, wi.x, wi.y)` to
/// `[a_k, ρ_k.x, ρ_k.y, τ_k]` per basis: weight logit, rotation vector and latent-code logit.
/// The bases are the tables `mass` (K × T), `table` (K × T × N × N), `marginal`
/// (K × T × N) and `conditional` (K × T × N × N). Densities are on the **projected disk**.
///
/// The constructor checks sizes only; the contents must have passed [`validate_tables`]
/// (the blob loader does this). Invalid contents cannot cause a panic or a NaN, only a wrong
/// or zero density.
#[derive(Copy, Clone, Debug)]
pub struct HistogramMixtureSampler<W> {
    params: W,
    mass: W,
    table: W,
    marginal: W,
    conditional: W,
    t_levels: u32,
    resolution: u32,
    interpolation: Interpolation,
}

impl<W: Weights> HistogramMixtureSampler<W> {
    /// Number of parameters: `dense(10,32) dense(32,32) dense(32,32) dense(32,40)` = 3784.
    pub const PARAM_COUNT: usize = MIX_END;

    /// A sampler over `params` and the baked tables of `t_levels` = T latent levels at
    /// resolution `resolution` = N. `None` unless `1 ≤ T ≤` [`MAX_T`], `1 ≤ N ≤` [`MAX_N`]
    /// and every array has exactly its required length (see the type docs).
    #[must_use]
    pub fn new(
        params: W,
        mass: W,
        table: W,
        marginal: W,
        conditional: W,
        t_levels: u32,
        resolution: u32,
        interpolation: Interpolation,
    ) -> Option<Self> {
        if params.len() as usize != Self::PARAM_COUNT {
            return None;
        }
        table_shapes(
            &mass,
            &table,
            &marginal,
            &conditional,
            BASES as u32,
            t_levels,
            resolution,
        )
        .ok()?;
        // The checked dimensions are within the clamps of `new_unchecked`.
        Some(Self::new_unchecked(
            params,
            mass,
            table,
            marginal,
            conditional,
            t_levels,
            resolution,
            interpolation,
        ))
    }

    /// A sampler without the size checks of [`Self::new`], for GPU shaders (`Option<Self>`
    /// with a borrowed `W` cannot be tested by rust-gpu). `t_levels` and `resolution` are
    /// clamped to `1 ..= MAX_T` and `1 ..= MAX_N`. Not `unsafe`: reads past the end of a
    /// short array give 0.0, so wrong densities but never a panic or NaN. Check the sizes on
    /// the host (e.g. with [`Self::new`]).
    #[inline]
    #[must_use]
    pub fn new_unchecked(
        params: W,
        mass: W,
        table: W,
        marginal: W,
        conditional: W,
        t_levels: u32,
        resolution: u32,
        interpolation: Interpolation,
    ) -> Self {
        HistogramMixtureSampler {
            params,
            mass,
            table,
            marginal,
            conditional,
            t_levels: t_levels.clamp(1, MAX_T as u32),
            resolution: resolution.clamp(1, MAX_N as u32),
            interpolation,
        }
    }

    /// The parameter array.
    #[must_use]
    pub fn params(&self) -> &W {
        &self.params
    }

    /// Number of latent-code levels T.
    #[must_use]
    pub fn t_levels(&self) -> u32 {
        self.t_levels
    }

    /// Grid resolution N.
    #[must_use]
    pub fn resolution(&self) -> u32 {
        self.resolution
    }

    /// How the latent axis is read.
    #[must_use]
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// The same sampler reading its latent axis with `interpolation`.
    #[must_use]
    pub fn with_interpolation(mut self, interpolation: Interpolation) -> Self {
        self.interpolation = interpolation;
        self
    }

    /// The raw network outputs `[a_k, ρ_k.x, ρ_k.y, τ_k]` (basis `k` at `4k..4k+4`) for a raw
    /// condition.
    #[inline]
    #[must_use]
    pub fn forward(&self, x: &[f32; RAW_CONDITION_DIM]) -> [f32; MIX_OUTPUTS] {
        let w = &self.params;
        let h: [f32; MIX_HIDDEN] = mlp::dense(w, MIX_L0 as u32, x, Activation::Relu);
        let h: [f32; MIX_HIDDEN] = mlp::dense(w, MIX_L1 as u32, &h, Activation::Relu);
        let h: [f32; MIX_HIDDEN] = mlp::dense(w, MIX_L2 as u32, &h, Activation::Relu);
        mlp::dense(w, MIX_L3 as u32, &h, Activation::Identity)
    }

    /// The prepared mixture from raw network outputs (see [`Self::forward`]):
    ///
    /// * rotation `(cos, sin) = ρ_k/|ρ_k|` (identity when `|ρ_k| < 1e−12` or not finite);
    /// * `s = sigmoid(τ_k)·(T − 1)`, slice `round(s)` ([`Interpolation::Nearest`]) or the
    ///   blend of `⌊s⌋` and `⌊s⌋ + 1` with weight `s − ⌊s⌋` ([`Interpolation::Linear`]);
    /// * `w_k ∝ softmax(a)_k · mass[k, s]` (mass blended like the table), normalised. When
    ///   every blended mass is 0, `w = softmax(a)` over the bases whose table is non-empty.
    ///
    /// `None` only when no basis has a usable table.
    #[inline(always)]
    #[must_use]
    pub fn prepare_outputs(&self, o: &[f32; MIX_OUTPUTS]) -> Option<HistogramMixturePrepared<'_, W>>
    where
        W: Copy,
    {
        let t_levels = self.t_levels;
        let mut soft = [0.0f32; BASES];
        let mut k = 0;
        while k < BASES {
            soft[k] = logit(o[4 * k]);
            k += 1;
        }
        gaussian::softmax(&mut soft);

        // Plain local arrays, assembled into the prepared state at the end: a mutable local
        // struct holding the sampler reference stays a pointer-typed variable on SPIR-V,
        // which spirv-val rejects under logical addressing.
        let mut weights = [0.0f32; BASES];
        let mut rotation = [Vec2::X; BASES];
        let mut slice0 = [0u32; BASES];
        let mut slice1 = [0u32; BASES];
        let mut lerp = [0.0f32; BASES];
        let mut mass = [0.0f32; BASES];
        let mut total = [0.0f32; BASES];
        let mut inv_integral = [0.0f32; BASES];
        let mut usable = [0u32; BASES]; // not [bool; _]: rust-gpu cannot memset bools
                                        // The latent codes t_k = sigmoid(τ_k), in a loop of their own so that it vectorises;
                                        // the fast form is exact down to EXP_IN_RANGE_MIN, the rest (and NaN) take libm's.
                                        // (Gathered into a contiguous array padded to a multiple of 4 first.)
        let mut code = [0.0f32; PADDED_BASES];
        k = 0;
        while k < BASES {
            code[k] = o[4 * k + 3];
            k += 1;
        }
        k = 0;
        while k < PADDED_BASES {
            code[k] = math::sigmoid_in_range(code[k]);
            k += 1;
        }
        k = 0;
        while k < BASES {
            if !(o[4 * k + 3] >= math::EXP_IN_RANGE_MIN) {
                code[k] = math::sigmoid(o[4 * k + 3]);
            }
            k += 1;
        }
        let top = (t_levels - 1) as f32;
        k = 0;
        while k < BASES {
            let rho = Vec2::new(o[4 * k + 1], o[4 * k + 2]);
            let len2 = rho.x * rho.x + rho.y * rho.y;
            if len2 >= MIN_ROTATION_NORM2 && math::is_finite(len2) {
                rotation[k] = rho * (1.0 / math::sqrt(len2));
            }
            // NaN τ gives NaN t; the clamp sends it to level 0.
            let s = math::clamp(code[k] * top, 0.0, top);
            let (l0, l1, a) = match self.interpolation {
                // s ≥ 0, so the truncation in clamp_index is the floor.
                Interpolation::Nearest => {
                    let l = math::clamp_index(s + 0.5, t_levels);
                    (l, l, 0.0)
                }
                Interpolation::Linear => {
                    if t_levels >= 2 {
                        let l = math::clamp_index(s, t_levels - 1);
                        (l, l + 1, math::clamp(s - l as f32, 0.0, 1.0))
                    } else {
                        (0, 0, 0.0)
                    }
                }
            };
            let base = k as u32 * t_levels;
            slice0[k] = base + l0;
            slice1[k] = base + l1;
            lerp[k] = a;
            let m0 = self.mass.at(base + l0);
            mass[k] = if a > 0.0 {
                (1.0 - a) * m0 + a * self.mass.at(base + l1)
            } else {
                m0
            };
            // The table's blended `marginal[N − 1]`, as `Table2D::from_parts` reads it.
            let n = self.resolution;
            let last = n - 1;
            let v0 = self.marginal.at(slice0[k] * n + last);
            total[k] = if a > 0.0 {
                (1.0 - a) * v0 + a * self.marginal.at(slice1[k] * n + last)
            } else {
                v0
            };
            k += 1;
        }
        // `Table2D::from_parts`'s total and 1/integral (kept, so that `table(k)` need not read
        // and divide again per pdf), usability and the unnormalised weights.
        let area = cell_area(self.resolution);
        k = 0;
        while k < BASES {
            let tot = total[k];
            let integral = tot * area;
            let ok = tot > 0.0 && math::is_finite(tot) && integral > 0.0;
            total[k] = if ok { tot } else { 0.0 };
            inv_integral[k] = if ok { 1.0 / integral } else { 0.0 };
            usable[k] = u32::from(ok);
            let w = soft[k] * mass[k];
            weights[k] = if ok && w > 0.0 && math::is_finite(w) {
                w
            } else {
                0.0
            };
            k += 1;
        }
        let mut sum = 0.0f32;
        k = 0;
        while k < BASES {
            sum += weights[k];
            k += 1;
        }
        if !(sum > 0.0 && math::is_finite(sum)) {
            // Every basis has zero mass here: fall back to the softmax weights.
            sum = 0.0;
            k = 0;
            while k < BASES {
                weights[k] = if usable[k] != 0 { soft[k] } else { 0.0 };
                sum += weights[k];
                k += 1;
            }
            if !(sum > 0.0) {
                return None;
            }
        }
        let inv = 1.0 / sum;
        k = 0;
        while k < BASES {
            weights[k] *= inv;
            k += 1;
        }
        Some(HistogramMixturePrepared {
            sampler: crate::sampler::Held::new(*self),
            _sampler: core::marker::PhantomData,
            weights,
            rotation,
            slice0,
            slice1,
            lerp,
            total,
            inv_integral,
        })
    }
}

/// The histogram mixture at one shading point: per-basis weight, rotation and table slices.
/// Borrows the sampler's tables.
#[derive(Debug)]
pub struct HistogramMixturePrepared<'s, W> {
    /// A copy of the sampler: weight and table handles (see `sampler::Held`).
    sampler: crate::sampler::Held<HistogramMixtureSampler<W>>,
    _sampler: core::marker::PhantomData<&'s W>,
    weights: [f32; BASES],
    rotation: [Vec2; BASES],
    slice0: [u32; BASES],
    slice1: [u32; BASES],
    lerp: [f32; BASES],
    /// Each basis table's blended `marginal[N − 1]` ([`Table2D`]'s `total`).
    total: [f32; BASES],
    /// Each basis table's `1 / (total · h²)` ([`Table2D`]'s `inv_integral`).
    inv_integral: [f32; BASES],
}

impl<W: Copy> Clone for HistogramMixturePrepared<'_, W> {
    fn clone(&self) -> Self {
        HistogramMixturePrepared {
            sampler: self.sampler.clone(),
            _sampler: core::marker::PhantomData,
            weights: self.weights,
            rotation: self.rotation,
            slice0: self.slice0,
            slice1: self.slice1,
            lerp: self.lerp,
            total: self.total,
            inv_integral: self.inv_integral,
        }
    }
}

impl<'s, W: Weights + Copy> HistogramMixturePrepared<'s, W> {
    /// Mixture weights `w_k` (sum 1).
    #[must_use]
    pub fn weights(&self) -> [f32; BASES] {
        self.weights
    }

    /// Rotation `(cos, sin)` of basis `k` (index clamped to `[0, K − 1]`).
    #[must_use]
    pub fn rotation(&self, k: usize) -> Vec2 {
        self.rotation[if k < BASES { k } else { BASES - 1 }]
    }

    /// The (possibly blended) table `H_k` of basis `k` (index clamped to `[0, K − 1]`), in
    /// the basis's rotated coordinates `q = Rᵀ_k ω⊥`.
    #[inline]
    #[must_use]
    pub fn table(&self, k: usize) -> Table2D<W> {
        let k = if k < BASES { k } else { BASES - 1 };
        let s = self.sampler.get();
        // What `Table2D::from_parts` computes, kept from `prepare`.
        Table2D {
            values: s.table,
            marginal: s.marginal,
            conditional: s.conditional,
            n: s.resolution,
            slice0: self.slice0[k],
            slice1: self.slice1[k],
            a: self.lerp[k],
            total: self.total[k],
            inv_integral: self.inv_integral[k],
        }
    }

    /// The `u` that [`Prepared::sample`] maps to `wo` *through basis `k`*: the basis's table
    /// inverse, with `u.x` mapped back into basis `k`'s interval of the component choice.
    /// `None` when basis `k` has zero weight or zero density at `wo`, or for invalid `wo`.
    #[must_use]
    pub fn invert_basis(&self, k: usize, wo: Vec3) -> Option<Vec2> {
        if k >= BASES || !(self.weights[k] > 0.0) {
            return None;
        }
        let w = warp::upper_hemisphere(wo)?;
        let q = warp::rotate_inverse(warp::to_disk(w), self.rotation[k]);
        let v = self.table(k).invert(q)?;
        // Start of basis k's interval, summed as gaussian::select_component does.
        let mut lo = 0.0f32;
        let mut i = 0;
        while i < k {
            if self.weights[i] > 0.0 {
                lo += self.weights[i];
            }
            i += 1;
        }
        let ux = lo + v.x * self.weights[k];
        Some(Vec2::new(
            math::clamp(ux, 0.0, math::ONE_MINUS_EPSILON),
            v.y,
        ))
    }
}

impl<W: Weights + Copy> Sampler for HistogramMixtureSampler<W> {
    type Prepared<'s>
        = HistogramMixturePrepared<'s, W>
    where
        Self: 's;

    #[inline]
    fn prepare<'s>(
        &'s self,
        phi: &[f32; FEATURE_DIM],
        wi: Vec3,
    ) -> Option<HistogramMixturePrepared<'s, W>> {
        let wi = check_condition(phi, wi)?;
        let o = self.forward(&raw_condition(phi, wi));
        self.prepare_outputs(&o)
    }
}

impl<W: Weights + Copy> Prepared for HistogramMixturePrepared<'_, W> {
    /// Chooses basis `k` by the weights (remapping `u.x`), samples its table in rotated
    /// coordinates and rotates back: `ω⊥ = R_k q`. The reported density is the full mixture
    /// (Eq. 5) at the drawn point; `None` when it lands outside the disk.
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let u = sanitize_u2(u)?;
        let (k, u0) = gaussian::select_component(&self.weights, u.x);
        let (q, _) = self.table(k).sample(Vec2::new(u0, u.y))?;
        let p = warp::rotate(q, self.rotation(k));
        Sample::from_disk(p, self.pdf_disk(p))
    }

    /// Eq. 5: `Σ_k w_k · H_k(Rᵀ_k ω⊥)` with respect to area on the projected disk; 0 outside
    /// the open unit disk.
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        if !(p.x * p.x + p.y * p.y < 1.0) {
            return 0.0;
        }
        // `Σ_k w_k · table(k).pdf(Rᵀ_k p)` in three passes: the cells first, then every
        // basis's table read (independent loads from a table too big for L1 overlap), then
        // the sum in basis order. The numbers are those of `Table2D::pdf`.
        let s = self.sampler.get();
        let n = s.resolution;
        let nn = n * n;
        let mut cell = [0u32; BASES];
        let mut inside = [0u32; BASES];
        let mut k = 0;
        while k < BASES {
            let q = warp::rotate_inverse(p, self.rotation[k]);
            inside[k] = u32::from(in_square(q));
            cell[k] = cell_index(q.y, n) * n + cell_index(q.x, n);
            k += 1;
        }
        let mut density = [0.0f32; BASES];
        k = 0;
        while k < BASES {
            let v0 = s.table.at(self.slice0[k] * nn + cell[k]);
            let a = self.lerp[k];
            let v = if a > 0.0 {
                (1.0 - a) * v0 + a * s.table.at(self.slice1[k] * nn + cell[k])
            } else {
                v0
            };
            density[k] = if inside[k] != 0 {
                finite_density(v * self.inv_integral[k])
            } else {
                0.0
            };
            k += 1;
        }
        let mut sum = 0.0f32;
        k = 0;
        while k < BASES {
            let w = self.weights[k];
            if w > 0.0 {
                sum += w * density[k];
            }
            k += 1;
        }
        finite_density(sum)
    }

    /// The unique `u` that `sample` maps to `wo` when exactly one basis has positive weight;
    /// `None` otherwise. With several bases the sampling map is not injective (each basis
    /// can produce the same direction), so no single inverse exists; see
    /// [`HistogramMixturePrepared::invert_basis`] for the per-basis inverse.
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        let mut only = BASES;
        let mut k = 0;
        while k < BASES {
            if self.weights[k] > 0.0 {
                if only < BASES {
                    return None;
                }
                only = k;
            }
            k += 1;
        }
        self.invert_basis(only, wo)
    }
}

// ---------------------------------------------------------------------------------------
// Validation and baking
// ---------------------------------------------------------------------------------------

fn shape(role: &'static str, len: u32, expected: u64) -> Result<(), Error> {
    if u64::from(len) == expected {
        Ok(())
    } else {
        Err(Error::TensorShape {
            role,
            expected: if expected > u64::from(u32::MAX) {
                u32::MAX
            } else {
                expected as u32
            },
            found: len,
        })
    }
}

fn dim(what: &'static str, found: u32, lo: u32, hi: u32) -> Result<(), Error> {
    if found >= lo && found <= hi {
        Ok(())
    } else {
        Err(Error::DimensionMismatch {
            what,
            expected: hi,
            found,
        })
    }
}

/// Dimension limits and tensor lengths of a set of baked tables.
fn table_shapes<W: Weights + ?Sized>(
    mass: &W,
    table: &W,
    marginal: &W,
    conditional: &W,
    bases: u32,
    t_levels: u32,
    resolution: u32,
) -> Result<(), Error> {
    dim("basis", bases, 1, BASES as u32)?;
    dim("t_levels", t_levels, 1, MAX_T as u32)?;
    dim("resolution", resolution, 1, MAX_N as u32)?;
    let slices = u64::from(bases) * u64::from(t_levels);
    let n = u64::from(resolution);
    shape("mass", mass.len(), slices)?;
    shape("table", table.len(), slices * n * n)?;
    shape("marginal", marginal.len(), slices * n)?;
    shape("conditional", conditional.len(), slices * n * n)?;
    Ok(())
}

fn all_finite<W: Weights + ?Sized>(role: &'static str, w: &W) -> Result<(), Error> {
    let mut i = 0;
    while i < w.len() {
        if !math::is_finite(w.at(i)) {
            return Err(Error::NonFinite { role, index: i });
        }
        i += 1;
    }
    Ok(())
}

/// Checks baked histogram-mixture tables (`ARCHITECTURES.md` §6) before use; the blob loader
/// calls this for every histogram-mixture blob.
///
/// For `bases` = K (1 ..= [`BASES`]), `t_levels` = T (1 ..= [`MAX_T`]) and `resolution` = N
/// (1 ..= [`MAX_N`]):
///
/// * lengths K·T, K·T·N², K·T·N, K·T·N² ([`Error::DimensionMismatch`], [`Error::TensorShape`]);
/// * every value finite ([`Error::NonFinite`]);
/// * `mass` and `table` non-negative, `table` exactly 0 on cells entirely outside the disk
///   ([`cell_outside_disk`]), each slice integrating to 1 (`|Σ value · h² − 1| ≤`
///   [`INTEGRAL_TOLERANCE`]);
/// * `conditional` non-decreasing within each row and within [`CDF_TOLERANCE`]` · row total +
///   10⁻⁶ · slice total` of the running sums of the values; `marginal` non-decreasing and
///   within [`CDF_TOLERANCE`]` · slice total` of the running sums of the row totals
///   ([`Error::TableNotNormalized`], with the flat index of the first bad element, or the
///   slice index for an integral).
///
/// Reference sums are accumulated in f64. CDFs stored as f16 cannot meet the tolerance: store
/// `marginal` and `conditional` as f32.
pub fn validate_tables<W: Weights + ?Sized>(
    mass: &W,
    table: &W,
    marginal: &W,
    conditional: &W,
    bases: u32,
    t_levels: u32,
    resolution: u32,
) -> Result<(), Error> {
    table_shapes(
        mass,
        table,
        marginal,
        conditional,
        bases,
        t_levels,
        resolution,
    )?;
    all_finite("mass", mass)?;
    all_finite("table", table)?;
    all_finite("marginal", marginal)?;
    all_finite("conditional", conditional)?;
    let bad = |role: &'static str, index: u32| Err(Error::TableNotNormalized { role, index });

    let n = resolution;
    let nn = n * n;
    let area = f64::from(cell_area(n));
    let slices = bases * t_levels;
    let mut s = 0;
    while s < slices {
        if !(mass.at(s) >= 0.0) {
            return bad("mass", s);
        }
        // Values: sign, mask, integral.
        let mut total = 0.0f64;
        let mut r = 0;
        while r < n {
            let mut c = 0;
            while c < n {
                let i = s * nn + r * n + c;
                let v = table.at(i);
                if !(v >= 0.0) || (v != 0.0 && cell_outside_disk(r, c, n)) {
                    return bad("table", i);
                }
                total += f64::from(v);
                c += 1;
            }
            r += 1;
        }
        if !(libm::fabs(total * area - 1.0) <= INTEGRAL_TOLERANCE) {
            return bad("table", s);
        }
        // Running sums.
        let mut run = 0.0f64;
        let mut prev_m = 0.0f32;
        r = 0;
        while r < n {
            let mut row = 0.0f64;
            let mut c = 0;
            while c < n {
                row += f64::from(table.at(s * nn + r * n + c));
                c += 1;
            }
            let tol_c = CDF_TOLERANCE * row + 1e-6 * total;
            let mut acc = 0.0f64;
            let mut prev_c = 0.0f32;
            c = 0;
            while c < n {
                let i = s * nn + r * n + c;
                acc += f64::from(table.at(i));
                let cv = conditional.at(i);
                if cv < prev_c || !(libm::fabs(f64::from(cv) - acc) <= tol_c) {
                    return bad("conditional", i);
                }
                prev_c = cv;
                c += 1;
            }
            run += row;
            let i = s * n + r;
            let mv = marginal.at(i);
            if mv < prev_m || !(libm::fabs(f64::from(mv) - run) <= CDF_TOLERANCE * total) {
                return bad("marginal", i);
            }
            prev_m = mv;
            r += 1;
        }
        s += 1;
    }
    Ok(())
}

/// Writes the running sums of the `n × n` slices in `table` (any number of whole slices):
/// `conditional` (same length as `table`) within each row and `marginal` (one entry per row)
/// over row totals, accumulated in f32 in index order — exactly what the runtime reads.
///
/// Call it on the values *as they will be stored* (e.g. after rounding to f16) so that the
/// CDFs and the values agree. Extra slots in the outputs are left untouched; missing ones are
/// skipped.
pub fn running_sums(table: &[f32], n: u32, marginal: &mut [f32], conditional: &mut [f32]) {
    let n = n as usize;
    if n == 0 {
        return;
    }
    let rows = table.len() / n;
    let mut row = 0;
    while row < rows {
        // The marginal restarts at the first row of every slice.
        let slice_row = row % n;
        let mut s = 0.0f32;
        let mut c = 0;
        while c < n {
            let i = row * n + c;
            s += table[i];
            if i < conditional.len() {
                conditional[i] = s;
            }
            c += 1;
        }
        let prev = if slice_row > 0 && row - 1 < marginal.len() {
            marginal[row - 1]
        } else {
            0.0
        };
        if row < marginal.len() {
            marginal[row] = prev + s;
        }
        row += 1;
    }
}

/// Baked histogram-mixture tables (host side), laid out as `ARCHITECTURES.md` §6 and ready to
/// pass to [`HistogramMixtureSampler::new`] (as `&[f32]`) or to a blob writer.
#[cfg(feature = "alloc")]
#[derive(Clone, Debug, PartialEq)]
pub struct BakedTables {
    /// K × T: the integral of each raw slice over the cells not entirely outside the disk.
    pub mass: alloc::vec::Vec<f32>,
    /// K × T × N × N: normalised densities (each slice integrates to 1), rounded to the
    /// storage type.
    pub table: alloc::vec::Vec<f32>,
    /// K × T × N: running sums of row totals of `table`.
    pub marginal: alloc::vec::Vec<f32>,
    /// K × T × N × N: running sums within each row of `table`.
    pub conditional: alloc::vec::Vec<f32>,
    /// K.
    pub bases: u32,
    /// T.
    pub t_levels: u32,
    /// N.
    pub resolution: u32,
}

#[cfg(feature = "alloc")]
impl BakedTables {
    /// [`validate_tables`] on these tables.
    pub fn validate(&self) -> Result<(), Error> {
        validate_tables(
            self.mass.as_slice(),
            self.table.as_slice(),
            self.marginal.as_slice(),
            self.conditional.as_slice(),
            self.bases,
            self.t_levels,
            self.resolution,
        )
    }
}

/// [`try_bake_slices`] for input known to be valid (the trainer's softplus outputs, tests).
///
/// # Panics
///
/// When [`try_bake_slices`] returns an error (wrong dimensions or length, NaN, ∞ or
/// negative values).
#[cfg(feature = "alloc")]
#[must_use]
pub fn bake_slices(
    raw: &[f32],
    bases: usize,
    t_levels: usize,
    resolution: usize,
    storage: crate::weights::DType,
) -> BakedTables {
    match try_bake_slices(raw, bases, t_levels, resolution, storage) {
        Ok(t) => t,
        Err(e) => panic!("bake_slices: {e}"),
    }
}

/// Bakes raw per-slice values into histogram-mixture tables.
///
/// `raw` holds K × T slices of `N × N` non-negative values (rows = y, as the tables), e.g.
/// the training model's basis `k` at level `t` evaluated at cell centres. For each slice:
/// cells entirely outside the disk are set to 0; `mass` = `Σ value · h²` (f64, stored f32);
/// the table is `value / mass`, then rounded to `storage` (f16 rounding happens *before* the
/// running sums, which are built by [`running_sums`] from the rounded values, so the CDFs
/// match the stored table exactly). A slice with no mass becomes uniform over the cells not
/// entirely outside the disk, with `mass` 0 (it then never receives weight unless every basis
/// is empty).
///
/// Errors: dimensions as in [`validate_tables`], [`Error::TensorShape`] for a `raw` of the
/// wrong length, [`Error::NonFinite`] / [`Error::TableNotNormalized`] (role `"raw"`) for NaN,
/// infinite or negative input.
#[cfg(feature = "alloc")]
pub fn try_bake_slices(
    raw: &[f32],
    bases: usize,
    t_levels: usize,
    resolution: usize,
    storage: crate::weights::DType,
) -> Result<BakedTables, Error> {
    use alloc::vec;
    let to_u32 = |x: usize| u32::try_from(x).unwrap_or(u32::MAX);
    let (bases, t_levels, resolution) = (to_u32(bases), to_u32(t_levels), to_u32(resolution));
    dim("basis", bases, 1, BASES as u32)?;
    dim("t_levels", t_levels, 1, MAX_T as u32)?;
    dim("resolution", resolution, 1, MAX_N as u32)?;
    let n = resolution as usize;
    let nn = n * n;
    let slices = (bases * t_levels) as usize;
    if raw.len() != slices * nn {
        return Err(Error::TensorShape {
            role: "raw",
            expected: (slices * nn) as u32,
            found: to_u32(raw.len()),
        });
    }
    let area = f64::from(cell_area(resolution));
    let round = |v: f64| -> f32 {
        let v = v as f32;
        match storage {
            crate::weights::DType::F32 => v,
            crate::weights::DType::F16 => half::f16::from_f32(v).to_f32(),
        }
    };
    let mut out = BakedTables {
        mass: vec![0.0; slices],
        table: vec![0.0; slices * nn],
        marginal: vec![0.0; slices * n],
        conditional: vec![0.0; slices * nn],
        bases,
        t_levels,
        resolution,
    };
    let inside = |i: usize| !cell_outside_disk((i / n) as u32, (i % n) as u32, resolution);
    let inside_cells = (0..nn).filter(|&i| inside(i)).count();
    for s in 0..slices {
        let mut sum = 0.0f64;
        for i in 0..nn {
            let v = raw[s * nn + i];
            if !v.is_finite() {
                return Err(Error::NonFinite {
                    role: "raw",
                    index: (s * nn + i) as u32,
                });
            }
            if v < 0.0 {
                return Err(Error::TableNotNormalized {
                    role: "raw",
                    index: (s * nn + i) as u32,
                });
            }
            if inside(i) {
                sum += f64::from(v);
            }
        }
        let mass = sum * area;
        let dst = &mut out.table[s * nn..(s + 1) * nn];
        if mass > 0.0 && mass.is_finite() {
            out.mass[s] = mass as f32;
            for i in 0..nn {
                if inside(i) {
                    dst[i] = round(f64::from(raw[s * nn + i]) / mass);
                }
            }
        } else {
            let uniform = round(1.0 / (inside_cells as f64 * area));
            for i in 0..nn {
                if inside(i) {
                    dst[i] = uniform;
                }
            }
        }
    }
    running_sums(
        &out.table,
        resolution,
        &mut out.marginal,
        &mut out.conditional,
    );
    Ok(out)
}
