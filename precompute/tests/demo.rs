//! `neusample demo --quick --use-fixtures` end to end (on the committed neural materials, the
//! demo's default setting): the report, its required fields, the fit against the source
//! materials, the images and plots.

use neusample_precompute::demo::{self, DemoArgs};

#[test]
fn quick_demo_with_fixtures_writes_a_complete_report() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = DemoArgs::new(dir.path());
    a.quick = true;
    a.use_fixtures = true;
    demo::run(&a).unwrap();

    let text = std::fs::read_to_string(dir.path().join("report.json")).unwrap();
    let r: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(r["schema"], demo::REPORT_SCHEMA);
    let mats = r["materials"].as_array().unwrap();
    assert_eq!(mats.len(), demo::DEFAULT_MATERIALS.len());
    let finite = |v: &serde_json::Value, what: &str| -> f64 {
        let x = v
            .as_f64()
            .unwrap_or_else(|| panic!("{what} is not a number: {v}"));
        assert!(x.is_finite(), "{what} = {x}");
        x
    };
    for (m, source) in mats.iter().zip(demo::DEFAULT_MATERIALS) {
        let name = m["material"].as_str().unwrap();
        assert_eq!(name, format!("{source}{}", demo::NEURAL_SUFFIX));
        // The neural material is measured against its source.
        let n = &m["neural"];
        assert_eq!(n["source"], source);
        let kl = finite(&n["fit"]["kl_pstar"], "neural kl_pstar");
        let kl_cos = finite(&n["fit"]["kl_pstar_vs_cosine"], "kl_pstar_vs_cosine");
        assert!(kl >= 0.0 && kl < kl_cos, "{name}: {kl} vs cosine {kl_cos}");
        assert!(finite(&n["cost"]["eval_ns"], "eval_ns") > 0.0);
        let methods = m["methods"].as_array().unwrap();
        let names: Vec<&str> = methods
            .iter()
            .map(|x| x["method"].as_str().unwrap())
            .collect();
        assert_eq!(
            names,
            [
                "cosine",
                "baseline",
                "analytic",
                "flow",
                "affine-flow",
                "direct-histogram",
                "histogram-mixture",
                "oracle"
            ]
        );
        for x in methods {
            let what = format!("{name}/{}", x["method"]);
            for field in [
                "speedup_vs_baseline",
                "mse_equal_spp",
                "mse_equal_time",
                "ns_per_sample",
                "kl_divergence",
                "cost_vs_material_eval",
            ] {
                let v = finite(&x[field], &format!("{what}.{field}"));
                assert!(v >= 0.0, "{what}.{field} = {v}");
            }
            assert!(finite(&x["kl_vs_source"], &format!("{what}.kl_vs_source")) >= 0.0);
            let rr = &x["render"];
            for field in [
                "ns_per_sample",
                "mse_equal_spp",
                "mse_equal_time",
                "speedup_vs_baseline",
            ] {
                assert!(finite(&rr[field], &format!("{what}.render.{field}")) > 0.0);
            }
            assert!(rr["equal_time_spp"].as_u64().unwrap() >= 1);
            let conv = rr["convergence"].as_array().unwrap();
            assert_eq!(
                conv.iter()
                    .map(|c| c["spp"].as_u64().unwrap())
                    .collect::<Vec<_>>(),
                [1, 2, 4, 8]
            );
            for f in ["equal_time_png", "equal_time_exr", "equal_spp_png"] {
                let p = dir.path().join(rr[f].as_str().unwrap());
                assert!(
                    std::fs::metadata(&p).unwrap().len() > 100,
                    "{}",
                    p.display()
                );
            }
        }
        let base = methods.iter().find(|x| x["method"] == "baseline").unwrap();
        assert!((finite(&base["speedup_vs_baseline"], "baseline") - 1.0).abs() < 1e-12);
        // Every image of the figures exists and is a PNG.
        for f in ["equal_time", "equal_spp", "convergence", "pdfs"] {
            let p = dir.path().join(m["figures"][f].as_str().unwrap());
            let bytes = std::fs::read(&p).unwrap();
            assert_eq!(&bytes[1..4], b"PNG", "{}", p.display());
        }
        assert!(finite(&m["reference"]["noise"], "noise") >= 0.0);
    }
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(md.contains("Table 2") && md.contains("![equal time]"));
}

#[test]
fn procedural_demo_uses_the_source_materials() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = DemoArgs::new(dir.path());
    a.quick = true;
    a.use_fixtures = true;
    a.procedural = true;
    a.no_render = true;
    demo::run(&a).unwrap();
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    let names: Vec<&str> = r["materials"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            assert!(m["neural"].is_null());
            for x in m["methods"].as_array().unwrap() {
                assert!(x["kl_vs_source"].is_null());
                assert!(x["kl_divergence"].as_f64().unwrap().is_finite());
            }
            m["material"].as_str().unwrap()
        })
        .collect();
    assert_eq!(names, demo::DEFAULT_MATERIALS);
    // --procedural with explicit materials is a usage error.
    a.materials = vec!["gold".into()];
    let e = demo::run(&a).unwrap_err().to_string();
    assert!(e.contains("--procedural"), "{e}");
}
