//! Shading frames and the maps between the projected unit disk and the hemisphere.
//!
//! Every sampler in this crate works on the **projected disk**: a direction `wo` in the local
//! shading frame (z = normal, pointing away from the surface) is represented by
//! `wo⊥ = (wo.x, wo.y)`, and `wo.z = √(1 − |wo⊥|²)`. Densities convert as
//!
//! ```text
//! p_solid_angle(wo) = p_disk(wo⊥) · cos θo        (cos θo = wo.z)
//! ```
//!
//! so sampling ∝ BRDF·cos over the hemisphere is sampling ∝ BRDF over the disk (paper §3,
//! "Projected hemisphere"). Warps come as pbrt-style triples: sample, pdf, invert.

use glam::{Vec2, Vec3};

use crate::math;

/// Smallest `cos θ` accepted for a direction to count as above the horizon.
pub const MIN_COS_THETA: f32 = 1e-6;

/// An orthonormal shading frame: `n` is the local z axis, `t` and `b` the x and y axes.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Frame {
    /// Tangent (local x).
    pub t: Vec3,
    /// Bitangent (local y).
    pub b: Vec3,
    /// Normal (local z).
    pub n: Vec3,
}

impl Frame {
    /// A frame around the unit normal `n` with an arbitrary but continuous tangent
    /// (Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
    #[must_use]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let bt = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { t, b: bt, n }
    }

    /// A frame from a unit normal and a tangent hint (for anisotropic materials): the
    /// tangent is Gram–Schmidt orthogonalised against `n`. Falls back to
    /// [`Frame::from_normal`] when the hint is parallel to `n` or not finite.
    #[must_use]
    pub fn from_normal_tangent(n: Vec3, tangent: Vec3) -> Self {
        let t = tangent - n * n.dot(tangent);
        let len2 = t.length_squared();
        if !(len2 > 1e-12) || !math::is_finite(len2) {
            return Frame::from_normal(n);
        }
        let t = t * (1.0 / math::sqrt(len2));
        Frame {
            t,
            b: n.cross(t),
            n,
        }
    }

    /// World → local.
    #[inline]
    #[must_use]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }

    /// Local → world.
    #[inline]
    #[must_use]
    pub fn from_local(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

/// A local direction normalised and checked: `None` for NaN/∞ components, zero length, or
/// `cos θ ≤` [`MIN_COS_THETA`] (at or below the horizon).
#[inline]
#[must_use]
pub fn upper_hemisphere(w: Vec3) -> Option<Vec3> {
    let (w, ok) = upper_hemisphere_lane(w);
    if ok {
        Some(w)
    } else {
        None
    }
}

/// [`upper_hemisphere`] without branches, so that a loop of it over lanes vectorises: the
/// direction it gives and whether it accepts `w` (the direction is meaningless, possibly NaN,
/// where it does not).
#[inline(always)]
#[must_use]
pub fn upper_hemisphere_lane(w: Vec3) -> (Vec3, bool) {
    let len2 = w.x * w.x + w.y * w.y + w.z * w.z;
    let ok = (len2 > 0.0) & math::is_finite(len2);
    // Directions that are already unit length to rounding are used as given: renormalising
    // them would move a sampled direction by an ulp and change its density slightly.
    let unit = math::abs(len2 - 1.0) <= 4.0 * f32::EPSILON;
    let scale = 1.0 / math::sqrt(len2);
    let w = if unit { w } else { w * scale };
    (w, ok & (w.z > MIN_COS_THETA) & math::is_finite(w.z))
}

/// Projected-disk point of a local direction: `(w.x, w.y)`.
#[inline(always)]
#[must_use]
pub fn to_disk(w: Vec3) -> Vec2 {
    Vec2::new(w.x, w.y)
}

/// `true` when `p` is finite and strictly inside the open unit disk.
#[inline(always)]
#[must_use]
pub fn inside_disk(p: Vec2) -> bool {
    p.x * p.x + p.y * p.y < 1.0
}

/// The upper-hemisphere direction above a disk point, or `None` when the point is not
/// strictly inside the unit disk (or not finite). `cos θ = √(1 − |p|²)`.
#[inline]
#[must_use]
pub fn from_disk(p: Vec2) -> Option<Vec3> {
    let r2 = p.x * p.x + p.y * p.y;
    if !(r2 < 1.0) {
        return None;
    }
    let z = math::sqrt(1.0 - r2);
    if z > MIN_COS_THETA {
        Some(Vec3::new(p.x, p.y, z))
    } else {
        None
    }
}

/// Converts a density on the projected disk to solid angle: `p_disk · cos θ`.
#[inline(always)]
#[must_use]
pub fn disk_to_solid_angle(pdf_disk: f32, cos_theta: f32) -> f32 {
    pdf_disk * cos_theta
}

/// Converts a solid-angle density to the projected disk: `p_ω / cos θ` (0 at the horizon).
#[inline(always)]
#[must_use]
pub fn solid_angle_to_disk(pdf_solid: f32, cos_theta: f32) -> f32 {
    if cos_theta > 0.0 {
        pdf_solid / cos_theta
    } else {
        0.0
    }
}

/// Shirley–Chiu concentric map from `[0, 1)²` to the unit disk (area-preserving up to the
/// constant π, continuous, low distortion).
#[inline]
#[must_use]
pub fn sample_uniform_disk_concentric(u: Vec2) -> Vec2 {
    // Map u to [−1, 1]² and handle the degeneracy at the origin.
    let o = Vec2::new(2.0 * u.x - 1.0, 2.0 * u.y - 1.0);
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if math::abs(o.x) > math::abs(o.y) {
        (o.x, (math::PI / 4.0) * (o.y / o.x))
    } else {
        (o.y, math::PI / 2.0 - (math::PI / 4.0) * (o.x / o.y))
    };
    let (s, c) = math::sin_cos(theta);
    Vec2::new(r * c, r * s)
}

/// Inverse of [`sample_uniform_disk_concentric`]: the `u ∈ [0, 1]²` that maps to `p`.
#[inline]
#[must_use]
pub fn invert_uniform_disk_concentric(p: Vec2) -> Vec2 {
    let theta = math::atan2(p.y, p.x); // (−π, π]
    let r = math::sqrt(p.x * p.x + p.y * p.y);
    let quarter = math::PI / 4.0;
    let (ox, oy);
    if math::abs(theta) < quarter || math::abs(theta) > 3.0 * quarter {
        // Left/right wedges: r = o.x, θ = π/4 · o.y/o.x.
        let rr = if math::abs(theta) < quarter { r } else { -r };
        ox = rr;
        let th = if math::abs(theta) < quarter {
            theta
        } else if theta > 0.0 {
            theta - math::PI
        } else {
            theta + math::PI
        };
        oy = rr * th / quarter;
    } else {
        // Top/bottom wedges: r = o.y, θ = π/2 − π/4 · o.x/o.y.
        let rr = if theta > 0.0 { r } else { -r };
        oy = rr;
        let th = if theta > 0.0 { theta } else { theta + math::PI };
        ox = rr * (math::PI / 2.0 - th) / quarter;
    }
    Vec2::new(0.5 * (ox + 1.0), 0.5 * (oy + 1.0))
}

/// Density of [`sample_uniform_disk_concentric`] with respect to area on the disk: 1/π inside.
#[inline(always)]
#[must_use]
pub fn uniform_disk_pdf(p: Vec2) -> f32 {
    if p.x * p.x + p.y * p.y < 1.0 {
        math::INV_PI
    } else {
        0.0
    }
}

/// Cosine-weighted hemisphere sample (Malley's method: a uniform disk point lifted to the
/// hemisphere). Never below the horizon for `u ∈ [0, 1)²`, but may lie at it.
#[inline]
#[must_use]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = sample_uniform_disk_concentric(u);
    let z = math::safe_sqrt(1.0 - d.x * d.x - d.y * d.y);
    Vec3::new(d.x, d.y, z)
}

/// Solid-angle density of [`sample_cosine_hemisphere`]: cos θ / π (0 below the horizon).
#[inline(always)]
#[must_use]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    if cos_theta > 0.0 {
        cos_theta * math::INV_PI
    } else {
        0.0
    }
}

/// Inverse of [`sample_cosine_hemisphere`]: the `u` that produced the direction `w`.
#[inline]
#[must_use]
pub fn invert_cosine_hemisphere_sample(w: Vec3) -> Vec2 {
    invert_uniform_disk_concentric(Vec2::new(w.x, w.y))
}

/// A 2-D rotation by angle θ given as `(cos θ, sin θ)`: `R·p`.
#[inline(always)]
#[must_use]
pub fn rotate(p: Vec2, cs: Vec2) -> Vec2 {
    Vec2::new(cs.x * p.x - cs.y * p.y, cs.y * p.x + cs.x * p.y)
}

/// The inverse rotation `Rᵀ·p` of [`rotate`].
#[inline(always)]
#[must_use]
pub fn rotate_inverse(p: Vec2, cs: Vec2) -> Vec2 {
    Vec2::new(cs.x * p.x + cs.y * p.y, -cs.y * p.x + cs.x * p.y)
}
