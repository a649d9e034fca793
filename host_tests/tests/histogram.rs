//! Histogram tables and samplers (`neusample::distrib::table2d`, `neusample::samplers::{direct_histogram, histogram_mixture}`): baking and validation of tables,
//! `Table2D` sample/pdf/invert (single slices and linear blends), the direct histogram
//! baseline and the histogram mixture (paper Eq. 5–6) with random weights and random baked
//! tables: sample/pdf consistency, mass on the disk, χ², inverses, hostile input.

use neusample::distrib::gaussian::select_component;
use neusample::distrib::table2d::{cell_area, cell_outside_disk, running_sums};
use neusample::samplers::direct_histogram::DIRECT_N;
use neusample::samplers::histogram_mixture::{
    bake_slices, try_bake_compact, try_bake_slices, validate_compact_tables, validate_tables,
    BakedTables, CompactTables, BASES, MAX_N, MAX_T,
};
use neusample::samplers::{
    DirectHistogramPrepared, DirectHistogramSampler, HistogramMixtureSampler,
};
use neusample::{DType, Error, Prepared, Sampler, Vec2, Vec3, FEATURE_DIM};
use neusample::{Interpolation, Table2D};
use neusample_host_tests::{
    bonferroni, chi2_checked, disk_integral, full_tests, pooled_chi2, rng, uniform2, TestRng,
};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use rand::RngExt;
use statrs::distribution::{ChiSquared, ContinuousCDF};

// ---------------------------------------------------------------------------------------
// Random models and tables
// ---------------------------------------------------------------------------------------

fn uniform(r: &mut TestRng, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * r.random::<f32>()
}

/// Random dense layers (input-major weights then bias), weight variance 1/fan_in.
fn random_mlp(r: &mut TestRng, layers: &[(usize, usize)], out_scale: f32) -> Vec<f32> {
    let mut p = Vec::new();
    for (li, &(i, o)) in layers.iter().enumerate() {
        let last = li + 1 == layers.len();
        let s = (3.0 / i as f32).sqrt() * if last { out_scale } else { 1.0 };
        for _ in 0..i * o {
            p.push((r.random::<f32>() * 2.0 - 1.0) * s);
        }
        for _ in 0..o {
            p.push((r.random::<f32>() * 2.0 - 1.0) * 0.1);
        }
    }
    p
}

fn direct_params(r: &mut TestRng) -> Vec<f32> {
    random_mlp(r, &[(30, 64), (64, 64), (64, 256)], 2.0)
}

fn mixture_params(r: &mut TestRng) -> Vec<f32> {
    let mut p = random_mlp(r, &[(10, 32), (32, 32), (32, 32), (32, 40)], 1.0);
    let n = p.len();
    for k in 0..BASES {
        p[n - 40 + 4 * k] = uniform(r, -1.5, 1.5);
        p[n - 40 + 4 * k + 1] = uniform(r, -1.0, 1.0);
        p[n - 40 + 4 * k + 2] = uniform(r, -1.0, 1.0);
        p[n - 40 + 4 * k + 3] = uniform(r, -2.0, 2.0);
    }
    p
}

fn random_condition(r: &mut TestRng) -> ([f32; FEATURE_DIM], Vec3) {
    let mut phi = [0.0; FEATURE_DIM];
    for v in &mut phi {
        *v = uniform(r, -1.5, 1.5);
    }
    let (a, rad) = (
        uniform(r, 0.0, std::f32::consts::TAU),
        0.97 * r.random::<f32>().sqrt(),
    );
    let (x, y) = (rad * a.cos(), rad * a.sin());
    (phi, Vec3::new(x, y, (1.0 - x * x - y * y).sqrt()))
}

/// Raw slice values: an anisotropic Gaussian blob plus a floor, with ~20 % of the cells set
/// to zero; about one slice in 12 is entirely zero (baked as uniform with mass 0).
fn random_raw(r: &mut TestRng, slices: usize, n: usize) -> Vec<f32> {
    let mut raw = Vec::with_capacity(slices * n * n);
    for _ in 0..slices {
        let empty = r.random::<f32>() < 1.0 / 12.0;
        let (cx, cy) = (uniform(r, -0.6, 0.6), uniform(r, -0.6, 0.6));
        let (sx, sy) = (uniform(r, 0.1, 0.6), uniform(r, 0.1, 0.6));
        let floor = if r.random::<bool>() {
            uniform(r, 0.0, 0.3)
        } else {
            0.0
        };
        let scale = uniform(r, 0.1, 5.0);
        for row in 0..n {
            for col in 0..n {
                let x = -1.0 + (col as f32 + 0.5) * 2.0 / n as f32;
                let y = -1.0 + (row as f32 + 0.5) * 2.0 / n as f32;
                let g =
                    (-0.5 * ((x - cx).powi(2) / (sx * sx) + (y - cy).powi(2) / (sy * sy))).exp();
                let v = if empty || r.random::<f32>() < 0.2 {
                    0.0
                } else {
                    scale * (g + floor)
                };
                raw.push(v);
            }
        }
    }
    raw
}

fn random_tables(r: &mut TestRng, k: usize, t: usize, n: usize, dtype: DType) -> BakedTables {
    bake_slices(&random_raw(r, k * t, n), k, t, n, dtype)
}

fn mixture<'a>(
    params: &'a [f32],
    b: &'a BakedTables,
    interpolation: Interpolation,
) -> HistogramMixtureSampler<&'a [f32]> {
    HistogramMixtureSampler::new(
        params,
        &b.mass[..],
        &b.table[..],
        &b.marginal[..],
        &b.conditional[..],
        b.t_levels,
        b.resolution,
        interpolation,
    )
    .expect("valid mixture")
}

fn view(b: &BakedTables, s0: u32, s1: u32, a: f32) -> Table2D<&[f32]> {
    Table2D::lerp(
        &b.table[..],
        &b.marginal[..],
        &b.conditional[..],
        b.resolution,
        s0,
        s1,
        a,
    )
    .expect("valid view")
}

// ---------------------------------------------------------------------------------------
// Shared checks
// ---------------------------------------------------------------------------------------

/// Draws `count` samples and checks them against the pdf. Returns (inside count, max
/// relative |pdf(wo) − sample.pdf| / sample.pdf).
fn check_samples<P: Prepared>(p: &P, r: &mut TestRng, count: usize) -> (usize, f64) {
    let mut inside = 0;
    let mut worst = 0.0f64;
    for _ in 0..count {
        let Some(s) = p.sample(uniform2(r)) else {
            continue;
        };
        inside += 1;
        assert!(s.wo.z > 0.0 && s.pdf > 0.0 && s.pdf.is_finite(), "{s:?}");
        assert_eq!(s.pdf, s.pdf_disk * s.wo.z);
        assert_eq!(p.pdf_disk(Vec2::new(s.wo.x, s.wo.y)), s.pdf_disk);
        let q = p.pdf(s.wo);
        worst = worst.max(f64::from((q - s.pdf).abs() / s.pdf));
    }
    (inside, worst)
}

/// Exact χ² of a table's sampled cell frequencies against its cell probabilities.
fn table_cell_chi2(v: &Table2D<&[f32]>, r: &mut TestRng, samples: usize) -> f64 {
    let n = v.resolution() as usize;
    let mut observed = vec![0.0f64; n * n];
    for _ in 0..samples {
        let (p, _) = v.sample(uniform2(r)).expect("positive table");
        let c = (((p.x + 1.0) * 0.5 * n as f32).floor() as usize).min(n - 1);
        let rr = (((p.y + 1.0) * 0.5 * n as f32).floor() as usize).min(n - 1);
        observed[rr * n + c] += 1.0;
    }
    let area = f64::from(cell_area(n as u32));
    let expected: Vec<f64> = (0..n * n)
        .map(|i| {
            let centre = Vec2::new(
                -1.0 + ((i % n) as f32 + 0.5) * 2.0 / n as f32,
                -1.0 + ((i / n) as f32 + 0.5) * 2.0 / n as f32,
            );
            f64::from(v.pdf(centre)) * area * samples as f64
        })
        .collect();
    let (stat, cells) = pooled_chi2(&observed, &expected, 5.0);
    ChiSquared::new(cells.saturating_sub(1).max(1) as f64)
        .map(|d| d.sf(stat))
        .unwrap_or(0.0)
}

// ---------------------------------------------------------------------------------------
// Grid helpers, baking, validation
// ---------------------------------------------------------------------------------------

#[test]
fn cell_mask_matches_geometry() {
    for n in 1..=70u32 {
        for r in 0..n {
            for c in 0..n {
                let h = 2.0 / f64::from(n);
                let near = |i: u32| {
                    let (lo, hi) = (-1.0 + f64::from(i) * h, -1.0 + f64::from(i + 1) * h);
                    if lo > 0.0 {
                        lo
                    } else if hi < 0.0 {
                        -hi
                    } else {
                        0.0
                    }
                };
                let d2 = near(r).powi(2) + near(c).powi(2);
                // Skip cells touching the circle at a corner (distance exactly 1 in exact
                // arithmetic, where f64 rounding could go either way).
                if (d2 - 1.0).abs() < 1e-12 {
                    continue;
                }
                assert_eq!(
                    cell_outside_disk(r, c, n),
                    d2 >= 1.0,
                    "n {n} cell ({r}, {c})"
                );
            }
        }
    }
    let inside = (0..256)
        .filter(|&i| !cell_outside_disk(i / 16, i % 16, 16))
        .count();
    eprintln!("16 × 16 grid: {inside} cells not entirely outside the disk");
    assert_eq!(inside, 224); // 8 corner cells per quadrant are outside
}

#[test]
fn bake_produces_valid_tables() {
    let mut r = rng(0xba4e);
    for &(k, t, n) in &[
        (1, 1, 1),
        (1, 1, 2),
        (2, 3, 5),
        (3, 2, 16),
        (10, 4, 8),
        (1, 2, 64),
    ] {
        for dtype in [DType::F32, DType::F16] {
            let raw = random_raw(&mut r, k * t, n);
            let b = bake_slices(&raw, k, t, n, dtype);
            b.validate()
                .unwrap_or_else(|e| panic!("K{k} T{t} N{n} {dtype:?}: {e}"));
            let nn = n * n;
            let area = f64::from(cell_area(n as u32));
            let mut worst = 0.0f64;
            for s in 0..k * t {
                let slice = &b.table[s * nn..(s + 1) * nn];
                let integral: f64 = slice.iter().map(|&v| f64::from(v)).sum::<f64>() * area;
                worst = worst.max((integral - 1.0).abs());
                // Mass: the f64 integral of the raw values on cells not outside the disk.
                let m: f64 = (0..nn)
                    .filter(|&i| !cell_outside_disk((i / n) as u32, (i % n) as u32, n as u32))
                    .map(|i| f64::from(raw[s * nn + i]))
                    .sum::<f64>()
                    * area;
                assert!((f64::from(b.mass[s]) - m).abs() <= 1e-6 * m.max(1e-30));
                for i in 0..nn {
                    if cell_outside_disk((i / n) as u32, (i % n) as u32, n as u32) {
                        assert_eq!(slice[i], 0.0);
                    }
                    if dtype == DType::F16 {
                        // Stored values are exactly f16-representable.
                        let v = half::f16::from_f32(slice[i]).to_f32();
                        assert_eq!(v, slice[i]);
                    }
                }
            }
            // The CDFs are exactly the f32 running sums of the stored values.
            let mut m2 = vec![0.0; b.marginal.len()];
            let mut c2 = vec![0.0; b.conditional.len()];
            running_sums(&b.table, n as u32, &mut m2, &mut c2);
            assert_eq!(m2, b.marginal);
            assert_eq!(c2, b.conditional);
            eprintln!("bake K{k} T{t} N{n} {dtype:?}: max |∫slice − 1| = {worst:.2e}");
            assert!(worst < if dtype == DType::F32 { 1e-5 } else { 1e-3 });
        }
    }
}

#[test]
fn bake_rejects_bad_raw() {
    let good = vec![1.0f32; 2 * 4 * 4];
    assert!(try_bake_slices(&good, 1, 2, 4, DType::F32).is_ok());
    let mut bad = good.clone();
    bad[5] = f32::NAN;
    assert_eq!(
        try_bake_slices(&bad, 1, 2, 4, DType::F32),
        Err(Error::NonFinite {
            role: "raw",
            index: 5
        })
    );
    bad[5] = -1.0;
    assert!(matches!(
        try_bake_slices(&bad, 1, 2, 4, DType::F32),
        Err(Error::TableNotNormalized {
            role: "raw",
            index: 5
        })
    ));
    assert!(matches!(
        try_bake_slices(&good[1..], 1, 2, 4, DType::F32),
        Err(Error::TensorShape { .. })
    ));
    assert!(matches!(
        try_bake_slices(&good, 1, 2, 0, DType::F32),
        Err(Error::DimensionMismatch { .. })
    ));
    assert!(try_bake_slices(&[], 1, MAX_T + 1, 1, DType::F32).is_err());
    assert!(try_bake_slices(&[], BASES + 1, 1, 1, DType::F32).is_err());
    // An all-zero slice becomes uniform over the disk cells, with mass 0.
    let b = bake_slices(&[0.0; 16], 1, 1, 4, DType::F32);
    assert_eq!(b.mass, vec![0.0]);
    let inside: Vec<f32> = b.table.iter().copied().filter(|&v| v > 0.0).collect();
    assert_eq!(inside.len(), 16); // at N = 4 every cell reaches into the disk
    b.validate().unwrap();
}

fn validate(b: &BakedTables) -> Result<(), Error> {
    validate_tables(
        &b.mass[..],
        &b.table[..],
        &b.marginal[..],
        &b.conditional[..],
        b.bases,
        b.t_levels,
        b.resolution,
    )
}

#[test]
fn validate_rejects_broken_tables() {
    let mut r = rng(0x7a1);
    let (k, t, n) = (2usize, 3usize, 8usize);
    let b0 = random_tables(&mut r, k, t, n, DType::F32);
    validate(&b0).unwrap();
    let nn = n * n;
    let centre = 3 * n + 4; // a cell well inside the disk
    let corner = 0; // cell (0, 0): entirely outside the disk at N = 8
    assert!(cell_outside_disk(0, 0, n as u32));
    let slice = 4;
    let i = slice * nn + centre;

    let mut b = b0.clone();
    b.table[i] = f32::NAN;
    assert_eq!(
        validate(&b),
        Err(Error::NonFinite {
            role: "table",
            index: i as u32
        })
    );
    let mut b = b0.clone();
    b.marginal[3] = f32::INFINITY;
    assert_eq!(
        validate(&b),
        Err(Error::NonFinite {
            role: "marginal",
            index: 3
        })
    );
    let mut b = b0.clone();
    b.conditional[7] = f32::NEG_INFINITY;
    assert_eq!(
        validate(&b),
        Err(Error::NonFinite {
            role: "conditional",
            index: 7
        })
    );
    let mut b = b0.clone();
    b.mass[1] = f32::NAN;
    assert_eq!(
        validate(&b),
        Err(Error::NonFinite {
            role: "mass",
            index: 1
        })
    );

    // Negative values.
    let mut b = b0.clone();
    b.table[i] = -1e-3;
    assert_eq!(
        validate(&b),
        Err(Error::TableNotNormalized {
            role: "table",
            index: i as u32
        })
    );
    let mut b = b0.clone();
    b.mass[2] = -1.0;
    assert_eq!(
        validate(&b),
        Err(Error::TableNotNormalized {
            role: "mass",
            index: 2
        })
    );

    // Unnormalised slice, with CDFs rebuilt so that only the integral is wrong.
    let mut b = b0.clone();
    for v in &mut b.table[slice * nn..(slice + 1) * nn] {
        *v *= 1.01;
    }
    running_sums(
        &b.table.clone(),
        n as u32,
        &mut b.marginal,
        &mut b.conditional,
    );
    assert_eq!(
        validate(&b),
        Err(Error::TableNotNormalized {
            role: "table",
            index: slice as u32
        })
    );
    // Within tolerance (0.05 %) passes.
    let mut b = b0.clone();
    for v in &mut b.table[slice * nn..(slice + 1) * nn] {
        *v *= 1.0005;
    }
    running_sums(
        &b.table.clone(),
        n as u32,
        &mut b.marginal,
        &mut b.conditional,
    );
    validate(&b).unwrap();

    // Density on a cell entirely outside the disk (integral and CDFs otherwise fine).
    let mut b = b0.clone();
    b.table[slice * nn + corner] = 1e-3;
    let j = slice * nn + corner;
    assert_eq!(
        validate(&b),
        Err(Error::TableNotNormalized {
            role: "table",
            index: j as u32
        })
    );

    // CDF inconsistent with the values.
    let mut b = b0.clone();
    let row = centre / n;
    let row_total = b0.conditional[slice * nn + row * n + n - 1];
    b.conditional[i] += 1e-3 * row_total.max(1.0);
    assert_eq!(
        validate(&b),
        Err(Error::TableNotNormalized {
            role: "conditional",
            index: i as u32
        })
    );
    let mut b = b0.clone();
    let total = b0.marginal[slice * n + n - 1];
    b.marginal[slice * n + 3] += 1e-3 * total;
    assert_eq!(
        validate(&b),
        Err(Error::TableNotNormalized {
            role: "marginal",
            index: (slice * n + 3) as u32
        })
    );
    // A decreasing conditional.
    let mut b = b0.clone();
    let j = slice * nn + row * n + 2;
    b.conditional.swap(j, j + 1);
    if b.conditional[j] != b.conditional[j + 1] {
        assert!(validate(&b).is_err());
    }
    // CDFs stored as f16 are too coarse.
    let mut b = b0.clone();
    for v in b.marginal.iter_mut().chain(b.conditional.iter_mut()) {
        *v = half::f16::from_f32(*v).to_f32();
    }
    let e = validate(&b);
    eprintln!("f16-rounded CDFs: {e:?}");
    assert!(matches!(e, Err(Error::TableNotNormalized { .. })));

    // Shapes and dimensions.
    let b = b0.clone();
    let short = &b.table[1..];
    assert!(matches!(
        validate_tables(
            &b.mass[..],
            short,
            &b.marginal[..],
            &b.conditional[..],
            2,
            3,
            8
        ),
        Err(Error::TensorShape { role: "table", .. })
    ));
    assert!(matches!(
        validate_tables(
            &b.mass[..],
            &b.table[..],
            &b.marginal[..],
            &b.conditional[..],
            2,
            3,
            7
        ),
        Err(Error::TensorShape { role: "mass", .. }) | Err(Error::TensorShape { .. })
    ));
    let e = validate_tables(
        &[0.0f32][..],
        &[][..],
        &[][..],
        &[][..],
        1,
        1,
        MAX_N as u32 + 1,
    );
    assert!(matches!(
        e,
        Err(Error::DimensionMismatch {
            what: "resolution",
            ..
        })
    ));
    let e = validate_tables(&[][..], &[][..], &[][..], &[][..], 1, 0, 4);
    assert!(matches!(
        e,
        Err(Error::DimensionMismatch {
            what: "t_levels",
            ..
        })
    ));
}

// ---------------------------------------------------------------------------------------
// Table2D
// ---------------------------------------------------------------------------------------

#[test]
fn table_sample_invert_roundtrip() {
    let mut r = rng(0x1e5);
    let mut worst_u = 0.0f32;
    let mut worst_p = 0.0f32;
    let mut refused = 0usize;
    let mut drawn = 0usize;
    for &(k, t, n, dtype) in &[
        (1, 2, 1, DType::F32),
        (1, 3, 3, DType::F32),
        (2, 3, 8, DType::F16),
        (1, 2, 16, DType::F32),
        (1, 2, 64, DType::F16),
        (1, 2, MAX_N, DType::F32),
    ] {
        let b = random_tables(&mut r, k, t, n, dtype);
        for s in 0..(k * t - 1) as u32 {
            for a in [0.0, 1.0, r.random::<f32>()] {
                let v = view(&b, s, s + 1, a);
                for _ in 0..2000 {
                    let u = uniform2(&mut r);
                    let Some((p, d)) = v.sample(u) else {
                        refused += 1;
                        continue;
                    };
                    drawn += 1;
                    assert!(d > 0.0 && d == v.pdf(p), "zero-density cell drawn");
                    let u2 = v.invert(p).expect("invertible");
                    worst_u = worst_u.max((u2 - u).abs().max_element());
                    // And the other way round.
                    let (p2, _) = v.sample(u2).expect("sample of inverse");
                    worst_p = worst_p.max((p2 - p).abs().max_element());
                }
            }
        }
    }
    eprintln!(
        "Table2D: max |invert(sample(u)) − u| = {worst_u:.2e}, max |sample(invert(p)) − p| = \
         {worst_p:.2e}, refused {refused} of {}",
        refused + drawn
    );
    assert!(worst_u < 1e-4 && worst_p < 1e-4);
    assert_eq!(refused, 0);
}

#[test]
fn interpolated_tables_integrate_to_one() {
    let mut r = rng(0x1f7);
    let mut worst_stored = 0.0f64;
    let mut worst_pdf = 0.0f64;
    for &(t, n, dtype) in &[(4, 5, DType::F32), (3, 16, DType::F16), (2, 40, DType::F32)] {
        let b = random_tables(&mut r, 1, t, n, dtype);
        for _ in 0..20 {
            let s = r.random_range(0..t as u32 - 1);
            let a = r.random::<f32>();
            let v = view(&b, s, s + 1, a);
            worst_stored = worst_stored.max((f64::from(v.integral()) - 1.0).abs());
            // ∫ pdf over the square, exactly (piecewise constant: cell centres × area).
            let mut sum = 0.0f64;
            for row in 0..n {
                for col in 0..n {
                    let p = Vec2::new(
                        -1.0 + (col as f32 + 0.5) * 2.0 / n as f32,
                        -1.0 + (row as f32 + 0.5) * 2.0 / n as f32,
                    );
                    sum += f64::from(v.pdf(p));
                    // The blend is the blend of the slices' values.
                    let (v0, v1) = (
                        b.table[(s as usize * n + row) * n + col],
                        b.table[((s as usize + 1) * n + row) * n + col],
                    );
                    let want = (1.0 - a) * v0 + a * v1;
                    assert!((v.value(row as u32, col as u32) - want).abs() <= 1e-6 * want.max(1.0));
                }
            }
            worst_pdf = worst_pdf.max((sum * f64::from(cell_area(n as u32)) - 1.0).abs());
        }
    }
    eprintln!(
        "interpolated slices: max |stored integral − 1| = {worst_stored:.2e}, max |∫pdf − 1| = \
         {worst_pdf:.2e}"
    );
    assert!(worst_stored < 1e-3 && worst_pdf < 1e-5);
}

#[test]
fn table_cell_frequencies_chi2() {
    let mut r = rng(0xce11);
    let b = random_tables(&mut r, 1, 4, 12, DType::F16);
    let mut min_p = 1.0f64;
    let cases = [(0, 0, 0.0), (1, 2, 0.3), (2, 3, 0.77), (3, 3, 0.0)];
    for &(s0, s1, a) in &cases {
        let v = view(&b, s0, s1, a);
        if v.integral() <= 0.0 {
            continue;
        }
        let p = table_cell_chi2(&v, &mut r, 200_000);
        eprintln!("Table2D slices ({s0}, {s1}) a = {a}: cell χ² p = {p:.4}");
        min_p = min_p.min(p);
    }
    assert!(min_p > bonferroni(0.01, cases.len()), "min p {min_p}");
}

#[test]
fn table_view_construction() {
    let b = bake_slices(&[1.0; 2 * 16], 1, 2, 4, DType::F32);
    let (t, m, c) = (&b.table[..], &b.marginal[..], &b.conditional[..]);
    assert!(Table2D::new(t, m, c, 4, 1).is_some());
    assert!(Table2D::new(t, m, c, 4, 2).is_none());
    assert!(Table2D::new(t, m, c, 0, 0).is_none());
    assert!(Table2D::new(t, m, c, MAX_N as u32 + 1, 0).is_none());
    assert!(Table2D::lerp(t, m, c, 4, 0, 1, 1.5).is_none());
    assert!(Table2D::lerp(t, m, c, 4, 0, 1, f32::NAN).is_none());
    assert!(Table2D::new(t, &m[..7], c, 4, 1).is_none());
    // An all-zero table samples nothing and has zero density.
    let z = [0.0f32; 16];
    let v = Table2D::new(&z[..], &z[..4], &z[..], 4, 0).unwrap();
    assert!(v.sample(Vec2::splat(0.5)).is_none());
    assert_eq!(v.pdf(Vec2::ZERO), 0.0);
    assert!(v.invert(Vec2::ZERO).is_none());
}

// ---------------------------------------------------------------------------------------
// Direct histogram
// ---------------------------------------------------------------------------------------

#[test]
fn direct_param_count_and_masking() {
    assert_eq!(DirectHistogramSampler::<&[f32]>::PARAM_COUNT, 22784);
    let v = vec![0.0f32; 22784];
    assert!(DirectHistogramSampler::new(&v[..22783]).is_none());
    let s = DirectHistogramSampler::new(&v[..]).unwrap();
    // Zero logits: uniform over the 224 cells not entirely outside the disk.
    let p = s.prepare(&[0.0; 8], Vec3::Z).unwrap();
    let d = p.table().pdf(Vec2::new(0.01, 0.01));
    assert!((d - 64.0 / 224.0).abs() < 1e-5, "{d}");
    assert_eq!(p.table().pdf(Vec2::new(-0.99, -0.99)), 0.0);
    assert!((p.table().integral() - 1.0).abs() < 1e-5);
    // Hostile logits: still a valid distribution on the unmasked cells.
    let mut logits = [0.0f32; DIRECT_N * DIRECT_N];
    logits[0] = 1e30; // masked corner cell: ignored
    logits[100] = f32::INFINITY;
    logits[101] = f32::NAN;
    logits[102] = f32::NEG_INFINITY;
    let p = DirectHistogramPrepared::from_logits(&logits);
    assert!((p.table().integral() - 1.0).abs() < 1e-5);
    let cell = |i: usize| {
        Vec2::new(
            -1.0 + ((i % 16) as f32 + 0.5) / 8.0,
            -1.0 + ((i / 16) as f32 + 0.5) / 8.0,
        )
    };
    assert!((p.table().pdf(cell(100)) - 64.0).abs() < 1e-3);
    assert_eq!(p.table().pdf(cell(0)), 0.0);
}

#[test]
fn direct_random_models() {
    let mut r = rng(0xd1ec);
    let conditions = if full_tests() { 12 } else { 4 };
    let samples = if full_tests() { 1_000_000 } else { 200_000 };
    let alpha = bonferroni(0.01, conditions);
    let (mut min_p, mut worst, mut worst_inv) = (1.0f64, 0.0f64, 0.0f32);
    for i in 0..conditions {
        let params = direct_params(&mut r);
        let s = DirectHistogramSampler::new(&params[..]).unwrap();
        let (phi, wi) = random_condition(&mut r);
        let p = s.prepare(&phi, wi).unwrap();
        worst = worst.max(check_samples(&p, &mut r, 5000).1);
        for _ in 0..2000 {
            let u = uniform2(&mut r);
            if let Some(smp) = p.sample(u) {
                let u2 = p.invert(smp.wo).expect("invertible");
                worst_inv = worst_inv.max((u2 - u).abs().max_element());
            }
        }
        let integral = disk_integral(&p, 512);
        let (inside, _) = check_samples(&p, &mut r, samples);
        let frac = inside as f64 / samples as f64;
        eprintln!("direct #{i}: ∫disk pdf {integral:.5}, inside fraction {frac:.5}");
        let sd = (frac * (1.0 - frac) / samples as f64).sqrt();
        assert!((integral - frac).abs() < 5.0 * sd + 1e-3);
        min_p = min_p.min(chi2_checked(&format!("direct #{i}"), &p, &mut r, samples));
    }
    eprintln!(
        "direct: max rel |pdf − sample.pdf| {worst:.2e}, max |invert(sample(u)) − u| \
         {worst_inv:.2e}, min χ² p {min_p:.4} (threshold {alpha:.1e})"
    );
    assert!(worst < 1e-4 && worst_inv < 1e-4);
    assert!(min_p > alpha);
}

// ---------------------------------------------------------------------------------------
// Histogram mixture
// ---------------------------------------------------------------------------------------

#[test]
fn mixture_construction() {
    assert_eq!(HistogramMixtureSampler::<&[f32]>::PARAM_COUNT, 3784);
    let mut r = rng(1);
    let b = random_tables(&mut r, BASES, 3, 6, DType::F32);
    let p = vec![0.0f32; 3784];
    let mk = |p: &[f32], m: &[f32], t: &[f32], mg: &[f32], c: &[f32], tl: u32, n: u32| {
        HistogramMixtureSampler::new(p, m, t, mg, c, tl, n, Interpolation::Linear).is_some()
    };
    let (m, t, mg, c) = (
        &b.mass[..],
        &b.table[..],
        &b.marginal[..],
        &b.conditional[..],
    );
    assert!(mk(&p, m, t, mg, c, 3, 6));
    assert!(!mk(&p[1..], m, t, mg, c, 3, 6));
    assert!(!mk(&p, &m[1..], t, mg, c, 3, 6));
    assert!(!mk(&p, m, &t[1..], mg, c, 3, 6));
    assert!(!mk(&p, m, t, &mg[1..], c, 3, 6));
    assert!(!mk(&p, m, t, mg, &c[1..], 3, 6));
    assert!(!mk(&p, m, t, mg, c, 2, 6));
    assert!(!mk(&p, m, t, mg, c, 3, 5));
    assert!(!mk(&p, &[], &[], &[], &[], 0, 0));
    // Fewer bases than K.
    let b2 = random_tables(&mut r, 2, 3, 6, DType::F32);
    assert!(!mk(
        &p,
        &b2.mass,
        &b2.table,
        &b2.marginal,
        &b2.conditional,
        3,
        6
    ));
}

/// Weights, rotations and latent lookup follow `ARCHITECTURES.md` §6.
#[test]
fn mixture_outputs_layout() {
    let mut r = rng(2);
    let (t, n) = (5usize, 16usize);
    // Basis 0: a narrow blob at (0.5, 0) on every level; others random.
    let mut raw = random_raw(&mut r, BASES * t, n);
    for l in 0..t {
        for row in 0..n {
            for col in 0..n {
                let x = -1.0 + (col as f32 + 0.5) * 2.0 / n as f32;
                let y = -1.0 + (row as f32 + 0.5) * 2.0 / n as f32;
                let g = (-((x - 0.5).powi(2) + y * y) / (2.0 * 0.01)).exp();
                raw[(l * n + row) * n + col] = g * (l + 1) as f32;
            }
        }
    }
    let b = bake_slices(&raw, BASES, t, n, DType::F32);
    let params = vec![0.0f32; 3784];
    for interp in [Interpolation::Nearest, Interpolation::Linear] {
        let s = mixture(&params, &b, interp);
        let mut o = [0.0f32; 40];
        for k in 0..BASES {
            o[4 * k] = -1000.0;
        }
        o[0] = 0.0;
        o[1] = 0.0; // ρ = (0, 2): a quarter turn
        o[2] = 2.0;
        o[3] = 0.0; // t = 0.5 → s = 2: exactly level 2 either way
        let p = s.prepare_outputs(&o).unwrap();
        assert!((p.weights()[0] - 1.0).abs() < 1e-6);
        assert!((p.rotation(0) - Vec2::new(0.0, 1.0)).length() < 1e-6);
        assert!(p.pdf_disk(Vec2::new(0.0, 0.5)) > 100.0 * p.pdf_disk(Vec2::new(0.5, 0.0)));
        // Single basis: invert is defined and exact.
        let wo = neusample::warp::from_disk(Vec2::new(0.03, 0.47)).unwrap();
        let u = p.invert(wo).expect("single basis is invertible");
        let back = p.sample(u).unwrap();
        assert!((back.wo - wo).length() < 1e-4);
        // Level lookup: τ = logit(0.6) → s = 2.4: nearest level 2, linear 2 ↔ 3 with a = 0.4.
        o[3] = (0.6f32 / 0.4).ln();
        let p = s.prepare_outputs(&o).unwrap();
        let v = p.table(0);
        let cell = |l: usize| b.table[(l * n + 8) * n + 12];
        let want = match interp {
            Interpolation::Nearest => cell(2),
            Interpolation::Linear => 0.6 * cell(2) + 0.4 * cell(3),
        };
        assert!((v.value(8, 12) - want).abs() < 1e-4 * want, "{interp:?}");
        // Zero-length ρ: identity rotation.
        o[1] = 0.0;
        o[2] = 0.0;
        let p = s.prepare_outputs(&o).unwrap();
        assert_eq!(p.rotation(0), Vec2::X);
    }
    // Mass weighting: equal logits, masses 1 : 3 on bases 0, 1, others 0.
    let mut b2 = b.clone();
    for (i, m) in b2.mass.iter_mut().enumerate() {
        *m = match i / t {
            0 => 1.0,
            1 => 3.0,
            _ => 0.0,
        };
    }
    let s = mixture(&params, &b2, Interpolation::Linear);
    let p = s.prepare_outputs(&[0.0; 40]).unwrap();
    assert!((p.weights()[0] - 0.25).abs() < 1e-6 && (p.weights()[1] - 0.75).abs() < 1e-6);
    // All masses zero: fall back to softmax weights.
    for m in b2.mass.iter_mut() {
        *m = 0.0;
    }
    let s = mixture(&params, &b2, Interpolation::Nearest);
    let p = s.prepare_outputs(&[0.0; 40]).unwrap();
    assert!(p.weights().iter().all(|&w| (w - 0.1).abs() < 1e-6));
}

#[test]
fn mixture_random_models() {
    let mut r = rng(0x415);
    let per_mode = if full_tests() { 8 } else { 3 };
    let samples = if full_tests() { 1_000_000 } else { 200_000 };
    let alpha = bonferroni(0.01, 2 * per_mode);
    let (mut min_p, mut worst, mut worst_inv) = (1.0f64, 0.0f64, 0.0f32);
    let configs = [
        (3usize, 8usize, DType::F32),
        (4, 12, DType::F16),
        (2, 5, DType::F32),
    ];
    for (m, interp) in [Interpolation::Nearest, Interpolation::Linear]
        .into_iter()
        .enumerate()
    {
        for i in 0..per_mode {
            let (t, n, dtype) = configs[(i + m) % configs.len()];
            let b = random_tables(&mut r, BASES, t, n, dtype);
            let params = mixture_params(&mut r);
            let s = mixture(&params, &b, interp);
            let (phi, wi) = random_condition(&mut r);
            let p = s.prepare(&phi, wi).unwrap();
            let w = p.weights();
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            worst = worst.max(check_samples(&p, &mut r, 5000).1);
            // Per-basis inverse: the basis that drew a sample maps it back to its u.
            for _ in 0..2000 {
                let u = uniform2(&mut r);
                let Some(smp) = p.sample(u) else { continue };
                let k = select_component(&w, u.x).0;
                let u2 = p.invert_basis(k, smp.wo).expect("drawing basis inverts");
                worst_inv = worst_inv.max((u2 - u).abs().max_element());
                let several = w.iter().filter(|&&x| x > 0.0).count() > 1;
                assert!(!several || p.invert(smp.wo).is_none());
            }
            let name = format!("mixture {interp:?} #{i} (T {t}, N {n}, {dtype:?})");
            min_p = min_p.min(chi2_checked(&name, &p, &mut r, samples));
        }
    }
    eprintln!(
        "mixture: max rel |pdf − sample.pdf| {worst:.2e}, max |invert_basis(k, sample(u)) − u| \
         {worst_inv:.2e}, min χ² p {min_p:.4} (threshold {alpha:.1e})"
    );
    assert!(worst < 1e-4);
    assert!(worst_inv < 1e-4);
    assert!(min_p > alpha);
}

// ---------------------------------------------------------------------------------------
// Hostile input
// ---------------------------------------------------------------------------------------

fn hostile_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(0.0f32),
        Just(-0.0f32),
        Just(1.0f32),
        Just(-1.0f32),
        Just(1.0 - f32::EPSILON / 2.0),
        Just(f32::MAX),
        Just(f32::MIN_POSITIVE),
        -2.0f32..2.0,
        proptest::num::f32::ANY,
    ]
}

fn assert_total<P: Prepared>(p: &P, u: Vec2, wo: Vec3, q: Vec2) -> Result<(), TestCaseError> {
    if let Some(s) = p.sample(u) {
        prop_assert!(s.pdf.is_finite() && s.pdf > 0.0 && s.wo.is_finite() && s.wo.z > 0.0);
    }
    let d = p.pdf(wo);
    prop_assert!(d.is_finite() && d >= 0.0);
    let d = p.pdf_disk(q);
    prop_assert!(d.is_finite() && d >= 0.0);
    if let Some(u) = p.invert(wo) {
        prop_assert!(u.is_finite() && u.min_element() >= 0.0 && u.max_element() < 1.0);
    }
    Ok(())
}

struct Fixture {
    direct: Vec<f32>,
    params: Vec<f32>,
    tables: BakedTables,
}

fn fixture(seed: u64) -> Fixture {
    let mut r = rng(seed);
    Fixture {
        direct: direct_params(&mut r),
        params: mixture_params(&mut r),
        tables: random_tables(&mut r, BASES, 3, 6, DType::F16),
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        rng_seed: RngSeed::Fixed(0x4157),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Hostile φ, wi, wo, u, raw network outputs and table points never panic or give NaN.
    #[test]
    fn prop_hostile_inputs(
        phi in proptest::array::uniform8(hostile_f32()),
        wi in proptest::array::uniform3(hostile_f32()),
        wo in proptest::array::uniform3(hostile_f32()),
        u in proptest::array::uniform2(hostile_f32()),
        outputs in proptest::collection::vec(hostile_f32(), 40),
        logits in proptest::collection::vec(hostile_f32(), 256),
        seed in 0u64..3,
    ) {
        let f = fixture(seed);
        let (wi, wo, u) = (Vec3::from(wi), Vec3::from(wo), Vec2::from(u));
        let q = Vec2::new(wo.x, wo.y);
        let bad = phi.iter().any(|v| !v.is_finite()) || wi.z.is_nan() || wi.z <= 0.0;

        let d = DirectHistogramSampler::new(&f.direct[..]).unwrap();
        let prepared = d.prepare(&phi, wi);
        prop_assert!(!bad || prepared.is_none());
        if let Some(p) = prepared {
            assert_total(&p, u, wo, q)?;
        }
        let logits: [f32; 256] = logits.try_into().unwrap();
        let p = DirectHistogramPrepared::from_logits(&logits);
        prop_assert!((p.table().integral() - 1.0).abs() < 1e-4);
        assert_total(&p, u, wo, q)?;

        for interp in [Interpolation::Nearest, Interpolation::Linear] {
            let s = mixture(&f.params, &f.tables, interp);
            let prepared = s.prepare(&phi, wi);
            prop_assert!(!bad || prepared.is_none());
            if let Some(p) = prepared {
                assert_total(&p, u, wo, q)?;
            }
            let o: [f32; 40] = outputs.clone().try_into().unwrap();
            if let Some(p) = s.prepare_outputs(&o) {
                let w = p.weights();
                prop_assert!(w.iter().all(|x| x.is_finite() && *x >= 0.0));
                prop_assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
                assert_total(&p, u, wo, q)?;
                for k in 0..BASES {
                    if let Some(v) = p.invert_basis(k, wo) {
                        prop_assert!(v.is_finite());
                    }
                    let t = p.table(k);
                    let d = t.pdf(q);
                    prop_assert!(d.is_finite() && d >= 0.0);
                    if let Some((x, d)) = t.sample(u) {
                        prop_assert!(x.is_finite() && d.is_finite() && d > 0.0);
                    }
                    if let Some(v) = t.invert(q) {
                        prop_assert!(v.is_finite());
                    }
                }
            }
        }
    }
}

/// u at the ends of [0, 1] and just outside, on every sampler.
#[test]
fn edge_u() {
    let f = fixture(11);
    let one = 1.0 - f32::EPSILON / 2.0;
    let (phi, wi) = random_condition(&mut rng(4));
    let d = DirectHistogramSampler::new(&f.direct[..]).unwrap();
    let pd = d.prepare(&phi, wi).unwrap();
    let s = mixture(&f.params, &f.tables, Interpolation::Linear);
    let pm = s.prepare(&phi, wi).unwrap();
    for x in [0.0, 1.0, one, 0.5, 1e-30] {
        for y in [0.0, 1.0, one, 0.5, 1e-30] {
            let u = Vec2::new(x, y);
            for smp in [pd.sample(u), pm.sample(u)].into_iter().flatten() {
                assert!(smp.pdf.is_finite() && smp.pdf > 0.0);
            }
        }
    }
    for bad in [-1e-7, 1.0 + 1e-6, f32::NAN, f32::INFINITY] {
        assert!(pd.sample(Vec2::new(bad, 0.5)).is_none());
        assert!(pm.sample(Vec2::new(0.5, bad)).is_none());
    }
}

/// A stratified sweep of u over [0, 1]² (both ends included) never refuses a sample of a
/// disk-masked table: points that round onto a neighbouring (empty) cell's edge are snapped
/// back into the cell they were drawn in, and their density is that cell's.
#[test]
fn stratified_u_including_one_is_never_refused() {
    use neusample::samplers::histogram_mixture::bake_slices;
    use neusample::Table2D;
    let n = 16usize;
    let mut r = neusample_host_tests::rng(31);
    let raw: Vec<f32> = (0..n * n)
        .map(|_| rand::RngExt::random::<f32>(&mut r) + 0.01)
        .collect();
    let baked = bake_slices(&raw, 1, 1, n, neusample::DType::F32);
    let t = Table2D::new(
        baked.table.as_slice(),
        baked.marginal.as_slice(),
        baked.conditional.as_slice(),
        n as u32,
        0,
    )
    .unwrap();
    let steps = 401;
    let mut refused = 0;
    for i in 0..steps {
        for j in 0..steps {
            let u =
                neusample::Vec2::new(i as f32 / (steps - 1) as f32, j as f32 / (steps - 1) as f32);
            match t.sample(u) {
                Some((p, pdf)) => assert_eq!(pdf, t.pdf(p)),
                None => refused += 1,
            }
        }
    }
    assert_eq!(
        refused,
        0,
        "{refused} of {} stratified u refused",
        steps * steps
    );
}

// ---------------------------------------------------------------------------------------
// The compact layout: no values, u16 CDFs
// ---------------------------------------------------------------------------------------

fn compact_view<'a>(
    c: &'a CompactTables,
    cond: &'a [f32],
    s0: u32,
    s1: u32,
    a: f32,
) -> Table2D<&'a [f32]> {
    Table2D::lerp_compact(&c.marginal[..], cond, c.resolution, s0, s1, a).expect("valid view")
}

#[test]
fn compact_bake_quantises_exactly_and_keeps_every_cell() {
    let mut r = rng(0xc0a1);
    for (t, n) in [(3usize, 8usize), (2, 32), (4, 5)] {
        let raw = random_raw(&mut r, BASES * t, n);
        let c = try_bake_compact(&raw, BASES, t, n).unwrap();
        let full = bake_slices(&raw, BASES, t, n, DType::F32);
        c.validate().unwrap();
        assert_eq!(c.mass, full.mass);
        let cond = c.conditional_f32();
        for s in 0..BASES * t {
            let v = compact_view(&c, &cond, s as u32, s as u32, 0.0);
            let w = view(&full, s as u32, s as u32, 0.0);
            assert!(
                (v.integral() - 1.0).abs() < 1e-4,
                "slice {s}: ∫ {}",
                v.integral()
            );
            for row in 0..n as u32 {
                for col in 0..n as u32 {
                    let (a, b) = (v.value(row, col), w.value(row, col));
                    // Every cell with mass keeps some (unless its whole row is below the f32
                    // resolution of the running sum); quantisation moves a cell by at most
                    // one unit, except the row's largest, which lends units to tiny cells.
                    let rt_stored = c.marginal[s * n + row as usize]
                        - if row > 0 {
                            c.marginal[s * n + row as usize - 1]
                        } else {
                            0.0
                        };
                    if rt_stored < 1e-30 {
                        continue; // stored empty, or below where the shares are comparable
                    }
                    assert_eq!(a > 0.0, b > 0.0, "slice {s} cell ({row}, {col})");
                    let row_total: f32 = (0..n as u32).map(|c| w.value(row, c)).sum();
                    let rt = c.marginal[s * n + row as usize]
                        - if row > 0 {
                            c.marginal[s * n + row as usize - 1]
                        } else {
                            0.0
                        };
                    // The stored row total is a difference of f32 running sums: compare the
                    // cell's share of its row.
                    let b = b * (rt_stored / row_total);
                    let largest = (0..n as u32)
                        .max_by(|&x, &y| w.value(row, x).total_cmp(&w.value(row, y)))
                        .unwrap();
                    let units = if col == largest { n as f32 } else { 1.01 };
                    assert!(
                        (a - b).abs() <= units * rt_stored / 65535.0,
                        "slice {s} cell ({row}, {col}): {a} vs {b}; row total {row_total} stored {rt}; cdf {:?}",
                        &cond[(s * n + row as usize) * n..(s * n + row as usize + 1) * n]
                    );
                }
            }
        }
        // Sampling: exact cell frequencies for a few slices and blends.
        for (s0, s1, a) in [(0u32, 0u32, 0.0f32), (1, 2, 0.3), (2, 1, 0.75)] {
            let v = compact_view(&c, &cond, s0, s1, a);
            if v.integral() > 0.0 {
                let p = table_cell_chi2(&v, &mut r, 100_000);
                assert!(p > 1e-4, "compact table ({s0}, {s1}, {a}): χ² p {p}");
            }
        }
    }
}

#[test]
fn compact_validation_rejects_broken_tables() {
    let mut r = rng(0xc0a2);
    let (t, n) = (2usize, 8usize);
    let c = try_bake_compact(&random_raw(&mut r, BASES * t, n), BASES, t, n).unwrap();
    let check = |m: &[f32], mg: &[f32], cd: &[f32]| {
        validate_compact_tables(m, mg, cd, BASES as u32, t as u32, n as u32)
    };
    let cond = c.conditional_f32();
    check(&c.mass, &c.marginal, &cond).unwrap();
    // A row of slice 0 that has mass: its end, a decrease, a fraction, a step off the disk.
    let row = (0..n)
        .find(|&r| c.marginal[r] > if r > 0 { c.marginal[r - 1] } else { 0.0 })
        .unwrap();
    let end = row * n + n - 1;
    let mut bad = cond.clone();
    bad[end] = 65534.0;
    assert!(matches!(
        check(&c.mass, &c.marginal, &bad),
        Err(Error::TableNotNormalized {
            role: "conditional",
            ..
        })
    ));
    let mut bad = cond.clone();
    bad[end - 1] = 65535.0;
    bad[end] = 65000.0;
    assert!(check(&c.mass, &c.marginal, &bad).is_err());
    let mut bad = cond.clone();
    bad[end] = 65534.5;
    assert!(check(&c.mass, &c.marginal, &bad).is_err());
    let mut bad = cond.clone();
    // Cell (0, 0) lies outside the disk: give it the row's first step.
    let first = (0..n).find(|&rr| cond[rr * n + n - 1] > 0.0).unwrap();
    assert!(cell_outside_disk(first as u32, 0, n as u32));
    bad[first * n] = 1.0;
    assert!(check(&c.mass, &c.marginal, &bad).is_err());
    let mut bad_m = c.marginal.clone();
    bad_m[n - 1] *= 1.01;
    assert!(matches!(
        check(&c.mass, &bad_m, &cond),
        Err(Error::TableNotNormalized {
            role: "marginal",
            ..
        })
    ));
    let mut bad_m = c.marginal.clone();
    bad_m[1] = -1.0;
    assert!(check(&c.mass, &bad_m, &cond).is_err());
    let mut bad_mass = c.mass.clone();
    bad_mass[0] = -0.5;
    assert!(check(&bad_mass, &c.marginal, &cond).is_err());
    assert!(matches!(
        check(&c.mass, &c.marginal, &cond[1..]),
        Err(Error::TensorShape { .. })
    ));
}

#[test]
fn compact_mixture_samples_its_pdf() {
    let mut r = rng(0xc0a3);
    let samples = if full_tests() { 1_000_000 } else { 200_000 };
    let mut min_p = 1.0f64;
    for (i, interp) in [
        Interpolation::Nearest,
        Interpolation::Linear,
        Interpolation::Linear,
    ]
    .into_iter()
    .enumerate()
    {
        let (t, n) = [(3usize, 8usize), (4, 16), (2, 32)][i];
        let c = try_bake_compact(&random_raw(&mut r, BASES * t, n), BASES, t, n).unwrap();
        let cond = c.conditional_f32();
        let params = mixture_params(&mut r);
        let s = HistogramMixtureSampler::new_compact(
            &params[..],
            &c.mass[..],
            &c.marginal[..],
            &cond[..],
            t as u32,
            n as u32,
            interp,
        )
        .unwrap();
        assert_eq!(
            s.layout(),
            neusample::distrib::table2d::TableLayout::Compact
        );
        let (phi, wi) = random_condition(&mut r);
        let p = s.prepare(&phi, wi).unwrap();
        let (_, worst) = check_samples(&p, &mut r, 5000);
        assert!(worst < 1e-5, "compact mixture: pdf vs sample.pdf {worst}");
        min_p = min_p.min(chi2_checked(&format!("compact #{i}"), &p, &mut r, samples));
    }
    assert!(min_p > bonferroni(0.01, 3), "compact mixture χ² p {min_p}");
}

#[test]
fn compact_blob_round_trips_and_is_smaller() {
    use neusample::{BlobWriter, SamplerKind, TensorRole};
    let mut r = rng(0xc0a4);
    let (t, n) = (4usize, 16usize);
    let raw = random_raw(&mut r, BASES * t, n);
    let c = try_bake_compact(&raw, BASES, t, n).unwrap();
    let full = bake_slices(&raw, BASES, t, n, DType::F32);
    let params = mixture_params(&mut r);
    let mut w = BlobWriter::new(SamplerKind::HistogramMixture, DType::F32, "compact")
        .histogram_dims(t as u32, n as u32, Interpolation::Linear);
    w.tensor(TensorRole::Params, &params)
        .tensor(TensorRole::Mass, &c.mass)
        .tensor(TensorRole::Marginal, &c.marginal)
        .tensor_u16(TensorRole::Conditional, &c.conditional);
    let bytes = w.to_bytes();
    let mut wf = BlobWriter::new(SamplerKind::HistogramMixture, DType::F32, "values")
        .histogram_dims(t as u32, n as u32, Interpolation::Linear);
    wf.tensor(TensorRole::Params, &params)
        .tensor(TensorRole::Mass, &full.mass)
        .tensor(TensorRole::Table, &full.table)
        .tensor(TensorRole::Marginal, &full.marginal)
        .tensor(TensorRole::Conditional, &full.conditional);
    let full_bytes = wf.to_bytes();
    assert!(
        4 * bytes.len() < full_bytes.len() + 4 * 16 * 1024,
        "{} vs {}",
        bytes.len(),
        full_bytes.len()
    );
    let blob = neusample::Blob::open(&bytes).unwrap();
    assert!(blob.is_compact());
    let from_blob = blob
        .sampler_as::<neusample::samplers::HistogramMixtureSampler<_>>()
        .unwrap();
    let cond = c.conditional_f32();
    let host = HistogramMixtureSampler::new_compact(
        &params[..],
        &c.mass[..],
        &c.marginal[..],
        &cond[..],
        t as u32,
        n as u32,
        Interpolation::Linear,
    )
    .unwrap();
    for _ in 0..200 {
        let (phi, wi) = random_condition(&mut r);
        let (a, b) = (
            from_blob.prepare(&phi, wi).unwrap(),
            host.prepare(&phi, wi).unwrap(),
        );
        let u = uniform2(&mut r);
        assert_eq!(a.sample(u), b.sample(u));
        let wo = Vec3::new(uniform(&mut r, -0.7, 0.7), uniform(&mut r, -0.7, 0.7), 0.5);
        assert_eq!(a.pdf(wo).to_bits(), b.pdf(wo).to_bits());
    }
    // Corruption of a u16 CDF is caught when the blob opens.
    let mut w2 = w.clone();
    let mut bad = c.conditional.clone();
    let end = (0..n).find(|&rr| bad[rr * n + n - 1] > 0).unwrap() * n + n - 1;
    bad[end] = 1234;
    w2.tensor_u16(TensorRole::Conditional, &bad);
    assert!(matches!(
        neusample::Blob::open(&w2.to_bytes()),
        Err(Error::TableNotNormalized { .. })
    ));
    // A values-layout conditional (f32) in a four-tensor blob is refused.
    let mut w3 = w.clone();
    w3.tensor(TensorRole::Conditional, &cond);
    assert!(matches!(
        neusample::Blob::open(&w3.to_bytes()),
        Err(Error::TensorDType { .. })
    ));
}
