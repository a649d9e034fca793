//! What the two flows share (`core/ARCHITECTURES.md` §3–4): the coupling networks' input
//! layout, the split of their first layer into a per-condition share (computed once in
//! `prepare`) and a per-sample share, and the conversion of a log-density.

use crate::math;
use crate::nn::{self, encoding_len, CONDITION_DIM};
use crate::weights::Weights;
#[cfg(not(target_arch = "spirv"))]
use {
    crate::distrib::spline::Knots,
    crate::wavefront::lanes::V8,
    crate::wavefront::simd::{dispatch, Isa, Kernel},
    core::marker::PhantomData,
};

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

/// A coupling network (`dense(39, 32)` LeakyReLU, `dense(32, 32)` LeakyReLU,
/// `dense(32, RAW)` at `offset`) over the first `m` lanes of a chunk, given each lane's
/// condition share and other coordinate `v`: the raw spline parameters `raw[·][lane]`. Both
/// flows' batched kernels run their couplings through it. The encoding of `v` runs over the
/// lanes with the batched path's fast `sin`/`cos`.
#[cfg(not(target_arch = "spirv"))]
#[inline(always)]
pub(crate) fn coupling_raw_chunk<W: Weights, const RAW: usize, const CHUNK: usize>(
    w: &W,
    offset: u32,
    share: &[[f32; HIDDEN]; CHUNK],
    v: &[f32; CHUNK],
    m: usize,
    raw: &mut crate::wavefront::Soa<RAW, CHUNK>,
) {
    use crate::nn::Activation;
    use crate::wavefront::{dense, lanes};
    let mut h = [[0.0f32; CHUNK]; HIDDEN];
    for (l, s) in share.iter().enumerate().take(m) {
        for (j, x) in s.iter().enumerate() {
            h[j][l] = *x;
        }
    }
    let mut e = [[0.0f32; CHUNK]; OTHER_DIM];
    lanes::encode_rows::<OTHER_BANDS, OTHER_DIM, CHUNK>(v, &mut e, 0);
    let l0 = offset + COUPLING_L0 as u32;
    let leaky = Activation::LeakyRelu;
    dense::accumulate_act::<W, OTHER_DIM, HIDDEN, CHUNK>(
        w,
        l0,
        CONDITION_DIM as u32,
        &e,
        &mut h,
        m,
        leaky,
    );
    let mut h2 = [[0.0f32; CHUNK]; HIDDEN];
    let l1 = offset + COUPLING_L1 as u32;
    dense::dense::<W, HIDDEN, HIDDEN, CHUNK>(w, l1, &h, leaky, &mut h2, m);
    let l2 = offset + COUPLING_L2 as u32;
    dense::dense::<W, HIDDEN, RAW, CHUNK>(w, l2, &h2, Activation::Identity, raw, m);
}

/// The splines of a chunk's lanes from coupling network `offset`: [`coupling_raw_chunk`],
/// then group `g` of `knots` from the raw parameters of lanes `8g .. 8g + 8`, with the ends
/// `E` ([`BoundedEnds`] on `[−tail_bound, tail_bound]`, or [`FreeEnds`]). Its own kernel,
/// compiled once per instruction set (up to AVX2: the splines run in eight-lane groups) and
/// called from the flows' sample, pdf and invert rather than inlined at each of their uses.
#[cfg(not(target_arch = "spirv"))]
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub(crate) fn coupling_splines_chunk<
    E: SplineEnds<K, RAW>,
    W: Weights,
    const K: usize,
    const RAW: usize,
    const CHUNK: usize,
>(
    w: &W,
    offset: u32,
    share: &[[f32; HIDDEN]; CHUNK],
    v: &[f32; CHUNK],
    m: usize,
    tail_bound: f32,
    knots: &mut [Knots<K, V8>],
) {
    dispatch(SplinesJob::<E, W, K, RAW, CHUNK> {
        ends: PhantomData,
        w,
        offset,
        share,
        v,
        m,
        tail_bound,
        knots,
    });
}

/// How [`coupling_splines_chunk`] turns a group's raw parameters into splines.
#[cfg(not(target_arch = "spirv"))]
pub(crate) trait SplineEnds<const K: usize, const RAW: usize> {
    /// The splines of eight lanes (`bound`: the half-width of their interval, if bounded).
    fn knots(raw: &[V8; RAW], bound: f32) -> Knots<K, V8>;
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
    fn knots(raw: &[V8; RAW], bound: f32) -> Knots<K, V8> {
        Knots::from_raw_lanes(raw, bound)
    }
}

#[cfg(not(target_arch = "spirv"))]
impl<const K: usize, const RAW: usize> SplineEnds<K, RAW> for FreeEnds {
    #[inline(always)]
    fn knots(raw: &[V8; RAW], _bound: f32) -> Knots<K, V8> {
        Knots::from_raw_free_lanes(raw)
    }
}

/// The arguments of [`coupling_splines_chunk`].
#[cfg(not(target_arch = "spirv"))]
struct SplinesJob<'a, E, W, const K: usize, const RAW: usize, const CHUNK: usize> {
    ends: PhantomData<E>,
    w: &'a W,
    offset: u32,
    share: &'a [[f32; HIDDEN]; CHUNK],
    v: &'a [f32; CHUNK],
    m: usize,
    tail_bound: f32,
    knots: &'a mut [Knots<K, V8>],
}

#[cfg(not(target_arch = "spirv"))]
impl<E: SplineEnds<K, RAW>, W: Weights, const K: usize, const RAW: usize, const CHUNK: usize> Kernel
    for SplinesJob<'_, E, W, K, RAW, CHUNK>
{
    const WIDEST: Isa = Isa::X86V3;
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let mut raw: crate::wavefront::Soa<RAW, CHUNK> = [[0.0; CHUNK]; RAW];
        coupling_raw_chunk(self.w, self.offset, self.share, self.v, self.m, &mut raw);
        for (g, kn) in self.knots.iter_mut().enumerate().take(self.m.div_ceil(8)) {
            let mut r = [V8::splat(0.0); RAW];
            for (rj, row) in r.iter_mut().zip(raw.iter()) {
                *rj = V8::load(&row[8 * g..]);
            }
            *kn = E::knots(&r, self.tail_bound);
        }
    }
}
