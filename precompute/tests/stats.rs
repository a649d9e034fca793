//! The evaluation's variance estimate on a case with a known answer: a material whose
//! estimator under cosine sampling and uniform light has a closed-form variance.

use glam::{Vec2, Vec3};
use neusample::samplers::CosineSampler;
use neusample_precompute::eval::metrics::{self, Reference};
use neusample_render::{
    render_wavefront, Camera, Environment, Material, Object, RenderOptions, Scene, Shape, Sky,
    Surface,
};

/// `f(wo) = (2a/π) · cos θo` per channel (not energy-conserving; a test device). Under
/// uniform unit light with cosine sampling (`pdf = cos θo / π`) one sample estimates
/// `f · cos θo / pdf = 2a · cos θo`, with `cos θo` distributed as `2c` on `[0, 1]`: mean
/// `4a/3`, variance `E[(2ac)²] − (4a/3)² = 2a² − 16a²/9 = 2a²/9`.
struct Linear([f32; 3]);

impl Material for Linear {
    fn features(&self, _uv: Vec2) -> [f32; 8] {
        [0.0; 8]
    }
    fn eval(&self, _phi: &[f32; 8], wi: Vec3, wo: Vec3) -> [f32; 3] {
        if wi.z > 0.0 && wo.z > 0.0 {
            self.0.map(|a| 2.0 * a * std::f32::consts::FRAC_1_PI * wo.z)
        } else {
            [0.0; 3]
        }
    }
}

#[test]
fn block_variance_interval_covers_the_closed_form_variance() {
    let albedo = [0.9f32, 0.5, 0.2];
    let m = Linear(albedo);
    let scene = Scene {
        camera: Camera::look_at(Vec3::new(0.0, -3.0, 0.4), Vec3::ZERO, Vec3::Z, 30.0, 40, 30),
        objects: vec![Object {
            shape: Shape::Sphere {
                center: Vec3::ZERO,
                radius: 0.8,
            },
            uv_scale: 1.0,
            surface: 0,
        }],
        env: Environment::new(Sky::constant([1.0; 3]), None, 16),
    };
    let want: f64 = albedo
        .iter()
        .map(|&a| 2.0 * f64::from(a) * f64::from(a) / 9.0)
        .sum::<f64>()
        / 3.0;
    let mut covered = 0;
    let seeds = 20;
    for seed in 0..seeds {
        let mut o = RenderOptions::new(32, seed);
        o.checkpoints.clear();
        o.blocks = metrics::DEFAULT_BLOCKS;
        let r = render_wavefront(&scene, &[Surface::new(&m, CosineSampler)], &o);
        assert_eq!(r.blocks.len(), 16);
        assert_eq!(r.block_samples(), vec![2; 16]);
        // The exact image: 4a/3 wherever the sphere is hit.
        let mut exact = r.clone();
        for (px, hit) in exact.image.data.iter_mut().zip(&r.mask) {
            *px = if *hit {
                albedo.map(|a| 4.0 * a / 3.0)
            } else {
                *px
            };
        }
        let reference = Reference {
            render: exact,
            noise: 0.0,
        };
        let blocks = metrics::block_variances(&r, &reference);
        let e = metrics::variance(&blocks, seed);
        assert!(e.lo <= e.value && e.value <= e.hi, "{e:?}");
        // Point estimate within 15 % of the truth (about 900 pixels × 3 channels × 32 samples).
        assert!((e.value / want - 1.0).abs() < 0.15, "{} vs {want}", e.value);
        if e.lo <= want && want <= e.hi {
            covered += 1;
        }
    }
    // Nominal 95 %: at least 16 of 20 seeds.
    assert!(
        covered >= 16,
        "the interval covered the variance in {covered} of {seeds} renders"
    );
}
