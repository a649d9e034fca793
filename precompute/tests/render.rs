//! The evaluation renderer with the trained samplers and the oracle: unbiasedness of every
//! sampler (all converge to the same image), determinism across thread counts, global
//! illumination, and the consistency of the oracle. (The renderer's own tests — exact
//! estimators, environment sampling — are in `precompute/render/tests/`.)

use glam::{Vec2, Vec3};
use neusample::{Blob, BlobSampler};
use neusample::{Prepared, Sampler};
use neusample_precompute::demo::fixtures_dir;
use neusample_precompute::eval::metrics::{self, Technique};
use neusample_precompute::eval::OracleSampler;
use neusample_precompute::materials::{self, Material, FEATURE_DIM};
use neusample_render::{self as render, Estimator, RenderOptions, Scene, SceneParams};
use rand::{RngExt, SeedableRng};

fn blob_bytes(material: &str, method: &str) -> Vec<u8> {
    let p = fixtures_dir().join(material).join(format!("{method}.nsb"));
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

const METHODS: [&str; 6] = [
    "baseline",
    "analytic",
    "flow",
    "affine-flow",
    "direct-histogram",
    "histogram-mixture",
];

/// A small demo scene with a softened sun (larger, dimmer), so that the estimators' tails
/// stay light enough for a z-test on a few thousand samples.
fn small_scene() -> Scene {
    render::demo_scene(&SceneParams {
        width: 24,
        height: 18,
        sun_radiance: 8.0,
        sun_radius_deg: 10.0,
        env_map: None,
        patch_tiling: 2.0,
        uniform_light: false,
    })
}

/// Every unbiased technique (cosine, the six fixture samplers, the oracle; BSDF sampling, and
/// MIS for a few) gives the same pixel-averaged radiance as an independent high-sample
/// reference, within 4.5 standard errors per channel (per-technique sample variances).
#[test]
fn every_method_converges_to_the_reference() {
    let m = materials::builtin("goat_leather").unwrap();
    let scene = small_scene();
    let blobs: Vec<(&str, Vec<u8>)> = METHODS
        .iter()
        .map(|n| (*n, blob_bytes("goat_leather", n)))
        .collect();
    let opened: Vec<(&str, Blob<'_>)> = blobs
        .iter()
        .map(|(n, b)| (*n, Blob::open(b).unwrap()))
        .collect();
    let mut techniques: Vec<(String, Technique<'_>)> =
        vec![("cosine".into(), Technique::Blob(BlobSampler::cosine()))];
    for (n, b) in &opened {
        techniques.push((n.to_string(), Technique::Blob(b.sampler().unwrap())));
    }
    techniques.push((
        "oracle".into(),
        Technique::Oracle(OracleSampler::new(m.as_ref(), 24)),
    ));

    let mut ref_opts = RenderOptions::new(2048, 99);
    ref_opts.estimator = Estimator::Mis;
    ref_opts.checkpoints.clear();
    let reference =
        Technique::Oracle(OracleSampler::new(m.as_ref(), 32)).render(&scene, m.as_ref(), &ref_opts);
    let mask = reference.mask.clone();
    let hits = mask.iter().filter(|&&b| b).count();
    assert!(
        hits > 250,
        "the objects fill the image: {hits} of {}",
        mask.len()
    );
    let (rm, rse) = metrics::pixel_average(&reference, &mask);
    assert!(rm.iter().all(|v| *v > 0.01), "lit: {rm:?}");

    let mut worst = 0.0f64;
    for (name, t) in &techniques {
        for estimator in [Estimator::Bsdf, Estimator::Mis] {
            if estimator == Estimator::Mis
                && !matches!(name.as_str(), "cosine" | "flow" | "histogram-mixture")
            {
                continue;
            }
            let mut o = RenderOptions::new(512, 7);
            o.estimator = estimator;
            o.checkpoints.clear();
            let r = t.render(&scene, m.as_ref(), &o);
            assert_eq!(r.mask, mask);
            let (mm, se) = metrics::pixel_average(&r, &mask);
            for c in 0..3 {
                let z = (mm[c] - rm[c]) / (se[c] * se[c] + rse[c] * rse[c]).sqrt();
                eprintln!(
                    "{name:>18} {estimator:?} ch{c}: mean {:.5} ± {:.5} vs reference {:.5} ± {:.5}, z = {z:+.2}",
                    mm[c], se[c], rm[c], rse[c]
                );
                assert!(
                    z.is_finite() && z.abs() < 4.5,
                    "{name} {estimator:?} channel {c}: z = {z}"
                );
                worst = worst.max(z.abs());
            }
        }
    }
    eprintln!("largest |z| = {worst:.2}");
}

/// A Lambertian material (constant albedo, φ ignored).
struct Lambert([f32; 3]);

impl Material for Lambert {
    fn name(&self) -> &str {
        "lambert"
    }
    fn features(&self, _uv: Vec2) -> [f32; FEATURE_DIM] {
        [0.0; FEATURE_DIM]
    }
    fn eval(&self, _phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3] {
        if wi.z > 0.0 && wo.z > 0.0 {
            self.0.map(|a| a * std::f32::consts::FRAC_1_PI)
        } else {
            [0.0; 3]
        }
    }
}

/// The same image, bit for bit, on one and on two threads (per-pixel random streams).
#[test]
fn renders_are_identical_for_any_thread_count() {
    let m = materials::builtin("brushed_metal").unwrap();
    let scene = small_scene();
    let bytes = blob_bytes("brushed_metal", "flow");
    let blob = Blob::open(&bytes).unwrap();
    for t in [
        Technique::Blob(blob.sampler().unwrap()),
        Technique::Oracle(OracleSampler::new(m.as_ref(), 16)),
    ] {
        for estimator in [Estimator::Bsdf, Estimator::Mis] {
            let mut o = RenderOptions::new(8, 11);
            o.estimator = estimator;
            let run = |threads: usize| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| t.render(&scene, m.as_ref(), &o))
            };
            let (a, b) = (run(1), run(2));
            let bits = |img: &render::Image| -> Vec<u32> {
                img.data.iter().flat_map(|c| c.map(f32::to_bits)).collect()
            };
            assert_eq!(bits(&a.image), bits(&b.image));
            assert_eq!(bits(&a.variance), bits(&b.variance));
            assert_eq!(a.checkpoints.len(), b.checkpoints.len());
            for ((sa, ia), (sb, ib)) in a.checkpoints.iter().zip(&b.checkpoints) {
                assert_eq!(sa, sb);
                assert_eq!(bits(ia), bits(ib));
            }
            assert!(a.image.data.iter().any(|c| c[0] > 0.0));
        }
    }
}

/// The oracle's samples report the density its `pdf` gives, and it puts (almost) all its
/// mass inside the disk.
#[test]
fn oracle_sample_and_pdf_agree() {
    let m = materials::builtin("victorian_fabric").unwrap();
    let oracle = OracleSampler::new(m.as_ref(), 32);
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
    let conds = neusample_precompute::groundtruth::conditions(m.as_ref(), 8, 3);
    for c in &conds {
        let p = oracle.prepare(&c.phi, c.wi).unwrap();
        let mut accepted = 0;
        for _ in 0..2000 {
            let u = Vec2::new(rng.random::<f32>(), rng.random::<f32>());
            if let Some(s) = p.sample(u) {
                accepted += 1;
                let q = p.pdf(s.wo);
                assert!((q - s.pdf).abs() <= 1e-4 * s.pdf, "{q} vs {}", s.pdf);
                assert!(s.wo.z > 0.0);
            }
        }
        assert!(accepted > 1900, "accepted {accepted} of 2000");
    }
    let fit = neusample_precompute::eval::fit(&oracle, m.as_ref(), 8, 64, 3);
    assert!(
        fit.mass_in_disk > 0.97 && fit.mass_in_disk < 1.01,
        "{fit:?}"
    );
    assert!(fit.kl_divergence < 0.1, "{fit:?}");
}

/// Global illumination (`max_bounces > 1`): the light the patch and the sphere exchange is
/// added (the image gets brighter where they see each other), and every sampler still
/// converges to the same image (sampler prepared at every path vertex).
#[test]
fn global_illumination_is_unbiased_for_every_sampler() {
    let m = materials::builtin("goat_leather").unwrap();
    let scene = small_scene();
    let blobs: Vec<(&str, Vec<u8>)> = ["analytic", "flow", "histogram-mixture"]
        .iter()
        .map(|n| (*n, blob_bytes("goat_leather", n)))
        .collect();
    let opened: Vec<(&str, Blob<'_>)> = blobs
        .iter()
        .map(|(n, b)| (*n, Blob::open(b).unwrap()))
        .collect();
    let gi = |spp: u32, seed: u64, bounces: u32| {
        let mut o = RenderOptions::new(spp, seed);
        o.estimator = Estimator::Mis;
        o.checkpoints.clear();
        o.max_bounces = bounces;
        o
    };
    // Reference: the analytic mixture, MIS, 3 interactions, many samples.
    let reference_t = Technique::Blob(opened[0].1.sampler().unwrap());
    let reference = reference_t.render(&scene, m.as_ref(), &gi(2048, 99, 3));
    let mask = reference.mask.clone();
    let (rm, rse) = metrics::pixel_average(&reference, &mask);

    // Indirect light is there: on a bright Lambertian scene (albedo 0.8) the image with three
    // interactions is brighter than direct lighting alone, by many standard errors.
    let white = Lambert([0.8; 3]);
    let cosine = Technique::Blob(BlobSampler::cosine());
    let (gm, gse) = metrics::pixel_average(&cosine.render(&scene, &white, &gi(1024, 5, 3)), &mask);
    let (dm, dse) = metrics::pixel_average(&cosine.render(&scene, &white, &gi(1024, 6, 1)), &mask);
    for c in 0..3 {
        let z = (gm[c] - dm[c]) / (gse[c] * gse[c] + dse[c] * dse[c]).sqrt();
        eprintln!(
            "GI {:.5} vs direct {:.5} (channel {c}, z = {z:.1})",
            gm[c], dm[c]
        );
        assert!(z > 5.0, "channel {c}: GI {} vs direct {}", gm[c], dm[c]);
    }

    let mut techniques: Vec<(String, Technique<'_>)> =
        vec![("cosine".into(), Technique::Blob(BlobSampler::cosine()))];
    for (n, b) in &opened {
        techniques.push((n.to_string(), Technique::Blob(b.sampler().unwrap())));
    }
    for (name, t) in &techniques {
        for estimator in [Estimator::Bsdf, Estimator::Mis] {
            let mut o = gi(512, 7, 3);
            o.estimator = estimator;
            let r = t.render(&scene, m.as_ref(), &o);
            let (mm, se) = metrics::pixel_average(&r, &mask);
            for c in 0..3 {
                let z = (mm[c] - rm[c]) / (se[c] * se[c] + rse[c] * rse[c]).sqrt();
                eprintln!(
                    "{name:>18} {estimator:?} GI ch{c}: {:.5} vs {:.5}, z = {z:+.2}",
                    mm[c], rm[c]
                );
                assert!(
                    z.is_finite() && z.abs() < 4.5,
                    "{name} {estimator:?} channel {c}: z = {z}"
                );
            }
        }
    }
}
