//! `neusample table --smoke` end to end on one built-in: both lightings' reports and the
//! combined tables.

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
