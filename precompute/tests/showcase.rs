//! `neusample scene` end to end at a tiny size: two materials with given methods, the files,
//! and the report's equal-time budget and MSEs; bad inputs are errors, not panics.

use neusample_precompute::demo::showcase::{self, MethodSource, ShowcaseConfig, ShowcaseReport};

fn tiny(out: &std::path::Path) -> ShowcaseConfig {
    let mut c = ShowcaseConfig::new(out);
    c.materials = vec!["wagon_wood".to_string(), "gold".to_string()];
    c.methods = vec![("gold".to_string(), "flow".to_string())];
    c.width = 24;
    c.spp = 2;
    c.ref_factor = 4;
    c.bounces = 2;
    c.timing_passes = 1;
    c
}

#[test]
fn tiny_showcase_writes_its_files_and_finite_mses() {
    let dir = tempfile::tempdir().unwrap();
    showcase::run(&tiny(dir.path())).unwrap();
    for f in [
        "showcase.png",
        "showcase.md",
        "showcase.json",
        "reference.exr",
        "baseline.exr",
        "best.exr",
    ] {
        assert!(dir.path().join(f).is_file(), "{f} missing");
    }
    let text = std::fs::read_to_string(dir.path().join("showcase.json")).unwrap();
    let r: ShowcaseReport = serde_json::from_str(&text).unwrap();
    assert_eq!(r.schema, showcase::SHOWCASE_SCHEMA);
    assert_eq!((r.width, r.height, r.bounces), (24, 13, 2));
    assert_eq!(r.baseline.spp, 2);
    assert!(r.best.spp >= 1);
    assert!(r.pixels > 0);
    for x in [&r.baseline, &r.best] {
        assert!(x.mse.mse.is_finite() && x.mse.mse >= 0.0, "{:?}", x.mse);
        assert!(x.ns_per_sample > 0.0);
    }
    let methods: Vec<(&str, &str, MethodSource)> = r
        .materials
        .iter()
        .map(|m| (m.material.as_str(), m.method.as_str(), m.method_source))
        .collect();
    assert_eq!(
        methods,
        [
            (
                "wagon_wood_neural",
                showcase::FALLBACK_METHOD,
                MethodSource::Fallback
            ),
            ("gold_neural", "flow", MethodSource::Given),
        ]
    );
    assert_eq!(r.materials[0].objects, ["floor"]);
    assert_eq!(r.materials[1].objects.len(), 4);
}

#[test]
fn bad_inputs_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let mut c = tiny(dir.path());
    c.materials = vec!["no_such_material".to_string()];
    let e = format!("{:#}", showcase::run(&c).unwrap_err());
    assert!(e.contains("no_such_material"), "{e}");

    let mut c = tiny(dir.path());
    c.methods = vec![("gold".to_string(), "oracle".to_string())];
    let e = format!("{:#}", showcase::run(&c).unwrap_err());
    assert!(e.contains("unknown method `oracle`"), "{e}");

    let mut c = tiny(dir.path());
    c.methods = vec![("car_paint".to_string(), "flow".to_string())];
    let e = format!("{:#}", showcase::run(&c).unwrap_err());
    assert!(e.contains("car_paint"), "{e}");

    let mut c = tiny(dir.path());
    c.table = Some(dir.path().join("no_table"));
    let e = format!("{:#}", showcase::run(&c).unwrap_err());
    assert!(e.contains("sky-sun/report.json"), "{e}");

    let not_a_report = dir.path().join("report.json");
    std::fs::write(&not_a_report, "{}").unwrap();
    let mut c = tiny(dir.path());
    c.table = Some(not_a_report);
    let e = format!("{:#}", showcase::run(&c).unwrap_err());
    assert!(e.contains("is not a demo report"), "{e}");

    assert!(showcase::parse_method_choice("gold").is_err());
    assert!(showcase::parse_method_choice("=flow").is_err());
    assert_eq!(
        showcase::parse_method_choice(" gold = flow ").unwrap(),
        ("gold".to_string(), "flow".to_string())
    );
    assert!(!dir.path().join("showcase.json").exists());
}
