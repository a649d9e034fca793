//! Golden values from the Rust scalar API (`features`, `prepare` → `sample`, `eval`) for
//! every fixture sampler of the three demo materials, written to
//! `bindings/python/tests/golden.txt`. The Python tests compare the batched bindings with
//! this file bit for bit; this test fails when the runtime's numbers change.
//! `NEUSAMPLE_BLESS=1 cargo test -p neusample-owned --test golden` rewrites it.

use std::fmt::Write as _;
use std::path::Path;

use neusample::{Prepared, Sampler, Vec2, Vec3};
use neusample_owned::{OwnedBlob, OwnedMaterial, OwnedSampler};

const MATERIALS: [&str; 3] = [
    "goat_leather_neural",
    "brushed_metal_neural",
    "victorian_fabric_neural",
];
const METHODS: [&str; 7] = [
    "cosine",
    "baseline",
    "analytic",
    "flow",
    "affine-flow",
    "direct-histogram",
    "histogram-mixture",
];

#[test]
fn golden_values_are_current() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut text = String::from(
        "# material method uv.x uv.y wi.x wi.y wi.z u.x u.y | phi[8] | wo.x wo.y wo.z pdf | f.r f.g f.b\n",
    );
    let points = [
        ([0.25f32, 0.5], [0.0f32, 0.0, 1.0], [0.3f32, 0.7]),
        ([0.77, 0.13], [0.48, -0.36, 0.8], [0.9, 0.05]),
        ([0.5, 0.91], [-0.6, 0.64, 0.48], [0.51, 0.49]),
    ];
    for m in MATERIALS {
        let mblob =
            OwnedBlob::open(&root.join(format!("fixtures/materials/neural/{m}.nsb"))).unwrap();
        let material = OwnedMaterial::new(&mblob).unwrap();
        for method in METHODS {
            let sampler = if method == "cosine" {
                OwnedSampler::cosine()
            } else {
                let b = OwnedBlob::open(&root.join(format!("fixtures/blobs/{m}/{method}.nsb")))
                    .unwrap();
                OwnedSampler::new(&b).unwrap()
            };
            for (uv, wi, u) in points {
                let wi = Vec3::from(wi).normalize();
                let phi = material.get().features(Vec2::from(uv));
                let (wo, pdf) = match sampler
                    .get()
                    .prepare(&phi, wi)
                    .and_then(|p| p.sample(Vec2::from(u)))
                {
                    Some(s) => (s.wo, s.pdf),
                    None => (Vec3::ZERO, 0.0),
                };
                let f = material.get().eval(&phi, wi, wo);
                write!(
                    text,
                    "{m} {method} {} {} {} {} {} {} {} |",
                    uv[0], uv[1], wi.x, wi.y, wi.z, u[0], u[1]
                )
                .unwrap();
                for p in phi {
                    write!(text, " {p}").unwrap();
                }
                writeln!(
                    text,
                    " | {} {} {} {pdf} | {} {} {}",
                    wo.x, wo.y, wo.z, f[0], f[1], f[2]
                )
                .unwrap();
            }
        }
    }
    let path = root.join("bindings/python/tests/golden.txt");
    if std::env::var_os("NEUSAMPLE_BLESS").is_some() {
        std::fs::write(&path, &text).unwrap();
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == text,
        "bindings/python/tests/golden.txt is stale: NEUSAMPLE_BLESS=1 cargo test -p neusample-owned --test golden"
    );
}
