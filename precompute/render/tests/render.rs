//! The renderer alone (no trained samplers): an exact estimator has zero variance, and
//! environment sampling integrates the sky.

use glam::{Vec2, Vec3};
use neusample::samplers::CosineSampler;
use neusample::FEATURE_DIM;
use neusample_render::{
    luminance, render, Camera, Environment, Material, Object, RenderOptions, Scene, Shape, Sky,
    Surface,
};
use rand::{RngExt, SeedableRng};

/// A Lambertian material (constant albedo, φ ignored).
struct Lambert([f32; 3]);

impl Material for Lambert {
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

/// Cosine sampling of a Lambertian surface under a constant environment is exact: every
/// sample returns albedo × radiance, so every pixel has zero variance (to float rounding).
#[test]
fn cosine_sampling_of_lambert_under_constant_light_has_zero_variance() {
    let albedo = [0.8, 0.5, 0.25];
    let l = [1.5, 1.0, 0.5];
    let m = Lambert(albedo);
    let scene = Scene {
        camera: Camera::look_at(Vec3::new(0.0, -3.0, 0.4), Vec3::ZERO, Vec3::Z, 30.0, 32, 24),
        objects: vec![Object {
            shape: Shape::Sphere {
                center: Vec3::ZERO,
                radius: 0.7,
            },
            uv_scale: 1.0,
            surface: 0,
        }],
        env: Environment::new(Sky::constant(l), None, 16),
    };
    let mut o = RenderOptions::new(64, 3);
    o.checkpoints.clear();
    let r = render(&scene, &[Surface::new(&m, CosineSampler)], &o);
    let hits = r.mask.iter().filter(|&&b| b).count();
    assert!(hits > 100);
    let mut worst_rel_sd = 0.0f64;
    for (i, (c, v)) in r.image.data.iter().zip(&r.variance.data).enumerate() {
        if !r.mask[i] {
            continue;
        }
        for k in 0..3 {
            let want = albedo[k] * l[k];
            assert!(
                (c[k] - want).abs() <= 1e-5 * want,
                "pixel {i} channel {k}: {} vs {want}",
                c[k]
            );
            let rel_sd = f64::from(v[k]).sqrt() / f64::from(want);
            worst_rel_sd = worst_rel_sd.max(rel_sd);
        }
    }
    eprintln!("{hits} pixels, largest relative standard deviation {worst_rel_sd:.2e}");
    assert!(worst_rel_sd < 1e-6, "relative sd {worst_rel_sd}");
}

/// Environment sampling integrates the sky correctly: E[L/pdf] over its own samples equals a
/// brute-force quadrature of ∫ L dω (sun included), so its density matches its sampling.
#[test]
fn environment_sampling_is_consistent() {
    let sky = Sky::daylight(30.0, 20.0, 300.0, 3.0);
    let env = Environment::new(sky, None, 64);
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(9);
    let n = 200_000;
    let mut est = 0.0f64;
    for _ in 0..n {
        let pick: f32 = rng.random();
        let u = Vec2::new(rng.random::<f32>(), rng.random::<f32>());
        if let Some((d, pdf)) = env.sample(pick, u) {
            est += f64::from(luminance(env.radiance(d)) / pdf);
        }
    }
    est /= n as f64;
    // Quadrature: sky by a fine (φ, cos θ) grid, sun analytically (uniform disc radiance).
    let (nu, nv) = (2048usize, 1024usize);
    let mut quad = 0.0f64;
    for i in 0..nv {
        let ct = 1.0 - 2.0 * (i as f64 + 0.5) / nv as f64;
        let st = (1.0 - ct * ct).sqrt();
        for j in 0..nu {
            let ph = std::f64::consts::TAU * (j as f64 + 0.5) / nu as f64;
            let d = Vec3::new((st * ph.cos()) as f32, (st * ph.sin()) as f32, ct as f32);
            quad += f64::from(luminance(env.sky.background(d)));
        }
    }
    quad *= 4.0 * std::f64::consts::PI / (nu * nv) as f64;
    let cos_a = f64::from(3.0f32.to_radians().cos());
    quad += f64::from(luminance(env.sky.sun_color)) * 300.0 * std::f64::consts::TAU * (1.0 - cos_a);
    eprintln!("E[L/pdf] = {est:.5}, quadrature {quad:.5}");
    assert!((est - quad).abs() < 0.01 * quad, "{est} vs {quad}");
}

/// The showcase frames its objects: the floor fills the background (every primary ray hits
/// something), every surface is seen, and the spheres stand apart on the floor.
#[test]
fn showcase_scene_frames_every_surface() {
    let p = neusample_render::ShowcaseParams::default();
    let scene = neusample_render::showcase_scene(&p);
    let (w, h) = (scene.camera.width, scene.camera.height);
    let mut seen = vec![0usize; p.surfaces];
    for y in 0..h {
        for x in 0..w {
            let r = scene.camera.ray(x as f32 + 0.5, y as f32 + 0.5);
            let hit = scene
                .intersect(&r)
                .expect("every pixel sees the floor or a sphere");
            seen[hit.surface] += 1;
        }
    }
    assert!(seen.iter().all(|&n| n > 0), "{seen:?}");
    let spheres: Vec<(Vec3, f32)> = scene
        .objects
        .iter()
        .filter_map(|o| match o.shape {
            Shape::Sphere { center, radius } => Some((center, radius)),
            Shape::Patch { .. } => None,
        })
        .collect();
    for (i, a) in spheres.iter().enumerate() {
        assert!((a.0.z - a.1).abs() < 1e-6, "sphere {i} stands on the floor");
        for b in &spheres[i + 1..] {
            assert!(a.0.distance(b.0) > a.1 + b.1, "spheres overlap");
        }
    }
}
