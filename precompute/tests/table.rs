//! `neusample table --smoke` end to end on one built-in (both lightings' reports and the
//! combined tables) and on material files (a measured material and its neural fit, whose
//! samplers it trains once).

use std::path::Path;
use std::time::Instant;

use neusample::SamplerKind;
use neusample_precompute::demo::{self, Lighting, TableConfig};

#[test]
fn smoke_table_writes_both_lightings_and_the_combined_tables() {
    let dir = tempfile::tempdir().unwrap();
    let mut c = TableConfig::new(dir.path());
    c.materials = vec!["goat_leather".into()];
    c.smoke = true;
    demo::table::run(&c).unwrap();
    for l in Lighting::ALL {
        let text = std::fs::read_to_string(dir.path().join(l.name()).join("report.json")).unwrap();
        let r: demo::Report = serde_json::from_str(&text).unwrap();
        assert_eq!(r.materials.len(), 1);
        assert_eq!(
            r.render.as_ref().unwrap().uniform_light,
            l == Lighting::Uniform
        );
    }
    let md = std::fs::read_to_string(dir.path().join("table.md")).unwrap();
    assert!(md.starts_with(demo::SMOKE_LINE));
    for needle in [
        "## Table 2, uniform white light",
        "## Table 2, sky with a small bright sun",
        "## Table 1",
        "| goat_leather_neural |",
        "uniform/plots/goat_leather_neural_convergence.png",
    ] {
        assert!(md.contains(needle), "table.md lacks `{needle}`");
    }
    // Table 2 has one row per material and lighting; Table 1 one per practical method.
    assert_eq!(md.matches("| goat_leather_neural |").count(), 2 + 2 + 1);
    // Rewriting from the reports gives the same file.
    c.markdown_only = true;
    demo::table::run(&c).unwrap();
    assert_eq!(
        std::fs::read_to_string(dir.path().join("table.md")).unwrap(),
        md
    );
    assert!(!md.contains("an earlier run"));
    // One lighting asked for: the other's report in the folder is kept, marked as earlier.
    c.lightings = vec![Lighting::Uniform];
    demo::table::run(&c).unwrap();
    let one = std::fs::read_to_string(dir.path().join("table.md")).unwrap();
    assert!(one.contains("## Table 2, sky with a small bright sun"));
    assert_eq!(one.matches("an earlier run").count(), 1);
    assert!(one.contains("sky with a small bright sun: "));
}

/// A measured material file and its neural fit, neither with committed samplers: `table
/// --smoke` trains their samplers once into `<out>/blobs/<name>/`, both lightings evaluate
/// those blobs, the fit is measured against its source (the material file one folder up),
/// and the combined tables have a row for each.
#[test]
fn smoke_table_on_material_files_trains_their_samplers_once() {
    let measured = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/measured");
    let dir = tempfile::tempdir().unwrap();
    let mut c = TableConfig::new(dir.path());
    c.materials = vec![
        measured.join("chm_mint.toml").display().to_string(),
        measured
            .join("neural/chm_mint_neural.nsb")
            .display()
            .to_string(),
    ];
    c.smoke = true;
    // The improved baseline alone (always evaluated): the least training and rendering.
    c.methods = vec![SamplerKind::ImprovedBaseline];
    let t = Instant::now();
    demo::table::run(&c).unwrap();
    eprintln!(
        "table --smoke on two files: {:.1} s",
        t.elapsed().as_secs_f64()
    );

    let methods = [SamplerKind::ImprovedBaseline];
    for name in ["chm_mint", "chm_mint_neural"] {
        for m in methods {
            let file = format!("{}.nsb", m.name());
            let trained = std::fs::read(dir.path().join("blobs").join(name).join(&file))
                .unwrap_or_else(|e| panic!("{name}/{file} not trained into <out>/blobs: {e}"));
            for l in Lighting::ALL {
                let used = dir
                    .path()
                    .join(l.name())
                    .join("blobs")
                    .join(name)
                    .join(&file);
                assert!(
                    std::fs::read(&used).unwrap() == trained,
                    "{}: the {} run used another {name}/{file}",
                    used.display(),
                    l.name()
                );
            }
        }
    }
    for l in Lighting::ALL {
        let text = std::fs::read_to_string(dir.path().join(l.name()).join("report.json")).unwrap();
        let r: demo::Report = serde_json::from_str(&text).unwrap();
        let names: Vec<&str> = r.materials.iter().map(|m| m.material.as_str()).collect();
        assert_eq!(names, ["chm_mint", "chm_mint_neural"]);
        let (mint, fit) = (&r.materials[0], &r.materials[1]);
        assert!(mint.methods.iter().any(|x| x.method == "measured-data"));
        assert!(mint.neural.is_none());
        assert_eq!(
            fit.neural.as_ref().map(|n| n.source.as_str()),
            Some("chm_mint")
        );
        for m in &r.materials {
            for k in methods {
                assert!(
                    m.methods.iter().any(|x| x.method == k.name()),
                    "{}",
                    m.material
                );
            }
        }
    }
    let md = std::fs::read_to_string(dir.path().join("table.md")).unwrap();
    assert!(md.starts_with(demo::SMOKE_LINE));
    assert!(md.contains("# neusample over the materials asked for"));
    // Table 2 and the MSE ratios: one row per lighting each; the plots table: one row.
    for name in ["chm_mint", "chm_mint_neural"] {
        assert_eq!(
            md.matches(&format!("| {name} |")).count(),
            2 + 2 + 1,
            "{name}"
        );
    }
}

/// An entry that is neither a built-in nor a file names itself.
#[test]
fn an_unknown_material_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let mut c = TableConfig::new(dir.path());
    c.materials = vec!["goat_leather".into(), "no_such_material".into()];
    c.smoke = true;
    let e = format!("{:#}", demo::table::run(&c).unwrap_err());
    assert!(
        e.contains("`no_such_material` is neither a built-in material nor a material file"),
        "{e}"
    );
}
