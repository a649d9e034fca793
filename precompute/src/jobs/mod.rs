//! The library side of the command-line jobs: typed settings in, typed reports out (the
//! binary only parses arguments into these and prints).
//!
//! * [`sampler`] — train, bake, verify and write one sampler; the `train --method all` sweep
//!   and its `summary.json`;
//! * [`material`] — fit a neural material to a material, import one from safetensors, measure
//!   a material's cost;
//! * [`inspect`] — describe a blob (`inspect --json`);
//! * [`measured`] — an RGL measured material (`.bsdf`) as a blob (`measured-blob`);
//! * [`bench`](mod@bench) — the runtime's cost per shading point, scalar and batched (`bench --json`).

pub mod bench;
pub mod inspect;
pub mod material;
pub mod measured;
pub mod sampler;
