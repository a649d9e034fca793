//! [`DiskFlowSampler`] over wavefronts ([`BatchSampler`](crate::wavefront::BatchSampler)): the
//! two-coupling flow's chunks ([`coupling_flow_chunks`]) with a uniform base and the chord
//! couplings, eight lanes at a time through the scalar path's own generic functions, so both
//! paths give the same bits.

use glam::Vec2;

use super::{
    chord_forward_next, chord_inverse, in_chord_lanes, invert_base, log_density, DiskFlowLane,
    DiskFlowSampler, DISK_FLOW_BINS, DISK_FLOW_COUPLING0, DISK_FLOW_COUPLING1, DISK_SPLINE_RAW_LEN,
};
use crate::distrib::spline::Knots;
use crate::math;
use crate::math::lane::Lane;
use crate::samplers::coupling::flow::{
    coupling_flow_chunks, coupling_shares, lane_shares, CouplingFlow, Rows, CHUNK,
};
use crate::samplers::coupling::{density_from_log, CouplingShares, FreeEnds, HIDDEN};
use crate::warp;
use crate::wavefront::{self, Features, Vec2s, Vec3s};
use crate::weights::Weights;

impl CouplingShares for DiskFlowLane {
    #[inline(always)]
    fn share(&self, net: usize) -> &[f32; HIDDEN] {
        &self.share[net & 1]
    }
}

impl<W: Weights + Copy> CouplingFlow<DISK_FLOW_BINS, DISK_SPLINE_RAW_LEN> for DiskFlowSampler<W> {
    type Lane = DiskFlowLane;
    type W = W;
    type Ends = FreeEnds;
    const COUPLINGS: [usize; 2] = [DISK_FLOW_COUPLING0, DISK_FLOW_COUPLING1];
    const TAIL_BOUND: f32 = 0.0;

    #[inline(always)]
    fn weights(&self) -> &W {
        &self.params
    }

    #[inline(always)]
    fn prepare_lanes(&self, phi: Features<'_>, wi: Vec3s<'_>, out: &mut [Option<DiskFlowLane>]) {
        let m = out.len();
        let (c, valid) = wavefront::encoded_conditions::<CHUNK>(&phi, &wi);
        let share = coupling_shares(self, &c, m);
        for l in 0..m {
            out[l] = if valid[l] {
                DiskFlowLane::new(lane_shares(&share, l))
            } else {
                None
            };
        }
    }

    /// Uniform on the disk: no parameters.
    type Base = ();

    #[inline(always)]
    fn base(_lanes: &[Option<DiskFlowLane>]) {}

    /// The concentric map of `u`.
    #[inline(always)]
    fn draw_base(
        _base: &(),
        lanes: &[Option<DiskFlowLane>],
        u: &Vec2s<'_>,
    ) -> (Rows, Rows, [bool; CHUNK]) {
        let mut bx = [0.0f32; CHUNK];
        let mut by = [0.0f32; CHUNK];
        let mut ok = [false; CHUNK];
        for l in 0..lanes.len() {
            if let (Some(_), Some(uu)) = (&lanes[l], math::sanitize_u2(u.at(l))) {
                let b = warp::sample_uniform_disk_concentric(uu);
                (bx[l], by[l]) = (b.x, b.y);
                ok[l] = true;
            }
        }
        (bx, by, ok)
    }

    #[inline(always)]
    fn inverse0<L: Lane>(k: &Knots<DISK_FLOW_BINS, L>, bx: L, by: L) -> L {
        chord_inverse(k, bx, by)
    }

    #[inline(always)]
    fn inverse1<L: Lane>(k: &Knots<DISK_FLOW_BINS, L>, by: L, x: L) -> L {
        chord_inverse(k, by, x)
    }

    #[inline(always)]
    fn forward1<L: Lane>(k: &Knots<DISK_FLOW_BINS, L>, y: L, x: L) -> (L, L, L) {
        chord_forward_next(k, y, x)
    }

    /// `C·S₀(x / C)` on the half chord `c` that [`Self::forward1`] returned.
    #[inline(always)]
    fn forward0<L: Lane>(k: &Knots<DISK_FLOW_BINS, L>, x: L, c: L) -> (L, L) {
        let (s0, d) = k.forward_lanes(in_chord_lanes(x, c));
        (c * s0, d)
    }

    /// Uniform base: `ld0 + ld1 − ln π`.
    #[inline(always)]
    fn densities(_base: &(), _bx: &Rows, _by: &Rows, ld0: &Rows, ld1: &Rows) -> Rows {
        let mut p = [0.0f32; CHUNK];
        for l in 0..CHUNK {
            p[l] = density_from_log(log_density(ld0[l] + ld1[l]));
        }
        p
    }

    #[inline(always)]
    fn invert_base(_lane: &DiskFlowLane, b: Vec2) -> Option<Vec2> {
        invert_base(b)
    }
}

coupling_flow_chunks!(DiskFlowSampler => DiskFlowLane, DISK_FLOW_BINS, DISK_SPLINE_RAW_LEN);
