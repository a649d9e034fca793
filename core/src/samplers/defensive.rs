//! [`Defensive`]: a learned sampler mixed with cosine sampling, so that no sample weight
//! exceeds `π·f/α` wherever the material reflects.
//!
//! The density is the one-sample mixture (Veach's defensive importance sampling; Owen & Zhou
//! 2000) of the learned density `p_l` and the cosine density:
//!
//! ```text
//! p(wo) = (1 − α)·p_l(wo) + α·cos θo / π      (solid angle)
//! p⊥(x) = (1 − α)·p_l⊥(x) + α / π             (projected-disk area)
//! ```
//!
//! One uniform chooses the part: `u.x < α` draws cosine from `(u.x / α, u.y)`, otherwise the
//! learned sampler draws from `((u.x − α) / (1 − α), u.y)`. Both parts are evaluated for
//! every density, so the pdf is exact whichever part drew the sample (the learned part's
//! density at a cosine sample costs one `pdf` of the learned sampler).
//!
//! With α = 0 every call is the learned sampler's own, bit for bit: version-1 blobs, which
//! have no α, behave as before.
//!
//! A learned part whose samples carry a density other than its `pdf` (a
//! [`Sample::mis_pdf`] other than [`Sample::pdf`]: the reparameterization sampler, exact
//! density `q`, pdf network `p̂`) cannot give the mixture's density at a cosine sample (`q`
//! is unknown there). The two parts are then combined as one-sample MIS with the balance
//! heuristic over `p̂` (Veach 1997, §9.2.4), which stays unbiased because the weights sum
//! to one:
//!
//! ```text
//! cosine sample:   divide by (1 − α)·p̂ + α·cos θo/π          (= pdf(wo), as before)
//! learned sample:  divide by ((1 − α)·p̂ + α·cos θo/π) · q/p̂  (q where p̂ = q)
//! ```
//!
//! and every sample's MIS density is `pdf(wo) = (1 − α)·p̂ + α·cos θo/π`. Where the learned
//! part's samples carry their `pdf` (`p̂ = q`) both are `(1 − α)·q + α·cos θo/π`.
//!
//! **Isotropic blobs.** A sampler trained on an isotropic material sees only `wi`'s elevation:
//! its conditions were rotated about the normal to azimuth 0. The wrapper does the same at
//! run time ([`Turn`]): `prepare` turns `wi` to `(|wi⊥|, 0, wi.z)` and remembers the turn,
//! samples are turned back and queried directions turned forward. A rotation about the normal
//! preserves solid angle and projected-disk area, so every density is unchanged.

use glam::{Vec2, Vec3};

use crate::math::{self, INV_PI, ONE_MINUS_EPSILON};
use crate::nn::FEATURE_DIM;
use crate::warp;

use super::{Prepared, Sample, Sampler};

/// A sampler `S` mixed with cosine sampling at weight α, for isotropic blobs in the frame of
/// `wi`'s azimuth (module docs).
#[derive(Copy, Clone, Debug)]
pub struct Defensive<S> {
    inner: S,
    alpha: f32,
    isotropic: bool,
}

/// The prepared state of a [`Defensive`] sampler: the learned part's state, α and the turn
/// from the frame the learned part was prepared in to the shading frame.
#[derive(Copy, Clone, Debug)]
pub struct DefensivePrepared<P> {
    inner: P,
    alpha: f32,
    turn: Turn,
}

/// A [`Defensive`] sampler's lane of the batched API: the learned part's lane and the turn
/// into its frame.
#[derive(Copy, Clone, Debug, Default)]
pub struct DefensiveLane<L> {
    inner: L,
    turn: Turn,
}

impl<L> DefensiveLane<L> {
    /// The learned part's lane.
    #[inline]
    #[must_use]
    pub fn inner(&self) -> &L {
        &self.inner
    }

    /// The turn from the learned part's frame to the shading frame.
    #[inline]
    #[must_use]
    pub fn turn(&self) -> Turn {
        self.turn
    }
}

/// A rotation about the normal, by `(cos, sin)` of an angle: [`Turn::to_world`] turns by it,
/// [`Turn::to_local`] back. The identity leaves every value bit for bit.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Turn {
    cos: f32,
    sin: f32,
}

impl Turn {
    /// No rotation.
    pub const IDENTITY: Turn = Turn { cos: 1.0, sin: 0.0 };

    /// The turn that carries `(|wi⊥|, 0, wi.z)` to `wi`, with that direction: `wi` at
    /// azimuth 0. The identity and `wi` itself where the azimuth is undefined (on the pole,
    /// or a non-finite `wi`, which the learned part then refuses).
    #[inline]
    #[must_use]
    pub fn aligning(wi: Vec3) -> (Turn, Vec3) {
        let r = math::sqrt(wi.x * wi.x + wi.y * wi.y);
        if r > 1e-20 && r < f32::INFINITY {
            let turn = Turn {
                cos: wi.x / r,
                sin: wi.y / r,
            };
            (turn, Vec3::new(r, 0.0, wi.z))
        } else {
            (Turn::IDENTITY, wi)
        }
    }

    /// Whether this is the identity.
    #[inline(always)]
    fn is_identity(self) -> bool {
        self.sin == 0.0 && self.cos == 1.0
    }

    /// `v` turned by the angle (local frame → shading frame).
    #[inline(always)]
    #[must_use]
    pub fn to_world(self, v: Vec3) -> Vec3 {
        let p = self.to_world_2d(Vec2::new(v.x, v.y));
        Vec3::new(p.x, p.y, v.z)
    }

    /// `v` turned back (shading frame → local frame).
    #[inline(always)]
    #[must_use]
    pub fn to_local(self, v: Vec3) -> Vec3 {
        let p = self.to_local_2d(Vec2::new(v.x, v.y));
        Vec3::new(p.x, p.y, v.z)
    }

    /// A projected-disk point turned by the angle.
    #[inline(always)]
    #[must_use]
    pub fn to_world_2d(self, p: Vec2) -> Vec2 {
        if self.is_identity() {
            return p;
        }
        Vec2::new(
            self.cos * p.x - self.sin * p.y,
            self.sin * p.x + self.cos * p.y,
        )
    }

    /// A projected-disk point turned back.
    #[inline(always)]
    #[must_use]
    pub fn to_local_2d(self, p: Vec2) -> Vec2 {
        Turn {
            cos: self.cos,
            sin: -self.sin,
        }
        .to_world_2d(p)
    }
}

impl Default for Turn {
    #[inline]
    fn default() -> Self {
        Turn::IDENTITY
    }
}

impl<S> Defensive<S> {
    /// `inner` mixed with cosine at weight `alpha`, or `None` unless `0 ≤ alpha < 1`.
    #[inline]
    #[must_use]
    pub fn new(inner: S, alpha: f32) -> Option<Self> {
        if alpha >= 0.0 && alpha < 1.0 {
            Some(Self::new_unchecked(inner, alpha))
        } else {
            None
        }
    }

    /// [`Defensive::new`] without the range check, for GPU shaders (`Option<Self>` with a
    /// borrowed sampler cannot be tested by rust-gpu). An α outside `[0, 1)` gives wrong
    /// densities, never a panic or NaN: α ≤ 0 (or NaN) is the learned sampler alone.
    #[inline]
    #[must_use]
    pub const fn new_unchecked(inner: S, alpha: f32) -> Self {
        Self {
            inner,
            alpha,
            isotropic: false,
        }
    }

    /// The same sampler, whose learned part was trained on conditions at azimuth 0 where
    /// `isotropic` (module docs).
    #[inline]
    #[must_use]
    pub const fn with_isotropic(mut self, isotropic: bool) -> Self {
        self.isotropic = isotropic;
        self
    }

    /// Whether the learned part sees `wi` at azimuth 0 (module docs).
    #[inline]
    #[must_use]
    pub fn is_isotropic(&self) -> bool {
        self.isotropic
    }

    /// `inner` alone (α = 0).
    #[inline]
    #[must_use]
    pub const fn plain(inner: S) -> Self {
        Self::new_unchecked(inner, 0.0)
    }

    /// The learned part.
    #[inline]
    #[must_use]
    pub fn inner(&self) -> &S {
        &self.inner
    }

    /// The defensive weight α.
    #[inline]
    #[must_use]
    pub fn alpha(&self) -> f32 {
        self.alpha
    }

    /// Whether the cosine part is present (α > 0).
    #[inline]
    #[must_use]
    pub fn is_mixed(&self) -> bool {
        self.alpha > 0.0
    }
}

/// What [`Blob::sampler`](crate::Blob::sampler) returns: whichever sampler the blob holds,
/// with the blob's defensive weight.
pub type BlobSampler<'a> = Defensive<super::AnySampler<'a>>;

impl<'a> Defensive<super::AnySampler<'a>> {
    /// Cosine sampling (no blob), as a [`BlobSampler`].
    #[inline]
    #[must_use]
    pub const fn cosine() -> Self {
        Self::plain(super::AnySampler::Cosine(super::CosineSampler))
    }

    /// The kind of the learned part.
    #[inline]
    #[must_use]
    pub fn kind(&self) -> crate::SamplerKind {
        self.inner.kind()
    }
}

/// `(1 − α)·p_l + α·cos θ / π`, the mixture's solid-angle density.
#[inline(always)]
fn mix(alpha: f32, p_learned: f32, cos_theta: f32) -> f32 {
    (1.0 - alpha) * p_learned + alpha * (cos_theta * INV_PI)
}

/// The mixture's sample of a learned sample drawn with solid-angle density `q` whose MIS
/// density is `p̂` (module docs): divided by `mix(p̂)·q/p̂`, weighed with `mix(p̂)`; with
/// `p̂ = q` (bit for bit) that is `mix(q)` for both. `None` (refused: its MIS weight is 0)
/// where `p̂` is not positive or a density is not finite.
#[inline(always)]
fn mixed_learned(alpha: f32, wo: Vec3, q: f32, p_hat: f32) -> Option<Sample> {
    let mis = mix(alpha, p_hat, wo.z);
    if q == p_hat {
        return Sample::from_solid_angle(wo, mis);
    }
    if !(p_hat > 0.0) {
        return None;
    }
    Some(Sample::from_solid_angle(wo, mis / p_hat * q)?.with_mis_pdf(mis))
}

/// Which part `u` chooses and the uniform it hands that part: `(true, u')` for cosine.
#[inline(always)]
fn split(alpha: f32, u: Vec2) -> (bool, Vec2) {
    let below = |x: f32| {
        if x < ONE_MINUS_EPSILON {
            x
        } else {
            ONE_MINUS_EPSILON
        }
    };
    if u.x < alpha {
        (true, Vec2::new(below(u.x / alpha), u.y))
    } else {
        (false, Vec2::new(below((u.x - alpha) / (1.0 - alpha)), u.y))
    }
}

/// The cosine part's direction for `u'`.
#[inline(always)]
fn cosine_direction(u: Vec2) -> Option<Vec3> {
    warp::from_disk(warp::sample_uniform_disk_concentric(u))
}

impl<S: Sampler> Sampler for Defensive<S> {
    type Prepared<'s>
        = DefensivePrepared<S::Prepared<'s>>
    where
        Self: 's;

    #[inline]
    fn prepare<'s>(&'s self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<Self::Prepared<'s>> {
        let (turn, wi) = if self.isotropic {
            Turn::aligning(wi)
        } else {
            (Turn::IDENTITY, wi)
        };
        Some(DefensivePrepared {
            inner: self.inner.prepare(phi, wi)?,
            alpha: self.alpha,
            turn,
        })
    }
}

impl<P: Prepared> DefensivePrepared<P> {
    /// The learned part's prepared state.
    #[inline]
    #[must_use]
    pub fn inner(&self) -> &P {
        &self.inner
    }

    /// The turn from the learned part's frame to the shading frame.
    #[inline]
    #[must_use]
    pub fn turn(&self) -> Turn {
        self.turn
    }

    /// The mixture's sample in the learned part's frame.
    #[inline]
    fn sample_local(&self, u: Vec2) -> Option<Sample> {
        if !(self.alpha > 0.0) {
            return self.inner.sample(u);
        }
        let u = math::sanitize_u2(u)?;
        let (cosine, u) = split(self.alpha, u);
        if cosine {
            let wo = cosine_direction(u)?;
            Sample::from_solid_angle(wo, mix(self.alpha, self.inner.pdf(wo), wo.z))
        } else {
            let s = self.inner.sample(u)?;
            mixed_learned(self.alpha, s.wo, s.pdf, s.mis_pdf)
        }
    }

    /// The mixture's density at `p` in the learned part's frame (projected-disk area).
    #[inline]
    fn pdf_disk_local(&self, p: Vec2) -> f32 {
        if !(self.alpha > 0.0) {
            return self.inner.pdf_disk(p);
        }
        if !warp::inside_disk(p) {
            return 0.0;
        }
        (1.0 - self.alpha) * self.inner.pdf_disk(p) + self.alpha * INV_PI
    }

    /// The mixture's density at `wo` in the learned part's frame (solid angle).
    #[inline]
    fn pdf_local(&self, wo: Vec3) -> f32 {
        if !(self.alpha > 0.0) {
            return self.inner.pdf(wo);
        }
        match warp::upper_hemisphere(wo) {
            Some(w) => mix(self.alpha, self.inner.pdf(w), w.z),
            None => 0.0,
        }
    }
}

impl<P: Prepared> Prepared for DefensivePrepared<P> {
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let s = self.sample_local(u)?;
        Some(Sample {
            wo: self.turn.to_world(s.wo),
            ..s
        })
    }

    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        self.pdf_disk_local(self.turn.to_local_2d(p))
    }

    #[inline]
    fn pdf(&self, wo: Vec3) -> f32 {
        self.pdf_local(self.turn.to_local(wo))
    }

    /// The learned part's inverse when α = 0; `None` otherwise (a mixture has no unique
    /// inverse: either part may have drawn a direction).
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        if !(self.alpha > 0.0) {
            return self.inner.invert(self.turn.to_local(wo));
        }
        None
    }
}

#[cfg(not(target_arch = "spirv"))]
mod batch;
