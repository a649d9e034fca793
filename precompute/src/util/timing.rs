//! Single-thread cost measurement: the renderer's harness (median of passes, ns per call) and
//! the random directions every `eval` timing uses.

use glam::Vec3;
use rand::RngExt;

pub use neusample_render::timing::{median, median_of_passes, ns_per_call};

/// A unit direction from spherical angles (polar `theta` from +z, azimuth `phi`).
#[must_use]
pub fn direction(theta: f32, phi: f32) -> Vec3 {
    Vec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// `n` random directions for timing `eval` (polar angle uniform in [0, 1.4], azimuth uniform).
pub fn timing_directions(rng: &mut impl rand::Rng, n: usize) -> Vec<Vec3> {
    (0..n)
        .map(|_| {
            direction(
                rng.random::<f32>() * 1.4,
                rng.random::<f32>() * std::f32::consts::TAU,
            )
        })
        .collect()
}
