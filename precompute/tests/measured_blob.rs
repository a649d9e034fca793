//! `neusample measured-blob`'s job: an RGL `.bsdf` file becomes a measured blob that opens
//! and that `inspect` describes; bad inputs are errors that name the file.

use std::path::Path;

use neusample_precompute::jobs::inspect::inspect;
use neusample_precompute::jobs::measured::{measured_blob, MeasuredBlobJob};

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/measured")
        .join(name)
}

#[test]
fn converts_and_inspects_a_fixture() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mint.nsb");
    let r = measured_blob(&MeasuredBlobJob {
        input: fixture("chm_mint_rgb.bsdf"),
        out: out.clone(),
        name: Some("mint".into()),
    })
    .unwrap();
    assert_eq!(r.bytes, std::fs::metadata(&out).unwrap().len() as usize);
    assert!(r
        .label
        .starts_with("name=mint source=chm_mint_rgb.bsdf description: "));
    assert_eq!(r.shape.len(), 11);
    let info = inspect(&out).unwrap();
    assert_eq!(info.kind, "measured");
    let m = info.measured.as_ref().expect("a measured section");
    assert_eq!([m.n_phi, m.n_theta], [r.shape[0], r.shape[1]]);
    assert_eq!(m.tables.len(), 11);
    let text = info.text();
    assert!(
        text.contains("measured blob") && text.contains("measured material:"),
        "{text}"
    );
    let json = serde_json::to_value(&info).unwrap();
    assert!(json["measured"]["tables"].is_array());
}

#[test]
fn bad_inputs_are_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let job = |input: &Path, out: &Path| MeasuredBlobJob {
        input: input.to_path_buf(),
        out: out.to_path_buf(),
        name: None,
    };
    let out = dir.path().join("x.nsb");
    let missing = dir.path().join("missing.bsdf");
    let e = measured_blob(&job(&missing, &out)).unwrap_err().to_string();
    assert!(e.contains("missing.bsdf"), "{e}");
    let e = measured_blob(&job(&fixture("MANIFEST.txt"), &out))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("MANIFEST.txt") && e.contains("tensor file"),
        "{e}"
    );
    let input = fixture("paper_white_rgb.bsdf");
    let e = measured_blob(&job(&input, &input)).unwrap_err().to_string();
    assert!(e.contains("overwrite"), "{e}");
    measured_blob(&job(&input, &out)).unwrap();
    let e = measured_blob(&job(&out, &dir.path().join("y.nsb")))
        .unwrap_err()
        .to_string();
    assert!(e.contains("already a neusample blob"), "{e}");
    let mut bad = job(&input, &out);
    bad.name = Some("two words".into());
    assert!(measured_blob(&bad).is_err());
    assert!(!dir.path().join("y.nsb").exists());
}
