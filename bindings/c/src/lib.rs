//! # neusample-capi — the C ABI of neusample
//!
//! Opaque handles for a blob (owning its bytes), a sampler, a neural material and a measured
//! (RGL) material (from a measured blob or its `.bsdf` file); scalar calls in pbrt's shape
//! (`prepare`, `sample`, `pdf`) and batched calls over structure-of-arrays float pointers;
//! `NsStatus` codes with a per-thread message. The
//! header, `include/neusample.h`, is generated from this crate by cbindgen and committed;
//! `tests/header.rs` fails when it is stale (`NEUSAMPLE_BLESS=1` rewrites it).
//!
//! ## Conventions
//!
//! - Every function returns an [`NsStatus`] (the `*_free` functions return nothing). On an
//!   error, outputs are left untouched unless documented otherwise, and
//!   [`ns_last_error`](ffi::ns_last_error) returns a message for the calling thread.
//! - Directions live in the local shading frame (z = normal, both pointing away from the
//!   surface); every pdf is with respect to **solid angle**.
//! - Handles are immutable once built and may be shared between threads. The per-thread
//!   [`NsPrepared`] scratch state is the caller's.
//! - No panic crosses the boundary: every entry point runs under `catch_unwind` and reports
//!   [`NsStatus::NS_ERR_PANIC`].
//!
//! ## Unsafe code
//!
//! The workspace forbids `unsafe`; a C ABI cannot avoid it (it receives raw pointers). This
//! crate denies it, and allows it in one module, `ffi`, whose every `unsafe` block carries a
//! `// SAFETY:` comment (clippy's `undocumented_unsafe_blocks` is denied). The module turns
//! pointers into references and slices after checking them (null, alignment, length,
//! overlap of outputs with anything else) and calls the safe code in `api`.
#![deny(unsafe_op_in_unsafe_fn)]

mod api;
mod error;
#[allow(unsafe_code)]
pub mod ffi;
mod types;

pub use types::*;
