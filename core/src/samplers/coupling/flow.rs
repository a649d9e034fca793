//! The batched path of a flow of two spline couplings on the unit disk, written once for
//! the spline flow and the disk flow ([`CouplingFlow`] says what differs: the base
//! distribution and how a coupling applies its spline). Lanes run in chunks of [`CHUNK`]:
//! the coupling networks as matrix products over the chunk's lanes, the splines a group of
//! [`GROUP`] lanes at a time ([`NARROW`] for a chunk of at most that many) through the
//! scalar path's own generic functions.
//!
//! Sampling runs coupling 0's inverse at the base point's `y`, then coupling 1's at the
//! result `x`; its density runs the couplings forward from the sample (as
//! `Prepared::sample` does): coupling 1's spline is the same, coupling 0's is rebuilt for
//! the lanes where its input (the base point's `y` recomputed) changed.

use glam::Vec2;

use core::slice;

use super::{
    coupling_splines_chunk, CouplingBuffers, CouplingLanes, CouplingShares, FlowScratch,
    GroupBuffer, SplineEnds, COUPLING_INPUTS, GROUP, HIDDEN,
};
use crate::distrib::spline::Knots;
use crate::math::lane::Lane;
use crate::nn::CONDITION_DIM;
use crate::samplers::Sample;
use crate::warp::{self, inside_disk};
use crate::wavefront::lanes::{Lanes, NARROW};
use crate::wavefront::{self, dense, Features, SamplesMut, Soa, Vec2s, Vec2sMut, Vec3s};
use crate::weights::Weights;

/// Lanes per chunk: activations, splines and lane states of a chunk stay in L1.
pub(crate) const CHUNK: usize = 32;
/// Groups of lanes per chunk (the splines are evaluated a group at a time).
pub(crate) const GROUPS: usize = CHUNK / GROUP;

/// One value per lane of a chunk.
pub(crate) type Rows = [f32; CHUNK];

/// What a two-coupling flow on the disk defines for [`coupling_flow_chunks`]: its lane
/// state, its coupling networks, its base distribution and its coupling transforms, each
/// on a group of lanes. `K` spline bins, `RAW` raw parameters per spline.
pub(crate) trait CouplingFlow<const K: usize, const RAW: usize> {
    /// The prepared state of one lane.
    type Lane: CouplingShares;
    /// The parameters' storage.
    type W: Weights;
    /// How a coupling network's raw outputs become splines.
    type Ends: SplineEnds<K, RAW>;
    /// Where the two coupling networks start in the parameters.
    const COUPLINGS: [usize; 2];
    /// The half-width of the splines' interval (for bounded [`Self::Ends`]).
    const TAIL_BOUND: f32;

    /// The parameters.
    fn weights(&self) -> &Self::W;

    /// The lane states of a chunk's conditions (`None` for refused lanes).
    fn prepare_lanes(&self, phi: Features<'_>, wi: Vec3s<'_>, out: &mut [Option<Self::Lane>]);

    /// The base distribution's parameters for a chunk's lanes (read once per call of
    /// [`Self::draw_base`] and [`Self::densities`]).
    type Base;

    /// [`Self::Base`] of the lanes.
    fn base(lanes: &[Option<Self::Lane>]) -> Self::Base;

    /// Base points drawn from `u` (0 where refused) and which lanes drew one.
    fn draw_base(
        base: &Self::Base,
        lanes: &[Option<Self::Lane>],
        u: &Vec2s<'_>,
    ) -> (Rows, Rows, [bool; CHUNK]);

    /// Coupling 0 inverted: the disk point's `x` from the base point's `(x, y)`.
    fn inverse0<L: Lane>(k: &Knots<K, L>, bx: L, by: L) -> L;

    /// Coupling 1 inverted: the disk point's `y` from the base point's `y` and the disk
    /// point's `x`.
    fn inverse1<L: Lane>(k: &Knots<K, L>, by: L, x: L) -> L;

    /// Coupling 1 forward at the disk point `(x, y)`: the base point's `y`, the coupling's
    /// log-derivative and what coupling 0 needs of it (the disk flow's half chord).
    fn forward1<L: Lane>(k: &Knots<K, L>, y: L, x: L) -> (L, L, L);

    /// Coupling 0 forward at the disk point's `x` with [`Self::forward1`]'s third value: the
    /// base point's `x` and the coupling's log-derivative.
    fn forward0<L: Lane>(k: &Knots<K, L>, x: L, c: L) -> (L, L);

    /// The densities on the disk (area measure) of lanes whose base points are `(bx, by)`,
    /// with the couplings' log-derivatives `ld0 + ld1`.
    fn densities(base: &Self::Base, bx: &Rows, by: &Rows, ld0: &Rows, ld1: &Rows) -> Rows;

    /// The random numbers that draw the base point `b` (`Prepared::invert`'s last step).
    fn invert_base(lane: &Self::Lane, b: Vec2) -> Option<Vec2>;
}

/// The condition's shares of the flow's two coupling networks' first layers for the first
/// `m` lanes of the encoded conditions `c`.
#[inline(always)]
pub(crate) fn coupling_shares<const K: usize, const RAW: usize, F: CouplingFlow<K, RAW>>(
    f: &F,
    c: &Soa<CONDITION_DIM, CHUNK>,
    m: usize,
) -> [Soa<HIDDEN, CHUNK>; 2] {
    let offsets = [F::COUPLINGS[0] as u32, F::COUPLINGS[1] as u32];
    let mut share = [[[0.0f32; CHUNK]; HIDDEN]; 2];
    dense::condition_shares::<F::W, COUPLING_INPUTS, CONDITION_DIM, HIDDEN, CHUNK, 2>(
        f.weights(),
        offsets,
        c,
        m,
        &mut share,
    );
    share
}

/// The splines of the flow's coupling network `net` (0 or 1) for the lanes `at` into
/// `knots`.
#[inline(always)]
fn splines<const K: usize, const RAW: usize, const G: usize, F: CouplingFlow<K, RAW>>(
    f: &F,
    net: usize,
    at: CouplingLanes<'_, F::Lane, CHUNK>,
    b: &mut CouplingBuffers<RAW, CHUNK>,
    knots: &mut [Knots<K, Lanes<G>>],
) where
    CouplingBuffers<RAW, CHUNK>: GroupBuffer<G, RAW, CHUNK>,
{
    let offset = F::COUPLINGS[net & 1] as u32;
    coupling_splines_chunk::<F::Ends, F::W, F::Lane, K, RAW, CHUNK, G>(
        f.weights(),
        offset,
        net,
        at,
        F::TAIL_BOUND,
        b,
        knots,
    );
}

/// Lane `l`'s two shares of [`coupling_shares`].
#[inline(always)]
pub(crate) fn lane_shares(share: &[Soa<HIDDEN, CHUNK>; 2], l: usize) -> [[f32; HIDDEN]; 2] {
    let mut sh = [[0.0f32; HIDDEN]; 2];
    for (dst, src) in sh.iter_mut().zip(share.iter()) {
        for j in 0..HIDDEN {
            dst[j] = src[j][l];
        }
    }
    sh
}

/// `ChunkedSampler::sample_chunk`: the splines in groups of [`GROUP`] lanes, or of
/// [`NARROW`] for a chunk of at most that many (the same bits).
#[inline(always)]
pub(crate) fn sample_chunk<const K: usize, const RAW: usize, F: CouplingFlow<K, RAW>>(
    f: &F,
    lanes: &[Option<F::Lane>],
    u: Vec2s<'_>,
    out: SamplesMut<'_>,
    scratch: &mut FlowScratch<K, RAW, CHUNK, GROUPS>,
) {
    let FlowScratch { b, k0, k1 } = scratch;
    if lanes.len() <= NARROW {
        let mut k = [Knots::<K, Lanes<NARROW>>::ZERO_LANES; 2];
        let [k0, k1] = &mut k;
        sample_groups(
            f,
            lanes,
            u,
            out,
            b,
            slice::from_mut(k0),
            slice::from_mut(k1),
        );
    } else {
        sample_groups(f, lanes, u, out, b, k0, k1);
    }
}

/// [`sample_chunk`] with the splines in groups of `G` lanes (`knots`: one per group).
#[inline(always)]
fn sample_groups<const K: usize, const RAW: usize, const G: usize, F: CouplingFlow<K, RAW>>(
    f: &F,
    lanes: &[Option<F::Lane>],
    u: Vec2s<'_>,
    mut out: SamplesMut<'_>,
    b: &mut CouplingBuffers<RAW, CHUNK>,
    k0: &mut [Knots<K, Lanes<G>>],
    k1: &mut [Knots<K, Lanes<G>>],
) where
    CouplingBuffers<RAW, CHUNK>: GroupBuffer<G, RAW, CHUNK>,
{
    let m = lanes.len();
    let groups = m.div_ceil(G).min(k0.len()).min(k1.len());
    let all = wavefront::identity_index::<CHUNK>();
    // Refused lanes keep the base point 0 and are dropped at the end.
    let base = F::base(lanes);
    let (bx, by, mut ok) = F::draw_base(&base, lanes, &u);
    let at = |idx, m, v| CouplingLanes { lanes, idx, m, v };
    splines(f, 0, at(&all, m, &by), b, k0);
    let mut px = [0.0f32; CHUNK];
    let mut py = [0.0f32; CHUNK];
    for g in 0..groups {
        let (b_x, b_y) = (
            Lanes::<G>::load(&bx[G * g..]),
            Lanes::<G>::load(&by[G * g..]),
        );
        F::inverse0(&k0[g], b_x, b_y).store(&mut px[G * g..]);
    }
    splines(f, 1, at(&all, m, &px), b, k1);
    let mut yb = [0.0f32; CHUNK];
    let mut cb = [0.0f32; CHUNK];
    let mut ld1 = [0.0f32; CHUNK];
    for g in 0..groups {
        let x = Lanes::<G>::load(&px[G * g..]);
        let y = F::inverse1(&k1[g], Lanes::<G>::load(&by[G * g..]), x);
        y.store(&mut py[G * g..]);
        let (a, d, c) = F::forward1(&k1[g], y, x);
        a.store(&mut yb[G * g..]);
        d.store(&mut ld1[G * g..]);
        c.store(&mut cb[G * g..]);
    }
    let mut xb = [0.0f32; CHUNK];
    let mut ld0 = [0.0f32; CHUNK];
    for g in 0..groups {
        let (a, d) = F::forward0(
            &k0[g],
            Lanes::<G>::load(&px[G * g..]),
            Lanes::<G>::load(&cb[G * g..]),
        );
        a.store(&mut xb[G * g..]);
        d.store(&mut ld0[G * g..]);
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
        splines(f, 0, at(&again, n_again, &yb), b, k0);
        let (mut x, mut c) = ([0.0f32; CHUNK], [0.0f32; CHUNK]);
        for k in 0..n_again {
            x[k] = px[again[k]];
            c[k] = cb[again[k]];
        }
        for g in 0..n_again.div_ceil(G).min(k0.len()) {
            let (a, d) = F::forward0(
                &k0[g],
                Lanes::<G>::load(&x[G * g..]),
                Lanes::<G>::load(&c[G * g..]),
            );
            for i in 0..G {
                if let Some(&l) = again[..n_again].get(G * g + i) {
                    xb[l] = a.0[i];
                    ld0[l] = d.0[i];
                }
            }
        }
    }
    let p = F::densities(&base, &xb, &yb, &ld0, &ld1);
    for l in 0..m {
        let s = if ok[l] {
            Sample::from_disk(Vec2::new(px[l], py[l]), p[l])
        } else {
            None
        };
        out.set(l, s);
    }
}

/// The disk points of a chunk's `wo` (0 where refused), their cosines, and whether each
/// lane has one inside the disk.
#[inline(always)]
fn disk_points<L>(lanes: &[Option<L>], wo: &Vec3s<'_>) -> (Rows, Rows, Rows, [bool; CHUNK]) {
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

/// The base points `(bx, by)` and log-dets of the disk points `(px, py)` of a chunk's lanes
/// (the density direction, `Prepared::pdf`'s couplings).
#[inline(always)]
fn to_base<const K: usize, const RAW: usize, F: CouplingFlow<K, RAW>>(
    f: &F,
    lanes: &[Option<F::Lane>],
    px: &Rows,
    py: &Rows,
    scratch: &mut FlowScratch<K, RAW, CHUNK, GROUPS>,
) -> (Rows, Rows, Rows) {
    if lanes.len() <= NARROW {
        let mut k = Knots::<K, Lanes<NARROW>>::ZERO_LANES;
        to_base_groups(f, lanes, px, py, &mut scratch.b, slice::from_mut(&mut k))
    } else {
        to_base_groups(f, lanes, px, py, &mut scratch.b, &mut scratch.k0)
    }
}

/// [`to_base`] with the splines in groups of `G` lanes (`k`: one per group).
#[inline(always)]
fn to_base_groups<const K: usize, const RAW: usize, const G: usize, F: CouplingFlow<K, RAW>>(
    f: &F,
    lanes: &[Option<F::Lane>],
    px: &Rows,
    py: &Rows,
    b: &mut CouplingBuffers<RAW, CHUNK>,
    k: &mut [Knots<K, Lanes<G>>],
) -> (Rows, Rows, Rows)
where
    CouplingBuffers<RAW, CHUNK>: GroupBuffer<G, RAW, CHUNK>,
{
    let m = lanes.len();
    let groups = m.div_ceil(G).min(k.len());
    let all = wavefront::identity_index::<CHUNK>();
    let at = |v| CouplingLanes {
        lanes,
        idx: &all,
        m,
        v,
    };
    splines(f, 1, at(px), b, k);
    let mut yb = [0.0f32; CHUNK];
    let mut cb = [0.0f32; CHUNK];
    let mut ld1 = [0.0f32; CHUNK];
    for g in 0..groups {
        let (x, y) = (
            Lanes::<G>::load(&px[G * g..]),
            Lanes::<G>::load(&py[G * g..]),
        );
        let (a, d, c) = F::forward1(&k[g], y, x);
        a.store(&mut yb[G * g..]);
        d.store(&mut ld1[G * g..]);
        c.store(&mut cb[G * g..]);
    }
    splines(f, 0, at(&yb), b, k);
    let mut xb = [0.0f32; CHUNK];
    let mut ld = [0.0f32; CHUNK];
    for g in 0..groups {
        let (a, d) = F::forward0(
            &k[g],
            Lanes::<G>::load(&px[G * g..]),
            Lanes::<G>::load(&cb[G * g..]),
        );
        a.store(&mut xb[G * g..]);
        (d + Lanes::<G>::load(&ld1[G * g..])).store(&mut ld[G * g..]);
    }
    (xb, yb, ld)
}

/// `ChunkedSampler::pdf_chunk`.
#[inline(always)]
pub(crate) fn pdf_chunk<const K: usize, const RAW: usize, F: CouplingFlow<K, RAW>>(
    f: &F,
    lanes: &[Option<F::Lane>],
    wo: Vec3s<'_>,
    pdf: &mut [f32],
    scratch: &mut FlowScratch<K, RAW, CHUNK, GROUPS>,
) {
    let (px, py, cos, ok) = disk_points(lanes, &wo);
    let (xb, yb, ld) = to_base(f, lanes, &px, &py, scratch);
    let p = F::densities(&F::base(lanes), &xb, &yb, &ld, &[0.0; CHUNK]);
    for l in 0..lanes.len() {
        pdf[l] = if ok[l] {
            warp::disk_to_solid_angle(p[l], cos[l])
        } else {
            0.0
        };
    }
}

/// `ChunkedSampler::invert_chunk`.
#[inline(always)]
pub(crate) fn invert_chunk<const K: usize, const RAW: usize, F: CouplingFlow<K, RAW>>(
    f: &F,
    lanes: &[Option<F::Lane>],
    wo: Vec3s<'_>,
    mut u: Vec2sMut<'_>,
    ok_out: &mut [bool],
    scratch: &mut FlowScratch<K, RAW, CHUNK, GROUPS>,
) {
    let (px, py, _, ok) = disk_points(lanes, &wo);
    let (xb, yb, _) = to_base(f, lanes, &px, &py, scratch);
    for l in 0..lanes.len() {
        let r = match (&lanes[l], ok[l]) {
            (Some(st), true) => F::invert_base(st, Vec2::new(xb[l], yb[l])),
            _ => None,
        };
        ok_out[l] = r.is_some();
        if let Some(v) = r {
            u.set(l, v);
        }
    }
}

/// The [`ChunkedSampler`](crate::wavefront::chunked::ChunkedSampler) of a
/// [`CouplingFlow`] `$sampler<W>` with lane state `$lane`, `$k` spline bins and `$raw` raw
/// parameters per spline. A macro rather than a blanket impl: the bins are the trait's const parameters,
/// which an impl over every flow could not name.
macro_rules! coupling_flow_chunks {
    ($sampler:ident => $lane:ident, $k:expr, $raw:expr) => {
        impl<W: $crate::weights::Weights + Copy> $crate::wavefront::chunked::ChunkedSampler
            for $sampler<W>
        {
            type Lane = Option<$lane>;
            type Scratch = $crate::samplers::coupling::FlowScratch<
                $k,
                $raw,
                { $crate::samplers::coupling::flow::CHUNK },
                { $crate::samplers::coupling::flow::GROUPS },
            >;
            const CHUNK: usize = $crate::samplers::coupling::flow::CHUNK;
            // The splines run in groups of 16 lanes.
            const WIDEST: $crate::wavefront::simd::Isa = $crate::wavefront::simd::Isa::X86V3;

            #[inline(always)]
            fn prepare_chunk(
                &self,
                phi: $crate::wavefront::Features<'_>,
                wi: $crate::wavefront::Vec3s<'_>,
                out: &mut [Self::Lane],
            ) {
                self.prepare_lanes(phi, wi, out);
            }

            #[inline(always)]
            fn sample_chunk(
                &self,
                lanes: &[Self::Lane],
                u: $crate::wavefront::Vec2s<'_>,
                out: $crate::wavefront::SamplesMut<'_>,
                scratch: &mut Self::Scratch,
            ) {
                $crate::samplers::coupling::flow::sample_chunk::<$k, $raw, Self>(
                    self, lanes, u, out, scratch,
                );
            }

            #[inline(always)]
            fn pdf_chunk(
                &self,
                lanes: &[Self::Lane],
                wo: $crate::wavefront::Vec3s<'_>,
                pdf: &mut [f32],
                scratch: &mut Self::Scratch,
            ) {
                $crate::samplers::coupling::flow::pdf_chunk::<$k, $raw, Self>(
                    self, lanes, wo, pdf, scratch,
                );
            }

            #[inline(always)]
            fn invert_chunk(
                &self,
                lanes: &[Self::Lane],
                wo: $crate::wavefront::Vec3s<'_>,
                u: $crate::wavefront::Vec2sMut<'_>,
                ok: &mut [bool],
                scratch: &mut Self::Scratch,
            ) {
                $crate::samplers::coupling::flow::invert_chunk::<$k, $raw, Self>(
                    self, lanes, wo, u, ok, scratch,
                );
            }
        }
    };
}
pub(crate) use coupling_flow_chunks;
