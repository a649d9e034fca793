//! Ground-truth target densities: normalisation, zero mass outside the disk, exact sampling
//! (χ² against the pdf), inversion, KL, conditions, batch determinism, and timings.

use std::time::Instant;

use glam::{Vec2, Vec3};
use neusample::Prepared;
use neusample_host_tests as ht;
use neusample_precompute::groundtruth::{
    self, batch, cell_inside_disk, random_condition, Condition, TargetPdf, MIN_WI_Z,
};
use neusample_precompute::materials::{builtin, builtin_names, luminance, Material};
use rand::RngExt;

fn some_conditions(m: &dyn Material, n: usize, seed: u64) -> Vec<Condition> {
    let mut rng = ht::rng(seed);
    (0..n).map(|_| random_condition(m, &mut rng)).collect()
}

#[test]
fn random_conditions_cover_the_hemisphere() {
    let m = builtin("goat_leather").unwrap();
    let cs = some_conditions(m.as_ref(), 20_000, 1);
    let mut grazing = 0;
    let mut steep = 0;
    for c in &cs {
        assert!((c.wi.length() - 1.0).abs() < 1e-5);
        assert!(c.wi.z >= MIN_WI_Z - 1e-6, "{}", c.wi);
        assert!(c.uv.x >= 0.0 && c.uv.x < 1.0 && c.uv.y >= 0.0 && c.uv.y < 1.0);
        assert_eq!(c.phi, m.features(c.uv));
        grazing += usize::from(c.wi.z < 0.2);
        steep += usize::from(c.wi.z > 0.9);
    }
    let g = grazing as f64 / cs.len() as f64;
    let s = steep as f64 / cs.len() as f64;
    eprintln!(
        "conditions: {:.1}% with wi.z < 0.2, {:.1}% with wi.z > 0.9",
        100.0 * g,
        100.0 * s
    );
    assert!(g > 0.05 && s > 0.15, "{g} {s}");
}

#[test]
fn target_is_normalised_and_zero_outside_the_disk() {
    for (i, name) in builtin_names().iter().enumerate() {
        let m = builtin(name).unwrap();
        for c in some_conditions(m.as_ref(), 3, i as u64) {
            for res in [32usize, 64, 128] {
                let t = TargetPdf::new(m.as_ref(), &c, res);
                assert!(!t.degenerate(), "{name}");
                let h = 2.0 / res as f64;
                let total: f64 = t.density().iter().map(|&d| f64::from(d)).sum::<f64>() * h * h;
                assert!((total - 1.0).abs() < 1e-5, "{name} res {res}: ∫ = {total}");
                // Cells not entirely inside the disk carry nothing; pdf is 0 outside.
                for r in 0..res {
                    for col in 0..res {
                        if !cell_inside_disk(res, r, col) {
                            assert_eq!(t.density()[r * res + col], 0.0);
                        }
                    }
                }
                assert_eq!(t.pdf(Vec2::new(0.8, 0.61)), 0.0);
                assert_eq!(t.pdf(Vec2::new(1.2, 0.0)), 0.0);
                assert_eq!(t.pdf(Vec2::new(f32::NAN, 0.0)), 0.0);
                // Integral by the shared harness (midpoints of a finer grid).
                let fine = ht::integrate_square(2 * res, |p| f64::from(t.pdf(p)));
                assert!((fine - 1.0).abs() < 1e-4, "{name}: {fine}");
            }
        }
    }
}

#[test]
fn target_is_proportional_to_luminance() {
    let m = builtin("giallo_marble").unwrap();
    let c = some_conditions(m.as_ref(), 1, 3)[0];
    let res = 64;
    let opts = groundtruth::TargetOptions {
        supersample: 1,
        ..Default::default()
    };
    let t = TargetPdf::with_options(m.as_ref(), &c, res, &opts);
    // With one point per cell, density = Y(f at the centre) / ∫Y(f).
    let k = t.integral();
    for (r, col) in [(32usize, 32usize), (20, 40), (45, 30), (10, 30)] {
        let h = 2.0 / res as f32;
        let p = Vec2::new(-1.0 + (col as f32 + 0.5) * h, -1.0 + (r as f32 + 0.5) * h);
        let wo = Vec3::new(p.x, p.y, (1.0 - p.length_squared()).sqrt());
        let want = f64::from(luminance(m.eval(&c.phi, c.wi, wo))) / k;
        let got = f64::from(t.pdf(p));
        assert!(
            (got - want).abs() <= 1e-4 * want.max(1e-3),
            "{got} vs {want}"
        );
    }
}

#[test]
fn sampling_matches_pdf_chi2() {
    let full = ht::full_tests();
    let names: Vec<&str> = if full {
        builtin_names().to_vec()
    } else {
        vec![
            "goat_leather",
            "melted_metal",
            "victorian_fabric",
            "moroccan_tiles",
            "tabulated_satin",
        ]
    };
    let per = if full { 4 } else { 2 };
    let tests = names.len() * per;
    let alpha = ht::bonferroni(0.01, tests);
    let mut min_p = 1.0f64;
    let mut min_inside = 1.0f64;
    for (i, name) in names.iter().enumerate() {
        let m = builtin(name).unwrap();
        for c in some_conditions(m.as_ref(), per, 100 + i as u64) {
            let t = TargetPdf::new(m.as_ref(), &c, 32);
            let mut rng = ht::rng(7 + i as u64);
            // Histogram on a grid twice as coarse as the table (4 table cells per bin) and on
            // the table's own grid.
            for (bins, sub) in [(16usize, 4usize), (32, 2)] {
                let out = ht::chi2_test(&t, &mut rng, bins, sub, 200_000, 5.0);
                min_p = min_p.min(out.p_value);
                assert!(
                    out.p_value > alpha,
                    "{name} bins {bins}: χ² = {} dof {} p = {}",
                    out.statistic,
                    out.dof,
                    out.p_value
                );
                assert!((out.pdf_integral - 1.0).abs() < 1e-4);
                // Table2D refuses a sample only when rounding puts it on the edge of an empty
                // neighbouring cell (measure ~1e-6).
                assert!(out.inside_fraction > 1.0 - 1e-4, "{}", out.inside_fraction);
                min_inside = min_inside.min(out.inside_fraction);
            }
        }
    }
    eprintln!(
        "χ²: {tests} conditions × 2 binnings, min p = {min_p:.4} (α = {alpha:.2e}), \
         min fraction of accepted samples {min_inside}"
    );
}

#[test]
fn sample_and_pdf_agree_and_invert() {
    let m = builtin("turtle_shell").unwrap();
    let c = some_conditions(m.as_ref(), 1, 11)[0];
    let t = TargetPdf::new(m.as_ref(), &c, 64);
    let mut rng = ht::rng(12);
    let mut worst = 0.0f32;
    for _ in 0..20_000 {
        let u = ht::uniform2(&mut rng);
        let Some(p) = t.sample(u) else { continue };
        assert!(p.length_squared() < 1.0);
        assert!(t.pdf(p) > 0.0);
        let s = Prepared::sample(&t, u).unwrap();
        assert_eq!(s.pdf_disk, t.pdf(p));
        assert!((s.pdf - s.pdf_disk * s.wo.z).abs() <= 1e-6 * s.pdf);
        let back = t.invert(p).unwrap();
        worst = worst.max((back - u).abs().max_element());
    }
    eprintln!("invert(sample(u)) − u: max {worst:.2e}");
    assert!(worst < 1e-3);
    // A stratified sweep of [0, 1)²: every u gives a point inside the disk in a cell of
    // non-zero density, whose reported density is pdf() there. (u → 1 is left out: there
    // `Table2D::sample` can round the point onto the far edge of the row's last non-empty
    // cell, find the empty neighbour and refuse — reported to the core owner.)
    let n = 400;
    let mut refused = 0;
    for i in 0..n {
        for j in 0..n {
            let u = Vec2::new(i as f32 / n as f32, j as f32 / n as f32);
            if let Some(s) = Prepared::sample(&t, u) {
                assert!(s.pdf_disk > 0.0);
                assert_eq!(s.pdf_disk, t.pdf(Vec2::new(s.wo.x, s.wo.y)));
            } else {
                refused += 1;
            }
        }
    }
    assert_eq!(refused, 0, "{refused} of {} stratified u refused", n * n);
    // Bad u.
    assert!(t.sample(Vec2::new(f32::NAN, 0.5)).is_none());
    assert!(t.sample(Vec2::new(1.5, 0.5)).is_none());
    assert!(t.sample(Vec2::new(0.5, -0.1)).is_none());
}

#[test]
fn degenerate_target_is_uniform() {
    let t = TargetPdf::from_values(16, vec![0.0; 256]);
    assert!(t.degenerate());
    let inside: Vec<f32> = t.density().iter().cloned().filter(|&d| d > 0.0).collect();
    assert!(inside.windows(2).all(|w| w[0] == w[1]));
    let total: f32 = t.density().iter().sum::<f32>() * (2.0f32 / 16.0).powi(2);
    assert!((total - 1.0).abs() < 1e-5);
}

#[test]
fn kl_divergence() {
    let m = builtin("melted_metal").unwrap();
    let c = some_conditions(m.as_ref(), 1, 21)[0];
    let t = TargetPdf::new(m.as_ref(), &c, 64);
    let self_kl = t.kl_from(|p| t.pdf(p));
    assert!(self_kl.abs() < 1e-6, "{self_kl}");
    let cosine = t.kl_from(|p| {
        if p.length_squared() < 1.0 {
            std::f32::consts::FRAC_1_PI
        } else {
            0.0
        }
    });
    assert!(cosine > 0.1, "{cosine}");
    // A flatter target (rough wood) is closer to cosine sampling than a glossy metal.
    let w = builtin("wagon_wood").unwrap();
    let cw = some_conditions(w.as_ref(), 1, 21)[0];
    let tw = TargetPdf::new(w.as_ref(), &cw, 64);
    let cos_w = tw.kl_from(|p| {
        if p.length_squared() < 1.0 {
            std::f32::consts::FRAC_1_PI
        } else {
            0.0
        }
    });
    eprintln!("KL(p*‖cosine): melted_metal {cosine:.3}, wagon_wood {cos_w:.3} nats");
    assert!(cos_w < cosine);
    // q = 0 where p* > 0 is penalised, never NaN.
    let zero = t.kl_from(|_| 0.0);
    assert!(zero.is_finite() && zero > 10.0);
}

fn same(a: &[(Condition, TargetPdf)], b: &[(Condition, TargetPdf)]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x.0 == y.0 && x.1.density() == y.1.density())
}

#[test]
fn batch_is_deterministic_per_seed() {
    let m = builtin("victorian_fabric").unwrap();
    let a = batch(m.as_ref(), 12, 32, 42);
    let b = batch(m.as_ref(), 12, 32, 42);
    assert!(same(&a, &b));
    let c = batch(m.as_ref(), 12, 32, 43);
    assert!(a.iter().zip(&c).all(|(x, y)| x.0 != y.0));
    // Prefix property and independence from the thread count.
    let short = batch(m.as_ref(), 5, 32, 42);
    assert!(same(&short, &a[..5]));
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let single = one.install(|| batch(m.as_ref(), 12, 32, 42));
    assert!(same(&single, &a));
    let conds = groundtruth::conditions(m.as_ref(), 12, 42);
    assert!(conds.iter().zip(&a).all(|(x, y)| *x == y.0));
    // The conditions are varied.
    let mut rng = ht::rng(0);
    let _: f32 = rng.random();
    assert!(a.windows(2).all(|w| w[0].0.uv != w[1].0.uv));
}

#[test]
fn timings() {
    // Reported figures (run with --nocapture).
    let m = builtin("goat_leather").unwrap();
    let cs = some_conditions(m.as_ref(), 20, 5);
    for res in [64usize, 128] {
        let t0 = Instant::now();
        let mut s = 0.0;
        for c in &cs {
            s += TargetPdf::new(m.as_ref(), c, res).density()[res * res / 2 + res / 2];
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3 / cs.len() as f64;
        eprintln!("TargetPdf::new goat_leather res {res}: {ms:.2} ms ({s:.1})");
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    for name in ["goat_leather", "car_paint", "victorian_fabric"] {
        let m = builtin(name).unwrap();
        let n = 200;
        let t0 = Instant::now();
        let b = pool.install(|| batch(m.as_ref(), n, 64, 1));
        let secs = t0.elapsed().as_secs_f64();
        eprintln!(
            "batch {name} res 64, 2 threads: {:.0} conditions/s ({})",
            n as f64 / secs,
            b.len()
        );
    }
}

#[test]
fn tables_above_the_runtime_limit_give_densities_only() {
    let m = builtin("gold").unwrap();
    let c = some_conditions(m.as_ref(), 1, 31)[0];
    let big = TargetPdf::new(m.as_ref(), &c, 160);
    assert!(big.table().is_none());
    assert!(big.sample(Vec2::splat(0.5)).is_none());
    let total = ht::integrate_square(320, |p| f64::from(big.pdf(p)));
    assert!((total - 1.0).abs() < 1e-4, "{total}");
    // The runtime layout: running sums end at Σ density.
    let small = TargetPdf::new(m.as_ref(), &c, 64);
    let (d, marginal, conditional) = small.tensors();
    let sum: f32 = d.iter().sum();
    assert!((marginal[63] - sum).abs() <= 1e-4 * sum);
    assert!((conditional[64 * 32 + 63] - d[64 * 32..64 * 33].iter().sum::<f32>()).abs() < 1e-3);
}

#[test]
fn chi2_divergence_known_answers() {
    // p* = 1 on the left half of the disk, 3 on the right (densities 1/(2A) and 3/(2A), A the
    // area of the cells inside the disk), q uniform 1/A: χ² = (1² + 3²)/8 − 1 = 0.25 and
    // KL = ¼ ln ½ + ¾ ln 3/2.
    let res = 32;
    let values: Vec<f32> = (0..res * res)
        .map(|i| if i % res < res / 2 { 1.0 } else { 3.0 })
        .collect();
    let t = TargetPdf::from_values(res, values);
    let uniform = TargetPdf::from_values(res, vec![1.0; res * res]);
    let chi2 = t.chi2_from(|p| uniform.pdf(p));
    assert!((chi2 - 0.25).abs() < 1e-5, "{chi2}");
    let kl = t.kl_from(|p| uniform.pdf(p));
    let want = 0.25 * 0.5f64.ln() + 0.75 * 1.5f64.ln();
    assert!((kl - want).abs() < 1e-5, "{kl} vs {want}");
    // χ² of p* against itself is 0, against c·p* it is 1/c − 1.
    assert!(t.chi2_from(|p| t.pdf(p)).abs() < 1e-5);
    let half = t.chi2_from(|p| 2.0 * t.pdf(p));
    assert!((half + 0.5).abs() < 1e-5, "{half}");
    // A density that misses part of p*'s support: the floor makes χ² huge while KL stays
    // moderate — the case the render's variance sees and KL does not.
    let thin = t.chi2_from(|p| if p.x < -0.9 { 0.0 } else { 1.2 * t.pdf(p) });
    let thin_kl = t.kl_from(|p| if p.x < -0.9 { 1e-6 } else { 1.2 * t.pdf(p) });
    assert!(thin > 1e3 && thin_kl < 1.0, "χ² {thin}, KL {thin_kl}");
}
