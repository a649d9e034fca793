//! χ² goodness of fit of every committed fixture blob (`fixtures/blobs/<material>/<method>.nsb`)
//! at conditions drawn from its material (`conditions.txt`): samples histogrammed on a grid
//! over the disk against the pdf integrated over the same cells, low-expectation cells
//! pooled, α = 0.01 with a Bonferroni correction over every test of the run. Also compares
//! ∫disk pdf with the fraction of samples that land in the disk.
//!
//! CI runs 12 conditions per blob with 40 000 samples; `NEUSAMPLE_FULL_TESTS=1` runs 128
//! conditions per blob with 200 000 samples.

use std::path::PathBuf;

use neusample::Blob;
use neusample::Sampler;
use neusample_host_tests::{
    bonferroni, chi2_test, fixture_blobs_dir, fixture_conditions, full_tests, rng,
};

#[test]
fn every_fixture_blob_passes_chi2() {
    let (per_blob, samples) = if full_tests() {
        (128, 200_000)
    } else {
        (12, 40_000)
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
        for b in blobs {
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
