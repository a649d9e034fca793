//! Burn building blocks shared by every trainer: the devices and host ↔ tensor helpers, the
//! MLP in the runtime's parameter layout with its plain-Rust f64 mirror, the sinusoidal
//! encodings and stable log-density helpers, and the one optimisation loop (AdamW, warm-up +
//! cosine learning rate, progress bar, skipped non-finite steps).
//!
//! Layout contract (`core/ARCHITECTURES.md`): burn's `Linear` stores its weight as
//! `[d_input, d_output]`, which is exactly the runtime's input-major `W[i][o]`, so a layer
//! exports as `weight` (row-major) followed by `bias`.

mod mlp;
mod ops;
mod optim;
mod tensor;

pub use mlp::{activate, activate_f64, mlp_f64, mlp_len, Activation, Mlp};
pub use ops::{
    clamp_log_sigma, encode, encode_f64, log_add_exp, log_sum_exp_last, softmax_f64, softplus_f64,
};
pub use optim::{learning_rate, optimise, OptimSettings};
pub use tensor::{infer_device, tensor2, to_host, train_device};
