//! χ² goodness of fit of every committed fixture blob (`fixtures/blobs/<material>/<method>.nsb`)
//! whose samples carry its pdf (all but the reparameterization sampler: `tests/reparam.rs`)
//! at conditions drawn from its material (`conditions.txt`): samples histogrammed on a grid
//! over the disk against the pdf integrated over the same cells, low-expectation cells
//! pooled, α = 0.01 with a Bonferroni correction over every test of the run. Also compares
//! ∫disk pdf with the fraction of samples that land in the disk.
//!
//! CI runs 12 conditions per blob with 40 000 samples; `NEUSAMPLE_FULL_TESTS=1` runs 128
//! conditions per blob with 200 000 samples. The batched path (samples drawn by
//! `BatchSampler::sample_batch` over a wavefront of lanes at the condition) runs the same
//! test on 4 conditions per blob (32 with `NEUSAMPLE_FULL_TESTS=1`).

use std::path::PathBuf;

use neusample::wavefront::{BatchSampler, Features, SamplesMut, Vec2s, Vec3s, Vec3sMut};
use neusample::{Blob, Prepared, Sampler, Vec2, Vec3, FEATURE_DIM};
use neusample_host_tests::{
    bonferroni, chi2_test, chi2_test_samples, fixture_blobs_dir, fixture_conditions, full_tests,
    rng, uniform2, Condition,
};

#[test]
fn every_fixture_blob_passes_chi2() {
    // Fast run: five conditions per blob over every fixture folder, about as many in all as
    // twelve over the demo materials' folders alone.
    let (per_blob, samples) = if full_tests() {
        (128, 200_000)
    } else {
        (5, 40_000)
    };
    let mut materials: Vec<PathBuf> = std::fs::read_dir(fixture_blobs_dir())
        .expect("fixtures/blobs is missing: run `neusample fixtures`")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_dir())
        .collect();
    materials.sort();
    let filtered = std::env::var("NEUSAMPLE_CHI2_ONLY").is_ok();
    assert!(
        materials.len() >= 3,
        "expected at least three fixture materials"
    );

    let mut jobs = Vec::new();
    for dir in &materials {
        let conds = fixture_conditions(dir);
        assert!(conds.len() >= per_blob);
        let mut blobs: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "nsb"))
            .collect();
        blobs.sort();
        assert!(blobs.len() >= 6, "{}: expected every method", dir.display());
        // `NEUSAMPLE_CHI2_ONLY=brushed_metal/flow,…` restricts a (full) run to some blobs.
        if let Ok(only) = std::env::var("NEUSAMPLE_CHI2_ONLY") {
            blobs.retain(|b| only.split(',').any(|o| b.to_string_lossy().contains(o)));
        }
        for b in blobs
            .into_iter()
            .filter(|b| samples_carry_pdf(b, &conds[0]))
        {
            jobs.push((b, conds[..per_blob].to_vec()));
        }
    }
    assert!(
        filtered || jobs.len() >= 18,
        "expected 3 materials × 6 methods"
    );
    let tests: usize = jobs.iter().map(|(_, c)| c.len()).sum();
    let alpha = bonferroni(0.01, tests);
    let mut failures = Vec::new();
    eprintln!(
        "{:<44} {:>6} {:>10} {:>10} {:>12}",
        "blob", "tests", "min p", "pass rate", "max |∫p−in|"
    );
    for (path, conds) in &jobs {
        let bytes = std::fs::read(path).unwrap();
        let blob = Blob::open(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let sampler = blob.sampler().unwrap();
        let mut r = rng(2024);
        let (mut min_p, mut passed, mut max_gap) = (1.0f64, 0usize, 0.0f64);
        for (phi, wi) in conds {
            let p = sampler
                .prepare(phi, *wi)
                .expect("fixture condition refused");
            let out = chi2_test(&p, &mut r, 24, 12, samples, 5.0);
            min_p = min_p.min(out.p_value);
            if out.p_value >= alpha {
                passed += 1;
            } else {
                failures.push(format!(
                    "{} at φ={phi:?} wi={wi}: p = {:e}",
                    path.display(),
                    out.p_value
                ));
            }
            // Sampling noise of the in-disk fraction is ~1/√samples; quadrature adds a little.
            max_gap = max_gap.max((out.pdf_integral - out.inside_fraction).abs());
        }
        let name = path
            .strip_prefix(fixture_blobs_dir())
            .unwrap()
            .display()
            .to_string();
        eprintln!(
            "{name:<44} {:>6} {min_p:>10.2e} {:>9.1}% {max_gap:>12.2e}",
            conds.len(),
            100.0 * passed as f64 / conds.len() as f64
        );
        assert!(
            max_gap < 0.02,
            "{name}: ∫pdf and in-disk fraction disagree by {max_gap}"
        );
    }
    assert!(
        failures.is_empty(),
        "χ² failures at α = {alpha:e}:\n{}",
        failures.join("\n")
    );
}

/// The fixture blobs as `(path, conditions)`, `per_blob` conditions each.
fn fixture_jobs(per_blob: usize) -> Vec<(PathBuf, Vec<Condition>)> {
    let mut materials: Vec<PathBuf> = std::fs::read_dir(fixture_blobs_dir())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_dir())
        .collect();
    materials.sort();
    let mut jobs = Vec::new();
    for dir in &materials {
        let conds = fixture_conditions(dir);
        let mut blobs: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "nsb"))
            .collect();
        blobs.sort();
        for b in blobs
            .into_iter()
            .filter(|b| samples_carry_pdf(b, &conds[0]))
        {
            jobs.push((b, conds[..per_blob].to_vec()));
        }
    }
    jobs
}

/// Whether the blob's samples are drawn with its pdf (their `mis_pdf` is their `pdf`, on 16
/// samples at `cond`): a χ² test of samples against the pdf is the test of those kinds. The
/// reparameterization sampler's pdf is a network's approximation of its samples' density by
/// design; `tests/reparam.rs` tests its fixtures (Jacobian consistency, unbiasedness).
fn samples_carry_pdf(path: &std::path::Path, (phi, wi): &Condition) -> bool {
    let bytes = std::fs::read(path).unwrap();
    let blob = Blob::open(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let sampler = blob.sampler().unwrap();
    let p = sampler
        .prepare(phi, *wi)
        .expect("fixture condition refused");
    (0..16).all(|i| {
        let u = Vec2::new((i % 4) as f32 * 0.25 + 0.125, (i / 4) as f32 * 0.25 + 0.125);
        p.sample(u).is_none_or(|s| s.mis_pdf == s.pdf)
    })
}

#[test]
fn every_fixture_blob_passes_chi2_on_the_batched_path() {
    let (per_blob, samples) = if full_tests() {
        (32, 200_000)
    } else {
        (2, 40_000)
    };
    let jobs = fixture_jobs(per_blob);
    assert!(jobs.len() >= 36, "expected 6 materials × 6 methods");
    let alpha = bonferroni(0.01, jobs.len() * per_blob);
    let mut failures = Vec::new();
    for (path, conds) in &jobs {
        let bytes = std::fs::read(path).unwrap();
        let blob = Blob::open(&bytes).unwrap();
        let sampler = blob.sampler().unwrap();
        let mut r = rng(77);
        for (phi, wi) in conds {
            // A wavefront of `samples` lanes at this condition, each with its own u.
            let phi_rows: Vec<Vec<f32>> = (0..FEATURE_DIM).map(|c| vec![phi[c]; samples]).collect();
            let wi_rows = [wi.x, wi.y, wi.z].map(|v| vec![v; samples]);
            let us: Vec<_> = (0..samples).map(|_| uniform2(&mut r)).collect();
            let u_rows = [0, 1].map(|k| us.iter().map(|u| u[k]).collect::<Vec<f32>>());
            let mut lanes = vec![Default::default(); samples];
            sampler
                .prepare_batch(
                    Features {
                        channels: std::array::from_fn(|c| phi_rows[c].as_slice()),
                    },
                    Vec3s {
                        x: &wi_rows[0],
                        y: &wi_rows[1],
                        z: &wi_rows[2],
                    },
                    &mut lanes,
                )
                .unwrap();
            let mut wo = [0, 1, 2].map(|_| vec![0.0f32; samples]);
            let (mut pdf, mut mis) = (vec![0.0f32; samples], vec![0.0f32; samples]);
            let [x, y, z] = &mut wo;
            sampler
                .sample_batch(
                    &lanes,
                    Vec2s {
                        x: &u_rows[0],
                        y: &u_rows[1],
                    },
                    SamplesMut {
                        wo: Vec3sMut { x, y, z },
                        pdf: &mut pdf,
                        mis_pdf: &mut mis,
                    },
                )
                .unwrap();
            assert_eq!(pdf, mis, "{}: samples carry their pdf", path.display());
            let drawn: Vec<Option<Vec3>> = (0..samples)
                .map(|i| (pdf[i] > 0.0).then(|| Vec3::new(wo[0][i], wo[1][i], wo[2][i])))
                .collect();
            let p = sampler
                .prepare(phi, *wi)
                .expect("fixture condition refused");
            let out = chi2_test_samples(&p, &drawn, 24, 12, 5.0);
            if out.p_value < alpha {
                failures.push(format!(
                    "{} at φ={phi:?} wi={wi}: p = {:e}",
                    path.display(),
                    out.p_value
                ));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "batched χ² failures at α = {alpha:e}:\n{}",
        failures.join("\n")
    );
}
