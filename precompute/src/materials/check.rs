//! Range checks of material parameters; errors name the offending field (`params.<field>`).

use anyhow::bail;

/// `lo ≤ v ≤ hi` and finite.
pub fn range(field: &str, v: f32, lo: f32, hi: f32) -> anyhow::Result<()> {
    if !(v.is_finite() && v >= lo && v <= hi) {
        bail!("field `params.{field}`: must be in [{lo}, {hi}], got {v}");
    }
    Ok(())
}

/// Every component in `[lo, hi]`.
pub fn range_n(field: &str, v: &[f32], lo: f32, hi: f32) -> anyhow::Result<()> {
    for (i, &x) in v.iter().enumerate() {
        if !(x.is_finite() && x >= lo && x <= hi) {
            bail!("field `params.{field}[{i}]`: must be in [{lo}, {hi}], got {x}");
        }
    }
    Ok(())
}

/// A `[min, max]` pair inside `[lo, hi]` with `min ≤ max`.
pub fn interval(field: &str, v: [f32; 2], lo: f32, hi: f32) -> anyhow::Result<()> {
    range_n(field, &v, lo, hi)?;
    if v[0] > v[1] {
        bail!("field `params.{field}`: expected [min, max] with min ≤ max, got {v:?}");
    }
    Ok(())
}

/// An integer in `[lo, hi]`.
pub fn count(field: &str, v: u32, lo: u32, hi: u32) -> anyhow::Result<()> {
    if v < lo || v > hi {
        bail!("field `params.{field}`: must be in [{lo}, {hi}], got {v}");
    }
    Ok(())
}
