//! [`ReparamSampler`] over wavefronts ([`BatchSampler`](crate::wavefront::BatchSampler)):
//! both networks as matrix products over a chunk's lanes; the warp's value and its two
//! tangents go through each layer as one product of three lane blocks (the weights are read
//! once for all three). The per-lane steps are the scalar path's own functions, in its
//! order, so both paths give the same bits.

use glam::Vec2;

use super::{
    density_from_output, finish_warp, sample_density, silu_slope, warp_sample, ReparamLane,
    ReparamSampler, DENSITY_L0, DENSITY_L1, REPARAM_HIDDEN, REPARAM_INPUTS, WARP_L0, WARP_L1,
    WARP_L2, WARP_OUTPUTS,
};
use crate::batch::chunked::ChunkedSampler;
use crate::batch::{self, dense, Features, SamplesMut, Vec2s, Vec2sMut, Vec3s};
use crate::distrib::gaussian;
use crate::math;
use crate::nn::{Activation, CONDITION_DIM};
use crate::warp::{self, inside_disk};
use crate::weights::Weights;

/// Lanes per chunk.
const CHUNK: usize = 32;
/// A chunk's value lanes followed by its two tangent blocks (∂/∂z.x, ∂/∂z.y).
const STACK: usize = 3 * CHUNK;
const H: usize = REPARAM_HIDDEN;

type Soa<const N: usize> = batch::Soa<N, CHUNK>;

/// `acc[j]` = the layer's bias on the value lanes and 0 on the tangent lanes.
#[inline(always)]
fn stacked_bias<W: Weights, const I: usize, const O: usize>(
    w: &W,
    offset: u32,
) -> [[f32; STACK]; O] {
    let b: [f32; O] = w.read(offset + (I * O) as u32);
    let mut acc = [[0.0f32; STACK]; O];
    for (row, v) in acc.iter_mut().zip(b) {
        for x in row[..CHUNK].iter_mut() {
            *x = v;
        }
    }
    acc
}

impl<W: Weights + Copy> ReparamSampler<W> {
    #[inline(always)]
    fn chunk_prepare(&self, phi: Features<'_>, wi: Vec3s<'_>, out: &mut [Option<ReparamLane>]) {
        let m = out.len();
        let (c, valid) = batch::encoded_conditions::<CHUNK>(&phi, &wi);
        let w = &self.params;
        let mut shares: [Soa<H>; 2] = [[[0.0; CHUNK]; H]; 2];
        for (s, off) in shares.iter_mut().zip([WARP_L0, DENSITY_L0]) {
            dense::bias::<W, REPARAM_INPUTS, H, CHUNK>(w, off as u32, s);
            dense::accumulate::<W, CONDITION_DIM, H, CHUNK>(w, off as u32, 0, &c, s, m);
        }
        for l in 0..m {
            out[l] = if valid[l] {
                ReparamLane::new(batch::column(&shares[0], l), batch::column(&shares[1], l))
            } else {
                None
            };
        }
    }

    #[inline(always)]
    fn chunk_sample(&self, lanes: &[Option<ReparamLane>], u: Vec2s<'_>, mut out: SamplesMut<'_>) {
        let m = lanes.len();
        let w = &self.params;
        let mut ok = [false; CHUNK];
        let mut z = [Vec2::ZERO; CHUNK];
        let mut zs: Soa<2> = [[0.0; CHUNK]; 2];
        let mut a: Soa<H> = [[0.0; CHUNK]; H];
        for i in 0..m {
            if let (Some(l), Some(uu)) = (&lanes[i], math::sanitize_u2(u.at(i))) {
                z[i] = gaussian::box_muller(uu);
                ok[i] = true;
                for j in 0..H {
                    a[j][i] = l.warp[j];
                }
            }
            zs[0][i] = z[i].x;
            zs[1][i] = z[i].y;
        }
        let l0 = WARP_L0 as u32;
        dense::accumulate::<W, 2, H, CHUNK>(w, l0, CONDITION_DIM as u32, &zs, &mut a, m);
        let r0: [f32; H] = w.read(l0 + (CONDITION_DIM * H) as u32);
        let r1: [f32; H] = w.read(l0 + ((CONDITION_DIM + 1) * H) as u32);
        let mut x = [[0.0f32; STACK]; H];
        for j in 0..H {
            for i in 0..m {
                let (y, d) = silu_slope(a[j][i]);
                x[j][i] = y;
                x[j][CHUNK + i] = d * r0[j];
                x[j][2 * CHUNK + i] = d * r1[j];
            }
        }
        let active = 2 * CHUNK + m;
        let l1 = WARP_L1 as u32;
        let mut a2 = stacked_bias::<W, H, H>(w, l1);
        dense::accumulate::<W, H, H, STACK>(w, l1, 0, &x, &mut a2, active);
        for j in 0..H {
            for i in 0..m {
                let (y, d) = silu_slope(a2[j][i]);
                x[j][i] = y;
                x[j][CHUNK + i] = d * a2[j][CHUNK + i];
                x[j][2 * CHUNK + i] = d * a2[j][2 * CHUNK + i];
            }
        }
        let l2 = WARP_L2 as u32;
        let mut o = stacked_bias::<W, H, WARP_OUTPUTS>(w, l2);
        dense::accumulate::<W, H, WARP_OUTPUTS, STACK>(w, l2, 0, &x, &mut o, active);
        for i in 0..m {
            let s = if ok[i] {
                let col = |base: usize| [o[0][base + i], o[1][base + i], o[2][base + i]];
                let t = finish_warp(col(0), col(CHUNK), col(2 * CHUNK));
                warp_sample(&t, sample_density(z[i], t.det))
            } else {
                None
            };
            out.set(i, s);
        }
    }

    #[inline(always)]
    fn chunk_pdf(&self, lanes: &[Option<ReparamLane>], wo: Vec3s<'_>, pdf: &mut [f32]) {
        let m = lanes.len();
        let w = &self.params;
        let mut ok = [false; CHUNK];
        let mut cos = [0.0f32; CHUNK];
        let mut ps: Soa<2> = [[0.0; CHUNK]; 2];
        let mut g: Soa<H> = [[0.0; CHUNK]; H];
        for i in 0..m {
            if let (Some(l), Some(d)) = (&lanes[i], warp::upper_hemisphere(wo.at(i))) {
                let p = warp::to_disk(d);
                if inside_disk(p) {
                    ok[i] = true;
                    cos[i] = d.z;
                    ps[0][i] = p.x;
                    ps[1][i] = p.y;
                    for j in 0..H {
                        g[j][i] = l.density[j];
                    }
                }
            }
        }
        let l0 = DENSITY_L0 as u32;
        dense::accumulate::<W, 2, H, CHUNK>(w, l0, CONDITION_DIM as u32, &ps, &mut g, m);
        dense::activate(Activation::Relu, &mut g, m);
        let mut o: Soa<1> = [[0.0; CHUNK]; 1];
        dense::dense::<W, H, 1, CHUNK>(w, DENSITY_L1 as u32, &g, Activation::Identity, &mut o, m);
        for i in 0..m {
            pdf[i] = if ok[i] {
                warp::disk_to_solid_angle(density_from_output(o[0][i]), cos[i])
            } else {
                0.0
            };
        }
    }
}

impl<W: Weights + Copy> ChunkedSampler for ReparamSampler<W> {
    type Lane = Option<ReparamLane>;
    const CHUNK: usize = CHUNK;
    const EXACT_PDF: bool = false;

    #[inline(always)]
    fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, lanes: &mut [Self::Lane]) {
        self.chunk_prepare(phi, wi, lanes);
    }

    #[inline(always)]
    fn sample_chunk(&self, lanes: &[Self::Lane], u: Vec2s<'_>, out: SamplesMut<'_>) {
        self.chunk_sample(lanes, u, out);
    }

    #[inline(always)]
    fn pdf_chunk(&self, lanes: &[Self::Lane], wo: Vec3s<'_>, pdf: &mut [f32]) {
        self.chunk_pdf(lanes, wo, pdf);
    }

    /// No lane has an inverse (the warp need not be injective).
    #[inline(always)]
    fn invert_chunk(
        &self,
        lanes: &[Self::Lane],
        _wo: Vec3s<'_>,
        _u: Vec2sMut<'_>,
        ok: &mut [bool],
    ) {
        for o in ok[..lanes.len()].iter_mut() {
            *o = false;
        }
    }
}
