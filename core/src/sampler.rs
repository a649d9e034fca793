//! What every sampler has in common: the condition, the sample, and the two traits a
//! renderer programs against.
//!
//! A sampler is used in two steps per shading point:
//!
//! 1. [`Sampler::prepare`] runs the networks once for the condition (φ, wi) and returns a
//!    small value that borrows the sampler's weights;
//! 2. on that value, [`Prepared::sample`] draws directions and [`Prepared::pdf`] evaluates
//!    the density of any direction — as often as needed (BSDF sampling and MIS).
//!
//! Both steps are total: bad input gives `None` or a zero density, never a panic or NaN.

use core::cell::Cell;
use core::fmt;

use glam::{Vec2, Vec3};

use crate::mlp::{self, CONDITION_BANDS};
use crate::warp;

/// Length of the material feature vector φ (NeuMIP-style latent, paper §3).
pub const FEATURE_DIM: usize = 8;

/// Length of the encoded condition fed to the lobe-mixture and flow networks:
/// φ, then `wi.x` and `wi.y` each with a [`CONDITION_BANDS`]-band sinusoidal encoding.
pub const CONDITION_DIM: usize = FEATURE_DIM + 2 * mlp::encoding_len(CONDITION_BANDS);

/// Length of the raw condition `(φ, wi.x, wi.y)` fed to the histogram networks.
pub const RAW_CONDITION_DIM: usize = FEATURE_DIM + 2;

/// A direction drawn by a sampler.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Sample {
    /// The sampled direction in the local shading frame (unit length, `wo.z > 0`).
    pub wo: Vec3,
    /// Its density with respect to **solid angle**: `pdf_disk · wo.z`. This is what a
    /// renderer divides by (pbrt `Sample_f().pdf`, Mitsuba `BSDFSample3f::pdf`).
    pub pdf: f32,
    /// Its density with respect to **area on the projected unit disk**.
    pub pdf_disk: f32,
}

impl Sample {
    /// A sample at disk point `p` with disk density `pdf_disk`, or `None` when `p` is not
    /// strictly inside the unit disk or the density is not finite and positive.
    #[inline]
    #[must_use]
    pub fn from_disk(p: Vec2, pdf_disk: f32) -> Option<Sample> {
        let wo = warp::from_disk(p)?;
        let pdf = warp::disk_to_solid_angle(pdf_disk, wo.z);
        if pdf > 0.0 && crate::math::is_finite(pdf) {
            Some(Sample { wo, pdf, pdf_disk })
        } else {
            None
        }
    }
}

/// A learned (or analytic) sampler of outgoing directions conditioned on (φ, wi).
pub trait Sampler {
    /// The per-shading-point state returned by [`Sampler::prepare`].
    type Prepared<'s>: Prepared
    where
        Self: 's;

    /// Runs the sampler's networks for feature vector `phi` and incoming direction `wi`
    /// (local shading frame, pointing away from the surface; normalised here).
    ///
    /// Returns `None` when the condition is unusable: `wi` at or below the horizon, of zero
    /// length, or with a NaN/∞ component, or `phi` with a NaN/∞ component.
    fn prepare<'s>(&'s self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<Self::Prepared<'s>>;
}

/// Sampling and density evaluation at one prepared shading point.
pub trait Prepared {
    /// Draws a direction from `u ∈ [0, 1)²`. `None` when `u` is not in `[0, 1]²` (1 is
    /// clamped below 1) or the sample falls outside the unit disk (zero contribution; its
    /// probability mass is the part of the density outside the disk).
    fn sample(&self, u: Vec2) -> Option<Sample>;

    /// Density of the disk point `p` with respect to **area on the projected disk**. 0 outside
    /// the open unit disk and for non-finite `p`.
    fn pdf_disk(&self, p: Vec2) -> f32;

    /// Density of direction `wo` (local frame; normalised here) with respect to **solid
    /// angle**: `pdf_disk(wo⊥) · cos θo`. 0 at or below the horizon and for non-finite `wo`.
    /// Equal to [`Sample::pdf`] for every direction [`Prepared::sample`] returns.
    #[inline]
    fn pdf(&self, wo: Vec3) -> f32 {
        match warp::upper_hemisphere(wo) {
            Some(w) => warp::disk_to_solid_angle(self.pdf_disk(warp::to_disk(w)), w.z),
            None => 0.0,
        }
    }

    /// The `u` that [`Prepared::sample`] maps to `wo`, where the method has a unique one
    /// (cosine, flows, histograms); `None` otherwise or for invalid `wo`.
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        let _ = wo;
        None
    }
}

/// Checks a condition: normalised `wi` strictly above the horizon and finite `phi`.
#[inline]
#[must_use]
pub fn check_condition(phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<Vec3> {
    let wi = warp::upper_hemisphere(wi)?;
    let mut k = 0;
    while k < FEATURE_DIM {
        if !crate::math::is_finite(phi[k]) {
            return None;
        }
        k += 1;
    }
    Some(wi)
}

/// The encoded condition for the lobe-mixture and flow networks (release layout):
///
/// ```text
/// [ φ₀ … φ₇,  enc(wi.x),  enc(wi.y) ]      enc = mlp::encode_scalar::<5>  (11 values each)
/// ```
#[inline]
#[must_use]
pub fn encode_condition(phi: &[f32; FEATURE_DIM], wi: Vec3) -> [f32; CONDITION_DIM] {
    let mut x = [0.0f32; CONDITION_DIM];
    let mut k = 0;
    while k < FEATURE_DIM {
        x[k] = phi[k];
        k += 1;
    }
    mlp::encode_scalar::<CONDITION_BANDS, CONDITION_DIM>(wi.x, &mut x, FEATURE_DIM);
    mlp::encode_scalar::<CONDITION_BANDS, CONDITION_DIM>(
        wi.y,
        &mut x,
        FEATURE_DIM + mlp::encoding_len(CONDITION_BANDS),
    );
    x
}

/// The raw condition `[φ₀ … φ₇, wi.x, wi.y]` for the histogram networks.
#[inline]
#[must_use]
pub fn raw_condition(phi: &[f32; FEATURE_DIM], wi: Vec3) -> [f32; RAW_CONDITION_DIM] {
    let mut x = [0.0f32; RAW_CONDITION_DIM];
    let mut k = 0;
    while k < FEATURE_DIM {
        x[k] = phi[k];
        k += 1;
    }
    x[FEATURE_DIM] = wi.x;
    x[FEATURE_DIM + 1] = wi.y;
    x
}

/// Checks both components of `u` with [`crate::math::sanitize_u`].
#[inline(always)]
#[must_use]
pub fn sanitize_u2(u: Vec2) -> Option<Vec2> {
    Some(Vec2::new(
        crate::math::sanitize_u(u.x)?,
        crate::math::sanitize_u(u.y)?,
    ))
}

/// Cosine-hemisphere sampling as a [`Sampler`]: the density is 1/π on the disk for every
/// condition. It has no parameters, so it needs no blob.
#[derive(Copy, Clone, Debug, Default)]
pub struct CosineSampler;

/// The prepared state of [`CosineSampler`] (nothing).
#[derive(Copy, Clone, Debug, Default)]
pub struct CosinePrepared;

impl Sampler for CosineSampler {
    type Prepared<'s> = CosinePrepared;
    #[inline]
    fn prepare(&self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<CosinePrepared> {
        check_condition(phi, wi)?;
        Some(CosinePrepared)
    }
}

impl Prepared for CosinePrepared {
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let u = sanitize_u2(u)?;
        let p = warp::sample_uniform_disk_concentric(u);
        Sample::from_disk(p, self.pdf_disk(p))
    }
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        warp::uniform_disk_pdf(p)
    }
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        let w = warp::upper_hemisphere(wo)?;
        Some(warp::invert_uniform_disk_concentric(warp::to_disk(w)))
    }
}

/// A copy of a sampler's weights handle (`&[f32]`, `Tensor`, …) kept by a prepared state.
///
/// Two constraints of GPU shaders (rust-gpu) shape it:
/// * a prepared state must not point at its sampler: with storage-buffer weights that is a
///   pointer to a local variable holding a buffer pointer, which rust-gpu cannot remove and
///   Vulkan drivers fail on (lavapipe crashes), so the handle is copied (`W: Copy`);
/// * the handle's null-pointer niche must be hidden, so that `Option<Prepared>` is a tagged
///   enum: rust-gpu cannot test a niche-encoded `Option` holding a pointer ("cannot convert
///   pointers to integers"). A `Cell` hides niches.
pub(crate) struct Held<W>(Cell<W>);

impl<W: Copy> Held<W> {
    /// Keeps a copy of `w`.
    #[inline(always)]
    pub(crate) fn new(w: W) -> Self {
        Held(Cell::new(w))
    }
    /// The handle.
    #[inline(always)]
    pub(crate) fn get(&self) -> W {
        self.0.get()
    }
}

impl<W: Copy> Clone for Held<W> {
    #[inline(always)]
    fn clone(&self) -> Self {
        Held::new(self.get())
    }
}

impl<W> fmt::Debug for Held<W> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Held(..)")
    }
}
