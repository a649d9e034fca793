//! The direct histogram baseline (Zhu et al. 2021; "histogram (baseline)" in the paper's
//! Table 2): an MLP predicts a 16 × 16 grid over the projected disk per condition
//! (`core/ARCHITECTURES.md` §5), sampled and evaluated as a [`Table2D`].

use glam::{Vec2, Vec3};

use crate::distrib::gaussian;
use crate::distrib::table2d::{cell_area, half_cell_gap, Table2D, TableLayout};
use crate::math::clamp_logit;
use crate::nn::{ReluMlp, CONDITION_DIM};
use crate::warp;

use super::{Prepared, Sample};

/// Grid resolution of the direct histogram baseline (16 × 16 cells).
pub const DIRECT_N: usize = 16;

/// Number of cells of the direct histogram baseline.
const DIRECT_CELLS: usize = DIRECT_N * DIRECT_N;

const DIRECT_HIDDEN: usize = 64;
type Net = ReluMlp<CONDITION_DIM, DIRECT_HIDDEN, DIRECT_CELLS, 3>;

// Chunks of 16 lanes: the 256 logits of 16 lanes take 16 KiB.
super::mlp::mlp_sampler! {
    /// The direct histogram baseline (Zhu et al. 2021; "histogram (baseline)" in the paper's
    /// Table 2): an MLP `30 → 64 → 64 → 256` (ReLU hidden) maps `encode_condition(φ, wi)` to
    /// the logits of a 16 × 16 grid over `[−1, 1]²` (cell `r·16 + c`). Cells entirely outside
    /// the disk are masked, the others get `softmax` probabilities `P_rc`, and the density on
    /// the projected disk is `P_rc / h²` (`ARCHITECTURES.md` §5).
    pub struct DirectHistogramSampler => DirectHistogramPrepared {
        kind: DirectHistogram,
        net: Net,
        outputs: DIRECT_CELLS,
        from: DirectHistogramPrepared::from_logits,
        chunk: 16,
        count: "Number of parameters: `dense(30,64) dense(64,64) dense(64,256)` = 22784.",
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
                clamp_logit(logits[i])
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
            TableLayout::Values,
        )
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

#[cfg(not(target_arch = "spirv"))]
impl crate::wavefront::chunked::LaneChunks for DirectHistogramPrepared {}

#[cfg(not(target_arch = "spirv"))]
impl crate::wavefront::FromOutputs<DIRECT_CELLS> for DirectHistogramPrepared {
    #[inline(always)]
    fn lanes<const B: usize>(
        o: &crate::wavefront::Soa<DIRECT_CELLS, B>,
        valid: &[bool; B],
        lanes: &mut [Option<Self>],
    ) {
        crate::wavefront::lanes_from_outputs(o, valid, lanes, DirectHistogramPrepared::from_logits);
    }
}
