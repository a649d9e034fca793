//! The measured-material reader and runtime against Mitsuba 3's `measured` BSDF (golden values
//! from `tools/measured_reference.py`), their own invariants (the sampler's pdf integrates to
//! one, sample and pdf agree, the weight is f·cos/pdf), a constructed anisotropic file, and
//! bad files.

use std::path::{Path, PathBuf};

use neusample::{Vec2, Vec3};
use neusample_owned::measured::{OwnedMeasured, MAGIC};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/measured")
}

const FILES: [&str; 5] = [
    "acrylic_felt_green_rgb.bsdf",
    "cc_ibiza_sunset_rgb.bsdf",
    "chm_mint_rgb.bsdf",
    "ilm_l3_37_metallic_rgb.bsdf",
    "paper_white_rgb.bsdf",
];

fn v3(v: &serde_json::Value) -> Vec3 {
    let a: Vec<f32> = serde_json::from_value(v.clone()).unwrap();
    Vec3::new(a[0], a[1], a[2])
}

fn rel(a: f64, b: f64, floor: f64) -> f64 {
    (a - b).abs() / b.abs().max(floor)
}

/// Eval, pdf and sample against Mitsuba at the golden pairs: relative error ≤ 1e-3 (with an
/// absolute floor of 1e-6 × the file's largest value) on ≥ 99.9 % of the values.
#[test]
fn agrees_with_mitsuba() {
    let text = std::fs::read_to_string(fixtures().join("mitsuba_reference.json")).unwrap();
    let reference: serde_json::Value = serde_json::from_str(&text).unwrap();
    for file in FILES {
        let m = OwnedMeasured::open(&fixtures().join(file)).unwrap();
        let r = &reference["files"][file];
        let n = r["wi"].as_array().unwrap().len();
        let f_max = r["f"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|v| v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
            .fold(0.0f64, f64::max);
        let pdf_max = r["pdf"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .fold(0.0f64, f64::max);
        let (mut bad_f, mut bad_pdf, mut bad_sample) = (0, 0, 0);
        let (mut worst_f, mut worst_pdf, mut worst_wo, mut worst_spdf) =
            (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for i in 0..n {
            let wi = v3(&r["wi"][i]);
            let wo = v3(&r["wo"][i]);
            let p = m.material().prepare(wi).unwrap();
            let f = p.eval(wo);
            for c in 0..3 {
                // Mitsuba keeps the data's slightly negative values; ours read as 0.
                let want = r["f"][i][c].as_f64().unwrap().max(0.0);
                let e = rel(f64::from(f[c]), want, 1e-6 * f_max);
                worst_f = worst_f.max(e);
                bad_f += usize::from(e > 1e-3);
            }
            let e = rel(
                f64::from(p.pdf(wo)),
                r["pdf"][i].as_f64().unwrap(),
                1e-6 * pdf_max,
            );
            worst_pdf = worst_pdf.max(e);
            bad_pdf += usize::from(e > 1e-3);
            if e > 1e-3 {
                eprintln!(
                    "{file} pair {i}: wi {wi:?} wo {wo:?} pdf {} vs Mitsuba {}",
                    p.pdf(wo),
                    r["pdf"][i]
                );
            }

            let u = Vec2::new(
                r["u"][i][0].as_f64().unwrap() as f32,
                r["u"][i][1].as_f64().unwrap() as f32,
            );
            let want_pdf = r["sample_pdf"][i].as_f64().unwrap();
            match p.sample(u) {
                Some(s) if want_pdf > 0.0 => {
                    let d = f64::from((s.wo - v3(&r["sample_wo"][i])).length());
                    let e = rel(f64::from(s.pdf), want_pdf, 1e-6 * pdf_max);
                    worst_wo = worst_wo.max(d);
                    worst_spdf = worst_spdf.max(e);
                    bad_sample += usize::from(d > 1e-3 || e > 1e-3);
                }
                None if want_pdf == 0.0 => {}
                other => {
                    eprintln!("{file} pair {i}: sample {other:?}, Mitsuba pdf {want_pdf}");
                    bad_sample += 1;
                }
            }
        }
        eprintln!(
            "{file}: worst relative f {worst_f:.2e}, pdf {worst_pdf:.2e}; sample |Δwo| {worst_wo:.2e}, pdf {worst_spdf:.2e}; \
             above 1e-3: f {bad_f}/{}, pdf {bad_pdf}/{n}, sample {bad_sample}/{n}",
            3 * n
        );
        // ≥ 99.9 % within 1e-3: with 256 pairs, no value may miss.
        let allowed = |total: usize| total / 1000;
        assert!(
            bad_f <= allowed(3 * n),
            "{file}: {bad_f} RGB values off by > 1e-3"
        );
        assert!(
            bad_pdf <= allowed(n),
            "{file}: {bad_pdf} pdfs off by > 1e-3"
        );
        assert!(
            bad_sample <= allowed(n),
            "{file}: {bad_sample} samples off by > 1e-3"
        );
    }
}
