//! [`Marginal2D`]: a continuous piecewise-bilinear 2-D distribution on `[0, 1]²` with
//! conditional slices blended linearly in up to two parameters — the warp of measured
//! materials (Mitsuba 3's `Marginal2D<Float, Dim, Continuous = true>`, pbrt-v4's
//! `PiecewiseLinear2D`), read-only over [`Weights`] storage.
//!
//! # Layout and measure
//!
//! A slice is a `height × width` grid of density values at the nodes `(x, y) = (c/(width −
//! 1), r/(height − 1))`, row-major (rows are y); the density between nodes is their bilinear
//! interpolant, a density with respect to **area on `[0, 1]²`**. Slices are stored one after
//! another, parameter 0 outermost: the slice of node `(i0, i1)` has index `i0·n1 + i1`.
//! Sampling inverts a marginal over y and a conditional over x, both continuous
//! (piecewise-quadratic CDFs), with per-slice running integrals built by [`build`]:
//!
//! ```text
//! cond[r][c] = Σ_{c' ≤ c} (v[r][c'] + v[r][c'+1]) / (2 (width − 1))      c < width − 1
//! marg[r]    = Σ_{r' ≤ r} (cond[r'][last] + cond[r'+1][last]) / (2 (height − 1))
//! ```
//!
//! A normalised slice is scaled so that `marg[last] = 1`. Blending slices with weights that
//! sum to one blends values and integrals alike, so a blend of normalised slices is
//! normalised, and `sample`, `invert` and `eval` agree on it.

use glam::Vec2;

use crate::math;
use crate::weights::Weights;

/// Largest number of parameter nodes along one axis.
pub const MAX_PARAM_NODES: u32 = 1 << 16;

/// Where a parameter value falls among a grid of parameter nodes: the lower node and the
/// weights of it and the next one (Mitsuba's `interpolate_weights`).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct SliceBlend {
    /// Index of the first slice read (the lower node along every axis).
    pub slice: u32,
    /// Slice stride of each axis (0 for an axis with one node).
    pub stride: [u32; 2],
    /// `(w_lower, w_upper)` of each axis.
    pub weight: [[f32; 2]; 2],
}

impl SliceBlend {
    /// The single slice `slice`, unblended.
    #[must_use]
    pub const fn single(slice: u32) -> Self {
        SliceBlend {
            slice,
            stride: [0, 0],
            weight: [[1.0, 0.0], [1.0, 0.0]],
        }
    }

    /// The blend of the slices around `value = (p0, p1)` on the node grids `nodes0` (its
    /// first `n0` elements) and `nodes1` (its first `n1`), each ascending with at least one
    /// node; parameter 0 outermost. The counts come from the caller, not from the storages'
    /// lengths, which may be padded (GPU buffers). Values outside a grid clamp to its end;
    /// NaN gives the lower end.
    #[must_use]
    pub fn new<W: Weights + ?Sized>(
        nodes0: &W,
        n0: u32,
        nodes1: &W,
        n1: u32,
        value: [f32; 2],
    ) -> Self {
        let (i0, w0) = locate(nodes0, n0, value[0]);
        let (i1, w1) = locate(nodes1, n1, value[1]);
        SliceBlend {
            slice: i0 * n1 + i1,
            stride: [if n0 > 1 { n1 } else { 0 }, if n1 > 1 { 1 } else { 0 }],
            weight: [w0, w1],
        }
    }

    /// The blended value of `table` at element `index` of the first slice (slices of `n`
    /// elements).
    #[inline]
    #[must_use]
    pub fn lookup<W: Weights + ?Sized>(&self, table: &W, n: u32, index: u32) -> f32 {
        let i1 = index + self.stride[1] * n;
        let axis0 = |i: u32| {
            let j = i + self.stride[0] * n;
            table.at(i) * self.weight[0][0] + table.at(j) * self.weight[0][1]
        };
        axis0(index) * self.weight[1][0] + axis0(i1) * self.weight[1][1]
    }
}

/// The interval of the first `n` `nodes` holding `p` and the linear weights across it.
fn locate<W: Weights + ?Sized>(nodes: &W, n: u32, p: f32) -> (u32, [f32; 2]) {
    if n < 2 {
        return (0, [1.0, 0.0]);
    }
    // The first index in 1 ..= n − 1 whose node is not below p, minus one.
    let (mut lo, mut hi) = (1u32, n - 1);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if nodes.at(mid) < p {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    let i = lo - 1;
    let (p0, p1) = (nodes.at(i), nodes.at(i + 1));
    let t = math::clamp((p - p0) / (p1 - p0), 0.0, 1.0);
    (i, [1.0 - t, t])
}

/// `a + (b − a)·t`.
#[inline(always)]
pub(crate) fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// A continuous piecewise-bilinear distribution (module docs) over the tables `data` (slices
/// of `width × height` values), `marg` (slices of `height − 1`) and `cond` (slices of
/// `height × (width − 1)`), all from [`build`]. `eval` needs only `data`.
///
/// The tables are handles held by value (`&[f32]`, `&Vec<f32>`, a blob's `Tensor`, …).
// rust-gpu: by value, not `&W`: with storage-buffer tables a reference would point at a
// local variable holding a buffer pointer, which lavapipe cannot compile.
#[derive(Copy, Clone, Debug)]
pub struct Marginal2D<W> {
    data: W,
    marg: W,
    cond: W,
    width: u32,
    height: u32,
}

impl<W: Weights> Marginal2D<W> {
    /// A distribution over tables that the caller has checked: `width, height ≥ 2` and every
    /// slice read is in range (reads past the end give 0, never a panic).
    #[must_use]
    pub fn new(data: W, marg: W, cond: W, width: u32, height: u32) -> Self {
        Marginal2D {
            data,
            marg,
            cond,
            width: if width < 2 { 2 } else { width },
            height: if height < 2 { 2 } else { height },
        }
    }

    fn n_data(&self) -> u32 {
        self.width * self.height
    }

    fn n_cond(&self) -> u32 {
        self.height * (self.width - 1)
    }

    fn n_marg(&self) -> u32 {
        self.height - 1
    }

    /// The patch holding `pos` (clamped to the square) and `pos` within it.
    fn patch(&self, pos: Vec2) -> (u32, u32, Vec2) {
        patch(self.width, self.height, pos)
    }

    /// The four corner values of patch `(c, r)` of the blended slice.
    fn corners(&self, blend: &SliceBlend, c: u32, r: u32) -> [f32; 4] {
        let n = self.n_data();
        let i = blend.slice * n + r * self.width + c;
        [
            blend.lookup(&self.data, n, i),
            blend.lookup(&self.data, n, i + 1),
            blend.lookup(&self.data, n, i + self.width),
            blend.lookup(&self.data, n, i + self.width + 1),
        ]
    }

    /// The density at `pos` (bilinear in the blended slice; `pos` clamped to the square).
    #[must_use]
    pub fn eval(&self, blend: &SliceBlend, pos: Vec2) -> f32 {
        let (c, r, t) = self.patch(pos);
        let [v00, v10, v01, v11] = self.corners(blend, c, r);
        lerp(lerp(v00, v10, t.x), lerp(v01, v11, t.x), t.y)
    }

    /// A point drawn from the blended slice by the uniform variates `u` (clamped inside the
    /// open square), and its density.
    #[must_use]
    pub fn sample(&self, blend: &SliceBlend, u: Vec2) -> (Vec2, f32) {
        let (w, h) = (self.width, self.height);
        let (n_marg, n_cond) = (self.n_marg(), self.n_cond());
        let eps = f32::EPSILON / 2.0;
        let mut ux = math::clamp(u.x, eps, math::ONE_MINUS_EPSILON);
        let mut uy = math::clamp(u.y, eps, math::ONE_MINUS_EPSILON);

        let off_marg = blend.slice * n_marg;
        let marg = |i: u32| blend.lookup(&self.marg, n_marg, off_marg + i);
        let row = search(n_marg - 1, |i| marg(i) < uy);
        if row > 0 {
            uy -= marg(row - 1);
        }

        let off_cond = blend.slice * n_cond + row * (w - 1);
        let r0 = blend.lookup(&self.cond, n_cond, off_cond + (w - 1) - 1);
        let r1 = blend.lookup(&self.cond, n_cond, off_cond + 2 * (w - 1) - 1);
        uy = sample_segment(uy, (h - 1) as f32, r0, r1);
        ux *= lerp(r0, r1, uy);

        let cond = |i: u32| {
            let v0 = blend.lookup(&self.cond, n_cond, off_cond + i);
            let v1 = blend.lookup(&self.cond, n_cond, off_cond + i + (w - 1));
            lerp(v0, v1, uy)
        };
        let col = search(w - 2, |i| cond(i) < ux);
        if col > 0 {
            ux -= cond(col - 1);
        }

        let [v00, v10, v01, v11] = self.corners(blend, col, row);
        let c0 = lerp(v00, v01, uy);
        let c1 = lerp(v10, v11, uy);
        ux = sample_segment(ux, (w - 1) as f32, c0, c1);
        let pos = Vec2::new(
            (col as f32 + ux) * (1.0 / (w - 1) as f32),
            (row as f32 + uy) * (1.0 / (h - 1) as f32),
        );
        (pos, lerp(c0, c1, ux))
    }

    /// The uniform variates that [`Marginal2D::sample`] maps to `pos` (clamped to the square),
    /// and the density at `pos`.
    #[must_use]
    pub fn invert(&self, blend: &SliceBlend, pos: Vec2) -> (Vec2, f32) {
        let w = self.width;
        let (n_marg, n_cond) = (self.n_marg(), self.n_cond());
        let (c, r, t) = self.patch(pos);
        let [v00, v10, v01, v11] = self.corners(blend, c, r);
        let c0 = lerp(v00, v01, t.y);
        let c1 = lerp(v10, v11, t.y);
        let pdf = lerp(c0, c1, t.x);

        let mut ux = invert_segment(t.x, 1.0 / (w - 1) as f32, c0, c1);
        let off_cond = blend.slice * n_cond + r * (w - 1);
        if c > 0 {
            let v0 = blend.lookup(&self.cond, n_cond, off_cond + c - 1);
            let v1 = blend.lookup(&self.cond, n_cond, off_cond + c - 1 + (w - 1));
            ux += lerp(v0, v1, t.y);
        }
        let r0 = blend.lookup(&self.cond, n_cond, off_cond + (w - 1) - 1);
        let r1 = blend.lookup(&self.cond, n_cond, off_cond + 2 * (w - 1) - 1);
        ux /= lerp(r0, r1, t.y);

        let mut uy = invert_segment(t.y, 1.0 / (self.height - 1) as f32, r0, r1);
        if r > 0 {
            uy += blend.lookup(&self.marg, n_marg, blend.slice * n_marg + r - 1);
        }
        (Vec2::new(ux, uy), pdf)
    }
}

/// The patch `(column, row)` of a `width × height` grid (both ≥ 2) holding `pos` (clamped to
/// the square) and `pos` within it.
#[inline(always)]
pub(crate) fn patch(width: u32, height: u32, pos: Vec2) -> (u32, u32, Vec2) {
    let x = math::clamp(pos.x, 0.0, 1.0) * (width - 1) as f32;
    let y = math::clamp(pos.y, 0.0, 1.0) * (height - 1) as f32;
    // NaN clamps to 0. x < width ≤ 2³¹ (w·h values, h ≥ 2, counted in u32), y likewise.
    let c = math::trunc_index(x).min(width - 2);
    let r = math::trunc_index(y).min(height - 2);
    (c, r, Vec2::new(x - c as f32, y - r as f32))
}

/// The first index in `0 ..= last` where `below` is false (`last` when it is true
/// everywhere): Dr.Jit's `binary_search`.
#[inline]
fn search(last: u32, below: impl Fn(u32) -> bool) -> u32 {
    let (mut lo, mut hi) = (0u32, last);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if below(mid) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The position in a segment of `1 / inv_width` whose density goes linearly from `v0` to
/// `v1`, at which its integral reaches `u`; in units of the segment.
#[inline]
pub(crate) fn sample_segment(u: f32, inv_width: f32, v0: f32, v1: f32) -> f32 {
    let non_const = math::abs(v0 - v1) > 1e-4 * (v0 + v1);
    let divisor = if non_const { v0 - v1 } else { v0 + v1 };
    let mut s = u * (2.0 * inv_width);
    if non_const {
        s = v0 - math::safe_sqrt(v0 * v0 + s * (v1 - v0));
    }
    if divisor != 0.0 {
        s /= divisor;
    }
    s
}

/// The integral of such a segment up to position `t` (in units of the segment).
#[inline]
pub(crate) fn invert_segment(t: f32, width: f32, v0: f32, v1: f32) -> f32 {
    t * lerp(v0, v1, 0.5 * t) * width
}

/// The tables of a [`Marginal2D`] built from raw slices (`data.len()` a multiple of `width ×
/// height`): `(data, marg, cond)`, with every slice scaled to integrate to one when
/// `normalize` (slices that integrate to zero stay zero). Integrals accumulate in f64.
#[cfg(feature = "alloc")]
#[must_use]
pub fn build(
    data: &[f32],
    width: usize,
    height: usize,
    normalize: bool,
) -> (
    alloc::vec::Vec<f32>,
    alloc::vec::Vec<f32>,
    alloc::vec::Vec<f32>,
) {
    use alloc::vec::Vec;
    let (w, h) = (width.max(2), height.max(2));
    let n = w * h;
    let slices = data.len() / n;
    let (sx, sy) = (0.5 / (w - 1) as f64, 0.5 / (h - 1) as f64);
    let mut out = Vec::with_capacity(slices * n);
    let mut marg = Vec::with_capacity(slices * (h - 1));
    let mut cond = Vec::with_capacity(slices * h * (w - 1));
    let mut row_sum = alloc::vec![0.0f64; h];
    for s in data.chunks_exact(n) {
        let mut c_slice = Vec::with_capacity(h * (w - 1));
        for (y, row) in s.chunks_exact(w).enumerate() {
            let mut acc = 0.0f64;
            for x in 0..w - 1 {
                acc += sx * (f64::from(row[x]) + f64::from(row[x + 1]));
                c_slice.push(acc);
            }
            row_sum[y] = acc;
        }
        let mut m_slice = Vec::with_capacity(h - 1);
        let mut acc = 0.0f64;
        for y in 0..h - 1 {
            acc += sy * (row_sum[y] + row_sum[y + 1]);
            m_slice.push(acc);
        }
        let norm = if normalize && acc > 0.0 {
            1.0 / acc
        } else {
            1.0
        };
        // As Mitsuba: the integrals are rounded to f32 before they are scaled.
        let scale = |v: f64| (v as f32) * norm as f32;
        cond.extend(c_slice.into_iter().map(scale));
        marg.extend(m_slice.into_iter().map(scale));
        out.extend(s.iter().map(|&v| v * norm as f32));
    }
    (out, marg, cond)
}
