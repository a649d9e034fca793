//! Helpers every other module may use and that use nothing of this crate: seeded random
//! streams, the timing harness, small statistics, atomic file output, progress bars and the
//! JSON convention for numbers that cannot be computed.

pub mod io;
pub mod json;
pub mod progress;
pub mod rng;
pub mod stats;
pub mod timing;
