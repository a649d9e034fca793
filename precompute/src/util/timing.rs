//! Single-thread cost measurement: the renderer's harness (median of passes, ns per call).

pub use neusample_render::timing::{median, median_of_passes, ns_per_call};
