//! Range checks of material parameters, and [`params!`], which declares a `[params]` struct
//! with each field's range; errors name the offending field (`params.<field>`).

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

/// The value a field's check applies to: the field itself, or an `Option`'s content when
/// given (an absent optional field passes).
pub trait Given {
    /// The checked value's type.
    type Value;
    /// The value, `None` when absent.
    fn given(&self) -> Option<&Self::Value>;
}

impl Given for f32 {
    type Value = f32;
    fn given(&self) -> Option<&f32> {
        Some(self)
    }
}

impl Given for u32 {
    type Value = u32;
    fn given(&self) -> Option<&u32> {
        Some(self)
    }
}

impl<const N: usize> Given for [f32; N] {
    type Value = [f32; N];
    fn given(&self) -> Option<&[f32; N]> {
        Some(self)
    }
}

impl<T> Given for Option<T> {
    type Value = T;
    fn given(&self) -> Option<&T> {
        self.as_ref()
    }
}

/// Declares a `[params]` struct whose fields state their range once, as
/// `pub name: Type => kind(lo..=hi)` with `kind` one of [`range`], [`count`], [`range_n`],
/// [`interval`] (fields without a range omit `=> …`; an `Option` is checked when given).
/// Generates the struct (`Deserialize`, unknown fields rejected, each ranged field's doc
/// followed by its range) and `check` / `check_in`, which run the checks in field order.
///
/// ```ignore
/// params! {
///     /// `[params]` of a `wood` material.
///     pub struct Params {
///         /// Noise seed.
///         pub seed: u32,
///         /// Growth rings per uv unit across the grain.
///         pub rings: u32 => count(1..=128),
///     }
/// }
/// ```
macro_rules! params {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $(
                $(#[$fmeta:meta])*
                pub $field:ident: $ty:ty $(=> $kind:ident($lo:literal ..= $hi:literal))?,
            )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Debug, ::serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $name {
            $(
                $(#[$fmeta])*
                $(#[doc = $crate::materials::check::params!(@doc $kind, $lo, $hi)])?
                pub $field: $ty,
            )*
        }

        impl $name {
            /// Checks the range of every field (errors name `params.<field>`).
            pub fn check(&self) -> ::anyhow::Result<()> {
                self.check_in("")
            }

            /// [`Self::check`] of a table nested in `params`: errors name
            /// `params.<prefix><field>`.
            pub fn check_in(&self, prefix: &str) -> ::anyhow::Result<()> {
                $($(
                    if let Some(v) = $crate::materials::check::Given::given(&self.$field) {
                        let field = [prefix, stringify!($field)].concat();
                        $crate::materials::check::params!(@check $kind, &field, v, $lo, $hi)?;
                    }
                )?)*
                Ok(())
            }
        }
    };
    (@doc range_n, $lo:literal, $hi:literal) => {
        concat!(" Each component in `", stringify!($lo), "..=", stringify!($hi), "`.")
    };
    (@doc interval, $lo:literal, $hi:literal) => {
        concat!(" `[min, max]` in `", stringify!($lo), "..=", stringify!($hi), "`, min ≤ max.")
    };
    // `range`, `count`.
    (@doc $scalar:ident, $lo:literal, $hi:literal) => {
        concat!(" Range: `", stringify!($lo), "..=", stringify!($hi), "`.")
    };
    (@check range, $f:expr, $v:expr, $lo:literal, $hi:literal) => {
        $crate::materials::check::range($f, *$v, $lo, $hi)
    };
    (@check count, $f:expr, $v:expr, $lo:literal, $hi:literal) => {
        $crate::materials::check::count($f, *$v, $lo, $hi)
    };
    (@check range_n, $f:expr, $v:expr, $lo:literal, $hi:literal) => {
        $crate::materials::check::range_n($f, $v, $lo, $hi)
    };
    (@check interval, $f:expr, $v:expr, $lo:literal, $hi:literal) => {
        $crate::materials::check::interval($f, *$v, $lo, $hi)
    };
}
pub(super) use params;
