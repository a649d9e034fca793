//! The encodings of a sampler's condition: the feature vector φ and the incoming direction
//! `wi` (`core/ARCHITECTURES.md`, "Common pieces").

use glam::Vec3;

use crate::math;
use crate::warp;

/// Length of the material feature vector φ (NeuMIP-style latent, paper §3).
pub const FEATURE_DIM: usize = 8;

/// Length of the encoded condition fed to the lobe-mixture and flow networks:
/// φ, then `wi.x` and `wi.y` each with a [`CONDITION_BANDS`]-band sinusoidal encoding.
pub const CONDITION_DIM: usize = FEATURE_DIM + 2 * encoding_len(CONDITION_BANDS);

/// Length of the raw condition `(φ, wi.x, wi.y)` fed to the histogram networks.
pub const RAW_CONDITION_DIM: usize = FEATURE_DIM + 2;

/// Number of frequency bands of the condition encoding of `wi.xy` (authors' release: 5).
pub const CONDITION_BANDS: usize = 5;
/// Length of a sinusoidal encoding of one scalar with `bands` bands: the value itself plus a
/// sine and a cosine per band.
#[inline]
#[must_use]
pub const fn encoding_len(bands: usize) -> usize {
    1 + 2 * bands
}

/// Sinusoidal positional encoding of one scalar `x` with `B` bands, written to
/// `out[at .. at + 1 + 2B]` as
///
/// ```text
/// x, sin(πx), cos(πx), sin(2πx), cos(2πx), …, sin(2^(B−1)πx), cos(2^(B−1)πx)
/// ```
///
/// The higher bands use the double-angle recurrences from `sincos(πx)` (one libm call instead
/// of B); they agree with direct evaluation to a few ulps per band.
#[inline(always)]
pub fn encode_scalar<const B: usize, const N: usize>(x: f32, out: &mut [f32; N], at: usize) {
    out[at] = x;
    let (mut s, mut c) = math::sin_cos(math::PI * x);
    let mut k = 0;
    while k < B {
        out[at + 1 + 2 * k] = s;
        out[at + 2 + 2 * k] = c;
        let s2 = 2.0 * s * c;
        let c2 = c * c - s * s;
        s = s2;
        c = c2;
        k += 1;
    }
}

/// Checks a condition: normalised `wi` strictly above the horizon and finite `phi`.
#[inline]
#[must_use]
pub fn check_condition(phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<Vec3> {
    let wi = warp::upper_hemisphere(wi)?;
    if features_finite(phi) {
        Some(wi)
    } else {
        None
    }
}

/// Whether every feature of `phi` is finite.
#[inline]
#[must_use]
pub(crate) fn features_finite(phi: &[f32; FEATURE_DIM]) -> bool {
    let mut k = 0;
    while k < FEATURE_DIM {
        if !crate::math::is_finite(phi[k]) {
            return false;
        }
        k += 1;
    }
    true
}

/// The encoded condition for the lobe-mixture and flow networks (release layout):
///
/// ```text
/// [ φ₀ … φ₇,  enc(wi.x),  enc(wi.y) ]      enc = encode_scalar::<5>  (11 values each)
/// ```
#[inline]
#[must_use]
pub fn encode_condition(phi: &[f32; FEATURE_DIM], wi: Vec3) -> [f32; CONDITION_DIM] {
    let mut x = [0.0f32; CONDITION_DIM];
    let mut k = 0;
    while k < FEATURE_DIM {
        x[k] = phi[k];
        k += 1;
    }
    encode_scalar::<CONDITION_BANDS, CONDITION_DIM>(wi.x, &mut x, FEATURE_DIM);
    encode_scalar::<CONDITION_BANDS, CONDITION_DIM>(
        wi.y,
        &mut x,
        FEATURE_DIM + encoding_len(CONDITION_BANDS),
    );
    x
}

/// The raw condition `[φ₀ … φ₇, wi.x, wi.y]` for the histogram networks.
#[inline]
#[must_use]
pub fn raw_condition(phi: &[f32; FEATURE_DIM], wi: Vec3) -> [f32; RAW_CONDITION_DIM] {
    let mut x = [0.0f32; RAW_CONDITION_DIM];
    let mut k = 0;
    while k < FEATURE_DIM {
        x[k] = phi[k];
        k += 1;
    }
    x[FEATURE_DIM] = wi.x;
    x[FEATURE_DIM + 1] = wi.y;
    x
}
