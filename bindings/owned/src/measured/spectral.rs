//! Spectral RGL files in linear sRGB: each texel's spectrum, read as Mitsuba's spectral
//! variants read it, integrated against the CIE 1931 2° observer under D65.
//!
//! # The conversion
//!
//! A texel holds values `v_k` at the file's wavelengths `λ_0 < … < λ_{n−1}`. Mitsuba's
//! spectral variants interpolate them linearly in `λ` and clamp outside the nodes (the
//! `Marginal2D` parameter lookup), so the texel's spectrum is `s(λ) = Σ_k v_k · b_k(λ)` with
//! `b_k` the hat functions of the nodes (`b_0 = 1` below `λ_0`, `b_{n−1} = 1` above `λ_{n−1}`).
//! Its colour is the light it reflects under D65, as tristimulus values normalised to the
//! illuminant's luminance, in linear sRGB:
//!
//! ```text
//! XYZ = ∫ s(λ) · (x̄, ȳ, z̄)(λ) · D65(λ) dλ / ∫ ȳ(λ) · D65(λ) dλ      (360–830 nm)
//! RGB = XYZ_TO_SRGB · XYZ
//! ```
//!
//! so a flat spectrum of 1 maps to D65's white, which linear sRGB calls (1, 1, 1) up to the
//! rounding of the tables and the matrix (within 2e-4, as the tests check). The conversion is linear in the
//! values, `RGB = Σ_k v_k · w_k`, and Mitsuba's interpolation over the incident angles and
//! the sample space is linear too: converting each texel equals integrating Mitsuba's
//! spectral evaluation over wavelength at any direction pair.
//!
//! The weights `w_k` are exact: on each piece between consecutive nodes of the merged set
//! (the 5 nm nodes of the tables and the file's wavelengths) the hat function, the observer
//! and the illuminant are all linear, so the integrand is a cubic and Simpson's rule
//! integrates it exactly (in f64).

use super::cie::{CIE1931_XYZ, D65, NODES, WAVELENGTH_MIN, WAVELENGTH_STEP, XYZ_TO_SRGB};

/// The largest tabulated wavelength, in nm.
const WAVELENGTH_MAX: f64 = WAVELENGTH_MIN + WAVELENGTH_STEP * (NODES - 1) as f64;

/// `(x̄, ȳ, z̄)(λ) · D65(λ)`, each table read linearly between its nodes; 0 outside them.
fn observer_d65(lambda: f64) -> [f64; 3] {
    let x = (lambda - WAVELENGTH_MIN) / WAVELENGTH_STEP;
    if !(x >= 0.0 && x <= (NODES - 1) as f64) {
        return [0.0; 3];
    }
    let i = (x as usize).min(NODES - 2);
    let t = x - i as f64;
    let lerp = |a: f32, b: f32| f64::from(a) * (1.0 - t) + f64::from(b) * t;
    let d65 = lerp(D65[i], D65[i + 1]);
    let (a, b) = (CIE1931_XYZ[i], CIE1931_XYZ[i + 1]);
    [0, 1, 2].map(|c| lerp(a[c], b[c]) * d65)
}

/// The hat functions at `lambda`: `(k, t)` with `s(λ) = (1 − t)·v_k + t·v_{k+1}` (`t = 0`
/// when there is one node), clamped outside the nodes.
fn hat(nodes: &[f64], lambda: f64) -> (usize, f64) {
    let n = nodes.len();
    if n < 2 || lambda <= nodes[0] {
        return (0, 0.0);
    }
    if lambda >= nodes[n - 1] {
        return (n - 2, 1.0);
    }
    let k = nodes.partition_point(|&l| l <= lambda) - 1;
    (k, (lambda - nodes[k]) / (nodes[k + 1] - nodes[k]))
}

/// The linear-sRGB weight of each wavelength node (module docs): a spectrum with values
/// `v_k` at `wavelengths` (in nm, ascending and finite, as the reader checks) has the colour
/// `Σ_k v_k · w_k`. Empty for no wavelengths.
#[must_use]
pub fn rgb_weights(wavelengths: &[f32]) -> Vec<[f64; 3]> {
    let nodes: Vec<f64> = wavelengths.iter().map(|&l| f64::from(l)).collect();
    let mut xyz = vec![[0.0f64; 3]; nodes.len()];
    if nodes.is_empty() {
        return xyz;
    }
    // The pieces: every table node and every wavelength inside the tables' range.
    let mut cuts: Vec<f64> = (0..NODES)
        .map(|i| WAVELENGTH_MIN + WAVELENGTH_STEP * i as f64)
        .chain(
            nodes
                .iter()
                .copied()
                .filter(|&l| l > WAVELENGTH_MIN && l < WAVELENGTH_MAX),
        )
        .collect();
    cuts.sort_by(f64::total_cmp);
    cuts.dedup();
    for piece in cuts.windows(2) {
        let (a, b) = (piece[0], piece[1]);
        let h = (b - a) / 6.0;
        for (lambda, simpson) in [(a, h), (0.5 * (a + b), 4.0 * h), (b, h)] {
            let w = observer_d65(lambda);
            let (k, t) = hat(&nodes, lambda);
            for c in 0..3 {
                xyz[k][c] += (1.0 - t) * simpson * w[c];
                if t > 0.0 {
                    xyz[k + 1][c] += t * simpson * w[c];
                }
            }
        }
    }
    // The hat functions sum to 1: the weights' Y sum to ∫ ȳ · D65.
    let luminance: f64 = xyz.iter().map(|w| w[1]).sum();
    xyz.iter()
        .map(|w| XYZ_TO_SRGB.map(|row| (row[0] * w[0] + row[1] * w[1] + row[2] * w[2]) / luminance))
        .collect()
}

/// The RGB table of a spectral file: `spectra` holds `slices` blocks of `weights.len()`
/// wavelength planes of `pixels` values each; the result holds `slices` blocks of 3 channel
/// planes (the layout of the `rgb` field).
pub(super) fn spectra_to_rgb(
    spectra: &[f32],
    weights: &[[f64; 3]],
    slices: usize,
    pixels: usize,
) -> Vec<f32> {
    let n = weights.len();
    let mut rgb = vec![0.0f32; slices * 3 * pixels];
    let mut acc = vec![[0.0f64; 3]; pixels];
    for s in 0..slices {
        acc.fill([0.0; 3]);
        for (k, w) in weights.iter().enumerate() {
            let plane = &spectra[(s * n + k) * pixels..][..pixels];
            for (a, &v) in acc.iter_mut().zip(plane) {
                for c in 0..3 {
                    a[c] += f64::from(v) * w[c];
                }
            }
        }
        for c in 0..3 {
            let out = &mut rgb[(s * 3 + c) * pixels..][..pixels];
            for (o, a) in out.iter_mut().zip(&acc) {
                *o = a[c] as f32;
            }
        }
    }
    rgb
}
