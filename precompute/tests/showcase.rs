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

fn fixture(rel: &str) -> String {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures")
        .join(rel)
        .display()
        .to_string()
}

#[test]
fn measured_file_renders_as_itself_with_its_committed_samplers() {
    let dir = tempfile::tempdir().unwrap();
    let mut c = tiny(dir.path());
    c.materials = vec!["wagon_wood".to_string(), fixture("measured/chm_mint.toml")];
    c.methods = vec![("chm_mint".to_string(), "analytic".to_string())];
    showcase::run(&c).unwrap();
    let text = std::fs::read_to_string(dir.path().join("showcase.json")).unwrap();
    let r: ShowcaseReport = serde_json::from_str(&text).unwrap();
    let mint = &r.materials[1];
    assert_eq!(
        (
            mint.material.as_str(),
            mint.method.as_str(),
            mint.method_source
        ),
        ("chm_mint", "analytic", MethodSource::Given)
    );
    assert_eq!(mint.objects.len(), 4);
    assert!(mint.pixels > 0);
    for x in [&mint.baseline, &mint.best] {
        assert!(x.mse.is_finite() && x.mse >= 0.0, "{x:?}");
    }
}

#[test]
fn file_materials_without_samplers_name_the_missing_blob() {
    let dir = tempfile::tempdir().unwrap();
    let mut c = tiny(dir.path());
    // The committed mint samplers hold no histogram mixture.
    c.materials = vec![fixture("measured/chm_mint.toml")];
    c.methods = vec![("chm_mint".to_string(), "histogram-mixture".to_string())];
    let e = format!("{:#}", showcase::run(&c).unwrap_err());
    assert!(e.contains("chm_mint/histogram-mixture.nsb"), "{e}");
    assert!(e.contains("neusample train"), "{e}");

    // `--blobs` is searched first: a folder holding the missing method (here the analytic
    // blob under the mixture's name) under the material's name completes the set.
    let blobs = dir.path().join("blobs");
    let src = fixture("measured/blobs/chm_mint");
    std::fs::create_dir_all(blobs.join("chm_mint")).unwrap();
    for m in ["baseline", "flow"] {
        std::fs::copy(
            format!("{src}/{m}.nsb"),
            blobs.join("chm_mint").join(format!("{m}.nsb")),
        )
        .unwrap();
    }
    std::fs::copy(
        format!("{src}/analytic.nsb"),
        blobs.join("chm_mint").join("histogram-mixture.nsb"),
    )
    .unwrap();
    c.blobs = Some(blobs);
    showcase::run(&c).unwrap();

    let mut c = tiny(dir.path());
    c.materials = vec![fixture("measured/no_such.toml")];
    let e = format!("{:#}", showcase::run(&c).unwrap_err());
    assert!(e.contains("no_such.toml"), "{e}");
}

/// The runtime sampler with the largest equal-time speed-up of `material` in a demo report.
fn best_runtime_sampler(report: &serde_json::Value, material: &str) -> String {
    let m = report["materials"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["material"] == material)
        .unwrap();
    m["methods"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|x| !["oracle", "measured-data"].contains(&x["method"].as_str().unwrap()))
        .filter_map(|x| {
            Some((
                x["method"].as_str()?,
                x["render"]["speedup"]["value"].as_f64()?,
            ))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap()
        .0
        .to_string()
}

#[test]
fn a_table_whose_verdict_is_the_data_sampler_gives_the_best_runtime_sampler() {
    // Under the sky the mint's verdict is the data's own sampler, which the scene's
    // wavefront renderer does not take: the table's best runtime sampler stands in.
    let table =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/measured/report_sky.json");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&table).unwrap()).unwrap();
    let mint = report["materials"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["material"] == "chm_mint")
        .unwrap();
    assert_eq!(mint["verdict"]["best"], "measured-data");
    let expected = best_runtime_sampler(&report, "chm_mint");

    let dir = tempfile::tempdir().unwrap();
    let mut c = tiny(dir.path());
    c.materials = vec![fixture("measured/chm_mint.toml")];
    c.methods.clear();
    c.table = Some(table);
    match showcase::run(&c) {
        Ok(()) => {
            let text = std::fs::read_to_string(dir.path().join("showcase.json")).unwrap();
            let r: ShowcaseReport = serde_json::from_str(&text).unwrap();
            assert_eq!(r.materials[0].method, expected);
            assert_eq!(r.materials[0].method_source, MethodSource::Table);
        }
        // The committed mint samplers may lack the chosen one: the error names it.
        Err(e) => {
            let e = format!("{e:#}");
            assert!(e.contains(&format!("chm_mint/{expected}.nsb")), "{e}");
        }
    }

    let mut c = tiny(dir.path());
    c.materials = vec![fixture("measured/chm_mint.toml")];
    c.methods = vec![("chm_mint".to_string(), "measured-data".to_string())];
    let e = format!("{:#}", showcase::run(&c).unwrap_err());
    assert!(e.contains("data's own sampler"), "{e}");
}
