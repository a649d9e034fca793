//! Small statistics over slices.

/// Mean of f32 values in f64; 0 for an empty slice.
#[must_use]
pub fn mean(v: &[f32]) -> f64 {
    v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len().max(1) as f64
}

/// `num / den`, or NaN when the quotient is not defined (`den ≤ 0` or either not finite).
#[must_use]
pub fn ratio(num: f64, den: f64) -> f64 {
    if den > 0.0 && num.is_finite() && den.is_finite() {
        num / den
    } else {
        f64::NAN
    }
}
