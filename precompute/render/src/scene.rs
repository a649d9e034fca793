//! Scenes: camera, objects and lighting, ray queries, and the scene presets (the evaluation
//! scene and the multi-material showcase).

use glam::Vec3;

use crate::environment::Environment;
use crate::envmap::EnvMap;
use crate::geometry::{Camera, Hit, Object, Ray, Shape};
use crate::sky::Sky;

/// Offset of secondary-ray origins along the geometric normal (scene units ~1).
pub(crate) const RAY_EPSILON: f32 = 1e-4;

/// A scene: camera, objects and lighting.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Camera (fixes the image size).
    pub camera: Camera,
    /// Objects.
    pub objects: Vec<Object>,
    /// Lighting.
    pub env: Environment,
}

impl Scene {
    /// Nearest hit along `r`.
    #[must_use]
    pub fn intersect(&self, r: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for o in &self.objects {
            let t_max = best.map_or(f32::INFINITY, |h| h.t);
            if let Some(h) = o.intersect(r, RAY_EPSILON, t_max) {
                best = Some(h);
            }
        }
        best
    }

    /// Whether anything blocks the ray `o + t·d`, `t > ε`.
    #[must_use]
    pub fn occluded(&self, o: Vec3, d: Vec3) -> bool {
        let r = Ray { o, d };
        self.objects
            .iter()
            .any(|ob| ob.intersect(&r, RAY_EPSILON, f32::INFINITY).is_some())
    }
}

/// Parameters of [`demo_scene`].
#[derive(Clone, Debug)]
pub struct SceneParams {
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Radiance of the sun disc.
    pub sun_radiance: f32,
    /// Angular radius of the sun, degrees.
    pub sun_radius_deg: f32,
    /// Optional environment map (replaces the procedural sky; the sun is added unless its
    /// radiance is 0).
    pub env_map: Option<EnvMap>,
    /// Texture tiling of the patch.
    pub patch_tiling: f32,
    /// Uniform white lighting (radiance 1 from every direction, no sun) instead of the sky:
    /// BSDF-sampling variance then depends on the sampler alone.
    pub uniform_light: bool,
}

impl Default for SceneParams {
    fn default() -> Self {
        SceneParams {
            width: 160,
            height: 120,
            sun_radiance: 60.0,
            sun_radius_deg: 4.0,
            env_map: None,
            patch_tiling: 2.0,
            uniform_light: false,
        }
    }
}

/// The evaluation scene: a textured square patch with a sphere standing on it, seen from
/// above at about 27°, under a daylight sky whose sun (elevation 27°, in front of the camera)
/// reflects in both objects (or under uniform light). Both objects use surface 0.
#[must_use]
pub fn demo_scene(p: &SceneParams) -> Scene {
    let camera = Camera::look_at(
        Vec3::new(0.0, -3.3, 1.75),
        Vec3::new(0.0, 0.15, 0.2),
        Vec3::Z,
        34.0,
        p.width.max(1),
        p.height.max(1),
    );
    Scene {
        camera,
        objects: vec![
            Object {
                shape: Shape::Patch {
                    center: Vec3::ZERO,
                    normal: Vec3::Z,
                    tangent: Vec3::X,
                    half_size: 1.6,
                },
                uv_scale: p.patch_tiling,
                surface: 0,
            },
            Object {
                shape: Shape::Sphere {
                    center: Vec3::new(0.62, 0.45, 0.5),
                    radius: 0.5,
                },
                uv_scale: 1.0,
                surface: 0,
            },
        ],
        env: lighting(p),
    }
}

/// The lighting of [`demo_scene`] and [`showcase_scene`]: the daylight sky (sun at elevation
/// 27°, azimuth −12°) or the environment map, plus the sun; or uniform white light.
fn lighting(p: &SceneParams) -> Environment {
    let sky = if p.uniform_light {
        Sky::constant([1.0; 3])
    } else {
        Sky::daylight(27.0, -12.0, p.sun_radiance, p.sun_radius_deg)
    };
    Environment::new(sky, p.env_map.clone(), 128)
}

/// Parameters of [`showcase_scene`].
#[derive(Clone, Debug)]
pub struct ShowcaseParams {
    /// Image size and lighting, as for [`demo_scene`] (`patch_tiling` tiles the floor).
    pub scene: SceneParams,
    /// Number of surfaces the objects use (at least 1; see [`showcase_scene`]).
    pub surfaces: usize,
}

impl Default for ShowcaseParams {
    fn default() -> Self {
        ShowcaseParams {
            scene: SceneParams {
                width: 256,
                height: 144,
                patch_tiling: SHOWCASE_FLOOR,
                ..SceneParams::default()
            },
            surfaces: SHOWCASE_OBJECTS,
        }
    }
}

/// Objects of [`showcase_scene`]: the floor and four spheres.
pub const SHOWCASE_OBJECTS: usize = 5;

/// Half the side of the showcase's floor: large enough that its far edge lies within a few
/// degrees of the horizon.
const SHOWCASE_FLOOR: f32 = 24.0;

/// Centres `(x, y)` of the showcase's unit-diameter spheres on the floor: a shallow arc,
/// neighbours 0.1 apart, so that each sees itself in the next one and all of them in the
/// floor.
const SHOWCASE_SPHERES: [(f32, f32); 4] = [(-1.6, 0.3), (-0.55, 0.0), (0.55, 0.0), (1.6, 0.3)];

/// A Fig. 11-style scene of several materials that light each other: a square floor patch
/// (side 6.4) with four spheres of radius 0.5 standing on it in a shallow arc, 0.1 apart,
/// seen from the front and above at about 20° through a 30° vertical field of view, under
/// the lighting of [`demo_scene`] (the daylight sky whose sun, behind the spheres, puts
/// highlights on every object; or an environment map plus the sun; or uniform light).
///
/// The floor uses surface 0 and the spheres, left to right, surfaces `1, 2, …, n − 1` for
/// `n = p.surfaces` (cycling when `n < 5`; every object uses surface 0 when `n = 1`).
/// Spheres tile their material once (`uv_scale` 1), the floor `p.scene.patch_tiling` times.
/// Inter-reflections need [`crate::RenderOptions::max_bounces`] `> 1`.
#[must_use]
pub fn showcase_scene(p: &ShowcaseParams) -> Scene {
    let s = &p.scene;
    let camera = Camera::look_at(
        Vec3::new(0.0, -4.9, 2.4),
        Vec3::new(0.0, 0.15, 0.4),
        Vec3::Z,
        32.0,
        s.width.max(1),
        s.height.max(1),
    );
    let mut objects = vec![Object {
        shape: Shape::Patch {
            center: Vec3::ZERO,
            normal: Vec3::Z,
            tangent: Vec3::X,
            half_size: SHOWCASE_FLOOR,
        },
        uv_scale: s.patch_tiling,
        surface: 0,
    }];
    let spheres = p.surfaces.max(1) - 1;
    for (k, &(x, y)) in SHOWCASE_SPHERES.iter().enumerate() {
        objects.push(Object {
            shape: Shape::Sphere {
                center: Vec3::new(x, y, 0.5),
                radius: 0.5,
            },
            uv_scale: 1.0,
            surface: if spheres == 0 { 0 } else { 1 + k % spheres },
        });
    }
    Scene {
        camera,
        objects,
        env: lighting(s),
    }
}
