//! The wavefront integrator against the scalar one: the same mask and the same image,
//! variance and checkpoints within the batched runtime's tolerances, on the committed fixture
//! samplers and neural material, with and without MIS, jitter and global illumination, with
//! tiles that do not divide the image, and with two surfaces in one scene; and bit for bit
//! independent of the number of threads.

use std::path::{Path, PathBuf};

use neusample::{Blob, BlobSampler, NeuralMaterial, Tensor};
use neusample_render::{
    demo_scene, render, render_wavefront, Estimator, Render, RenderOptions, Scene, SceneParams,
    Surface,
};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures")
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The sampler blobs of the goat-leather fixture, and the cosine blob.
fn sampler_blobs() -> Vec<(String, Vec<u8>)> {
    let dir = fixtures().join("blobs/goat_leather_neural");
    let mut v: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "nsb"))
        .collect();
    v.sort();
    v.push(fixtures().join("blobs/cosine.nsb"));
    v.into_iter()
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                read(&p),
            )
        })
        .collect()
}

fn values(r: &Render) -> Vec<f32> {
    let mut v = Vec::new();
    for img in [&r.image, &r.variance]
        .into_iter()
        .chain(r.checkpoints.iter().map(|(_, i)| i))
    {
        v.extend(img.data.iter().flat_map(|c| *c));
    }
    v
}

/// The two renders bit for bit (the same integrator and instruction set).
fn assert_identical(a: &Render, b: &Render, what: &str) {
    assert_eq!(a.mask, b.mask, "{what}: hit masks differ");
    let (x, y) = (values(a), values(b));
    let differ = x
        .iter()
        .zip(&y)
        .filter(|(p, q)| p.to_bits() != q.to_bits())
        .count();
    assert_eq!(differ, 0, "{what}: {differ} of {} values differ", x.len());
}

/// Values (image, variance, checkpoints) that may differ from the other integrator's by more
/// than [`VALUE_RTOL`], as a fraction: a path whose direction moved by the batched path's
/// rounding can hit another surface after a bounce (measured: at most 1 % with global
/// illumination, none in direct lighting).
const FAR_FRACTION: f64 = 0.02;
/// Relative tolerance per value (measured in direct lighting: at most 4.9e-4).
const VALUE_RTOL: f64 = 1e-3;
/// Relative tolerance on the mean of the image (measured: at most 6e-6).
const MEAN_RTOL: f64 = 1e-4;

/// The wavefront render against the scalar one: the same pixels hit, every value within
/// [`VALUE_RTOL`] but for [`FAR_FRACTION`] of them, the mean image within [`MEAN_RTOL`].
/// The batched runtime agrees with the scalar one within its tolerances (fused multiply-adds
/// in the networks), not bit for bit.
fn assert_same(a: &Render, b: &Render, what: &str) {
    assert_eq!(a.checkpoints.len(), b.checkpoints.len(), "{what}");
    assert_eq!(a.mask, b.mask, "{what}: hit masks differ");
    let (x, y) = (values(a), values(b));
    let far = x
        .iter()
        .zip(&y)
        .filter(|(p, q)| {
            let (p, q) = (f64::from(**p), f64::from(**q));
            (p - q).abs() > VALUE_RTOL * p.abs().max(q.abs())
        })
        .count();
    assert!(
        far as f64 <= FAR_FRACTION * x.len() as f64,
        "{what}: {far} of {} values differ by more than {VALUE_RTOL:e}",
        x.len()
    );
    let mean = |r: &Render| {
        r.image
            .data
            .iter()
            .flat_map(|c| *c)
            .map(f64::from)
            .sum::<f64>()
    };
    let (ma, mb) = (mean(a), mean(b));
    assert!(
        (ma - mb).abs() <= MEAN_RTOL * ma.abs().max(mb.abs()),
        "{what}: mean images differ: {ma} vs {mb}"
    );
}

/// The option sets compared: the paper's mode, MIS with jitter, and three-bounce global
/// illumination with MIS, each with a tile size that does not divide the image.
fn option_sets() -> Vec<(&'static str, RenderOptions)> {
    let mut v = Vec::new();
    let mut o = RenderOptions::new(4, 11);
    o.wavefront_pixels = 37;
    v.push(("bsdf", o.clone()));
    o.estimator = Estimator::Mis;
    o.jitter = true;
    o.wavefront_pixels = 100;
    v.push(("mis+jitter", o.clone()));
    o.max_bounces = 3;
    o.wavefront_pixels = 64;
    v.push(("mis+gi", o));
    v
}

fn scene() -> Scene {
    demo_scene(&SceneParams {
        width: 24,
        height: 18,
        ..SceneParams::default()
    })
}

fn material(bytes: &[u8]) -> NeuralMaterial<Tensor<'_>> {
    Blob::open(bytes).unwrap().neural_material().unwrap()
}

#[test]
fn wavefront_equals_scalar_for_every_fixture_sampler() {
    let mbytes = read(&fixtures().join("materials/neural/goat_leather_neural.nsb"));
    let m = material(&mbytes);
    let scene = scene();
    for (name, bytes) in sampler_blobs() {
        let blob = Blob::open(&bytes).unwrap();
        let s = blob.sampler().unwrap();
        for (what, o) in option_sets() {
            let surfaces = [Surface::new(&m, s)];
            let a = render(&scene, &surfaces, &o);
            let b = render_wavefront(&scene, &surfaces, &o);
            assert!(a.mask.iter().any(|&h| h), "{name}: nothing hit");
            assert_same(&a, &b, &format!("{name} {what}"));
        }
    }
}

#[test]
fn wavefront_equals_scalar_with_two_surfaces() {
    let mbytes = read(&fixtures().join("materials/neural/goat_leather_neural.nsb"));
    let m = material(&mbytes);
    let dir = fixtures().join("blobs/goat_leather_neural");
    let flow = read(&dir.join("flow.nsb"));
    let mixture = read(&dir.join("histogram-mixture.nsb"));
    let (flow, mixture) = (Blob::open(&flow).unwrap(), Blob::open(&mixture).unwrap());
    let samplers: [BlobSampler<'_>; 2] = [flow.sampler().unwrap(), mixture.sampler().unwrap()];
    let mut scene = scene();
    scene.objects[1].surface = 1;
    let surfaces = samplers.map(|s| Surface::new(&m, s));
    for (what, o) in option_sets() {
        let a = render(&scene, &surfaces, &o);
        let b = render_wavefront(&scene, &surfaces, &o);
        assert_same(&a, &b, &format!("two surfaces, {what}"));
    }
}

#[test]
fn wavefront_is_independent_of_the_thread_count() {
    let mbytes = read(&fixtures().join("materials/neural/goat_leather_neural.nsb"));
    let m = material(&mbytes);
    let bytes = read(&fixtures().join("blobs/goat_leather_neural/flow.nsb"));
    let blob = Blob::open(&bytes).unwrap();
    let surfaces = [Surface::new(&m, blob.sampler().unwrap())];
    let scene = scene();
    let (_, o) = option_sets().pop().unwrap();
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| render_wavefront(&scene, &surfaces, &o))
    };
    assert_identical(&run(1), &run(3), "1 vs 3 threads");
}
