//! The histogram mixture's baked tables (`core/ARCHITECTURES.md` §6): the checks they must
//! pass before use ([`validate_tables`]) and, with the `alloc` feature, how they are built
//! from raw slice values ([`try_bake_slices`]).

#[cfg(feature = "alloc")]
use crate::distrib::table2d::running_sums;
use crate::distrib::table2d::{cell_area, cell_outside_disk, CDF_UNITS, MAX_N};
#[cfg(feature = "alloc")]
use crate::dtype::DType;
use crate::error::Error;
use crate::math;
use crate::weights::Weights;

/// Largest number of latent-code levels T a histogram mixture may have.
pub const MAX_T: usize = 256;
/// Number of basis histograms K of the histogram mixture (paper §3.3: K = 10).
pub const BASES: usize = 10;

/// Relative tolerance of [`validate_tables`] on each slice's integral.
pub const INTEGRAL_TOLERANCE: f64 = 1e-3;
/// Relative tolerance of [`validate_tables`] on the running sums (see there).
pub const CDF_TOLERANCE: f64 = 1e-4;

fn shape(role: &'static str, len: u32, expected: u64) -> Result<(), Error> {
    if u64::from(len) == expected {
        Ok(())
    } else {
        Err(Error::TensorShape {
            role,
            expected: if expected > u64::from(u32::MAX) {
                u32::MAX
            } else {
                expected as u32
            },
            found: len,
        })
    }
}

fn dim(what: &'static str, found: u32, lo: u32, hi: u32) -> Result<(), Error> {
    if found >= lo && found <= hi {
        Ok(())
    } else {
        Err(Error::DimensionMismatch {
            what,
            expected: hi,
            found,
        })
    }
}

/// Dimension limits and tensor lengths of a set of baked tables; `table` is `None` for
/// compact tables ([`TableLayout::Compact`](crate::distrib::table2d::TableLayout::Compact)),
/// which store no values.
pub(crate) fn table_shapes<W: Weights + ?Sized>(
    mass: &W,
    table: Option<&W>,
    marginal: &W,
    conditional: &W,
    bases: u32,
    t_levels: u32,
    resolution: u32,
) -> Result<(), Error> {
    dim("basis", bases, 1, BASES as u32)?;
    dim("t_levels", t_levels, 1, MAX_T as u32)?;
    dim("resolution", resolution, 1, MAX_N as u32)?;
    let slices = u64::from(bases) * u64::from(t_levels);
    let n = u64::from(resolution);
    shape("mass", mass.len(), slices)?;
    if let Some(table) = table {
        shape("table", table.len(), slices * n * n)?;
    }
    shape("marginal", marginal.len(), slices * n)?;
    shape("conditional", conditional.len(), slices * n * n)?;
    Ok(())
}

/// Checks compact histogram-mixture tables
/// ([`TableLayout::Compact`](crate::distrib::table2d::TableLayout::Compact)) before use; the
/// blob loader calls this for every compact histogram-mixture blob.
///
/// Dimensions and lengths as [`validate_tables`] (no values tensor); every value finite;
/// `mass ≥ 0`; `marginal` non-negative, non-decreasing within each slice and each slice's
/// `marginal[N − 1] · h²` within [`INTEGRAL_TOLERANCE`] of 1; every `conditional` entry an
/// integer in `0 ..= CDF_UNITS`, non-decreasing within each row, a row whose total is
/// positive ending at exactly `CDF_UNITS` and an empty row all zero, and no step on a cell
/// entirely outside the disk ([`Error::TableNotNormalized`] with the flat index of the first
/// bad element, or the slice index for an integral).
pub fn validate_compact_tables<W: Weights + ?Sized>(
    mass: &W,
    marginal: &W,
    conditional: &W,
    bases: u32,
    t_levels: u32,
    resolution: u32,
) -> Result<(), Error> {
    table_shapes(
        mass,
        None,
        marginal,
        conditional,
        bases,
        t_levels,
        resolution,
    )?;
    all_finite("mass", mass)?;
    all_finite("marginal", marginal)?;
    all_finite("conditional", conditional)?;
    let bad = |role: &'static str, index: u32| Err(Error::TableNotNormalized { role, index });
    let n = resolution;
    let area = f64::from(cell_area(n));
    let slices = bases * t_levels;
    let mut s = 0;
    while s < slices {
        if !(mass.at(s) >= 0.0) {
            return bad("mass", s);
        }
        let mut prev_m = 0.0f32;
        let mut r = 0;
        while r < n {
            let i = s * n + r;
            let m = marginal.at(i);
            if !(m >= prev_m) {
                return bad("marginal", i);
            }
            let row_total = m - prev_m;
            let mut prev_c = 0.0f32;
            let mut c = 0;
            while c < n {
                let j = s * n * n + r * n + c;
                let v = conditional.at(j);
                let integer = v >= 0.0 && v <= CDF_UNITS && v == libm::floorf(v);
                let step = v - prev_c;
                if !integer || step < 0.0 || (step > 0.0 && cell_outside_disk(r, c, n)) {
                    return bad("conditional", j);
                }
                prev_c = v;
                c += 1;
            }
            let end = if row_total > 0.0 { CDF_UNITS } else { 0.0 };
            if prev_c != end {
                return bad("conditional", s * n * n + r * n + n - 1);
            }
            prev_m = m;
            r += 1;
        }
        if !(libm::fabs(f64::from(prev_m) * area - 1.0) <= INTEGRAL_TOLERANCE) {
            return bad("marginal", s);
        }
        s += 1;
    }
    Ok(())
}

fn all_finite<W: Weights + ?Sized>(role: &'static str, w: &W) -> Result<(), Error> {
    let mut i = 0;
    while i < w.len() {
        if !math::is_finite(w.at(i)) {
            return Err(Error::NonFinite { role, index: i });
        }
        i += 1;
    }
    Ok(())
}

/// Checks baked histogram-mixture tables (`ARCHITECTURES.md` §6) before use; the blob loader
/// calls this for every histogram-mixture blob.
///
/// For `bases` = K (1 ..= [`BASES`]), `t_levels` = T (1 ..= [`MAX_T`]) and `resolution` = N
/// (1 ..= [`MAX_N`]):
///
/// * lengths K·T, K·T·N², K·T·N, K·T·N² ([`Error::DimensionMismatch`], [`Error::TensorShape`]);
/// * every value finite ([`Error::NonFinite`]);
/// * `mass` and `table` non-negative, `table` exactly 0 on cells entirely outside the disk
///   ([`cell_outside_disk`]), each slice integrating to 1 (`|Σ value · h² − 1| ≤`
///   [`INTEGRAL_TOLERANCE`]);
/// * `conditional` non-decreasing within each row and within [`CDF_TOLERANCE`]` · row total +
///   10⁻⁶ · slice total` of the running sums of the values; `marginal` non-decreasing and
///   within [`CDF_TOLERANCE`]` · slice total` of the running sums of the row totals
///   ([`Error::TableNotNormalized`], with the flat index of the first bad element, or the
///   slice index for an integral).
///
/// Reference sums are accumulated in f64. CDFs stored as f16 cannot meet the tolerance: store
/// `marginal` and `conditional` as f32.
pub fn validate_tables<W: Weights + ?Sized>(
    mass: &W,
    table: &W,
    marginal: &W,
    conditional: &W,
    bases: u32,
    t_levels: u32,
    resolution: u32,
) -> Result<(), Error> {
    let (k, t, n) = (bases, t_levels, resolution);
    table_shapes(mass, Some(table), marginal, conditional, k, t, n)?;
    all_finite("mass", mass)?;
    all_finite("table", table)?;
    all_finite("marginal", marginal)?;
    all_finite("conditional", conditional)?;
    let bad = |role: &'static str, index: u32| Err(Error::TableNotNormalized { role, index });

    let n = resolution;
    let nn = n * n;
    let area = f64::from(cell_area(n));
    let slices = bases * t_levels;
    let mut s = 0;
    while s < slices {
        if !(mass.at(s) >= 0.0) {
            return bad("mass", s);
        }
        // Values: sign, mask, integral.
        let mut total = 0.0f64;
        let mut r = 0;
        while r < n {
            let mut c = 0;
            while c < n {
                let i = s * nn + r * n + c;
                let v = table.at(i);
                if !(v >= 0.0) || (v != 0.0 && cell_outside_disk(r, c, n)) {
                    return bad("table", i);
                }
                total += f64::from(v);
                c += 1;
            }
            r += 1;
        }
        if !(libm::fabs(total * area - 1.0) <= INTEGRAL_TOLERANCE) {
            return bad("table", s);
        }
        // Running sums.
        let mut run = 0.0f64;
        let mut prev_m = 0.0f32;
        r = 0;
        while r < n {
            let mut row = 0.0f64;
            let mut c = 0;
            while c < n {
                row += f64::from(table.at(s * nn + r * n + c));
                c += 1;
            }
            let tol_c = CDF_TOLERANCE * row + 1e-6 * total;
            let mut acc = 0.0f64;
            let mut prev_c = 0.0f32;
            c = 0;
            while c < n {
                let i = s * nn + r * n + c;
                acc += f64::from(table.at(i));
                let cv = conditional.at(i);
                if cv < prev_c || !(libm::fabs(f64::from(cv) - acc) <= tol_c) {
                    return bad("conditional", i);
                }
                prev_c = cv;
                c += 1;
            }
            run += row;
            let i = s * n + r;
            let mv = marginal.at(i);
            if mv < prev_m || !(libm::fabs(f64::from(mv) - run) <= CDF_TOLERANCE * total) {
                return bad("marginal", i);
            }
            prev_m = mv;
            r += 1;
        }
        s += 1;
    }
    Ok(())
}

/// Baked histogram-mixture tables (host side), laid out as `ARCHITECTURES.md` §6 and ready to
/// pass to [`HistogramMixtureSampler::new`](crate::samplers::HistogramMixtureSampler::new)
/// (as `&[f32]`) or to a blob writer.
#[cfg(feature = "alloc")]
#[derive(Clone, Debug, PartialEq)]
pub struct BakedTables {
    /// K × T: the integral of each raw slice over the cells not entirely outside the disk.
    pub mass: alloc::vec::Vec<f32>,
    /// K × T × N × N: normalised densities (each slice integrates to 1), rounded to the
    /// storage type.
    pub table: alloc::vec::Vec<f32>,
    /// K × T × N: running sums of row totals of `table`.
    pub marginal: alloc::vec::Vec<f32>,
    /// K × T × N × N: running sums within each row of `table`.
    pub conditional: alloc::vec::Vec<f32>,
    /// K.
    pub bases: u32,
    /// T.
    pub t_levels: u32,
    /// N.
    pub resolution: u32,
}

#[cfg(feature = "alloc")]
impl BakedTables {
    /// [`validate_tables`] on these tables.
    pub fn validate(&self) -> Result<(), Error> {
        validate_tables(
            self.mass.as_slice(),
            self.table.as_slice(),
            self.marginal.as_slice(),
            self.conditional.as_slice(),
            self.bases,
            self.t_levels,
            self.resolution,
        )
    }
}

/// [`try_bake_slices`] for input known to be valid (the trainer's softplus outputs, tests).
///
/// # Panics
///
/// When [`try_bake_slices`] returns an error (wrong dimensions or length, NaN, ∞ or
/// negative values).
#[cfg(feature = "alloc")]
#[must_use]
pub fn bake_slices(
    raw: &[f32],
    bases: usize,
    t_levels: usize,
    resolution: usize,
    storage: DType,
) -> BakedTables {
    match try_bake_slices(raw, bases, t_levels, resolution, storage) {
        Ok(t) => t,
        Err(e) => panic!("bake_slices: {e}"),
    }
}

/// Bakes raw per-slice values into histogram-mixture tables.
///
/// `raw` holds K × T slices of `N × N` non-negative values (rows = y, as the tables), e.g.
/// the training model's basis `k` at level `t` evaluated at cell centres. For each slice:
/// cells entirely outside the disk are set to 0; `mass` = `Σ value · h²` (f64, stored f32);
/// the table is `value / mass`, then rounded to `storage` (f16 rounding happens *before* the
/// running sums, which are built by [`running_sums`] from the rounded values, so the CDFs
/// match the stored table exactly). A slice with no mass becomes uniform over the cells not
/// entirely outside the disk, with `mass` 0 (it then never receives weight unless every basis
/// is empty).
///
/// Errors: dimensions as in [`validate_tables`], [`Error::TensorShape`] for a `raw` of the
/// wrong length, [`Error::NonFinite`] / [`Error::TableNotNormalized`] (role `"raw"`) for NaN,
/// infinite or negative input.
#[cfg(feature = "alloc")]
pub fn try_bake_slices(
    raw: &[f32],
    bases: usize,
    t_levels: usize,
    resolution: usize,
    storage: DType,
) -> Result<BakedTables, Error> {
    use alloc::vec;
    let to_u32 = |x: usize| u32::try_from(x).unwrap_or(u32::MAX);
    let (bases, t_levels, resolution) = (to_u32(bases), to_u32(t_levels), to_u32(resolution));
    dim("basis", bases, 1, BASES as u32)?;
    dim("t_levels", t_levels, 1, MAX_T as u32)?;
    dim("resolution", resolution, 1, MAX_N as u32)?;
    let n = resolution as usize;
    let nn = n * n;
    let slices = (bases * t_levels) as usize;
    if raw.len() != slices * nn {
        return Err(Error::TensorShape {
            role: "raw",
            expected: (slices * nn) as u32,
            found: to_u32(raw.len()),
        });
    }
    if storage == DType::U16 {
        // Values are densities; quantised CDFs are the compact layout (`try_bake_compact`).
        return Err(Error::TensorDType {
            role: "table",
            found: storage,
        });
    }
    let area = f64::from(cell_area(resolution));
    let round = |v: f64| -> f32 {
        let v = v as f32;
        match storage {
            DType::F16 => half::f16::from_f32(v).to_f32(),
            DType::F32 | DType::U16 => v,
        }
    };
    let mut out = BakedTables {
        mass: vec![0.0; slices],
        table: vec![0.0; slices * nn],
        marginal: vec![0.0; slices * n],
        conditional: vec![0.0; slices * nn],
        bases,
        t_levels,
        resolution,
    };
    let inside = |i: usize| !cell_outside_disk((i / n) as u32, (i % n) as u32, resolution);
    let inside_cells = (0..nn).filter(|&i| inside(i)).count();
    for s in 0..slices {
        let mut sum = 0.0f64;
        for i in 0..nn {
            let v = raw[s * nn + i];
            if !v.is_finite() {
                return Err(Error::NonFinite {
                    role: "raw",
                    index: (s * nn + i) as u32,
                });
            }
            if v < 0.0 {
                return Err(Error::TableNotNormalized {
                    role: "raw",
                    index: (s * nn + i) as u32,
                });
            }
            if inside(i) {
                sum += f64::from(v);
            }
        }
        let mass = sum * area;
        let dst = &mut out.table[s * nn..(s + 1) * nn];
        if mass > 0.0 && mass.is_finite() {
            out.mass[s] = mass as f32;
            for i in 0..nn {
                if inside(i) {
                    dst[i] = round(f64::from(raw[s * nn + i]) / mass);
                }
            }
        } else {
            let uniform = round(1.0 / (inside_cells as f64 * area));
            for i in 0..nn {
                if inside(i) {
                    dst[i] = uniform;
                }
            }
        }
    }
    running_sums(
        &out.table,
        resolution,
        &mut out.marginal,
        &mut out.conditional,
    );
    Ok(out)
}

/// Compact histogram-mixture tables (host side,
/// [`TableLayout::Compact`](crate::distrib::table2d::TableLayout::Compact)), ready to pass to
/// [`HistogramMixtureSampler::new_compact`](crate::samplers::HistogramMixtureSampler::new_compact)
/// or to a blob writer.
#[cfg(feature = "alloc")]
#[derive(Clone, Debug, PartialEq)]
pub struct CompactTables {
    /// K × T: the integral of each raw slice over the cells not entirely outside the disk.
    pub mass: alloc::vec::Vec<f32>,
    /// K × T × N: running sums of the row totals of each normalised slice (f32, in index
    /// order).
    pub marginal: alloc::vec::Vec<f32>,
    /// K × T × N × N: each row's CDF in units of `CDF_UNITS`.
    pub conditional: alloc::vec::Vec<u16>,
    /// K.
    pub bases: u32,
    /// T.
    pub t_levels: u32,
    /// N.
    pub resolution: u32,
}

#[cfg(feature = "alloc")]
impl CompactTables {
    /// The conditional CDFs as f32 values (exact), as a sampler over host arrays reads them.
    #[must_use]
    pub fn conditional_f32(&self) -> alloc::vec::Vec<f32> {
        self.conditional.iter().map(|&v| f32::from(v)).collect()
    }

    /// [`validate_compact_tables`] on these tables.
    pub fn validate(&self) -> Result<(), Error> {
        validate_compact_tables(
            self.mass.as_slice(),
            self.marginal.as_slice(),
            self.conditional_f32().as_slice(),
            self.bases,
            self.t_levels,
            self.resolution,
        )
    }
}

/// [`try_bake_slices`] into the compact layout: per slice the same masking, mass and
/// normalisation; each row's total `R` goes into the f32 running sums `marginal`, and its CDF
/// is quantised to integers ending at exactly `CDF_UNITS`: each cell gets its share of the
/// units rounded by largest remainders (ties to the lower column), then every cell with a
/// positive value that got none takes one unit from the row's largest cell, so no cell with
/// mass is dropped and every other cell is within one unit of its share. A row whose total
/// does not move the f32 running sum (absorbed by rounding) is stored empty: its stored mass
/// is zero. Errors as [`try_bake_slices`].
#[cfg(feature = "alloc")]
pub fn try_bake_compact(
    raw: &[f32],
    bases: usize,
    t_levels: usize,
    resolution: usize,
) -> Result<CompactTables, Error> {
    use alloc::vec;
    let baked = try_bake_slices(raw, bases, t_levels, resolution, DType::F32)?;
    let (bases, t_levels, resolution) = (baked.bases, baked.t_levels, baked.resolution);
    let n = resolution as usize;
    let slices = (bases * t_levels) as usize;
    let mut out = CompactTables {
        mass: baked.mass.clone(),
        marginal: vec![0.0; slices * n],
        conditional: vec![0; slices * n * n],
        bases,
        t_levels,
        resolution,
    };
    let units = CDF_UNITS as u32;
    let mut counts: vec::Vec<u32> = vec![0; n];
    let mut rem: vec::Vec<(f64, usize)> = vec::Vec::with_capacity(n);
    for s in 0..slices {
        let mut run = 0.0f32;
        for r in 0..n {
            let row = &baked.table[(s * n + r) * n..(s * n + r + 1) * n];
            let total: f64 = row.iter().map(|&v| f64::from(v)).sum();
            let next = run + total as f32;
            let dst = &mut out.conditional[(s * n + r) * n..(s * n + r + 1) * n];
            if total > 0.0 && next > run {
                rem.clear();
                let mut given = 0u32;
                for (c, &v) in row.iter().enumerate() {
                    let share = f64::from(units) * f64::from(v) / total;
                    counts[c] = share.floor() as u32;
                    given += counts[c];
                    rem.push((share - share.floor(), c));
                }
                rem.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
                for &(_, c) in rem.iter().take((units - given) as usize) {
                    counts[c] += 1;
                }
                for c in 0..n {
                    if row[c] > 0.0 && counts[c] == 0 {
                        let big = (0..n).max_by_key(|&i| (counts[i], n - i)).unwrap_or(c);
                        counts[big] -= 1;
                        counts[c] = 1;
                    }
                }
                let mut acc = 0u32;
                for (d, k) in dst.iter_mut().zip(&counts) {
                    acc += k;
                    *d = acc as u16;
                }
                run = next;
            }
            out.marginal[s * n + r] = run;
        }
    }
    Ok(out)
}
