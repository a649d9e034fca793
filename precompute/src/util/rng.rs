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
