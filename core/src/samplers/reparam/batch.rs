//! [`ReparamSampler`] over wavefronts ([`BatchSampler`](crate::wavefront::BatchSampler)):
//! both networks as matrix products over a chunk's lanes; the warp's value and its two
//! tangents go through each layer as one product of three lane blocks (the weights are read
//! once for all three). The per-lane steps are the scalar path's operations with the fast
//! approximations of `math::approx`, each step across the whole chunk so that the lanes'
//! dependency chains interleave: the SiLUs ([`approx::sigmoid_row`]), the warp's last step
//! through [`Lane`](crate::math::lane::Lane) on all the chunk's lanes at once ([`Lanes`]);
//! a chunk of at most [`NARROW`] lanes runs these steps that wide. Both paths agree within
//! the `wavefront` tolerances.

use glam::Vec2;

use super::{
    finish_warp, sample_density, silu_from_sigmoid, warp_sample, ReparamLane, ReparamSampler,
    DENSITY_L0, DENSITY_L1, LOG_DENSITY_MAX, LOG_DENSITY_MIN, REPARAM_HIDDEN, REPARAM_INPUTS,
    WARP_L0, WARP_L1, WARP_L2, WARP_OUTPUTS,
};
use crate::math;
use crate::math::approx;
use crate::nn::{Activation, CONDITION_DIM};
use crate::warp::{self, inside_disk};
use crate::wavefront::chunked::ChunkedSampler;
use crate::wavefront::lanes::{self, Lanes, NARROW};
use crate::wavefront::{self, dense, Features, SamplesMut, Scratch, Vec2s, Vec2sMut, Vec3s};
use crate::weights::Weights;

/// Lanes per chunk.
const CHUNK: usize = 32;
/// A chunk's value lanes followed by its two tangent blocks (∂/∂z.x, ∂/∂z.y).
const STACK: usize = 3 * CHUNK;
const H: usize = REPARAM_HIDDEN;

type Soa<const N: usize> = wavefront::Soa<N, CHUNK>;

/// `acc[j]` = the layer's bias on the value lanes and 0 on the tangent lanes.
#[inline(always)]
fn stacked_bias<W: Weights, const I: usize, const O: usize>(
    w: &W,
    offset: u32,
    acc: &mut [[f32; STACK]; O],
) {
    let b: [f32; O] = w.read(offset + (I * O) as u32);
    for (row, v) in acc.iter_mut().zip(b) {
        let (value, tangents) = row.split_at_mut(CHUNK);
        value.fill(v);
        tangents.fill(0.0);
    }
}

/// [`ReparamSampler`]'s working memory ([`Scratch`]): a chunk's lane blocks of both
/// networks. Lanes past a call's count keep an earlier call's values: lanes are independent
/// and no result reads those.
pub struct ReparamScratch {
    /// The warp's first layer: each lane's share plus its latent point's rows.
    a: Soa<H>,
    /// The warp's hidden activations, value lanes then both tangent blocks.
    x: [[f32; STACK]; H],
    /// The warp's second layer before its activation, in the same blocks.
    a2: [[f32; STACK]; H],
    /// The warp's outputs, in the same blocks.
    o: [[f32; STACK]; WARP_OUTPUTS],
    /// The pdf network's hidden layer.
    g: Soa<H>,
}

impl Scratch for ReparamScratch {
    const NEW: Self = ReparamScratch {
        a: [[0.0; CHUNK]; H],
        x: [[0.0; STACK]; H],
        a2: [[0.0; STACK]; H],
        o: [[0.0; STACK]; WARP_OUTPUTS],
        g: [[0.0; CHUNK]; H],
    };
}

impl<W: Weights + Copy> ReparamSampler<W> {
    /// [`ChunkedSampler::sample_chunk`] of a chunk of at most `B` lanes, its element-wise
    /// steps `B` lanes wide.
    #[inline(always)]
    fn sample_rows<const B: usize>(
        &self,
        lanes: &[Option<ReparamLane>],
        u: Vec2s<'_>,
        mut out: SamplesMut<'_>,
        scratch: &mut ReparamScratch,
    ) {
        let m = lanes.len().min(B);
        let w = &self.params;
        let ReparamScratch { a, x, a2, o, g } = scratch;
        // Refused lanes keep u = 0 (z = 0) and a zero share, and are dropped at the end.
        let (mut u0, mut u1) = ([0.0f32; B], [0.0f32; B]);
        let mut ok = [false; B];
        for i in 0..m {
            let mut share = None;
            if let (Some(l), Some(uu)) = (&lanes[i], math::sanitize_u2(u.at(i))) {
                (u0[i], u1[i]) = (uu.x, uu.y);
                ok[i] = true;
                share = Some(&l.warp);
            }
            wavefront::set_column(a, i, share);
        }
        let (mut zx, mut zy) = ([0.0f32; B], [0.0f32; B]);
        lanes::box_muller_rows(&u0, &u1, &mut zx, &mut zy);
        let mut zs: Soa<2> = [[0.0; CHUNK]; 2];
        Lanes(zx).store(&mut zs[0]);
        Lanes(zy).store(&mut zs[1]);
        let l0 = WARP_L0 as u32;
        dense::accumulate::<W, 2, H, CHUNK>(w, l0, CONDITION_DIM as u32, &zs, a, m);
        let r0: [f32; H] = w.read(l0 + (CONDITION_DIM * H) as u32);
        let r1: [f32; H] = w.read(l0 + ((CONDITION_DIM + 1) * H) as u32);
        let mut s = [0.0f32; B];
        for (xj, (aj, (r0j, r1j))) in x.iter_mut().zip(a.iter().zip(r0.into_iter().zip(r1))) {
            approx::sigmoid_row(aj, &mut s);
            let (y, t) = xj.split_at_mut(CHUNK);
            let (t0, t1) = t.split_at_mut(CHUNK);
            for ((((y, t0), t1), a), s) in y.iter_mut().zip(t0).zip(t1).zip(&aj[..m]).zip(&s) {
                let (v, d) = silu_from_sigmoid(*a, *s);
                (*y, *t0, *t1) = (v, d * r0j, d * r1j);
            }
        }
        let active = 2 * CHUNK + m;
        let l1 = WARP_L1 as u32;
        stacked_bias::<W, H, H>(w, l1, a2);
        dense::accumulate::<W, H, H, STACK>(w, l1, 0, x, a2, active);
        for (xj, aj) in x.iter_mut().zip(a2.iter()) {
            let (y, t) = xj.split_at_mut(CHUNK);
            let (t0, t1) = t.split_at_mut(CHUNK);
            let (a, da) = aj.split_at(CHUNK);
            let (da0, da1) = da.split_at(CHUNK);
            approx::sigmoid_row(a, &mut s);
            let lanes = y
                .iter_mut()
                .zip(t0)
                .zip(t1)
                .zip(&a[..m])
                .zip(da0)
                .zip(da1)
                .zip(&s);
            for ((((((y, t0), t1), a), da0), da1), s) in lanes {
                let (v, d) = silu_from_sigmoid(*a, *s);
                (*y, *t0, *t1) = (v, d * da0, d * da1);
            }
        }
        let l2 = WARP_L2 as u32;
        stacked_bias::<W, H, WARP_OUTPUTS>(w, l2, o);
        dense::accumulate::<W, H, WARP_OUTPUTS, STACK>(w, l2, 0, x, o, active);
        // Each lane's direction and density, the `B` lanes side by side.
        let mut v: Soa<3> = [[0.0; CHUNK]; 3];
        let mut q = [0.0f32; B];
        let block = |base: usize| {
            let at = |k: usize| Lanes::<B>::load(&o[k][base..]);
            [at(0), at(1), at(2)]
        };
        let (dir, det) = finish_warp(block(0), block(CHUNK), block(2 * CHUNK));
        sample_density(Lanes(zx), Lanes(zy), det).store(&mut q);
        for (row, d) in v.iter_mut().zip(dir) {
            d.store(row);
        }
        for i in 0..m {
            let s = if ok[i] {
                warp_sample(Vec2::new(v[0][i], v[1][i]), v[2][i], q[i])
            } else {
                None
            };
            out.set(i, s);
        }
        // The MIS density: the pdf network at each sample (0 at refused lanes, `wo = 0`).
        let wo = Vec3s {
            x: &out.wo.x[..m],
            y: &out.wo.y[..m],
            z: &out.wo.z[..m],
        };
        self.pdf_rows::<B>(lanes, wo, &mut out.mis_pdf[..m], g);
    }

    /// [`ChunkedSampler::pdf_chunk`] of a chunk of at most `B` lanes, its element-wise steps
    /// `B` lanes wide.
    #[inline(always)]
    fn pdf_rows<const B: usize>(
        &self,
        lanes: &[Option<ReparamLane>],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        g: &mut Soa<H>,
    ) {
        let m = lanes.len().min(B);
        let w = &self.params;
        let mut ok = [false; B];
        let mut cos = [0.0f32; B];
        let mut ps: Soa<2> = [[0.0; CHUNK]; 2];
        for i in 0..m {
            let mut share = None;
            if let (Some(l), Some(d)) = (&lanes[i], warp::upper_hemisphere(wo.at(i))) {
                let p = warp::to_disk(d);
                if inside_disk(p) {
                    ok[i] = true;
                    cos[i] = d.z;
                    ps[0][i] = p.x;
                    ps[1][i] = p.y;
                    share = Some(&l.density);
                }
            }
            wavefront::set_column(g, i, share);
        }
        let l0 = DENSITY_L0 as u32;
        dense::accumulate::<W, 2, H, CHUNK>(w, l0, CONDITION_DIM as u32, &ps, g, m);
        dense::activate(Activation::Relu, g, m);
        let mut o: Soa<1> = [[0.0; CHUNK]; 1];
        dense::dense::<W, H, 1, CHUNK>(w, DENSITY_L1 as u32, g, Activation::Identity, &mut o, m);
        // The scalar path's `density_from_output` with the fast `exp`, over the whole row.
        let mut density = [0.0f32; B];
        for (d, o) in density.iter_mut().zip(&o[0]) {
            *d = approx::exp(math::clamp(*o, LOG_DENSITY_MIN, LOG_DENSITY_MAX));
        }
        for i in 0..m {
            pdf[i] = if ok[i] {
                warp::disk_to_solid_angle(density[i], cos[i])
            } else {
                0.0
            };
        }
    }
}

impl<W: Weights + Copy> ChunkedSampler for ReparamSampler<W> {
    type Lane = Option<ReparamLane>;
    type Scratch = ReparamScratch;
    const CHUNK: usize = CHUNK;

    #[inline(always)]
    fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, out: &mut [Option<ReparamLane>]) {
        let m = out.len();
        let (c, valid) = wavefront::encoded_conditions::<CHUNK>(&phi, &wi);
        let w = &self.params;
        let offsets = [WARP_L0 as u32, DENSITY_L0 as u32];
        let mut shares: [Soa<H>; 2] = [[[0.0; CHUNK]; H]; 2];
        dense::condition_shares::<W, REPARAM_INPUTS, CONDITION_DIM, H, CHUNK, 2>(
            w,
            offsets,
            &c,
            m,
            &mut shares,
        );
        // ReparamLane::new's finiteness check, across lanes: 0·v is ±0 for a finite v and NaN
        // otherwise, so a lane's sum of them is 0 exactly when all its values are finite
        // (float adds vectorise where a chain of boolean ands does not).
        let mut nonfinite = [0.0f32; CHUNK];
        for row in shares.iter().flatten() {
            for (acc, v) in nonfinite.iter_mut().zip(row) {
                *acc += 0.0 * *v;
            }
        }
        // Each kept lane's shares written in place (no per-lane temporaries to move).
        for l in 0..m {
            if valid[l] && nonfinite[l] == 0.0 {
                let lane = out[l].insert(ReparamLane {
                    warp: [0.0; H],
                    density: [0.0; H],
                });
                for j in 0..H {
                    lane.warp[j] = shares[0][j][l];
                    lane.density[j] = shares[1][j][l];
                }
            } else {
                out[l] = None;
            }
        }
    }

    /// A chunk of at most [`NARROW`] lanes runs its element-wise steps that wide (the same
    /// bits).
    #[inline(always)]
    fn sample_chunk(
        &self,
        lanes: &[Option<ReparamLane>],
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
        scratch: &mut ReparamScratch,
    ) {
        if lanes.len() <= NARROW {
            self.sample_rows::<NARROW>(lanes, u, out, scratch);
        } else {
            self.sample_rows::<CHUNK>(lanes, u, out, scratch);
        }
    }

    #[inline(always)]
    fn pdf_chunk(
        &self,
        lanes: &[Option<ReparamLane>],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        scratch: &mut ReparamScratch,
    ) {
        if lanes.len() <= NARROW {
            self.pdf_rows::<NARROW>(lanes, wo, pdf, &mut scratch.g);
        } else {
            self.pdf_rows::<CHUNK>(lanes, wo, pdf, &mut scratch.g);
        }
    }

    /// No lane has an inverse (the warp need not be injective).
    #[inline(always)]
    fn invert_chunk(
        &self,
        lanes: &[Self::Lane],
        _wo: Vec3s<'_>,
        _u: Vec2sMut<'_>,
        ok: &mut [bool],
        _scratch: &mut Self::Scratch,
    ) {
        for o in ok[..lanes.len()].iter_mut() {
            *o = false;
        }
    }
}
