//! What the two flows share (`core/ARCHITECTURES.md` §3–4): the coupling networks' input
//! layout, the split of their first layer into a per-condition share (computed once in
//! `prepare`) and a per-sample share, and the conversion of a log-density.

use crate::math;
use crate::nn::{self, encoding_len, CONDITION_DIM};
use crate::weights::Weights;

/// Frequency bands of the encoding of the coupling layers' "other coordinate" (release: 4).
pub const OTHER_BANDS: usize = 4;
/// Length of the encoded other coordinate: `1 + 2·OTHER_BANDS` = 9.
pub const OTHER_DIM: usize = encoding_len(OTHER_BANDS);
/// Inputs of every coupling network: the encoded condition then the encoded other
/// coordinate (30 + 9 = 39).
pub const COUPLING_INPUTS: usize = CONDITION_DIM + OTHER_DIM;
/// Width of every hidden layer of the flows' networks.
pub const HIDDEN: usize = 32;

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

/// `true` when every element is finite.
#[inline(always)]
pub(crate) fn all_finite<const N: usize>(v: &[f32; N]) -> bool {
    let mut k = 0;
    while k < N {
        if !math::is_finite(v[k]) {
            return false;
        }
        k += 1;
    }
    true
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
