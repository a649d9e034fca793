//! Microfacet building blocks: anisotropic GGX (Trowbridge–Reitz) distribution,
//! height-correlated Smith masking-shadowing, Fresnel terms, the Charlie sheen lobe, and the
//! "max-cosine" normal-mapping frame used by every analytic model.
//!
//! All functions take directions in a *lobe frame* (z = the lobe's normal, x = its tangent).
//!
//! # Normal mapping
//!
//! A shading normal `n_s` that differs from the geometric normal `n_g = z` is handled by
//! evaluating the microfacet lobe in the shading frame but dividing by
//! `M_i = max(cos_s θi, cos_g θi)` and `M_o = max(cos_s θo, cos_g θo)` instead of the shading
//! cosines ([`ShadingFrame::local`]):
//!
//! ```text
//! f = F · D(h) · G2(wi, wo) / (4 M_i M_o)
//! ```
//!
//! It equals the standard microfacet BRDF when `n_s = n_g`, is reciprocal, and is energy
//! conserving for every `n_s`: with `dωo = 4 (wo·h) dωh` and the Smith identity
//! `∫ G1(wi, h) (wi·h) D(h) dωh = cos_s θi`,
//! `∫ f cos_g θo dωo ≤ (cos_s θi / M_i) · sup(cos_g θo / M_o) ≤ 1`. Directions below the
//! shading horizon get `f = 0` (the usual black band of normal mapping, but never extra
//! energy).

use glam::Vec3;
use neusample::Frame;
use std::f32::consts::{FRAC_1_PI as INV_PI, PI};

/// Smallest GGX α accepted (below it the lobe is a near-delta the 64² to 128² targets
/// cannot resolve).
pub const ALPHA_MIN: f32 = 2e-3;

/// GGX α from a perceptual roughness `r ∈ [0, 1]`: `α = r²` (Burley 2012), clamped to
/// [`ALPHA_MIN`]..1.
#[inline]
#[must_use]
pub fn alpha_from_roughness(r: f32) -> f32 {
    (r * r).clamp(ALPHA_MIN, 1.0)
}

/// Anisotropic GGX normal distribution `D(h)` (Walter et al. 2007; Heitz 2014, Eq. 83),
/// normalised so that `∫ D(h) cos θh dωh = 1`. 0 for `h.z ≤ 0`.
#[inline]
#[must_use]
pub fn ggx_d(h: Vec3, ax: f32, ay: f32) -> f32 {
    if h.z <= 0.0 {
        return 0.0;
    }
    let x = h.x / ax;
    let y = h.y / ay;
    let d = x * x + y * y + h.z * h.z;
    INV_PI / (ax * ay * d * d)
}

/// Smith Λ of anisotropic GGX (Heitz 2014, Eq. 86) for a direction with `w.z > 0`.
#[inline]
#[must_use]
pub fn ggx_lambda(w: Vec3, ax: f32, ay: f32) -> f32 {
    let z2 = w.z * w.z;
    let t2 = (ax * ax * w.x * w.x + ay * ay * w.y * w.y) / z2.max(1e-12);
    0.5 * ((1.0 + t2).sqrt() - 1.0)
}

/// Height-correlated Smith masking-shadowing `G2 = 1 / (1 + Λ(wi) + Λ(wo))` (Heitz 2014,
/// Eq. 99), symmetric in `wi`, `wo`.
#[inline]
#[must_use]
pub fn ggx_g2(wi: Vec3, wo: Vec3, ax: f32, ay: f32) -> f32 {
    1.0 / (1.0 + ggx_lambda(wi, ax, ay) + ggx_lambda(wo, ax, ay))
}

/// `D(h) · G2(wi, wo)` for reflection, with the unnormalised half vector, and `wi·h` (for
/// Fresnel). Both directions must be above the lobe's horizon (`z > 0`); returns
/// `(0, 1)` otherwise.
#[inline]
#[must_use]
pub fn ggx_dg(wi: Vec3, wo: Vec3, ax: f32, ay: f32) -> (f32, f32) {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return (0.0, 1.0);
    }
    let h = wi + wo;
    let len2 = h.length_squared();
    if len2 <= 1e-20 {
        return (0.0, 1.0);
    }
    let h = h * (1.0 / len2.sqrt());
    let cos_d = wi.dot(h).clamp(0.0, 1.0);
    (ggx_d(h, ax, ay) * ggx_g2(wi, wo, ax, ay), cos_d)
}

/// Schlick's Fresnel `F0 + (1 − F0)(1 − cos)^5` per channel.
#[inline]
#[must_use]
pub fn schlick(f0: [f32; 3], cos: f32) -> [f32; 3] {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    let w = m2 * m2 * m;
    [
        f0[0] + (1.0 - f0[0]) * w,
        f0[1] + (1.0 - f0[1]) * w,
        f0[2] + (1.0 - f0[2]) * w,
    ]
}

/// Scalar Schlick Fresnel.
#[inline]
#[must_use]
pub fn schlick1(f0: f32, cos: f32) -> f32 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (1.0 - f0) * m2 * m2 * m
}

/// Exact unpolarised Fresnel reflectance of a dielectric interface with relative index
/// `eta = n_inside / n_outside > 1`, light arriving from outside at `cos_i ∈ [0, 1]`
/// (pbrt-v4 `FrDielectric`). Also returns the cosine of the refracted direction.
#[inline]
#[must_use]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> (f32, f32) {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (0.5 * (r_parl * r_parl + r_perp * r_perp), cos_t)
}

/// Direction refracted into a flat dielectric of index `eta` (z = normal), pointing away from
/// the interface on the inside's side mirrored back up (so `z > 0`): `(x, y)/eta`, `z = cos_t`.
#[inline]
#[must_use]
pub fn refract_up(w: Vec3, eta: f32, cos_t: f32) -> Vec3 {
    Vec3::new(w.x / eta, w.y / eta, cos_t)
}

/// "Charlie" sheen distribution (Estevez & Kulla 2017):
/// `D(h) = (2 + 1/α) sin^(1/α) θh / 2π`, normalised so that `∫ D cos θh dωh = 1`.
#[inline]
#[must_use]
pub fn charlie_d(h_z: f32, alpha: f32) -> f32 {
    let inv_a = 1.0 / alpha;
    let sin2 = (1.0 - h_z * h_z).max(0.0);
    (2.0 + inv_a) * sin2.powf(0.5 * inv_a) * (0.5 * INV_PI)
}

/// The "Neubelt–Pettineo" sheen visibility `V = 1 / (4 (cos_i + cos_o − cos_i cos_o))`
/// (already containing the `1/(4 cos_i cos_o)` of the microfacet BRDF), symmetric and bounded.
#[inline]
#[must_use]
pub fn sheen_visibility(cos_i: f32, cos_o: f32) -> f32 {
    0.25 / (cos_i + cos_o - cos_i * cos_o).max(1e-4)
}

/// Lambert `1/π`.
pub const LAMBERT: f32 = INV_PI;

/// `π`, re-exported for model code.
pub const PI_F: f32 = PI;

/// Directions in a shading frame with the max-cosine denominators of the module docs.
#[derive(Copy, Clone, Debug)]
pub struct Local {
    /// `wi` in the shading frame.
    pub wi: Vec3,
    /// `wo` in the shading frame.
    pub wo: Vec3,
    /// `1 / (4 M_i M_o)`, the microfacet denominator.
    pub inv_4mm: f32,
    /// `cos_s θi / M_i ∈ (0, 1]`.
    pub ci: f32,
    /// `cos_s θo / M_o ∈ (0, 1]`.
    pub co: f32,
}

/// A shading frame (normal-mapped normal plus tangent) inside the geometric frame z = n_g.
#[derive(Copy, Clone, Debug)]
pub struct ShadingFrame {
    frame: Frame,
}

impl ShadingFrame {
    /// The frame of shading normal `(nx, ny, √(1 − nx² − ny²))` and tangent hint
    /// `(cos ψ, sin ψ, 0)`. `(nx, ny)` is clamped to length [`MAX_TILT_XY`].
    #[inline]
    #[must_use]
    pub fn new(nx: f32, ny: f32, cos_psi: f32, sin_psi: f32) -> Self {
        let mut n2 = Vec3::new(nx, ny, 0.0);
        let l2 = nx * nx + ny * ny;
        if l2.is_nan() || l2 > MAX_TILT_XY * MAX_TILT_XY {
            n2 = if l2.is_finite() && l2 > 0.0 {
                n2 * (MAX_TILT_XY / l2.sqrt())
            } else {
                Vec3::ZERO
            };
        }
        let n = Vec3::new(n2.x, n2.y, (1.0 - n2.x * n2.x - n2.y * n2.y).sqrt());
        ShadingFrame {
            frame: Frame::from_normal_tangent(n, Vec3::new(cos_psi, sin_psi, 0.0)),
        }
    }

    /// The frame whose normal is tilted by θ towards the tangent `(cos ψ, sin ψ, 0)`:
    /// `n = (sin θ cos ψ, sin θ sin ψ, cos θ)`, `t = (cos θ cos ψ, cos θ sin ψ, −sin θ)`,
    /// `b = (−sin ψ, cos ψ, 0)`. The same frame as
    /// `ShadingFrame::new(sin θ cos ψ, sin θ sin ψ, cos ψ, sin ψ)` for `sin θ ≤` [`MAX_TILT_XY`],
    /// without square roots. `θ` may be negative.
    #[inline]
    #[must_use]
    pub fn tilted_along_tangent(cos_psi: f32, sin_psi: f32, sin_t: f32, cos_t: f32) -> Self {
        ShadingFrame {
            frame: Frame {
                t: Vec3::new(cos_t * cos_psi, cos_t * sin_psi, -sin_t),
                b: Vec3::new(-sin_psi, cos_psi, 0.0),
                n: Vec3::new(sin_t * cos_psi, sin_t * sin_psi, cos_t),
            },
        }
    }

    /// A geometric-frame direction in the shading frame.
    #[inline]
    #[must_use]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        self.frame.to_local(v)
    }

    /// The shading normal.
    #[must_use]
    pub fn normal(&self) -> Vec3 {
        self.frame.n
    }

    /// `wi`, `wo` (geometric frame, unit length) in the shading frame with the max-cosine
    /// denominators; `None` when either is at or below the geometric or the shading horizon.
    #[inline]
    #[must_use]
    pub fn local(&self, wi: Vec3, wo: Vec3) -> Option<Local> {
        let li = self.frame.to_local(wi);
        let lo = self.frame.to_local(wo);
        if !(li.z > 1e-6 && lo.z > 1e-6 && wi.z > 1e-6 && wo.z > 1e-6) {
            return None;
        }
        let mi = li.z.max(wi.z);
        let mo = lo.z.max(wo.z);
        Some(Local {
            wi: li,
            wo: lo,
            inv_4mm: 0.25 / (mi * mo),
            ci: li.z / mi,
            co: lo.z / mo,
        })
    }
}

/// Largest `|(nx, ny)|` of a shading normal (tilt ≈ 64°).
pub const MAX_TILT_XY: f32 = 0.9;

/// Clamps a normal's `(x, y)` to length [`MAX_TILT_XY`] (so φ holds exactly what the
/// decoder uses; the models write their normal maps into φ through it).
#[must_use]
pub fn clamp_tilt(x: f32, y: f32) -> (f32, f32) {
    let m = MAX_TILT_XY;
    let l = (x * x + y * y).sqrt();
    if l > m {
        (x * m / l, y * m / l)
    } else {
        (x, y)
    }
}

/// Unit vectors for `wi`, `wo`, or `None` when either is at or below the horizon or not finite.
#[inline]
#[must_use]
pub fn normalize_pair(wi: Vec3, wo: Vec3) -> Option<(Vec3, Vec3)> {
    let wi = neusample::warp::upper_hemisphere(wi)?;
    let wo = neusample::warp::upper_hemisphere(wo)?;
    Some((wi, wo))
}

/// `(cos ψ, sin ψ)` from the doubled-angle encoding `(cos 2ψ, sin 2ψ)` used in φ for tangent
/// directions (anisotropic GGX is π-periodic in ψ). Unnormalised input is fine; `(0, 0)`
/// gives ψ = 0.
#[inline]
#[must_use]
pub fn half_angle(c2: f32, s2: f32) -> (f32, f32) {
    let l = (c2 * c2 + s2 * s2).sqrt();
    if l.is_nan() || l <= 1e-12 {
        return (1.0, 0.0);
    }
    let c = c2 / l;
    let s = s2 / l;
    let cos = (0.5 * (1.0 + c)).max(0.0).sqrt();
    let sin = (0.5 * (1.0 - c)).max(0.0).sqrt();
    (cos, if s < 0.0 { -sin } else { sin })
}
