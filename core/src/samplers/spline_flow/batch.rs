//! [`SplineFlowSampler`] over wavefronts ([`BatchSampler`]). Lanes run in chunks of [`CHUNK`]: the
//! networks as matrix products over the chunk's lanes ([`dense`]), the splines, Box–Muller and
//! the densities per lane through the scalar path's own functions (the paths agree within
//! the `wavefront` tolerances).

use glam::Vec2;

use super::{
    SplineFlowLane, SplineFlowSampler, BASE_OUTPUTS, FLOW_BASE_L0, FLOW_BASE_L1, FLOW_COUPLING0,
    FLOW_COUPLING1, SPLINE_BINS, SPLINE_RAW_LEN, TAIL_BOUND,
};
use crate::distrib::spline::Knots;
use crate::math;
use crate::nn::{Activation, CONDITION_DIM};
use crate::samplers::coupling::{
    coupling_splines_chunk, BoundedEnds, CouplingBuffers, CouplingLanes, CouplingShares,
    FlowScratch, COUPLING_INPUTS, HIDDEN,
};
use crate::samplers::Sample;
use crate::warp::{self, inside_disk};
use crate::wavefront::chunked::ChunkedSampler;
use crate::wavefront::lanes::{self, V8};
use crate::wavefront::simd::Isa;
use crate::wavefront::{self, dense, Features, SamplesMut, Vec2s, Vec2sMut, Vec3s};
use crate::weights::Weights;

/// Lanes per chunk: activations, splines and lane states of a chunk stay in L1.
const CHUNK: usize = 32;
/// Groups of eight lanes per chunk (the splines are evaluated eight lanes at a time).
const GROUPS: usize = CHUNK / 8;

/// Activations of a chunk: `[feature][lane]`.
type Soa<const N: usize> = wavefront::Soa<N, CHUNK>;

/// The splines of a chunk's lanes, one group of eight lanes each.
type Splines = [Knots<SPLINE_BINS, V8>; GROUPS];

/// The working memory of a batched call.
type Scratch = FlowScratch<SPLINE_BINS, SPLINE_RAW_LEN, CHUNK, GROUPS>;

impl CouplingShares for SplineFlowLane {
    #[inline(always)]
    fn share(&self, net: usize) -> &[f32; HIDDEN] {
        &self.share[net & 1]
    }
}

/// The base Gaussians of a chunk's lanes, as rows (refused lanes: `μ = 0`, `σ = 1`).
struct Base {
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

impl<W: Weights + Copy> SplineFlowSampler<W> {
    /// The splines of coupling network `net` for the lanes `idx[..m]` of a chunk, each at its
    /// own other coordinate `v[lane]`: group `g` of `knots` holds the splines of
    /// `idx[8g .. 8g + 8]`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn knots_for(
        &self,
        net: usize,
        lanes: &[Option<SplineFlowLane>],
        idx: &[usize; CHUNK],
        m: usize,
        v: &[f32; CHUNK],
        b: &mut CouplingBuffers<SPLINE_RAW_LEN, CHUNK>,
        knots: &mut Splines,
    ) {
        let which = if net == FLOW_COUPLING0 { 0 } else { 1 };
        let at = CouplingLanes { lanes, idx, m, v };
        coupling_splines_chunk::<BoundedEnds, W, _, SPLINE_BINS, SPLINE_RAW_LEN, CHUNK>(
            &self.params,
            net as u32,
            which,
            at,
            TAIL_BOUND,
            b,
            knots,
        );
    }

    /// The latent points and log-dets of the disk points `p` (density direction,
    /// `SplineFlowPrepared::to_latent`) of a chunk's lanes.
    #[inline(always)]
    fn latent_chunk(
        &self,
        lanes: &[Option<SplineFlowLane>],
        px: &[f32; CHUNK],
        py: &[f32; CHUNK],
        zl: &mut [Vec2; CHUNK],
        ld: &mut [f32; CHUNK],
        sc: &mut Scratch,
    ) {
        let m = lanes.len();
        let groups = m.div_ceil(8);
        let all = wavefront::identity_index::<CHUNK>();
        let k = &mut sc.k0;
        self.knots_for(FLOW_COUPLING1, lanes, &all, m, px, &mut sc.b, k);
        let mut yl = [0.0f32; CHUNK];
        let mut ld1 = [0.0f32; CHUNK];
        for g in 0..groups {
            let (a, d) = k[g].forward_lanes(V8::load(&py[8 * g..]));
            a.store(&mut yl[8 * g..]);
            d.store(&mut ld1[8 * g..]);
        }
        self.knots_for(FLOW_COUPLING0, lanes, &all, m, &yl, &mut sc.b, k);
        for g in 0..groups {
            let (a, d) = k[g].forward_lanes(V8::load(&px[8 * g..]));
            for i in 0..8 {
                let l = 8 * g + i;
                if l < m {
                    zl[l] = Vec2::new(a.0[i], yl[l]);
                    ld[l] = d.0[i] + ld1[l];
                }
            }
        }
    }
}

impl<W: Weights + Copy> ChunkedSampler for SplineFlowSampler<W> {
    type Lane = Option<SplineFlowLane>;
    type Scratch = Scratch;
    const CHUNK: usize = CHUNK;
    // The splines run in eight-lane groups.
    const WIDEST: Isa = Isa::X86V3;

    #[inline(always)]
    fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, out: &mut [Option<SplineFlowLane>]) {
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
        let mut share: [Soa<HIDDEN>; 2] = [[[0.0; CHUNK]; HIDDEN]; 2];
        for (s, net) in share.iter_mut().zip([FLOW_COUPLING0, FLOW_COUPLING1]) {
            dense::bias::<W, COUPLING_INPUTS, HIDDEN, CHUNK>(w, net as u32, s);
            dense::accumulate::<W, CONDITION_DIM, HIDDEN, CHUNK>(w, net as u32, 0, &c, s, m);
        }
        for l in 0..m {
            out[l] = if valid[l] {
                let oo = [o[0][l], o[1][l], o[2][l], o[3][l]];
                let mut sh = [[0.0f32; HIDDEN]; 2];
                for (dst, src) in sh.iter_mut().zip(share.iter()) {
                    for j in 0..HIDDEN {
                        dst[j] = src[j][l];
                    }
                }
                SplineFlowLane::new(&oo, sh)
            } else {
                None
            };
        }
    }

    #[inline(always)]
    fn sample_chunk(
        &self,
        lanes: &[Option<SplineFlowLane>],
        u: Vec2s<'_>,
        mut out: SamplesMut<'_>,
        scratch: &mut Self::Scratch,
    ) {
        let m = lanes.len();
        let groups = m.div_ceil(8);
        let all = wavefront::identity_index::<CHUNK>();
        // Base points z = μ + σ ⊙ n (refused lanes keep z = 0 and are dropped at the end).
        let base = Base::of(lanes);
        let (mut u0, mut u1) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
        let mut ok = [false; CHUNK];
        for l in 0..m {
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
        // Sampling direction: x = RQ⁻¹(z.x; coupling0(z.y)), y = RQ⁻¹(z.y; coupling1(x)).
        let FlowScratch { b, k0, k1 } = scratch;
        self.knots_for(FLOW_COUPLING0, lanes, &all, m, &zy, b, k0);
        let mut px = [0.0f32; CHUNK];
        let mut py = [0.0f32; CHUNK];
        for g in 0..groups {
            k0[g]
                .inverse_with::<false>(V8::load(&zx[8 * g..]))
                .0
                .store(&mut px[8 * g..]);
        }
        self.knots_for(FLOW_COUPLING1, lanes, &all, m, &px, b, k1);
        // Density direction at the sample (`Prepared::sample`): coupling 1's spline is the
        // same; coupling 0's is rebuilt where its input y' = RQ(y) differs from z.y.
        let mut yl = [0.0f32; CHUNK];
        let mut ld1 = [0.0f32; CHUNK];
        for g in 0..groups {
            let y = k1[g].inverse_with::<false>(V8::load(&zy[8 * g..])).0;
            y.store(&mut py[8 * g..]);
            let (a, d) = k1[g].forward_lanes(y);
            a.store(&mut yl[8 * g..]);
            d.store(&mut ld1[8 * g..]);
        }
        let mut xl = [0.0f32; CHUNK];
        let mut ld0 = [0.0f32; CHUNK];
        for g in 0..groups {
            let (a, d) = k0[g].forward_lanes(V8::load(&px[8 * g..]));
            a.store(&mut xl[8 * g..]);
            d.store(&mut ld0[8 * g..]);
        }
        let mut again = [0usize; CHUNK];
        let mut n_again = 0;
        for l in 0..m {
            ok[l] = ok[l] && inside_disk(Vec2::new(px[l], py[l]));
            if ok[l] && yl[l].to_bits() != zy[l].to_bits() {
                again[n_again] = l;
                n_again += 1;
            }
        }
        if n_again > 0 {
            self.knots_for(FLOW_COUPLING0, lanes, &again, n_again, &yl, b, k0);
            let mut x = [0.0f32; CHUNK];
            for k in 0..n_again {
                x[k] = px[again[k]];
            }
            for g in 0..n_again.div_ceil(8) {
                let (a, d) = k0[g].forward_lanes(V8::load(&x[8 * g..]));
                for i in 0..8 {
                    if let Some(&l) = again[..n_again].get(8 * g + i) {
                        xl[l] = a.0[i];
                        ld0[l] = d.0[i];
                    }
                }
            }
        }
        let mut p = base.log_densities(&xl, &yl, &ld0, &ld1);
        lanes::densities_from_log(&mut p);
        for l in 0..m {
            let s = if ok[l] {
                Sample::from_disk(Vec2::new(px[l], py[l]), p[l])
            } else {
                None
            };
            out.set(l, s);
        }
    }

    #[inline(always)]
    fn pdf_chunk(
        &self,
        lanes: &[Option<SplineFlowLane>],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        scratch: &mut Self::Scratch,
    ) {
        let m = lanes.len();
        let (mut px, mut py) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
        let mut cos = [0.0f32; CHUNK];
        let mut ok = [false; CHUNK];
        for l in 0..m {
            if let (Some(_), Some(w)) = (&lanes[l], warp::upper_hemisphere(wo.at(l))) {
                (px[l], py[l]) = (w.x, w.y);
                cos[l] = w.z;
                ok[l] = inside_disk(warp::to_disk(w));
            }
        }
        let mut zl = [Vec2::ZERO; CHUNK];
        let mut ld = [0.0f32; CHUNK];
        self.latent_chunk(lanes, &px, &py, &mut zl, &mut ld, scratch);
        let (mut xl, mut yl) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
        for l in 0..m {
            (xl[l], yl[l]) = (zl[l].x, zl[l].y);
        }
        let mut p = Base::of(lanes).log_densities(&xl, &yl, &ld, &[0.0; CHUNK]);
        lanes::densities_from_log(&mut p);
        for l in 0..m {
            pdf[l] = if ok[l] {
                warp::disk_to_solid_angle(p[l], cos[l])
            } else {
                0.0
            };
        }
    }

    #[inline(always)]
    fn invert_chunk(
        &self,
        lanes: &[Option<SplineFlowLane>],
        wo: Vec3s<'_>,
        mut u: Vec2sMut<'_>,
        ok_out: &mut [bool],
        scratch: &mut Self::Scratch,
    ) {
        let m = lanes.len();
        let (mut px, mut py) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
        let mut ok = [false; CHUNK];
        for l in 0..m {
            if let (Some(_), Some(w)) = (&lanes[l], warp::upper_hemisphere(wo.at(l))) {
                (px[l], py[l]) = (w.x, w.y);
                ok[l] = inside_disk(warp::to_disk(w));
            }
        }
        let mut zl = [Vec2::ZERO; CHUNK];
        let mut ld = [0.0f32; CHUNK];
        self.latent_chunk(lanes, &px, &py, &mut zl, &mut ld, scratch);
        for l in 0..m {
            let r = match (&lanes[l], ok[l]) {
                (Some(st), true) => st.invert_base(zl[l]),
                _ => None,
            };
            ok_out[l] = r.is_some();
            if let Some(v) = r {
                u.set(l, v);
            }
        }
    }
}
