//! What the two flows share (`core/ARCHITECTURES.md` §3–4): the coupling networks' input
//! layout, the split of their first layer into a per-condition share (computed once in
//! `prepare`) and a per-sample share, and the conversion of a log-density.

use crate::math;
use crate::nn::{self, encoding_len, CONDITION_DIM};
use crate::weights::Weights;
#[cfg(not(target_arch = "spirv"))]
use {
    crate::distrib::spline::Knots,
    crate::math::lane::Lane,
    crate::wavefront::lanes::{Lanes, NARROW},
    crate::wavefront::simd::{dispatch, Isa, Kernel},
    crate::wavefront::Soa,
    core::marker::PhantomData,
};

#[cfg(not(target_arch = "spirv"))]
pub(crate) mod flow;

/// Lanes whose splines the batched path evaluates side by side: more than one vector's worth,
/// so that the long dependency chains of the softmaxes and the spline steps of several
/// vectors interleave.
#[cfg(not(target_arch = "spirv"))]
pub(crate) const GROUP: usize = 16;
/// A group of [`GROUP`] lanes.
#[cfg(not(target_arch = "spirv"))]
pub(crate) type Group = Lanes<GROUP>;

/// Frequency bands of the encoding of the coupling layers' "other coordinate" (release: 4).
pub const OTHER_BANDS: usize = 4;
/// Length of the encoded other coordinate: `1 + 2·OTHER_BANDS` = 9.
pub const OTHER_DIM: usize = encoding_len(OTHER_BANDS);
/// Inputs of every coupling network: the encoded condition then the encoded other
/// coordinate (30 + 9 = 39).
pub const COUPLING_INPUTS: usize = CONDITION_DIM + OTHER_DIM;
/// Width of every hidden layer of the flows' networks.
pub const HIDDEN: usize = 32;
/// Offset of a spline coupling network's `dense(39, 32)`, relative to the network.
pub(crate) const COUPLING_L0: usize = 0;
/// Offset of a spline coupling network's `dense(32, 32)`, relative to the network.
pub(crate) const COUPLING_L1: usize = COUPLING_L0 + nn::dense_len(COUPLING_INPUTS, HIDDEN);
/// Offset of a spline coupling network's output layer, relative to the network.
pub(crate) const COUPLING_L2: usize = COUPLING_L1 + nn::dense_len(HIDDEN, HIDDEN);

/// `enc4(v)`: the 9-value sinusoidal encoding of the coordinate a coupling is conditioned on.
#[inline(always)]
#[must_use]
pub fn encode_other(v: f32) -> [f32; OTHER_DIM] {
    let mut e = [0.0f32; OTHER_DIM];
    nn::encode_scalar::<OTHER_BANDS, OTHER_DIM>(v, &mut e, 0);
    e
}

/// The condition's share of the first layer (`dense(39, 32)` at `offset`) of a coupling
/// network: bias plus the product with inputs `0 .. 30`.
#[inline(always)]
pub(crate) fn condition_share<W: Weights>(
    w: &W,
    offset: u32,
    c: &[f32; CONDITION_DIM],
) -> [f32; HIDDEN] {
    let mut acc = nn::bias::<W, COUPLING_INPUTS, HIDDEN>(w, offset);
    nn::accumulate_inputs::<W, CONDITION_DIM, HIDDEN>(w, offset, 0, c, &mut acc);
    acc
}

/// First hidden layer of a coupling network from its precomputed condition share and the
/// other coordinate `v` (before the activation).
#[inline(always)]
pub(crate) fn first_layer<W: Weights>(
    w: &W,
    offset: u32,
    share: &[f32; HIDDEN],
    v: f32,
) -> [f32; HIDDEN] {
    let enc = encode_other(v);
    let mut acc = *share;
    nn::accumulate_inputs::<W, OTHER_DIM, HIDDEN>(w, offset, CONDITION_DIM as u32, &enc, &mut acc);
    acc
}

/// A coupling network (`dense(39, 32)` LeakyReLU, `dense(32, 32)` LeakyReLU,
/// `dense(32, RAW)` at `offset`) for one point, given its condition share and the other
/// coordinate `v`: the raw spline parameters. Both flows' scalar paths run their couplings
/// through it ([`coupling_raw_chunk`] is the batched form).
#[inline]
pub(crate) fn coupling_raw<W: Weights, const RAW: usize>(
    w: &W,
    offset: u32,
    share: &[f32; HIDDEN],
    v: f32,
) -> [f32; RAW] {
    let mut h = first_layer(w, offset + COUPLING_L0 as u32, share, v);
    nn::Activation::LeakyRelu.apply_all(&mut h);
    let h = nn::dense::<W, HIDDEN, HIDDEN>(
        w,
        offset + COUPLING_L1 as u32,
        &h,
        nn::Activation::LeakyRelu,
    );
    nn::linear::<W, HIDDEN, RAW>(w, offset + COUPLING_L2 as u32, &h)
}

/// `true` when every element is finite.
#[inline(always)]
pub(crate) fn all_finite<const N: usize>(v: &[f32; N]) -> bool {
    // No early exit: a loop without branches vectorises.
    let mut ok = true;
    let mut k = 0;
    while k < N {
        ok &= math::is_finite(v[k]);
        k += 1;
    }
    ok
}

/// `exp(log_pdf)` as a density: 0 for −∞, NaN or an overflow.
#[inline(always)]
pub(crate) fn density_from_log(log_pdf: f32) -> f32 {
    let p = math::exp(log_pdf);
    if p > 0.0 && math::is_finite(p) {
        p
    } else {
        0.0
    }
}

/// A lane state holding the condition's share of each coupling network's first layer.
#[cfg(not(target_arch = "spirv"))]
pub(crate) trait CouplingShares {
    /// The share of coupling network `net` (0 or 1).
    fn share(&self, net: usize) -> &[f32; HIDDEN];
}

/// The buffers of [`coupling_splines_chunk`], part of a flow's
/// [`Scratch`](crate::wavefront::Scratch) (made once per batched call or kept by the caller),
/// so that no coupling zeroes or copies its activations.
#[cfg(not(target_arch = "spirv"))]
pub struct CouplingBuffers<const RAW: usize, const CHUNK: usize> {
    /// The first hidden layer (starting as the lanes' shares).
    h: Soa<HIDDEN, CHUNK>,
    /// The second hidden layer.
    h2: Soa<HIDDEN, CHUNK>,
    /// The encoded other coordinates.
    e: Soa<OTHER_DIM, CHUNK>,
    /// The other coordinates.
    v: [f32; CHUNK],
    /// The raw spline parameters.
    raw: Soa<RAW, CHUNK>,
    /// The raw spline parameters of one group of [`GROUP`] lanes.
    group: [Group; RAW],
    /// Those of a group of [`NARROW`] lanes (small calls).
    narrow: [Lanes<NARROW>; RAW],
}

#[cfg(not(target_arch = "spirv"))]
impl<const RAW: usize, const CHUNK: usize> CouplingBuffers<RAW, CHUNK> {
    /// Zeroed buffers.
    pub(crate) const ZERO: Self = {
        CouplingBuffers {
            h: [[0.0; CHUNK]; HIDDEN],
            h2: [[0.0; CHUNK]; HIDDEN],
            e: [[0.0; CHUNK]; OTHER_DIM],
            v: [0.0; CHUNK],
            raw: [[0.0; CHUNK]; RAW],
            group: [Group::splat(0.0); RAW],
            narrow: [Lanes::splat(0.0); RAW],
        }
    };
}

/// The buffers' raw spline parameters and the buffer of one group of `G` lanes of them, for
/// the two group widths of the batched path ([`GROUP`], and [`NARROW`] for small calls).
#[cfg(not(target_arch = "spirv"))]
pub(crate) trait GroupBuffer<const G: usize, const RAW: usize, const CHUNK: usize> {
    /// The raw parameters (read) and the group's buffer (written).
    fn split(&mut self) -> (&Soa<RAW, CHUNK>, &mut [Lanes<G>; RAW]);
}

#[cfg(not(target_arch = "spirv"))]
impl<const RAW: usize, const CHUNK: usize> GroupBuffer<GROUP, RAW, CHUNK>
    for CouplingBuffers<RAW, CHUNK>
{
    #[inline(always)]
    fn split(&mut self) -> (&Soa<RAW, CHUNK>, &mut [Group; RAW]) {
        (&self.raw, &mut self.group)
    }
}

#[cfg(not(target_arch = "spirv"))]
impl<const RAW: usize, const CHUNK: usize> GroupBuffer<NARROW, RAW, CHUNK>
    for CouplingBuffers<RAW, CHUNK>
{
    #[inline(always)]
    fn split(&mut self) -> (&Soa<RAW, CHUNK>, &mut [Lanes<NARROW>; RAW]) {
        (&self.raw, &mut self.narrow)
    }
}

/// A flow's [`Scratch`](crate::wavefront::Scratch): the couplings'
/// buffers and two sets of splines of `K` bins (one per group of [`GROUP`] lanes).
#[cfg(not(target_arch = "spirv"))]
pub struct FlowScratch<const K: usize, const RAW: usize, const CHUNK: usize, const GROUPS: usize> {
    pub(crate) b: CouplingBuffers<RAW, CHUNK>,
    pub(crate) k0: [Knots<K, Group>; GROUPS],
    pub(crate) k1: [Knots<K, Group>; GROUPS],
}

#[cfg(not(target_arch = "spirv"))]
impl<const K: usize, const RAW: usize, const CHUNK: usize, const GROUPS: usize>
    crate::wavefront::Scratch for FlowScratch<K, RAW, CHUNK, GROUPS>
{
    const NEW: Self = FlowScratch {
        b: CouplingBuffers::ZERO,
        k0: [Knots::ZERO_LANES; GROUPS],
        k1: [Knots::ZERO_LANES; GROUPS],
    };
}

/// A coupling network (`dense(39, 32)` LeakyReLU, `dense(32, 32)` LeakyReLU,
/// `dense(32, RAW)` at `offset`) over the first `m` lanes of `b`, whose first hidden layer
/// holds each lane's condition share and `b.v` its other coordinate: the raw spline
/// parameters `b.raw[·][lane]`. The encoding of `v` runs over the lanes with the batched
/// path's fast `sin`/`cos`.
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
fn coupling_raw_chunk<W: Weights, const RAW: usize, const CHUNK: usize>(
    w: &W,
    offset: u32,
    m: usize,
    b: &mut CouplingBuffers<RAW, CHUNK>,
) {
    use crate::nn::Activation;
    use crate::wavefront::{dense, lanes};
    lanes::encode_rows::<OTHER_BANDS, OTHER_DIM, CHUNK>(&b.v, &mut b.e, 0);
    let l0 = offset + COUPLING_L0 as u32;
    let leaky = Activation::LeakyRelu;
    dense::accumulate_act::<W, OTHER_DIM, HIDDEN, CHUNK>(
        w,
        l0,
        CONDITION_DIM as u32,
        &b.e,
        &mut b.h,
        m,
        leaky,
    );
    let l1 = offset + COUPLING_L1 as u32;
    dense::dense::<W, HIDDEN, HIDDEN, CHUNK>(w, l1, &b.h, leaky, &mut b.h2, m);
    let l2 = offset + COUPLING_L2 as u32;
    dense::dense::<W, HIDDEN, RAW, CHUNK>(w, l2, &b.h2, Activation::Identity, &mut b.raw, m);
}

/// Which lanes of a chunk a coupling runs for: lane `k < m` of the coupling is
/// `lanes[idx[k]]` at other coordinate `v[idx[k]]` (a refused lane runs on zeros).
#[cfg(not(target_arch = "spirv"))]
pub(crate) struct CouplingLanes<'a, S, const CHUNK: usize> {
    /// The chunk's lane states.
    pub lanes: &'a [Option<S>],
    /// The chunk lane of each coupling lane.
    pub idx: &'a [usize; CHUNK],
    /// How many coupling lanes.
    pub m: usize,
    /// The other coordinate of each chunk lane.
    pub v: &'a [f32; CHUNK],
}

/// The splines of coupling network `net` (0 or 1, at `offset`) for the lanes `at`: the
/// lanes' shares and coordinates gathered into `b` (no copy of a lane state), then
/// [`coupling_raw_chunk`], then group `g` of `knots` from the raw parameters of coupling
/// lanes `G·g .. G·(g + 1)`, with the ends `E` ([`BoundedEnds`] on
/// `[−tail_bound, tail_bound]`, or [`FreeEnds`]). Its own kernel, compiled once per
/// instruction set (up to AVX2: the splines run in groups of [`GROUP`] lanes, or fewer for a
/// small chunk) and called from the flows' sample, pdf and invert rather than inlined at each
/// of their uses.
#[cfg(not(target_arch = "spirv"))]
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub(crate) fn coupling_splines_chunk<
    E: SplineEnds<K, RAW>,
    W: Weights,
    S: CouplingShares,
    const K: usize,
    const RAW: usize,
    const CHUNK: usize,
    const G: usize,
>(
    w: &W,
    offset: u32,
    net: usize,
    at: CouplingLanes<'_, S, CHUNK>,
    tail_bound: f32,
    b: &mut CouplingBuffers<RAW, CHUNK>,
    knots: &mut [Knots<K, Lanes<G>>],
) where
    CouplingBuffers<RAW, CHUNK>: GroupBuffer<G, RAW, CHUNK>,
{
    dispatch(SplinesJob::<E, W, S, K, RAW, CHUNK, G> {
        ends: PhantomData,
        w,
        offset,
        net,
        at,
        tail_bound,
        b,
        knots,
    });
}

/// How [`coupling_splines_chunk`] turns a group's raw parameters into splines.
#[cfg(not(target_arch = "spirv"))]
pub(crate) trait SplineEnds<const K: usize, const RAW: usize> {
    /// Sets `knots` to the splines of a group's lanes (`bound`: the half-width of their
    /// interval, if bounded).
    fn set_knots<L: Lane>(knots: &mut Knots<K, L>, raw: &[L; RAW], bound: f32);
}

/// Splines on `[−bound, bound]` with identity tails (`RAW = 3K − 1`).
#[cfg(not(target_arch = "spirv"))]
pub(crate) struct BoundedEnds;

/// Splines with free end knots (`RAW = 3K + 1`).
#[cfg(not(target_arch = "spirv"))]
pub(crate) struct FreeEnds;

#[cfg(not(target_arch = "spirv"))]
impl<const K: usize, const RAW: usize> SplineEnds<K, RAW> for BoundedEnds {
    #[inline(always)]
    fn set_knots<L: Lane>(knots: &mut Knots<K, L>, raw: &[L; RAW], bound: f32) {
        knots.set_raw_lanes(raw, bound);
    }
}

#[cfg(not(target_arch = "spirv"))]
impl<const K: usize, const RAW: usize> SplineEnds<K, RAW> for FreeEnds {
    #[inline(always)]
    fn set_knots<L: Lane>(knots: &mut Knots<K, L>, raw: &[L; RAW], _bound: f32) {
        knots.set_raw_free_lanes(raw);
    }
}

/// The arguments of [`coupling_splines_chunk`].
#[cfg(not(target_arch = "spirv"))]
struct SplinesJob<'a, E, W, S, const K: usize, const RAW: usize, const CHUNK: usize, const G: usize>
{
    ends: PhantomData<E>,
    w: &'a W,
    offset: u32,
    net: usize,
    at: CouplingLanes<'a, S, CHUNK>,
    tail_bound: f32,
    b: &'a mut CouplingBuffers<RAW, CHUNK>,
    knots: &'a mut [Knots<K, Lanes<G>>],
}

#[cfg(not(target_arch = "spirv"))]
impl<
        E: SplineEnds<K, RAW>,
        W: Weights,
        S: CouplingShares,
        const K: usize,
        const RAW: usize,
        const CHUNK: usize,
        const G: usize,
    > Kernel for SplinesJob<'_, E, W, S, K, RAW, CHUNK, G>
where
    CouplingBuffers<RAW, CHUNK>: GroupBuffer<G, RAW, CHUNK>,
{
    const WIDEST: Isa = Isa::X86V3;
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let SplinesJob {
            w,
            offset,
            net,
            at,
            tail_bound,
            b,
            knots,
            ..
        } = self;
        let m = at.m.min(CHUNK);
        // Lanes from `m` on keep what an earlier coupling left in the buffers: lanes are
        // independent and no result reads those, so they are not zeroed.
        for (k, &i) in at.idx.iter().enumerate().take(m) {
            let share = at
                .lanes
                .get(i)
                .and_then(Option::as_ref)
                .map(|s| s.share(net));
            crate::wavefront::set_column(&mut b.h, k, share);
            b.v[k] = at.v.get(i).copied().unwrap_or(0.0);
        }
        coupling_raw_chunk(w, offset, m, b);
        let (raw, group) = b.split();
        for (g, kn) in knots.iter_mut().enumerate().take(m.div_ceil(G)) {
            for (rj, row) in group.iter_mut().zip(raw.iter()) {
                *rj = Lanes::load(&row[G * g..]);
            }
            E::set_knots(kn, group, tail_bound);
        }
    }
}
