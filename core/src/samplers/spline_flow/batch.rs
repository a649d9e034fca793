//! [`SplineFlowSampler`] over wavefronts ([`BatchSampler`](crate::wavefront::BatchSampler)): the
//! two-coupling flow's chunks ([`coupling_flow_chunks`]) with a Gaussian base, bounded
//! splines, and the base network in `prepare` (the paths agree within the `wavefront`
//! tolerances).

use glam::Vec2;

use super::{
    SplineFlowLane, SplineFlowSampler, BASE_OUTPUTS, FLOW_BASE_L0, FLOW_BASE_L1, FLOW_COUPLING0,
    FLOW_COUPLING1, SPLINE_BINS, SPLINE_RAW_LEN, TAIL_BOUND,
};
use crate::distrib::spline::Knots;
use crate::math;
use crate::math::lane::Lane;
use crate::nn::{Activation, CONDITION_DIM};
use crate::samplers::coupling::flow::{
    coupling_flow_chunks, coupling_shares, lane_shares, CouplingFlow, Rows, CHUNK,
};
use crate::samplers::coupling::{BoundedEnds, CouplingShares, HIDDEN};
use crate::wavefront::lanes;
use crate::wavefront::{self, dense, Features, Vec2s, Vec3s};
use crate::weights::Weights;

/// Activations of a chunk: `[feature][lane]`.
type Soa<const N: usize> = wavefront::Soa<N, CHUNK>;

impl CouplingShares for SplineFlowLane {
    #[inline(always)]
    fn share(&self, net: usize) -> &[f32; HIDDEN] {
        &self.share[net & 1]
    }
}

/// The base Gaussians of a chunk's lanes, as rows (refused lanes: `μ = 0`, `σ = 1`).
pub(crate) struct Base {
    mx: [f32; CHUNK],
    my: [f32; CHUNK],
    sx: [f32; CHUNK],
    sy: [f32; CHUNK],
    ln_sigma: [f32; CHUNK],
}

impl Base {
    #[inline(always)]
    fn of(lanes: &[Option<SplineFlowLane>]) -> Base {
        let mut b = Base {
            mx: [0.0; CHUNK],
            my: [0.0; CHUNK],
            sx: [1.0; CHUNK],
            sy: [1.0; CHUNK],
            ln_sigma: [0.0; CHUNK],
        };
        for (l, s) in lanes.iter().enumerate().take(CHUNK) {
            if let Some(s) = s {
                (b.mx[l], b.my[l]) = (s.mu.x, s.mu.y);
                (b.sx[l], b.sy[l]) = (s.sigma.x, s.sigma.y);
                b.ln_sigma[l] = s.ln_sigma;
            }
        }
        b
    }

    /// `SplineFlowLane::log_density` of the latent points `(x, y)` with log-dets `ld0 + ld1`, for
    /// every lane (NaN → −∞).
    #[inline(always)]
    fn log_densities(
        &self,
        x: &[f32; CHUNK],
        y: &[f32; CHUNK],
        ld0: &[f32; CHUNK],
        ld1: &[f32; CHUNK],
    ) -> [f32; CHUNK] {
        let mut out = [0.0f32; CHUNK];
        for l in 0..CHUNK {
            let dx = (x[l] - self.mx[l]) / self.sx[l];
            let dy = (y[l] - self.my[l]) / self.sy[l];
            let v =
                -0.5 * (dx * dx + dy * dy) - math::LN_TWO_PI - self.ln_sigma[l] + (ld0[l] + ld1[l]);
            out[l] = if v.is_nan() { f32::NEG_INFINITY } else { v };
        }
        out
    }
}

impl<W: Weights + Copy> CouplingFlow<SPLINE_BINS, SPLINE_RAW_LEN> for SplineFlowSampler<W> {
    type Lane = SplineFlowLane;
    type W = W;
    type Ends = BoundedEnds;
    const COUPLINGS: [usize; 2] = [FLOW_COUPLING0, FLOW_COUPLING1];
    const TAIL_BOUND: f32 = TAIL_BOUND;

    #[inline(always)]
    fn weights(&self) -> &W {
        &self.params
    }

    #[inline(always)]
    fn prepare_lanes(&self, phi: Features<'_>, wi: Vec3s<'_>, out: &mut [Option<SplineFlowLane>]) {
        let m = out.len();
        let (c, valid) = wavefront::encoded_conditions::<CHUNK>(&phi, &wi);
        let w = &self.params;
        let mut h: Soa<HIDDEN> = [[0.0; CHUNK]; HIDDEN];
        dense::dense::<W, CONDITION_DIM, HIDDEN, CHUNK>(
            w,
            FLOW_BASE_L0 as u32,
            &c,
            Activation::Relu,
            &mut h,
            m,
        );
        let mut o: Soa<BASE_OUTPUTS> = [[0.0; CHUNK]; BASE_OUTPUTS];
        dense::dense::<W, HIDDEN, BASE_OUTPUTS, CHUNK>(
            w,
            FLOW_BASE_L1 as u32,
            &h,
            Activation::Identity,
            &mut o,
            m,
        );
        let share = coupling_shares(self, &c, m);
        for l in 0..m {
            out[l] = if valid[l] {
                let oo = [o[0][l], o[1][l], o[2][l], o[3][l]];
                SplineFlowLane::new(&oo, lane_shares(&share, l))
            } else {
                None
            };
        }
    }

    type Base = Base;

    #[inline(always)]
    fn base(lanes: &[Option<SplineFlowLane>]) -> Base {
        Base::of(lanes)
    }

    /// `z = μ + σ ⊙ n` with `n` from Box–Muller.
    #[inline(always)]
    fn draw_base(
        base: &Base,
        lanes: &[Option<SplineFlowLane>],
        u: &Vec2s<'_>,
    ) -> (Rows, Rows, [bool; CHUNK]) {
        let (mut u0, mut u1) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
        let mut ok = [false; CHUNK];
        for l in 0..lanes.len() {
            if let (Some(_), Some(uu)) = (&lanes[l], math::sanitize_u2(u.at(l))) {
                (u0[l], u1[l]) = (uu.x, uu.y);
                ok[l] = true;
            }
        }
        let (mut zx, mut zy) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
        lanes::box_muller_rows(&u0, &u1, &mut zx, &mut zy);
        for l in 0..CHUNK {
            zx[l] = if ok[l] {
                base.mx[l] + base.sx[l] * zx[l]
            } else {
                0.0
            };
            zy[l] = if ok[l] {
                base.my[l] + base.sy[l] * zy[l]
            } else {
                0.0
            };
        }
        (zx, zy, ok)
    }

    #[inline(always)]
    fn inverse0<L: Lane>(k: &Knots<SPLINE_BINS, L>, bx: L, _by: L) -> L {
        k.inverse_with::<false>(bx).0
    }

    #[inline(always)]
    fn inverse1<L: Lane>(k: &Knots<SPLINE_BINS, L>, by: L, _x: L) -> L {
        k.inverse_with::<false>(by).0
    }

    #[inline(always)]
    fn forward1<L: Lane>(k: &Knots<SPLINE_BINS, L>, y: L, _x: L) -> (L, L, L) {
        let (a, d) = k.forward_lanes(y);
        (a, d, L::splat(0.0))
    }

    #[inline(always)]
    fn forward0<L: Lane>(k: &Knots<SPLINE_BINS, L>, x: L, _c: L) -> (L, L) {
        k.forward_lanes(x)
    }

    #[inline(always)]
    fn densities(base: &Base, bx: &Rows, by: &Rows, ld0: &Rows, ld1: &Rows) -> Rows {
        let mut p = base.log_densities(bx, by, ld0, ld1);
        lanes::densities_from_log(&mut p);
        p
    }

    #[inline(always)]
    fn invert_base(lane: &SplineFlowLane, b: Vec2) -> Option<Vec2> {
        lane.invert_base(b)
    }
}

coupling_flow_chunks!(SplineFlowSampler => SplineFlowLane, SPLINE_BINS, SPLINE_RAW_LEN);
