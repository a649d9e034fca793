//! Rays, the pinhole camera and the two primitives (a square patch and a sphere) with their
//! texture coordinates and tangents.

use glam::{Vec2, Vec3};

/// A ray `o + t·d` (`d` unit).
#[derive(Copy, Clone, Debug)]
pub struct Ray {
    /// Origin.
    pub o: Vec3,
    /// Unit direction.
    pub d: Vec3,
}

/// A pinhole camera.
#[derive(Copy, Clone, Debug)]
pub struct Camera {
    eye: Vec3,
    forward: Vec3,
    /// Right axis scaled by `tan(fov/2) · aspect`.
    right: Vec3,
    /// Up axis scaled by `tan(fov/2)`.
    up: Vec3,
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
}

impl Camera {
    /// A camera at `eye` looking at `target`, `up` the world's up hint, `vfov_deg` the vertical
    /// field of view in degrees.
    #[must_use]
    pub fn look_at(
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        vfov_deg: f32,
        width: usize,
        height: usize,
    ) -> Camera {
        let forward = (target - eye).normalize();
        let right = forward.cross(up).normalize();
        let true_up = right.cross(forward);
        let tan_half = (0.5 * vfov_deg.to_radians()).tan();
        let aspect = width as f32 / height.max(1) as f32;
        Camera {
            eye,
            forward,
            right: right * tan_half * aspect,
            up: true_up * tan_half,
            width,
            height,
        }
    }

    /// The ray through image position `(px, py)` in pixels (`(0, 0)` = top-left corner;
    /// pixel centres at `+0.5`).
    #[must_use]
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        let sx = 2.0 * px / self.width as f32 - 1.0;
        let sy = 1.0 - 2.0 * py / self.height as f32;
        Ray {
            o: self.eye,
            d: (self.forward + sx * self.right + sy * self.up).normalize(),
        }
    }
}

/// A primitive.
#[derive(Copy, Clone, Debug)]
pub enum Shape {
    /// A square planar patch: `center`, unit `normal`, unit `tangent` (the u axis, ⊥ normal)
    /// and half the side length.
    Patch {
        /// Centre.
        center: Vec3,
        /// Unit normal (the shaded side).
        normal: Vec3,
        /// Unit tangent (u axis).
        tangent: Vec3,
        /// Half the side length.
        half_size: f32,
    },
    /// A sphere (shaded from outside).
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius.
        radius: f32,
    },
}

/// A shape with its surface.
#[derive(Copy, Clone, Debug)]
pub struct Object {
    /// Geometry.
    pub shape: Shape,
    /// Texture tiling scale (how many times the material repeats across the object).
    pub uv_scale: f32,
    /// Index into the surfaces passed to [`crate::render()`].
    pub surface: usize,
}

/// A ray–surface intersection.
#[derive(Copy, Clone, Debug)]
pub struct Hit {
    /// Ray parameter.
    pub t: f32,
    /// Position.
    pub p: Vec3,
    /// Unit geometric normal (facing outward / up for the patch).
    pub n: Vec3,
    /// Tangent hint `∂P/∂u` (not necessarily ⊥ `n` or unit).
    pub tangent: Vec3,
    /// Texture coordinate in `[0, 1)²`.
    pub uv: Vec2,
    /// Surface index.
    pub surface: usize,
}

#[inline]
fn wrap01(x: f32) -> f32 {
    let f = x - x.floor();
    if f >= 1.0 {
        0.0
    } else {
        f
    }
}

impl Object {
    /// The nearest intersection with `t ∈ (t_min, t_max)`.
    #[must_use]
    pub fn intersect(&self, r: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        match self.shape {
            Shape::Patch {
                center,
                normal,
                tangent,
                half_size,
            } => {
                let denom = r.d.dot(normal);
                if denom.abs() < 1e-12 {
                    return None;
                }
                let t = (center - r.o).dot(normal) / denom;
                if !(t > t_min && t < t_max) {
                    return None;
                }
                let p = r.o + t * r.d;
                let l = p - center;
                let bitangent = normal.cross(tangent);
                let a = l.dot(tangent);
                let b = l.dot(bitangent);
                if a.abs() > half_size || b.abs() > half_size {
                    return None;
                }
                let s = self.uv_scale / (2.0 * half_size);
                Some(Hit {
                    t,
                    p,
                    n: normal,
                    tangent,
                    uv: Vec2::new(wrap01((a + half_size) * s), wrap01((b + half_size) * s)),
                    surface: self.surface,
                })
            }
            Shape::Sphere { center, radius } => {
                let oc = r.o - center;
                let b = oc.dot(r.d);
                let c = oc.length_squared() - radius * radius;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let sq = disc.sqrt();
                let mut t = -b - sq;
                if !(t > t_min) {
                    t = -b + sq;
                }
                if !(t > t_min && t < t_max) {
                    return None;
                }
                let p = r.o + t * r.d;
                let n = ((p - center) / radius).normalize();
                let phi = n.y.atan2(n.x);
                let theta = n.z.clamp(-1.0, 1.0).acos();
                Some(Hit {
                    t,
                    p,
                    n,
                    tangent: Vec3::new(-phi.sin(), phi.cos(), 0.0),
                    uv: Vec2::new(
                        wrap01(
                            (phi * std::f32::consts::FRAC_1_PI * 0.5 + 0.5) * 2.0 * self.uv_scale,
                        ),
                        wrap01(theta * std::f32::consts::FRAC_1_PI * self.uv_scale),
                    ),
                    surface: self.surface,
                })
            }
        }
    }
}
