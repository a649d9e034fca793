//! `neusample demo --quick --use-fixtures` end to end: the report, its required fields, the
//! images and plots.

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
    for m in mats {
        let name = m["material"].as_str().unwrap();
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
