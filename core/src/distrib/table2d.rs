//! [`Table2D`]: a piecewise-constant 2-D distribution on an `N × N` grid over `[−1, 1]²`
//! (pbrt's `PiecewiseConstant2D`, Mitsuba's `Marginal2D`), read-only, stored as density values
//! plus unnormalised running sums (a *marginal* over rows and a *conditional* within each
//! row), with `sample`, `pdf` and `invert`. Generic over [`Weights`], so the same code reads
//! blob tensors (f32 or f16), host slices, GPU storage buffers and the fixed arrays of a
//! prepared sampler. Both histogram samplers are built on it.
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

use glam::Vec2;

use crate::math::{self, finite_density};
use crate::weights::Weights;

/// Largest grid resolution N a [`Table2D`] may have.
pub const MAX_N: usize = 128;

/// The units of a [`TableLayout::Compact`] conditional CDF: every non-empty row ends at
/// exactly this value (the largest `u16`).
pub const CDF_UNITS: f32 = 65535.0;

/// How a [`Table2D`] stores its slices.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default)]
#[repr(u32)] // rust-gpu: a u8 discriminant needs the Int8 capability
pub enum TableLayout {
    /// Density values (f32 or f16) with f32 running sums of them within each row
    /// (`conditional`) and over row totals (`marginal`).
    #[default]
    Values,
    /// No values: `conditional` holds each row's CDF quantised to integers in
    /// `0 ..= CDF_UNITS` (stored as u16, ending at [`CDF_UNITS`] in non-empty rows) and
    /// `marginal` the running sums of row totals; a cell's density is its row's total times
    /// its step of the row's CDF. Sampling and density read the same integers, so they agree
    /// exactly, and the table takes a quarter of the memory of values plus f32 CDFs.
    Compact,
}

/// Iterations of the fixed-length binary searches: enough for any `N ≤ MAX_N`.
const SEARCH_STEPS: u32 = 7;
const _: () = assert!(1usize << SEARCH_STEPS >= MAX_N);

/// Resolutions above this are clamped by [`cell_outside_disk`] (keeps its integer test exact
/// and overflow-free).
const MAX_MASK_N: u32 = 16384;

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
pub(crate) fn half_cell_gap(i: u32, n: u32) -> u32 {
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
pub(crate) fn cell_index(x: f32, n: u32) -> u32 {
    math::clamp_index((x + 1.0) * (0.5 * n as f32), n)
}

/// The row and column `(r, c)` of the cell holding `p` (indices clamped into the grid;
/// callers test [`in_square`] first).
#[inline(always)]
pub(crate) fn cell_of(p: Vec2, n: u32) -> (u32, u32) {
    (cell_index(p.y, n), cell_index(p.x, n))
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
pub(crate) fn in_square(p: Vec2) -> bool {
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
    /// Density values (unused, a copy of `marginal`'s storage, in the compact layout).
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
    layout: TableLayout,
}

/// The checks [`Table2D::lerp`] and [`Table2D::lerp_compact`] share: `n` in `1 ..=`
/// [`MAX_N`], `a ∈ [0, 1]` (not NaN), and slices `slice0` and `slice1` inside `conditional`
/// (`N²` entries a slice) and `marginal` (`N` a slice). The later of the two slices, or `None`.
#[inline(always)]
fn blend_fits<M: Weights + ?Sized, C: Weights + ?Sized>(
    marginal: &M,
    conditional: &C,
    n: u32,
    slice0: u32,
    slice1: u32,
    a: f32,
) -> Option<u32> {
    if n == 0 || n as usize > MAX_N || !(0.0..=1.0).contains(&a) {
        return None;
    }
    let last = if slice0 > slice1 { slice0 } else { slice1 };
    // Written as divisions so that nothing can overflow.
    if last >= conditional.len() / (n * n) || last >= marginal.len() / n {
        return None;
    }
    Some(last)
}

impl<T: Copy, M: Copy, C: Copy> Clone for Table2D<T, M, C> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T: Copy, M: Copy, C: Copy> Copy for Table2D<T, M, C> {}

impl<M: Weights + Copy, C: Weights> Table2D<M, M, C> {
    /// A view of the blend `(1 − a)·slice0 + a·slice1` of slices in the
    /// [`TableLayout::Compact`] layout (`N` marginal and `N²` conditional entries per slice).
    /// `None` under the conditions of [`Table2D::lerp`].
    #[inline]
    #[must_use]
    pub fn lerp_compact(
        marginal: M,
        conditional: C,
        n: u32,
        slice0: u32,
        slice1: u32,
        a: f32,
    ) -> Option<Self> {
        blend_fits(&marginal, &conditional, n, slice0, slice1, a)?;
        Some(Self::from_parts(
            marginal,
            marginal,
            conditional,
            n,
            slice0,
            slice1,
            a,
            TableLayout::Compact,
        ))
    }
}

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
        let last = blend_fits(&marginal, &conditional, n, slice0, slice1, a)?;
        // A division, as in `blend_fits`, so that nothing can overflow.
        if last >= values.len() / (n * n) {
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
            TableLayout::Values,
        ))
    }

    /// A view without the size checks (reads past the end give 0, so this is safe; callers
    /// check sizes once, at construction of the sampler).
    #[inline(always)]
    pub(crate) fn from_parts(
        values: T,
        marginal: M,
        conditional: C,
        n: u32,
        slice0: u32,
        slice1: u32,
        a: f32,
        layout: TableLayout,
    ) -> Self {
        let mut t = Self::from_normalized_parts(
            values,
            marginal,
            conditional,
            n,
            (slice0, slice1, a),
            0.0,
            0.0,
            layout,
        );
        let total = t.marginal_at(n - 1);
        let integral = total * cell_area(n);
        if total > 0.0 && math::is_finite(total) && integral > 0.0 {
            t.total = total;
            t.inv_integral = 1.0 / integral;
        }
        t
    }

    /// [`Table2D::from_parts`] with its normalisation (`total`, `inv_integral`) already
    /// known, as a prepared sampler keeps it per table.
    #[inline(always)]
    pub(crate) fn from_normalized_parts(
        values: T,
        marginal: M,
        conditional: C,
        n: u32,
        slices: (u32, u32, f32),
        total: f32,
        inv_integral: f32,
        layout: TableLayout,
    ) -> Self {
        Table2D {
            values,
            marginal,
            conditional,
            n,
            slice0: slices.0,
            slice1: slices.1,
            a: slices.2,
            total,
            inv_integral,
            layout,
        }
    }

    /// The blended `marginal[N − 1]` (0 when it is not positive and finite) and
    /// `1 / (total · h²)` (0 likewise): what [`Table2D::from_normalized_parts`] takes.
    #[inline(always)]
    pub(crate) fn normalization(&self) -> (f32, f32) {
        (self.total, self.inv_integral)
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

    /// Slice `s`'s total of row `r`: `marginal[r] − marginal[r − 1]`.
    #[inline(always)]
    fn row_total(&self, s: u32, r: u32) -> f32 {
        let m1 = self.marginal.at(s * self.n + r);
        let m0 = if r > 0 {
            self.marginal.at(s * self.n + r - 1)
        } else {
            0.0
        };
        m1 - m0
    }

    /// Slice `s`'s running sum of row `r` up to column `c`, in density units.
    #[inline(always)]
    fn slice_conditional(&self, s: u32, r: u32, c: u32) -> f32 {
        let i = s * self.n * self.n + r * self.n + c;
        match self.layout {
            TableLayout::Values => self.conditional.at(i),
            TableLayout::Compact => self.row_total(s, r) * (self.conditional.at(i) / CDF_UNITS),
        }
    }

    /// Slice `s`'s density value of cell `(r, c)`.
    #[inline(always)]
    fn slice_value(&self, s: u32, r: u32, c: u32) -> f32 {
        let i = s * self.n * self.n + r * self.n + c;
        match self.layout {
            TableLayout::Values => self.values.at(i),
            TableLayout::Compact => {
                let c1 = self.conditional.at(i);
                let c0 = if c > 0 {
                    self.conditional.at(i - 1)
                } else {
                    0.0
                };
                self.row_total(s, r) * ((c1 - c0) / CDF_UNITS)
            }
        }
    }

    /// `f` of `slice0` and `slice1` blended with weights `(1 − a, a)`.
    #[inline(always)]
    fn blend_slices(&self, f: impl Fn(u32) -> f32) -> f32 {
        let v0 = f(self.slice0);
        if self.a > 0.0 {
            (1.0 - self.a) * v0 + self.a * f(self.slice1)
        } else {
            v0
        }
    }

    /// Blended `conditional[r][c]` (density units).
    #[inline(always)]
    fn conditional_at(&self, r: u32, c: u32) -> f32 {
        self.blend_slices(|s| self.slice_conditional(s, r, c))
    }

    /// Blended stored value of cell `(r, c)` (indices clamped into the grid).
    #[inline]
    #[must_use]
    pub fn value(&self, row: u32, col: u32) -> f32 {
        let r = if row < self.n { row } else { self.n - 1 };
        let c = if col < self.n { col } else { self.n - 1 };
        self.blend_slices(|s| self.slice_value(s, r, c))
    }

    /// Draws a point of `[−1, 1]²` from `u ∈ [0, 1)²`: `u.x` picks the row, `u.y` the column
    /// and the offsets within the cell are continuous. Returns the point and its density
    /// ([`Table2D::pdf`] at the point, area measure). `None` for invalid `u` or a table whose
    /// total is not positive.
    #[inline]
    #[must_use]
    pub fn sample(&self, u: Vec2) -> Option<(Vec2, f32)> {
        let u = math::sanitize_u2(u)?;
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
        let (r, c) = cell_of(p, self.n);
        self.density_at_cell(r, c)
    }

    /// The density of the cell in row `r`, column `c` (as [`cell_of`] gives them): the
    /// (blended) value over the stored integral, never NaN or negative.
    #[inline(always)]
    pub(crate) fn density_at_cell(&self, r: u32, c: u32) -> f32 {
        finite_density(self.blend_slices(|s| self.slice_value(s, r, c)) * self.inv_integral)
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
