//! `neusample demo --smoke` end to end (on the committed neural materials, the
//! demo's default setting): the report, read back into its typed schema, its required fields
//! and the relations between them, the fit against the source materials, the images and
//! plots.

use neusample_precompute::demo::{self, DemoConfig, Report, BASELINE, COSINE, ORACLE};

/// The oracle tabulates p* on its own grid (`oracle_res²`, coarser than the `eval_res²` grid
/// of the KL measure), so its KL carries a discretisation error of its own: it must be the
/// smallest up to this many nats.
const ORACLE_KL_TOLERANCE: f64 = 0.05;

/// Masses in the disk are midpoint sums over the evaluation grid: at most 1 up to this.
const MASS_TOLERANCE: f64 = 0.01;

/// Relative tolerance of values the report copies or derives from others.
const COPY_TOLERANCE: f64 = 1e-12;

fn read_report(dir: &std::path::Path) -> Report {
    let text = std::fs::read_to_string(dir.join("report.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= COPY_TOLERANCE * a.abs().max(b.abs()).max(1.0)
}

#[test]
fn quick_demo_with_fixtures_writes_a_complete_report() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = DemoConfig::new(dir.path());
    a.quick = true;
    a.use_fixtures = true;
    demo::run(&a).unwrap();

    let r = read_report(dir.path());
    assert_eq!(r.schema, demo::REPORT_SCHEMA);
    assert!(r.quick && r.fixtures && r.steps_scale.is_none());
    // A smoke test says so before anything else.
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(
        md.starts_with(demo::SMOKE_LINE),
        "{}",
        &md[..200.min(md.len())]
    );
    let setup = r.render.as_ref().expect("rendered");
    let max_spp = setup.settings.max_spp;
    assert_eq!(r.materials.len(), demo::DEFAULT_MATERIALS.len());
    let finite = |x: f64, what: &str| -> f64 {
        assert!(x.is_finite(), "{what} = {x}");
        x
    };
    for (m, source) in r.materials.iter().zip(demo::DEFAULT_MATERIALS) {
        let name = &m.material;
        assert_eq!(*name, format!("{source}{}", demo::NEURAL_SUFFIX));
        // The neural material is measured against its source.
        let n = m.neural.as_ref().expect("neural report");
        assert_eq!(n.source, source);
        let kl = finite(n.fit.kl_pstar, "neural kl_pstar");
        let kl_cos = finite(n.fit.kl_pstar_vs_cosine, "kl_pstar_vs_cosine");
        assert!(kl >= 0.0 && kl < kl_cos, "{name}: {kl} vs cosine {kl_cos}");
        assert!(finite(n.cost.eval_ns, "eval_ns") > 0.0);
        let names: Vec<&str> = m.methods.iter().map(|x| x.method.as_str()).collect();
        assert_eq!(
            names,
            [
                "cosine",
                "baseline",
                "analytic",
                "flow",
                "disk-flow",
                "affine-flow",
                "direct-histogram",
                "histogram-mixture",
                "reparam",
                "oracle"
            ]
        );
        let base = m.methods.iter().find(|x| x.method == BASELINE).unwrap();
        let oracle = m.methods.iter().find(|x| x.method == ORACLE).unwrap();
        let cosine = m.methods.iter().find(|x| x.method == COSINE).unwrap();
        for x in &m.methods {
            let what = format!("{name}/{}", x.method);
            let rr = x.render.as_ref().expect("render report");
            for (field, v) in [
                (
                    "speedup_vs_baseline",
                    x.speedup_vs_baseline().unwrap_or(f64::NAN),
                ),
                ("cost.total_ns", x.cost.total_ns),
                ("kl_divergence", x.fit.kl_divergence),
                ("cost_vs_material_eval", x.cost_vs_material_eval()),
            ] {
                let v = finite(v, &format!("{what}.{field}"));
                assert!(v >= 0.0, "{what}.{field} = {v}");
            }
            assert!(
                finite(
                    x.kl_vs_source.unwrap_or(f64::NAN),
                    &format!("{what}.kl_vs_source")
                ) >= 0.0
            );
            for (field, v) in [
                ("ns_per_sample", rr.ns_per_sample),
                ("mse_equal_spp", rr.mse_equal_spp),
                ("mse_equal_time", rr.mse_equal_time),
                ("speedup", rr.speedup.value),
            ] {
                assert!(finite(v, &format!("{what}.render.{field}")) > 0.0);
            }
            assert!(rr.equal_time_spp >= 1);
            // Intervals: the value inside, positive bounds, one speed-up for both fields.
            for (field, e) in [
                ("speedup", rr.speedup),
                ("mse_ratio", rr.mse_ratio),
                ("variance", rr.variance),
                ("mse_equal_spp_interval", rr.mse_equal_spp_interval),
            ] {
                assert!(
                    e.lo > 0.0 && e.lo <= e.value && e.value <= e.hi && e.hi.is_finite(),
                    "{what}.render.{field} = {e:?}"
                );
            }
            assert_eq!(rr.blocks, setup.settings.blocks.min(max_spp), "{what}");
            assert!(
                (rr.mse_equal_spp_interval.value * f64::from(max_spp) / rr.variance.value - 1.0)
                    .abs()
                    < 1e-12,
                "{what}"
            );
            assert_eq!(
                rr.convergence.iter().map(|c| c.spp).collect::<Vec<_>>(),
                [1, 2, 4, 8]
            );
            for f in [&rr.equal_time_png, &rr.equal_time_exr, &rr.equal_spp_png] {
                let p = dir.path().join(f);
                assert!(
                    std::fs::metadata(&p).unwrap().len() > 100,
                    "{}",
                    p.display()
                );
            }

            // Relations between the fields. The pdf of a kind whose samples are drawn with
            // another density (the reparameterization sampler's pdf network, measured on its
            // samples in `sampled`) is not normalised: only the others' are bounded.
            let exact = x.fit.sampled.is_none();
            assert_eq!(
                x.fit.sampled.is_some(),
                x.method == "reparam",
                "{what}: measured on its own samples"
            );
            assert!(
                !exact || x.fit.mass_in_disk <= 1.0 + MASS_TOLERANCE,
                "{what}: mass in the disk {}",
                x.fit.mass_in_disk
            );
            assert!(
                oracle.fit.kl_divergence <= x.fit.kl_divergence + ORACLE_KL_TOLERANCE,
                "{what}: KL {} below the oracle's {}",
                x.fit.kl_divergence,
                oracle.fit.kl_divergence
            );
            assert!(
                close(
                    x.cost_vs_material_eval(),
                    x.cost.total_ns / x.cost.material_eval_ns.max(1e-9)
                ),
                "{what}"
            );
            assert_eq!(x.speedup_vs_baseline(), Some(rr.speedup.value), "{what}");
            assert_eq!(rr.equal_spp, max_spp, "{what}");
            let cosine_ns = cosine.render.as_ref().unwrap().ns_per_sample;
            assert!(
                close(rr.time_vs_cosine, rr.ns_per_sample / cosine_ns),
                "{what}"
            );
            assert!(rr.equal_time_spp <= 64 * max_spp, "{what}");
        }
        let b = base.render.as_ref().unwrap();
        assert!((base.speedup_vs_baseline().unwrap() - 1.0).abs() < 1e-12);
        assert!((b.speedup_measured_mse - 1.0).abs() < 1e-12);
        assert!((b.mse_ratio.value - 1.0).abs() < 1e-12);
        assert_eq!(b.equal_time_spp, max_spp);
        assert!((cosine.render.as_ref().unwrap().time_vs_cosine - 1.0).abs() < 1e-12);
        // Every image of the figures exists and is a PNG.
        let figures = m.figures.as_ref().expect("figures");
        for f in [
            &figures.equal_time,
            &figures.equal_spp,
            &figures.convergence,
            &figures.pdfs,
        ] {
            let p = dir.path().join(f);
            let bytes = std::fs::read(&p).unwrap();
            assert_eq!(&bytes[1..4], b"PNG", "{}", p.display());
        }
        // The verdict names a practical method with the largest speed-up.
        let v = m.verdict.as_ref().expect("verdict");
        assert_ne!(v.best, ORACLE);
        assert_eq!(v.clear, v.tied_with.is_empty());
        let best = m.methods.iter().find(|x| x.method == v.best).unwrap();
        for x in m.methods.iter().filter(|x| x.method != ORACLE) {
            assert!(
                x.speedup_vs_baseline() <= best.speedup_vs_baseline(),
                "{name}: {}",
                x.method
            );
        }
        let reference = m.reference.as_ref().expect("reference");
        assert!(finite(reference.noise, "noise") >= 0.0);
        assert_eq!(reference.spp, setup.settings.ref_spp);
    }
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(md.contains("Table 2") && md.contains("![equal time]"));
}

#[test]
fn procedural_demo_uses_the_source_materials() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = DemoConfig::new(dir.path());
    a.quick = true;
    a.use_fixtures = true;
    a.procedural = true;
    a.no_render = true;
    demo::run(&a).unwrap();
    let r = read_report(dir.path());
    assert!(r.render.is_none());
    let names: Vec<&str> = r
        .materials
        .iter()
        .map(|m| {
            assert!(m.neural.is_none());
            assert!(m.reference.is_none() && m.figures.is_none());
            for x in &m.methods {
                assert!(x.kl_vs_source.is_none());
                assert!(x.fit.kl_divergence.is_finite());
                assert!(x.render.is_none() && x.speedup_vs_baseline().is_none());
                assert!(x.fit.mass_in_disk <= 1.0 + MASS_TOLERANCE);
            }
            m.material.as_str()
        })
        .collect();
    assert_eq!(names, demo::DEFAULT_MATERIALS);
    // --procedural with explicit materials is a usage error.
    a.materials = vec!["gold".into()];
    let e = demo::run(&a).unwrap_err().to_string();
    assert!(e.contains("--procedural"), "{e}");
}

/// The committed reports still read into the current schema, written before it dropped the
/// copies of render values (schema 4) or after: where a report still holds the copies, they
/// equal what the current schema derives, and the fit's fields read into the method's `fit`.
#[test]
fn committed_reports_still_read() {
    let docs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs");
    for rel in [
        "table/uniform/report.json",
        "table/sky-sun/report.json",
        "measured/report_uniform.json",
    ] {
        let text = std::fs::read_to_string(docs.join(rel)).unwrap();
        let r: Report = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{rel}: {e}"));
        let raw: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert!(r.schema <= demo::REPORT_SCHEMA, "{rel}");
        let mut compared = 0;
        for (m, rm) in r.materials.iter().zip(raw["materials"].as_array().unwrap()) {
            for (x, rx) in m.methods.iter().zip(rm["methods"].as_array().unwrap()) {
                let what = format!("{rel}: {}/{}", m.material, x.method);
                let old = |v: &serde_json::Value| v.as_f64();
                let fit = [
                    ("kl_divergence", x.fit.kl_divergence),
                    ("pdf_mse", x.fit.pdf_mse),
                    ("mass_in_disk", x.fit.mass_in_disk),
                ];
                for (key, value) in fit {
                    let v = old(&rx[key]).unwrap_or_else(|| panic!("{what}: no {key}"));
                    assert_eq!(value, v, "{what}: {key}");
                }
                if let Some(v) = old(&rx["speedup_vs_baseline"]) {
                    assert_eq!(x.speedup_vs_baseline(), Some(v), "{what}");
                    compared += 1;
                }
                if let Some(v) = old(&rx["cost_vs_material_eval"]) {
                    assert!(close(x.cost_vs_material_eval(), v), "{what}");
                }
                if let Some(v) = old(&rx["render"]["mse_ratio_equal_spp"]) {
                    assert_eq!(x.render.as_ref().unwrap().mse_ratio.value, v, "{what}");
                }
            }
        }
        assert!(r.schema >= demo::REPORT_SCHEMA || compared > 0, "{rel}");
    }
}
