//! [`AffineFlowSampler`] over wavefronts ([`BatchSampler`](crate::wavefront::BatchSampler)):
//! the coupling networks as matrix products over a chunk's lanes, the affine updates per lane
//! in the scalar path's order.

use glam::Vec2;

use super::{
    scale_shift, AffineFlowLane, AffineFlowPrepared, AffineFlowSampler, AFFINE_LAYERS,
    AFFINE_NET_L0, AFFINE_NET_L1, AFFINE_NET_L2, AFFINE_NET_LEN, AFFINE_OUTPUTS,
};
use crate::distrib::gaussian;
use crate::math;
use crate::math::approx;
use crate::nn::{Activation, CONDITION_DIM};
use crate::samplers::coupling::{COUPLING_INPUTS, HIDDEN, OTHER_BANDS, OTHER_DIM};
use crate::samplers::Sample;
use crate::warp::{self, inside_disk};
use crate::wavefront::chunked::ChunkedSampler;
use crate::wavefront::lanes;
use crate::wavefront::lanes::density_from_log;
use crate::wavefront::{self, dense, Features, SamplesMut, Scratch, Vec2s, Vec2sMut, Vec3s};
use crate::weights::Weights;

/// Lanes per chunk.
const CHUNK: usize = 32;

type Soa<const N: usize> = wavefront::Soa<N, CHUNK>;

/// Per coupling layer and lane, the input `v` and the `(s, t)` computed from it.
type Seen = [[(f32, f32, f32); CHUNK]; AFFINE_LAYERS];

/// [`AffineFlowSampler`]'s working memory ([`Scratch`]): one coupling network's lane blocks.
/// Lanes past a network's count keep earlier values: lanes are independent and no result
/// reads those.
pub struct AffineScratch {
    /// The first hidden layer (starting as the lanes' shares).
    h: Soa<HIDDEN>,
    /// The encoded other coordinates.
    e: Soa<OTHER_DIM>,
    /// The second hidden layer.
    g: Soa<HIDDEN>,
    /// The network's outputs.
    o: Soa<AFFINE_OUTPUTS>,
}

impl Scratch for AffineScratch {
    const NEW: Self = AffineScratch {
        h: [[0.0; CHUNK]; HIDDEN],
        e: [[0.0; CHUNK]; OTHER_DIM],
        g: [[0.0; CHUNK]; HIDDEN],
        o: [[0.0; CHUNK]; AFFINE_OUTPUTS],
    };
}

impl<W: Weights + Copy> AffineFlowSampler<W> {
    /// `(s, t)` of coupling network `l` for the lanes `idx[..m]` of a chunk, each at its own
    /// other coordinate `v[lane]` (`affine_params`, lane by lane); written to `st[lane]`.
    #[inline(always)]
    fn scale_shift_for(
        &self,
        l: usize,
        lanes: &[Option<AffineFlowLane>],
        idx: &[usize; CHUNK],
        m: usize,
        v: &[f32; CHUNK],
        st: &mut [(f32, f32); CHUNK],
        scratch: &mut AffineScratch,
    ) {
        let w = &self.params;
        let off = (l * AFFINE_NET_LEN) as u32;
        let AffineScratch { h, e, g, o } = scratch;
        let mut vv = [0.0f32; CHUNK];
        for k in 0..m {
            wavefront::set_column(h, k, lanes[idx[k]].as_ref().map(|s| &s.share[l]));
            vv[k] = v[idx[k]];
        }
        lanes::encode_rows::<OTHER_BANDS, OTHER_DIM, CHUNK>(&vv, e, 0);
        let l0 = off + AFFINE_NET_L0 as u32;
        dense::accumulate_act::<W, OTHER_DIM, HIDDEN, CHUNK>(
            w,
            l0,
            CONDITION_DIM as u32,
            e,
            h,
            m,
            Activation::Relu,
        );
        dense::dense(w, off + AFFINE_NET_L1 as u32, h, Activation::Relu, g, m);
        dense::dense(w, off + AFFINE_NET_L2 as u32, g, Activation::Identity, o, m);
        for k in 0..m {
            st[idx[k]] = scale_shift(&[o[0][k], o[1][k]]);
        }
    }

    /// The density direction (`latent_with_layer0`) of disk points `p` given layer 0's
    /// `(s, t)`: layers 1‥3 rerun where their input differs from `seen` (`reuse`) or always.
    #[inline(always)]
    fn latent_chunk(
        &self,
        lanes: &[Option<AffineFlowLane>],
        p: &[Vec2; CHUNK],
        st0: &[(f32, f32); CHUNK],
        seen: Option<&Seen>,
        zl: &mut [Vec2; CHUNK],
        ld: &mut [f32; CHUNK],
        scratch: &mut AffineScratch,
    ) {
        let m = lanes.len();
        for i in 0..m {
            let (s0, t0) = st0[i];
            zl[i] = Vec2::new(p[i].x * approx::exp(s0) + t0, p[i].y);
            ld[i] = s0;
        }
        let mut st = [(0.0f32, 0.0f32); CHUNK];
        let mut v = [0.0f32; CHUNK];
        for l in 1..AFFINE_LAYERS {
            let mut idx = [0usize; CHUNK];
            let mut n_run = 0;
            for i in 0..m {
                v[i] = if l % 2 == 0 { zl[i].y } else { zl[i].x };
                match seen {
                    Some(sn) if v[i].to_bits() == sn[l][i].0.to_bits() => {
                        st[i] = (sn[l][i].1, sn[l][i].2);
                    }
                    _ => {
                        idx[n_run] = i;
                        n_run += 1;
                    }
                }
            }
            if n_run > 0 {
                self.scale_shift_for(l, lanes, &idx, n_run, &v, &mut st, scratch);
            }
            for i in 0..m {
                let (s, t) = st[i];
                if l % 2 == 0 {
                    zl[i].x = zl[i].x * approx::exp(s) + t;
                } else {
                    zl[i].y = zl[i].y * approx::exp(s) + t;
                }
                ld[i] += s;
            }
        }
    }

    /// The density direction (`to_latent`) at the directions `wo`: per lane, whether its disk
    /// point is valid, cos θ, the latent point and the log-det.
    #[inline(always)]
    fn latent_at_chunk(
        &self,
        lanes: &[Option<AffineFlowLane>],
        wo: Vec3s<'_>,
        scratch: &mut AffineScratch,
    ) -> LatentAt {
        let mut at = LatentAt {
            ok: [false; CHUNK],
            cos: [0.0; CHUNK],
            z: [Vec2::ZERO; CHUNK],
            log_det: [0.0; CHUNK],
        };
        let (ok, cos) = (&mut at.ok, &mut at.cos);
        let m = lanes.len();
        let all = wavefront::identity_index::<CHUNK>();
        let mut p = [Vec2::ZERO; CHUNK];
        let mut v = [0.0f32; CHUNK];
        for i in 0..m {
            if let (Some(_), Some(w)) = (&lanes[i], warp::upper_hemisphere(wo.at(i))) {
                p[i] = warp::to_disk(w);
                cos[i] = w.z;
                ok[i] = inside_disk(p[i]);
            }
            v[i] = p[i].y;
        }
        let mut st0 = [(0.0f32, 0.0f32); CHUNK];
        self.scale_shift_for(0, lanes, &all, m, &v, &mut st0, scratch);
        let (z, log_det) = (&mut at.z, &mut at.log_det);
        self.latent_chunk(lanes, &p, &st0, None, z, log_det, scratch);
        at
    }
}

/// What `latent_at_chunk` gives per lane of a chunk.
struct LatentAt {
    /// Whether the lane is prepared and its direction's disk point strictly inside the disk.
    ok: [bool; CHUNK],
    /// cos θ of the direction.
    cos: [f32; CHUNK],
    /// The latent point.
    z: [Vec2; CHUNK],
    /// `ln |det ∂z/∂p|`.
    log_det: [f32; CHUNK],
}

impl<W: Weights + Copy> ChunkedSampler for AffineFlowSampler<W> {
    type Lane = Option<AffineFlowLane>;
    type Scratch = AffineScratch;
    const CHUNK: usize = CHUNK;

    #[inline(always)]
    fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, out: &mut [Option<AffineFlowLane>]) {
        let m = out.len();
        let (c, valid) = wavefront::encoded_conditions::<CHUNK>(&phi, &wi);
        let w = &self.params;
        let mut offsets = [0u32; AFFINE_LAYERS];
        for (l, off) in offsets.iter_mut().enumerate() {
            *off = (l * AFFINE_NET_LEN + AFFINE_NET_L0) as u32;
        }
        let mut share: [Soa<HIDDEN>; AFFINE_LAYERS] = [[[0.0; CHUNK]; HIDDEN]; AFFINE_LAYERS];
        dense::condition_shares::<W, COUPLING_INPUTS, CONDITION_DIM, HIDDEN, CHUNK, AFFINE_LAYERS>(
            w, offsets, &c, m, &mut share,
        );
        for l in 0..m {
            out[l] = if valid[l] {
                let mut sh = [[0.0f32; HIDDEN]; AFFINE_LAYERS];
                for (dst, src) in sh.iter_mut().zip(share.iter()) {
                    *dst = wavefront::column(src, l);
                }
                AffineFlowLane::new(sh)
            } else {
                None
            };
        }
    }

    #[inline(always)]
    fn sample_chunk(
        &self,
        lanes: &[Option<AffineFlowLane>],
        u: Vec2s<'_>,
        mut out: SamplesMut<'_>,
        scratch: &mut AffineScratch,
    ) {
        let m = lanes.len();
        let all = wavefront::identity_index::<CHUNK>();
        let mut ok = [false; CHUNK];
        let (mut u0, mut u1) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
        for i in 0..m {
            if let (Some(_), Some(uu)) = (&lanes[i], math::sanitize_u2(u.at(i))) {
                (u0[i], u1[i]) = (uu.x, uu.y);
                ok[i] = true;
            }
        }
        let (mut nx, mut ny) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
        lanes::box_muller_rows(&u0, &u1, &mut nx, &mut ny);
        let mut xy = [Vec2::ZERO; CHUNK];
        for i in 0..m {
            if ok[i] {
                xy[i] = Vec2::new(nx[i], ny[i]);
            }
        }
        // Sampling direction (`point_and_layer0`): layers 3‥1, then layer 0 at the final y.
        let mut seen: Seen = [[(0.0, 0.0, 0.0); CHUNK]; AFFINE_LAYERS];
        let mut st = [(0.0f32, 0.0f32); CHUNK];
        let mut v = [0.0f32; CHUNK];
        for l in (1..AFFINE_LAYERS).rev() {
            for i in 0..m {
                v[i] = if l % 2 == 0 { xy[i].y } else { xy[i].x };
            }
            self.scale_shift_for(l, lanes, &all, m, &v, &mut st, scratch);
            for i in 0..m {
                let (s, t) = st[i];
                seen[l][i] = (v[i], s, t);
                if l % 2 == 0 {
                    xy[i].x = (xy[i].x - t) * approx::exp(-s);
                } else {
                    xy[i].y = (xy[i].y - t) * approx::exp(-s);
                }
            }
        }
        for i in 0..m {
            v[i] = xy[i].y;
        }
        let mut st0 = [(0.0f32, 0.0f32); CHUNK];
        self.scale_shift_for(0, lanes, &all, m, &v, &mut st0, scratch);
        for i in 0..m {
            let (s0, t0) = st0[i];
            xy[i].x = (xy[i].x - t0) * approx::exp(-s0);
            ok[i] = ok[i] && inside_disk(xy[i]);
        }
        let mut zl = [Vec2::ZERO; CHUNK];
        let mut ld = [0.0f32; CHUNK];
        self.latent_chunk(lanes, &xy, &st0, Some(&seen), &mut zl, &mut ld, scratch);
        for i in 0..m {
            let s = if ok[i] {
                let log_p = AffineFlowPrepared::<W>::log_density(zl[i], ld[i]);
                Sample::from_disk(xy[i], density_from_log(log_p))
            } else {
                None
            };
            out.set(i, s);
        }
    }

    #[inline(always)]
    fn pdf_chunk(
        &self,
        lanes: &[Option<AffineFlowLane>],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        scratch: &mut AffineScratch,
    ) {
        let at = self.latent_at_chunk(lanes, wo, scratch);
        for i in 0..lanes.len() {
            pdf[i] = if at.ok[i] {
                let d = AffineFlowPrepared::<W>::log_density(at.z[i], at.log_det[i]);
                warp::disk_to_solid_angle(density_from_log(d), at.cos[i])
            } else {
                0.0
            };
        }
    }

    #[inline(always)]
    fn invert_chunk(
        &self,
        lanes: &[Option<AffineFlowLane>],
        wo: Vec3s<'_>,
        mut u: Vec2sMut<'_>,
        ok_out: &mut [bool],
        scratch: &mut AffineScratch,
    ) {
        let at = self.latent_at_chunk(lanes, wo, scratch);
        for i in 0..lanes.len() {
            let z = at.z[i];
            let r = if at.ok[i] && math::is_finite(z.x) && math::is_finite(z.y) {
                Some(gaussian::invert_box_muller(z))
            } else {
                None
            };
            ok_out[i] = r.is_some();
            if let Some(x) = r {
                u.set(i, x);
            }
        }
    }
}
