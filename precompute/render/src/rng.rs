//! Seeded random streams that do not depend on scheduling: item `index` of a batch (a pixel of
//! an image, a condition of a training batch) draws from its own stream, so results are
//! bit-identical for any number of threads.

use rand::SeedableRng;

/// The random stream of one item.
pub type StreamRng = rand_pcg::Pcg64Mcg;

/// The SplitMix64 finaliser (Steele et al. 2014): decorrelates seeds built from small
/// integers.
#[inline]
#[must_use]
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The stream of item `index` of a batch seeded with `seed`: independent of the thread count
/// and of the batch size (a batch of n items is a prefix of a batch of m > n).
#[must_use]
pub fn indexed_rng(seed: u64, index: usize) -> StreamRng {
    StreamRng::seed_from_u64(splitmix64(seed ^ splitmix64(index as u64)))
}
