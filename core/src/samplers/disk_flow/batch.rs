//! [`DiskFlowSampler`] over wavefronts ([`BatchSampler`](crate::BatchSampler)). Lanes run in
//! chunks of [`CHUNK`]: the coupling networks as matrix products over the chunk's lanes, the
//! chord couplings eight lanes at a time through the scalar path's own generic functions, so
//! both paths give the same bits.

use glam::Vec2;

use super::{
    chord_forward_next, chord_inverse, chord_log_derivative, in_chord_lanes, invert_base,
    log_density, DiskFlowLane, DiskFlowSampler, DISK_FLOW_BINS, DISK_FLOW_COUPLING0,
    DISK_FLOW_COUPLING1, DISK_SPLINE_RAW_LEN,
};
use crate::distrib::spline::Knots;
use crate::math;
use crate::nn::CONDITION_DIM;
use crate::samplers::coupling::{
    coupling_splines_chunk, density_from_log, CouplingBuffers, CouplingLanes, CouplingShares,
    FlowScratch, FreeEnds, COUPLING_INPUTS, HIDDEN,
};
use crate::samplers::Sample;
use crate::warp::{self, inside_disk};
use crate::wavefront::chunked::ChunkedSampler;
use crate::wavefront::lanes::V8;
use crate::wavefront::simd::Isa;
use crate::wavefront::{self, dense, Features, SamplesMut, Vec2s, Vec2sMut, Vec3s};
use crate::weights::Weights;

/// Lanes per chunk: activations, splines and lane states of a chunk stay in L1.
const CHUNK: usize = 32;
/// Groups of eight lanes per chunk (the splines are evaluated eight lanes at a time).
const GROUPS: usize = CHUNK / 8;

type Splines = [Knots<DISK_FLOW_BINS, V8>; GROUPS];

/// The working memory of a batched call.
type Scratch = FlowScratch<DISK_FLOW_BINS, DISK_SPLINE_RAW_LEN, CHUNK, GROUPS>;

impl CouplingShares for DiskFlowLane {
    #[inline(always)]
    fn share(&self, net: usize) -> &[f32; HIDDEN] {
        &self.share[net & 1]
    }
}

impl<W: Weights + Copy> DiskFlowSampler<W> {
    /// The splines of coupling network `net` (0 or 1) for the lanes `idx[..m]` of a chunk,
    /// each at its own other coordinate `v[lane]`: group `g` of `knots` holds the splines of
    /// `idx[8g .. 8g + 8]`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn knots_for(
        &self,
        net: usize,
        lanes: &[Option<DiskFlowLane>],
        idx: &[usize; CHUNK],
        m: usize,
        v: &[f32; CHUNK],
        b: &mut CouplingBuffers<DISK_SPLINE_RAW_LEN, CHUNK>,
        knots: &mut Splines,
    ) {
        let offset = if net == 0 {
            DISK_FLOW_COUPLING0
        } else {
            DISK_FLOW_COUPLING1
        };
        let at = CouplingLanes { lanes, idx, m, v };
        coupling_splines_chunk::<FreeEnds, W, _, DISK_FLOW_BINS, DISK_SPLINE_RAW_LEN, CHUNK>(
            &self.params,
            offset as u32,
            net,
            at,
            0.0,
            b,
            knots,
        );
    }

    /// The base points and log-dets of the disk points `p` (density direction,
    /// `DiskFlowPrepared::to_base`) of a chunk's lanes.
    #[inline(always)]
    fn base_chunk(
        &self,
        lanes: &[Option<DiskFlowLane>],
        px: &[f32; CHUNK],
        py: &[f32; CHUNK],
        b: &mut [Vec2; CHUNK],
        ld: &mut [f32; CHUNK],
        sc: &mut Scratch,
    ) {
        let m = lanes.len();
        let groups = m.div_ceil(8);
        let all = wavefront::identity_index::<CHUNK>();
        let k = &mut sc.k0;
        self.knots_for(1, lanes, &all, m, px, &mut sc.b, k);
        let mut yb = [0.0f32; CHUNK];
        let mut cb = [0.0f32; CHUNK];
        let mut ld1 = [0.0f32; CHUNK];
        for g in 0..groups {
            let (x, y) = (V8::load(&px[8 * g..]), V8::load(&py[8 * g..]));
            let (a, d, c) = chord_forward_next(&k[g], y, x);
            a.store(&mut yb[8 * g..]);
            d.store(&mut ld1[8 * g..]);
            c.store(&mut cb[8 * g..]);
        }
        self.knots_for(0, lanes, &all, m, &yb, &mut sc.b, k);
        for g in 0..groups {
            let (x, c) = (V8::load(&px[8 * g..]), V8::load(&cb[8 * g..]));
            let (s0, d) = k[g].forward_lanes(in_chord_lanes(x, c));
            let bx = c * s0;
            for i in 0..8 {
                let l = 8 * g + i;
                if l < m {
                    b[l] = Vec2::new(bx.0[i], yb[l]);
                    ld[l] = d.0[i] + ld1[l];
                }
            }
        }
    }

    /// The disk points of a chunk's `wo` (0 where refused) and whether each is usable.
    #[inline(always)]
    fn disk_points(
        lanes: &[Option<DiskFlowLane>],
        wo: Vec3s<'_>,
    ) -> ([f32; CHUNK], [f32; CHUNK], [f32; CHUNK], [bool; CHUNK]) {
        let (mut px, mut py) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
        let mut cos = [0.0f32; CHUNK];
        let mut ok = [false; CHUNK];
        for l in 0..lanes.len() {
            if let (Some(_), Some(w)) = (&lanes[l], warp::upper_hemisphere(wo.at(l))) {
                (px[l], py[l]) = (w.x, w.y);
                cos[l] = w.z;
                ok[l] = inside_disk(warp::to_disk(w));
            }
        }
        (px, py, cos, ok)
    }
}

impl<W: Weights + Copy> ChunkedSampler for DiskFlowSampler<W> {
    type Lane = Option<DiskFlowLane>;
    type Scratch = Scratch;
    const CHUNK: usize = CHUNK;
    // The splines run in eight-lane groups.
    const WIDEST: Isa = Isa::X86V3;

    #[inline(always)]
    fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, out: &mut [Option<DiskFlowLane>]) {
        let m = out.len();
        let (c, valid) = wavefront::encoded_conditions::<CHUNK>(&phi, &wi);
        let w = &self.params;
        let mut share = [[[0.0f32; CHUNK]; HIDDEN]; 2];
        for (s, net) in share
            .iter_mut()
            .zip([DISK_FLOW_COUPLING0, DISK_FLOW_COUPLING1])
        {
            dense::bias::<W, COUPLING_INPUTS, HIDDEN, CHUNK>(w, net as u32, s);
            dense::accumulate::<W, CONDITION_DIM, HIDDEN, CHUNK>(w, net as u32, 0, &c, s, m);
        }
        for l in 0..m {
            out[l] = if valid[l] {
                let mut sh = [[0.0f32; HIDDEN]; 2];
                for (dst, src) in sh.iter_mut().zip(share.iter()) {
                    for j in 0..HIDDEN {
                        dst[j] = src[j][l];
                    }
                }
                DiskFlowLane::new(sh)
            } else {
                None
            };
        }
    }

    #[inline(always)]
    fn sample_chunk(
        &self,
        lanes: &[Option<DiskFlowLane>],
        u: Vec2s<'_>,
        mut out: SamplesMut<'_>,
        scratch: &mut Self::Scratch,
    ) {
        let m = lanes.len();
        let groups = m.div_ceil(8);
        let all = wavefront::identity_index::<CHUNK>();
        // Base points (refused lanes keep b = 0 and are dropped at the end).
        let mut bx = [0.0f32; CHUNK];
        let mut by = [0.0f32; CHUNK];
        let mut ok = [false; CHUNK];
        for l in 0..m {
            if let (Some(_), Some(uu)) = (&lanes[l], math::sanitize_u2(u.at(l))) {
                let b = warp::sample_uniform_disk_concentric(uu);
                (bx[l], by[l]) = (b.x, b.y);
                ok[l] = true;
            }
        }
        // Sampling direction: x = C(b.y)·S₀⁻¹(…), y = C(x)·S₁⁻¹(…).
        let FlowScratch { b: buf, k0, k1 } = scratch;
        self.knots_for(0, lanes, &all, m, &by, buf, k0);
        let mut px = [0.0f32; CHUNK];
        let mut py = [0.0f32; CHUNK];
        for g in 0..groups {
            let (b_x, b_y) = (V8::load(&bx[8 * g..]), V8::load(&by[8 * g..]));
            chord_inverse(&k0[g], b_x, b_y).store(&mut px[8 * g..]);
        }
        self.knots_for(1, lanes, &all, m, &px, buf, k1);
        // Density direction at the sample (`Prepared::sample`): coupling 1's spline is the
        // same; coupling 0's is rebuilt where its input (the base point's y) changed.
        let mut yb = [0.0f32; CHUNK];
        let mut cb = [0.0f32; CHUNK];
        let mut ld1 = [0.0f32; CHUNK];
        for g in 0..groups {
            let x = V8::load(&px[8 * g..]);
            let y = chord_inverse(&k1[g], V8::load(&by[8 * g..]), x);
            y.store(&mut py[8 * g..]);
            let (a, d, c) = chord_forward_next(&k1[g], y, x);
            a.store(&mut yb[8 * g..]);
            d.store(&mut ld1[8 * g..]);
            c.store(&mut cb[8 * g..]);
        }
        let mut ld0 = [0.0f32; CHUNK];
        for g in 0..groups {
            let x = V8::load(&px[8 * g..]);
            chord_log_derivative(&k0[g], x, V8::load(&cb[8 * g..])).store(&mut ld0[8 * g..]);
        }
        let mut again = [0usize; CHUNK];
        let mut n_again = 0;
        for l in 0..m {
            ok[l] = ok[l] && inside_disk(Vec2::new(px[l], py[l]));
            if ok[l] && yb[l].to_bits() != by[l].to_bits() {
                again[n_again] = l;
                n_again += 1;
            }
        }
        if n_again > 0 {
            self.knots_for(0, lanes, &again, n_again, &yb, buf, k0);
            let (mut x, mut c) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
            for k in 0..n_again {
                x[k] = px[again[k]];
                c[k] = cb[again[k]];
            }
            for g in 0..n_again.div_ceil(8) {
                let (x8, c8) = (V8::load(&x[8 * g..]), V8::load(&c[8 * g..]));
                let d = chord_log_derivative(&k0[g], x8, c8);
                for i in 0..8 {
                    if let Some(&l) = again[..n_again].get(8 * g + i) {
                        ld0[l] = d.0[i];
                    }
                }
            }
        }
        for l in 0..m {
            let s = if ok[l] {
                let p = density_from_log(log_density(ld0[l] + ld1[l]));
                Sample::from_disk(Vec2::new(px[l], py[l]), p)
            } else {
                None
            };
            out.set(l, s);
        }
    }

    #[inline(always)]
    fn pdf_chunk(
        &self,
        lanes: &[Option<DiskFlowLane>],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        scratch: &mut Self::Scratch,
    ) {
        let (px, py, cos, ok) = Self::disk_points(lanes, wo);
        let mut b = [Vec2::ZERO; CHUNK];
        let mut ld = [0.0f32; CHUNK];
        self.base_chunk(lanes, &px, &py, &mut b, &mut ld, scratch);
        for l in 0..lanes.len() {
            pdf[l] = if ok[l] {
                warp::disk_to_solid_angle(density_from_log(log_density(ld[l])), cos[l])
            } else {
                0.0
            };
        }
    }

    #[inline(always)]
    fn invert_chunk(
        &self,
        lanes: &[Option<DiskFlowLane>],
        wo: Vec3s<'_>,
        mut u: Vec2sMut<'_>,
        ok_out: &mut [bool],
        scratch: &mut Self::Scratch,
    ) {
        let (px, py, _, ok) = Self::disk_points(lanes, wo);
        let mut b = [Vec2::ZERO; CHUNK];
        let mut ld = [0.0f32; CHUNK];
        self.base_chunk(lanes, &px, &py, &mut b, &mut ld, scratch);
        for l in 0..lanes.len() {
            let r = if ok[l] { invert_base(b[l]) } else { None };
            ok_out[l] = r.is_some();
            if let Some(v) = r {
                u.set(l, v);
            }
        }
    }
}
