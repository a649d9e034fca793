//! Cost of every sampler on the committed fixture blobs, per call: `prepare`, `sample`, `pdf`
//! and `prepare + sample + pdf` (one shading point), through the blob's `AnySampler` as a
//! renderer would use it.
//!
//! ```text
//! cargo bench -p neusample-host-tests --bench cost
//! NEUSAMPLE_COST_MATERIAL=brushed_metal cargo bench -p neusample-host-tests --bench cost
//! ```
//!
//! Each call takes the next of 256 conditions of the material's `conditions.txt` (so the
//! branch predictor does not learn one input), a seeded uniform `u` for `sample`, and a
//! seeded direction (θ < 1.4 rad, uniform azimuth) for `pdf`. Divan reports the time per
//! call; run single-threaded (the default) on an otherwise idle machine.
//!
//! `total_by_ref` is `total` with the prepared state matched by reference: the difference is
//! the cost of moving an `Option<AnyPrepared>` (2 KiB, sized by the direct histogram's tables)
//! out of `prepare`'s return value.

use std::hint::black_box;
use std::path::PathBuf;
use std::sync::OnceLock;

use divan::Bencher;
use neusample::{AnyPrepared, AnySampler, Blob, TensorRole};
use neusample::{Prepared, Sampler, Tensor, Vec2, Vec3, Weights};
use rand::RngExt;

/// Conditions (and inputs) cycled through; a power of two.
const CALLS: usize = 256;

/// The blobs benchmarked, by file stem.
const METHODS: [&str; 7] = [
    "cosine",
    "baseline",
    "analytic",
    "flow",
    "affine-flow",
    "direct-histogram",
    "histogram-mixture",
];

/// One method's sampler and its inputs.
struct Fixture {
    blob: Blob<'static>,
    sampler: AnySampler<'static>,
    conds: Vec<([f32; 8], Vec3)>,
    us: Vec<Vec2>,
    wos: Vec<Vec3>,
}

impl Fixture {
    /// The prepared state of every condition (all fixture conditions are accepted).
    fn prepared(&self) -> Vec<AnyPrepared<'_, 'static>> {
        self.conds
            .iter()
            .map(|(phi, wi)| {
                self.sampler
                    .prepare(phi, *wi)
                    .expect("fixture condition refused")
            })
            .collect()
    }
}

fn blob_dir() -> PathBuf {
    neusample_host_tests::fixture_blobs_dir()
}

fn material() -> String {
    std::env::var("NEUSAMPLE_COST_MATERIAL").unwrap_or_else(|_| "goat_leather".into())
}

fn load(method: &str) -> Fixture {
    let dir = blob_dir().join(material());
    let path = if method == "cosine" {
        blob_dir().join("cosine.nsb")
    } else {
        dir.join(format!("{method}.nsb"))
    };
    // Leaked once per method so the sampler can borrow the bytes for the whole run.
    let bytes: &'static [u8] =
        Vec::leak(std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())));
    let blob = Blob::open(bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let sampler = blob.sampler().expect("fixture blob has no sampler");
    let mut conds = neusample_host_tests::fixture_conditions(&dir);
    assert!(!conds.is_empty());
    while conds.len() < CALLS {
        conds.extend_from_within(..);
    }
    conds.truncate(CALLS);
    let mut rng = neusample_host_tests::rng(0xC057);
    let us = (0..CALLS)
        .map(|_| neusample_host_tests::uniform2(&mut rng))
        .collect();
    let wos = (0..CALLS)
        .map(|_| {
            let theta = rng.random::<f32>() * 1.4;
            let phi = rng.random::<f32>() * std::f32::consts::TAU;
            Vec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            )
        })
        .collect();
    Fixture {
        blob,
        sampler,
        conds,
        us,
        wos,
    }
}

/// The fixture of `method`, loaded once.
fn fixture(method: &str) -> &'static Fixture {
    static ALL: OnceLock<Vec<(&'static str, Fixture)>> = OnceLock::new();
    let all = ALL.get_or_init(|| METHODS.iter().map(|&m| (m, load(m))).collect());
    &all.iter()
        .find(|(m, _)| *m == method)
        .expect("unknown method")
        .1
}

fn main() {
    println!(
        "material {}; size_of AnySampler {} B, Option<AnyPrepared> {} B",
        material(),
        std::mem::size_of::<AnySampler<'static>>(),
        std::mem::size_of::<Option<AnyPrepared<'static, 'static>>>()
    );
    for m in METHODS {
        let f = fixture(m);
        let mut tensors = String::new();
        for role in [
            TensorRole::Params,
            TensorRole::Mass,
            TensorRole::Table,
            TensorRole::Marginal,
            TensorRole::Conditional,
        ] {
            if let Some(t) = f.blob.tensor(role) {
                let storage = match t {
                    Tensor::F32(_) => "f32",
                    Tensor::F32Bytes(_) => "f32 (unaligned bytes)",
                    Tensor::F16Bytes(_) => "f16",
                };
                tensors += &format!(" {}[{}] {storage};", role.name(), t.len());
            }
        }
        let h = f.blob.header();
        println!(
            "{m:<18} T = {}, N = {}, {:?}:{tensors}",
            h.t_levels, h.resolution, h.interpolation
        );
    }
    divan::main();
}

/// `prepare` alone (the networks, once per shading point).
#[divan::bench(args = METHODS, sample_size = CALLS as u32)]
fn prepare(b: Bencher, method: &str) {
    let f = fixture(method);
    let mut i = 0;
    b.bench_local(|| {
        i = (i + 1) % CALLS;
        let (phi, wi) = &f.conds[i];
        f.sampler.prepare(black_box(phi), black_box(*wi))
    });
}

/// `sample` on a prepared state.
#[divan::bench(args = METHODS, sample_size = CALLS as u32)]
fn sample(b: Bencher, method: &str) {
    let f = fixture(method);
    let prepared = f.prepared();
    let mut i = 0;
    b.bench_local(|| {
        i = (i + 1) % CALLS;
        prepared[i].sample(black_box(f.us[i]))
    });
}

/// `pdf` (solid angle) of a direction on a prepared state.
#[divan::bench(args = METHODS, sample_size = CALLS as u32)]
fn pdf(b: Bencher, method: &str) {
    let f = fixture(method);
    let prepared = f.prepared();
    let mut i = 0;
    b.bench_local(|| {
        i = (i + 1) % CALLS;
        prepared[i].pdf(black_box(f.wos[i]))
    });
}

/// One shading point: `prepare`, one `sample` and one `pdf` (BSDF sample + MIS of a light
/// sample).
#[divan::bench(args = METHODS, sample_size = CALLS as u32)]
fn total(b: Bencher, method: &str) {
    let f = fixture(method);
    let mut i = 0;
    b.bench_local(|| {
        i = (i + 1) % CALLS;
        let (phi, wi) = &f.conds[i];
        match f.sampler.prepare(black_box(phi), black_box(*wi)) {
            Some(p) => (p.sample(black_box(f.us[i])), p.pdf(black_box(f.wos[i]))),
            None => (None, 0.0),
        }
    });
}

/// `total` binding the prepared state by reference (no move out of the `Option`).
#[divan::bench(args = METHODS, sample_size = CALLS as u32)]
fn total_by_ref(b: Bencher, method: &str) {
    let f = fixture(method);
    let mut i = 0;
    b.bench_local(|| {
        i = (i + 1) % CALLS;
        let (phi, wi) = &f.conds[i];
        let prepared = f.sampler.prepare(black_box(phi), black_box(*wi));
        match &prepared {
            Some(p) => (p.sample(black_box(f.us[i])), p.pdf(black_box(f.wos[i]))),
            None => (None, 0.0),
        }
    });
}
