//! What [`Blob::open`](super::Blob::open) checks of a measured-material blob
//! ([`BlobKind::Measured`](crate::BlobKind::Measured)), and how its two tensors become a
//! [`MeasuredMaterial`]: the `shape` tensor read as exact integers, the `tables` tensor split
//! into the 11 tables without copying, and the running integrals of the VNDF and luminance
//! slices compared with their values (what [`MeasuredMaterial::new`] does not check).

use crate::distrib::marginal2d::MAX_PARAM_NODES;
use crate::error::{Error, Result};
use crate::measured::{MeasuredMaterial, MeasuredShape, MeasuredTables, MAX_TABLE_SIZE};
use crate::weights::{Tensor, Weights};

use super::format::MEASURED_SHAPE_LEN;

/// Relative tolerance of a stored running integral against the one recomputed from the
/// stored (normalised) values: the writer rounds the integrals of the raw values, so the two
/// differ by a few units in the last place, far below a corrupted value's error.
const INTEGRAL_RTOL: f64 = 1e-4;
/// Absolute floor of that tolerance (integrals are in units of the slice's total, 1).
const INTEGRAL_ATOL: f64 = 1e-6;

/// The names and limits of the shape tensor's first ten entries, as
/// [`MeasuredMaterial::new`] checks them.
const LIMITS: [(&str, u32, u32); MEASURED_SHAPE_LEN - 1] = [
    ("n_phi", 1, MAX_PARAM_NODES),
    ("n_theta", 1, MAX_PARAM_NODES),
    ("ndf width", 2, MAX_TABLE_SIZE),
    ("ndf height", 2, MAX_TABLE_SIZE),
    ("sigma width", 2, MAX_TABLE_SIZE),
    ("sigma height", 2, MAX_TABLE_SIZE),
    ("vndf width", 2, MAX_TABLE_SIZE),
    ("vndf height", 2, MAX_TABLE_SIZE),
    ("rgb width", 2, MAX_TABLE_SIZE),
    ("rgb height", 2, MAX_TABLE_SIZE),
];

/// The shape tensor's values in the order [`LIMITS`] names them, then the jacobian flag.
#[cfg(feature = "alloc")]
#[must_use]
pub(crate) fn shape_values(shape: &MeasuredShape, jacobian: bool) -> [f32; MEASURED_SHAPE_LEN] {
    let mut out = [0.0; MEASURED_SHAPE_LEN];
    for (o, v) in out.iter_mut().zip(shape.values()) {
        *o = v as f32;
    }
    out[MEASURED_SHAPE_LEN - 1] = f32::from(u8::from(jacobian));
    out
}

/// The shape tensor as sizes and the jacobian flag, with every size in its range and the
/// tables' element counts representable.
///
/// # Errors
/// [`Error::TensorShape`] for a shape tensor of the wrong length, [`Error::HeaderInvalid`]
/// for a value that is not an exact non-negative integer (or a flag other than 0 and 1),
/// [`Error::DimensionMismatch`] for a size out of range or tables too large.
pub(crate) fn shape(t: &Tensor<'_>) -> Result<(MeasuredShape, bool)> {
    if t.len() != MEASURED_SHAPE_LEN as u32 {
        return Err(Error::TensorShape {
            role: "shape",
            expected: MEASURED_SHAPE_LEN as u32,
            found: t.len(),
        });
    }
    let mut v = [0u32; MEASURED_SHAPE_LEN];
    for (i, out) in v.iter_mut().enumerate() {
        let x = t.at(i as u32);
        // Exact integers only: 2^24 bounds every limit and keeps the conversion exact.
        if !(x >= 0.0 && x <= 16_777_216.0 && crate::math::floor(x) == x) {
            return Err(Error::HeaderInvalid);
        }
        *out = x as u32;
    }
    for (i, (what, lo, hi)) in LIMITS.iter().enumerate() {
        if v[i] < *lo || v[i] > *hi {
            return Err(Error::DimensionMismatch {
                what,
                expected: if v[i] < *lo { *lo } else { *hi },
                found: v[i],
            });
        }
    }
    let jacobian = match v[MEASURED_SHAPE_LEN - 1] {
        0 => false,
        1 => true,
        _ => return Err(Error::HeaderInvalid),
    };
    let shape = MeasuredShape {
        n_phi: v[0],
        n_theta: v[1],
        ndf: [v[2], v[3]],
        sigma: [v[4], v[5]],
        vndf: [v[6], v[7]],
        rgb: [v[8], v[9]],
    };
    // Every table, and all of them together, must count fewer than 2^32 elements (so that
    // `MeasuredShape::lens` cannot overflow).
    if tables_len(&shape) > u64::from(u32::MAX) {
        return Err(Error::DimensionMismatch {
            what: "table elements",
            expected: u32::MAX,
            found: u32::MAX,
        });
    }
    Ok((shape, jacobian))
}

/// The element count of the tables tensor, in u64 (the sizes are in range, so nothing
/// overflows).
fn tables_len(s: &MeasuredShape) -> u64 {
    let n = |x: u32| u64::from(x);
    let slices = n(s.n_phi) * n(s.n_theta);
    let [vw, vh] = s.vndf.map(n);
    let [rw, rh] = s.rgb.map(n);
    n(s.n_phi)
        + n(s.n_theta)
        + n(s.ndf[0]) * n(s.ndf[1])
        + n(s.sigma[0]) * n(s.sigma[1])
        + slices * (vw * vh + (vh - 1) + vh * (vw - 1))
        + slices * (rw * rh + (rh - 1) + rh * (rw - 1))
        + slices * 3 * rw * rh
}

/// The material of a measured blob's two tensors: the shape read by [`shape`], the tables
/// tensor split without copying, and [`MeasuredMaterial::new`]'s checks.
///
/// # Errors
/// Those of [`shape`]; [`Error::TensorShape`] when the tables tensor's length does not match
/// the shape; those of [`MeasuredMaterial::new`].
pub(crate) fn material<'a>(
    shape_t: &Tensor<'a>,
    tables_t: &Tensor<'a>,
) -> Result<MeasuredMaterial<Tensor<'a>>> {
    let (shape, jacobian) = shape(shape_t)?;
    let total = tables_len(&shape);
    if u64::from(tables_t.len()) != total {
        return Err(Error::TensorShape {
            role: "tables",
            expected: total as u32,
            found: tables_t.len(),
        });
    }
    let mut parts = [Tensor::F32(&[]); 11];
    let mut at = 0u32;
    for (part, (role, len)) in parts.iter_mut().zip(shape.lens()) {
        *part = tables_t
            .range(at, len)
            .ok_or(Error::TensorBounds { role })?;
        at += len;
    }
    MeasuredMaterial::new(shape, MeasuredTables::from_array(parts), jacobian)
}

/// The running integrals of the VNDF and luminance slices against their values
/// ([`crate::distrib::marginal2d`]'s layout), and every slice normalised or empty.
///
/// # Errors
/// [`Error::TableNotNormalized`] naming the first integral that is off, or the last marginal
/// entry of a slice that integrates neither to 1 nor to 0.
pub(crate) fn check_integrals(m: &MeasuredMaterial<Tensor<'_>>) -> Result<()> {
    let (s, t) = (m.shape(), m.tables());
    let slices = s.slices();
    check_slices(
        ["vndf_marginal", "vndf_conditional"],
        [&t.vndf, &t.vndf_marginal, &t.vndf_conditional],
        s.vndf,
        slices,
    )?;
    check_slices(
        ["luminance_marginal", "luminance_conditional"],
        [
            &t.luminance,
            &t.luminance_marginal,
            &t.luminance_conditional,
        ],
        s.rgb,
        slices,
    )
}

fn close(stored: f32, exact: f64) -> bool {
    let d = f64::from(stored) - exact;
    let tol = INTEGRAL_RTOL * if exact < 0.0 { -exact } else { exact } + INTEGRAL_ATOL;
    d <= tol && d >= -tol
}

/// [`check_integrals`] for one table: `[data, marg, cond]`, slices of `[width, height]`.
fn check_slices(
    roles: [&'static str; 2],
    [data, marg, cond]: [&Tensor<'_>; 3],
    [w, h]: [u32; 2],
    slices: u32,
) -> Result<()> {
    let (sx, sy) = (0.5 / f64::from(w - 1), 0.5 / f64::from(h - 1));
    let value = |i: u32| f64::from(data.at(i));
    for s in 0..slices {
        let (d0, m0, c0) = (s * w * h, s * (h - 1), s * h * (w - 1));
        let (mut total, mut prev_row) = (0.0f64, 0.0f64);
        for y in 0..h {
            let mut row = 0.0f64;
            for x in 0..w - 1 {
                let i = d0 + y * w + x;
                row += sx * (value(i) + value(i + 1));
                let c = c0 + y * (w - 1) + x;
                if !close(cond.at(c), row) {
                    return Err(Error::TableNotNormalized {
                        role: roles[1],
                        index: c,
                    });
                }
            }
            if y > 0 {
                total += sy * (prev_row + row);
                let k = m0 + y - 1;
                if !close(marg.at(k), total) {
                    return Err(Error::TableNotNormalized {
                        role: roles[0],
                        index: k,
                    });
                }
            }
            prev_row = row;
        }
        // A slice integrates to 1, or is empty (all zero: the builder leaves it so).
        if !(close(1.0, total) || total == 0.0) {
            return Err(Error::TableNotNormalized {
                role: roles[0],
                index: m0 + h - 2,
            });
        }
    }
    Ok(())
}
