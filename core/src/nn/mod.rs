//! Fixed-size neural-network inference: dense layers over [`Weights`](crate::Weights)
//! ([`dense`](self::dense())) and the encodings of a sampler's condition (φ, wi)
//! ([`encode_condition`], [`raw_condition`]).
//!
//! Layer sizes are const generics, so every activation vector is a stack array and nothing
//! allocates.

mod dense;
mod encoding;

pub use dense::{
    accumulate_inputs, bias, dense, dense_len, linear, Activation, ReluMlp, LEAKY_RELU_SLOPE,
};
pub(crate) use encoding::features_finite;
pub use encoding::{
    check_condition, encode_condition, encode_scalar, encoding_len, raw_condition, CONDITION_BANDS,
    CONDITION_DIM, FEATURE_DIM, RAW_CONDITION_DIM,
};
