//! Seeded random streams. Every random number of training and evaluation comes from a stream
//! keyed by `(seed, …)` through the one SplitMix64 ([`splitmix64`], shared with the
//! renderer's per-pixel streams), so results do not depend on how rayon schedules work.

use rand::SeedableRng;
use rand_pcg::Pcg64;

pub use neusample_render::rng::{indexed_rng, splitmix64, StreamRng};

/// Mixes two seeds into one: `splitmix64(a·φ + b + c)` with φ the golden-ratio increment of
/// SplitMix64 and `c` a fixed offset.
#[inline]
#[must_use]
pub fn mix_seed(a: u64, b: u64) -> u64 {
    // splitmix64 adds the golden-ratio increment 0x9E37_79B9_7F4A_7C15 itself; the offset
    // below is 0x632B_E59B_D9B4_E019 minus that increment.
    splitmix64(
        a.wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(b)
            .wrapping_add(0x632B_E59B_D9B4_E019u64.wrapping_sub(0x9E37_79B9_7F4A_7C15)),
    )
}

/// The PCG stream of `(seed, a, b)` (training data, initialisations).
#[must_use]
pub fn rng_for(seed: u64, a: u64, b: u64) -> Pcg64 {
    Pcg64::seed_from_u64(mix_seed(mix_seed(seed, a), b))
}

/// The named seed streams of the jobs and drivers: each use of randomness derives its seed
/// from the run's seed under its own name, so that no two uses share random numbers by
/// accident and a reader sees which draws are meant to be the same. The derivations are the
/// ones the committed fixtures and reports were made with.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Stream {
    /// The demo's check of a freshly baked blob against the model it was baked from.
    DemoBlobCheck,
    /// `neusample train`'s and `train-material`'s check of the blob they write.
    BlobCheck,
    /// The conditions a fit (KL, χ², pdf MSE) is measured at, and a neural material's fit
    /// report in the demo; the weights figure shows the worst of the same conditions.
    Fit,
    /// `train-material`'s fit report of the neural material against its source.
    MaterialFit,
    /// The conditions and samples the defensive weight α is chosen on.
    Defend,
    /// The conditions of the pdf figure (the paper's Fig. 7).
    PdfFigure,
    /// The reference render (many samples per pixel), independent of the compared renders.
    Reference,
    /// The equal-time render of the technique compared with the baseline.
    EqualTime,
    /// The bootstrap of a technique's render blocks for its intervals (with the technique's
    /// name mixed in).
    Bootstrap,
}

impl Stream {
    /// The stream's seed for the run's `seed`.
    #[must_use]
    pub const fn of(self, seed: u64) -> u64 {
        match self {
            Stream::DemoBlobCheck => seed.wrapping_add(7),
            Stream::BlobCheck => seed ^ 0x5EED,
            Stream::Fit => seed.wrapping_add(100),
            Stream::MaterialFit => seed ^ 0xF17,
            Stream::Defend => seed.wrapping_add(300),
            Stream::PdfFigure => seed.wrapping_add(500),
            Stream::Reference => seed ^ 0x5EF0_0000_0000_5EF0,
            Stream::EqualTime => seed.wrapping_add(0x00E9_0A17),
            Stream::Bootstrap => seed ^ 0xB007,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The seed mixing the committed fixtures were trained with, written out.
    fn mix_seed_reference(a: u64, b: u64) -> u64 {
        let mut z = a
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(b)
            .wrapping_add(0x632B_E59B_D9B4_E019);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    #[test]
    fn mix_seed_is_the_reference_mixing() {
        for a in [0u64, 1, 7, 0xdead_beef, u64::MAX] {
            for b in [0u64, 1, 0x0f00, 0xda7a, u64::MAX - 3] {
                assert_eq!(mix_seed(a, b), mix_seed_reference(a, b));
            }
        }
    }
}
