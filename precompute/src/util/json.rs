//! The JSON convention of the reports: a number that cannot be computed (NaN, ±∞) is written
//! as `null` (serde_json's behaviour) and read back as NaN.

use serde::{Deserialize, Deserializer};

/// NaN: the value of a number a report written before it existed does not have (use with
/// `#[serde(default = "nan")]`).
#[must_use]
pub fn nan() -> f64 {
    f64::NAN
}

/// Reads a number, or `null` as NaN (use with `#[serde(deserialize_with = …)]`).
pub fn f64_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}
