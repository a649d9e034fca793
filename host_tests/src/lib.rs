//! Shared machinery of the host test suite: seeded RNGs, numerical integration of densities
//! over the projected disk, and a χ² goodness-of-fit test of a sampler against its own pdf
//! (after Mitsuba 3's `chi2` module: cells with small expected counts are pooled).

use std::path::{Path, PathBuf};

use neusample::{Prepared, Vec2, Vec3, FEATURE_DIM};
use rand::{RngExt, SeedableRng};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// The RNG every test uses: PCG64 from a fixed seed.
pub type TestRng = rand_pcg::Pcg64Mcg;

/// A seeded test RNG.
#[must_use]
pub fn rng(seed: u64) -> TestRng {
    TestRng::seed_from_u64(seed)
}

/// A uniform `u ∈ [0, 1)²`.
pub fn uniform2(rng: &mut TestRng) -> Vec2 {
    Vec2::new(rng.random::<f32>(), rng.random::<f32>())
}

/// ∫ f over the square `[-1, 1]²`, by the midpoint rule on an `n × n` grid (f is expected to
/// be 0 outside the disk).
pub fn integrate_square(n: usize, mut f: impl FnMut(Vec2) -> f64) -> f64 {
    let h = 2.0 / n as f64;
    let mut sum = 0.0;
    for r in 0..n {
        let y = -1.0 + (r as f64 + 0.5) * h;
        for c in 0..n {
            let x = -1.0 + (c as f64 + 0.5) * h;
            sum += f(Vec2::new(x as f32, y as f32));
        }
    }
    sum * h * h
}

/// ∫ pdf_disk over the disk (the probability mass that lands inside it).
pub fn disk_integral<P: Prepared>(p: &P, n: usize) -> f64 {
    integrate_square(n, |q| f64::from(p.pdf_disk(q)))
}

/// Outcome of [`chi2_test`].
#[derive(Clone, Debug)]
pub struct Chi2Outcome {
    /// The χ² statistic.
    pub statistic: f64,
    /// Degrees of freedom (pooled cells − 1).
    pub dof: usize,
    /// P-value of the statistic under the hypothesis that samples follow the pdf.
    pub p_value: f64,
    /// ∫ pdf_disk over the disk, from the cell integrals.
    pub pdf_integral: f64,
    /// Fraction of samples that landed inside the disk (`sample` returned `Some`).
    pub inside_fraction: f64,
}

/// χ² test of `p.sample` against `p.pdf_disk` on a `res × res` grid over `[-1, 1]²` plus one
/// cell for samples refused (`None`, mass outside the disk). Each cell's expected count is
/// `samples · ∫cell pdf`, integrated with `sub × sub` midpoints; cells expecting fewer than
/// `min_expected` samples are pooled (smallest first) until the pool reaches it.
pub fn chi2_test<P: Prepared>(
    p: &P,
    rng: &mut TestRng,
    res: usize,
    sub: usize,
    samples: usize,
    min_expected: f64,
) -> Chi2Outcome {
    let drawn: Vec<Option<Vec3>> = (0..samples)
        .map(|_| p.sample(uniform2(rng)).map(|s| s.wo))
        .collect();
    chi2_test_samples(p, &drawn, res, sub, min_expected)
}

/// [`chi2_test`] of samples drawn elsewhere (e.g. by the batched API; `None`: refused)
/// against `p.pdf_disk`.
pub fn chi2_test_samples<P: Prepared>(
    p: &P,
    drawn: &[Option<Vec3>],
    res: usize,
    sub: usize,
    min_expected: f64,
) -> Chi2Outcome {
    let samples = drawn.len();
    let cells = res * res;
    let mut observed = vec![0f64; cells + 1];
    let mut refused = 0usize;
    for s in drawn {
        match s {
            Some(wo) => {
                let x = ((wo.x + 1.0) * 0.5 * res as f32).floor();
                let y = ((wo.y + 1.0) * 0.5 * res as f32).floor();
                let c = (x.clamp(0.0, (res - 1) as f32)) as usize;
                let r = (y.clamp(0.0, (res - 1) as f32)) as usize;
                observed[r * res + c] += 1.0;
            }
            None => refused += 1,
        }
    }
    observed[cells] = refused as f64;

    let h = 2.0 / res as f64;
    let mut expected = vec![0f64; cells + 1];
    let mut integral = 0.0;
    for r in 0..res {
        for c in 0..res {
            let (x0, y0) = (-1.0 + c as f64 * h, -1.0 + r as f64 * h);
            let mass = cell_integral(p, x0, y0, h, sub, samples);
            integral += mass;
            expected[r * res + c] = mass * samples as f64;
        }
    }
    // Quadrature error can put the integral at or above 1 while a few samples are refused;
    // a floor of one expected sample keeps that cell from making the statistic infinite
    // (pooling merges it with other small cells).
    expected[cells] = ((1.0 - integral) * samples as f64).max(1.0);

    let (statistic, pooled) = pooled_chi2(&observed, &expected, min_expected);
    let dof = pooled.saturating_sub(1).max(1);
    let p_value = ChiSquared::new(dof as f64)
        .map(|d| d.sf(statistic))
        .unwrap_or(0.0);
    Chi2Outcome {
        statistic,
        dof,
        p_value,
        pdf_integral: integral,
        inside_fraction: (samples - refused) as f64 / samples as f64,
    }
}

/// ∫ pdf_disk over the square cell `[x0, x0 + h] × [y0, y0 + h]`: midpoint rule with
/// `sub × sub` points, refined (doubling the points per side, up to 16× `sub`) until two
/// successive estimates of the cell's expected count (`samples` × mass) differ by less than
/// a tenth of its Poisson standard deviation — narrow lobes (σ down to e⁻⁷) need it.
pub fn cell_integral<P: Prepared>(
    p: &P,
    x0: f64,
    y0: f64,
    h: f64,
    sub: usize,
    samples: usize,
) -> f64 {
    let midpoint = |k: usize| {
        let hs = h / k as f64;
        let mut acc = 0.0;
        for i in 0..k {
            let y = y0 + (i as f64 + 0.5) * hs;
            for j in 0..k {
                let x = x0 + (j as f64 + 0.5) * hs;
                acc += f64::from(p.pdf_disk(Vec2::new(x as f32, y as f32)));
            }
        }
        acc * hs * hs
    };
    let mut k = sub.max(1);
    let mut prev = midpoint(k);
    let n = samples as f64;
    while k < 16 * sub.max(1) {
        k *= 2;
        let next = midpoint(k);
        if (next - prev).abs() * n <= 0.1 * (next.abs() * n + 1.0).sqrt() {
            return next;
        }
        prev = next;
    }
    prev
}

/// χ² statistic with pooling of low-expectation cells; returns (statistic, number of cells
/// after pooling). A cell with zero expectation but observations makes the statistic ∞.
pub fn pooled_chi2(observed: &[f64], expected: &[f64], min_expected: f64) -> (f64, usize) {
    let mut idx: Vec<usize> = (0..observed.len()).collect();
    idx.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let mut stat = 0.0;
    let mut cells = 0;
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for &i in &idx {
        if expected[i] == 0.0 {
            if observed[i] > 0.0 {
                return (f64::INFINITY, cells.max(1));
            }
            continue;
        }
        if expected[i] < min_expected || pool_e > 0.0 && pool_e < min_expected {
            pool_o += observed[i];
            pool_e += expected[i];
            if pool_e >= min_expected {
                stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
                cells += 1;
                pool_o = 0.0;
                pool_e = 0.0;
            }
            continue;
        }
        stat += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
        cells += 1;
    }
    if pool_e > 0.0 {
        stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        cells += 1;
    }
    (stat, cells)
}

/// Bonferroni-corrected significance level for `tests` tests at family level `alpha`.
#[must_use]
pub fn bonferroni(alpha: f64, tests: usize) -> f64 {
    alpha / tests.max(1) as f64
}

/// Whether heavier statistical runs were asked for (`NEUSAMPLE_FULL_TESTS=1`).
#[must_use]
pub fn full_tests() -> bool {
    std::env::var("NEUSAMPLE_FULL_TESTS").is_ok_and(|v| v == "1")
}

/// A small valid blob of `kind`: random parameters (N(0, 0.3²)-ish, seeded) and, for the
/// histogram mixture, random baked tables (T = 4, N = 8, linear in t). Returns the bytes and
/// the f32 parameters that were written.
#[must_use]
pub fn small_blob(
    kind: neusample::SamplerKind,
    dtype: neusample::DType,
    seed: u64,
) -> (Vec<u8>, Vec<f32>) {
    use neusample::{BlobWriter, Interpolation, SamplerKind, TensorRole};
    let mut r = rng(seed);
    let params: Vec<f32> = (0..kind.param_count())
        .map(|_| (r.random::<f32>() - 0.5) * 0.6)
        .collect();
    let mut w = BlobWriter::new(kind, dtype, "test blob");
    if kind == SamplerKind::Cosine {
        return (w.to_bytes(), params);
    }
    if kind == SamplerKind::HistogramMixture {
        let (t, n) = (4u32, 8u32);
        w = w.histogram_dims(t, n, Interpolation::Linear);
        let k = neusample::samplers::histogram_mixture::BASES;
        let raw: Vec<f32> = (0..k * (t * n * n) as usize)
            .map(|_| r.random::<f32>())
            .collect();
        let baked = neusample::samplers::histogram_mixture::bake_slices(
            &raw, k, t as usize, n as usize, dtype,
        );
        w.tensor(TensorRole::Mass, &baked.mass)
            .tensor(TensorRole::Table, &baked.table)
            .tensor(TensorRole::Marginal, &baked.marginal)
            .tensor(TensorRole::Conditional, &baked.conditional);
    }
    w.tensor(TensorRole::Params, &params);
    (w.to_bytes(), params)
}

/// The folder of the committed fixture blobs (`fixtures/blobs`, one folder per material).
#[must_use]
pub fn fixture_blobs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/blobs")
}

/// A shading condition of the fixture suites: φ and wi (local frame).
pub type Condition = ([f32; FEATURE_DIM], Vec3);

/// The conditions `(φ, wi)` of a fixture material folder (`conditions.txt`, written by
/// `neusample fixtures`: one `φ0 … φ7 wi.x wi.y wi.z` line each, `#` comments). Panics on a
/// missing file or a malformed line (test input).
#[must_use]
pub fn fixture_conditions(dir: &Path) -> Vec<Condition> {
    let text = std::fs::read_to_string(dir.join("conditions.txt"))
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            assert_eq!(v.len(), FEATURE_DIM + 3, "bad line in conditions.txt: {l}");
            let phi: [f32; FEATURE_DIM] = v[..FEATURE_DIM].try_into().unwrap();
            (
                phi,
                Vec3::new(v[FEATURE_DIM], v[FEATURE_DIM + 1], v[FEATURE_DIM + 2]),
            )
        })
        .collect()
}

/// [`chi2_test`] on a 32² grid (16² quadrature points per cell) with the mass check: the
/// pdf's integral over the disk must equal the fraction of samples landing inside it. Returns
/// the p-value (of [`chi2_inside`] when only the refused cell's quadrature is off).
pub fn chi2_checked<P: Prepared>(name: &str, p: &P, r: &mut TestRng, samples: usize) -> f64 {
    let o = chi2_test(p, r, 32, 16, samples, 5.0);
    eprintln!(
        "{name}: χ² {:.1} dof {} p {:.4}  ∫pdf {:.5}  inside {:.5}",
        o.statistic, o.dof, o.p_value, o.pdf_integral, o.inside_fraction
    );
    let sd = (o.inside_fraction * (1.0 - o.inside_fraction) / samples as f64).sqrt();
    assert!(
        (o.pdf_integral - o.inside_fraction).abs() < 5.0 * sd + 2e-3,
        "{name}: ∫pdf {} vs inside {}",
        o.pdf_integral,
        o.inside_fraction
    );
    if o.statistic.is_infinite() && o.pdf_integral > 1.0 - 1e-4 {
        // The harness expects 0 refused samples when its quadrature puts ∫pdf at ≥ 1, but a
        // Gaussian tail of ~1e−5 outside the disk is below that quadrature's resolution.
        // Test the shape inside the disk instead (the mass was checked just above).
        let p_inside = chi2_inside(p, r, 32, 16, samples);
        eprintln!("{name}: refused-cell artefact; χ² of the inside samples p {p_inside:.4}");
        return p_inside;
    }
    o.p_value
}

/// χ² of the samples that land inside the disk against `pdf_disk` normalised over the disk
/// (same grid and quadrature as `chi2_test`, without the refused cell).
pub fn chi2_inside<P: Prepared>(p: &P, r: &mut TestRng, res: usize, sub: usize, n: usize) -> f64 {
    let mut observed = vec![0.0f64; res * res];
    let mut inside = 0.0;
    for _ in 0..n {
        if let Some(s) = p.sample(uniform2(r)) {
            let c = (((s.wo.x + 1.0) * 0.5 * res as f32).floor() as usize).min(res - 1);
            let rr = (((s.wo.y + 1.0) * 0.5 * res as f32).floor() as usize).min(res - 1);
            observed[rr * res + c] += 1.0;
            inside += 1.0;
        }
    }
    let (h, hs) = (2.0 / res as f64, 2.0 / (res * sub) as f64);
    let mut expected = vec![0.0f64; res * res];
    for rr in 0..res {
        for c in 0..res {
            let mut acc = 0.0;
            for i in 0..sub {
                for j in 0..sub {
                    let x = -1.0 + c as f64 * h + (j as f64 + 0.5) * hs;
                    let y = -1.0 + rr as f64 * h + (i as f64 + 0.5) * hs;
                    acc += f64::from(p.pdf_disk(Vec2::new(x as f32, y as f32)));
                }
            }
            expected[rr * res + c] = acc;
        }
    }
    let total: f64 = expected.iter().sum();
    for e in &mut expected {
        *e *= inside / total;
    }
    let (stat, cells) = pooled_chi2(&observed, &expected, 5.0);
    ChiSquared::new(cells.saturating_sub(1).max(1) as f64)
        .map(|d| d.sf(stat))
        .unwrap_or(0.0)
}
