//! What the two analytic-lobe mixtures share: the improved baseline (paper Eq. 1,
//! [`super::improved_baseline`]) and the analytic mixture (paper Eq. 2,
//! [`super::analytic_mixture`]), both on the **projected unit disk** (`ARCHITECTURES.md`
//! §1–2).
//!
//! A small MLP maps the encoded condition `encode_condition(φ, wi)` to the parameters of a
//! mixture of a Lambertian lobe (the constant 1/π on the disk) and one or two Gaussians:
//!
//! ```text
//! Eq. 1   p(ω⊥) = w_L/π · [|ω⊥| < 1] + w_G · N(ω⊥; μ, σ² I)
//! Eq. 2   p(ω⊥) = w0/π · [|ω⊥| < 1] + w1 · N(ω⊥; μ1, diag σ1²) + w2 · N(ω⊥; μ2, diag σ2²)
//! ```
//!
//! [`Sampler::prepare`] runs the network once and keeps only the lobe parameters; sampling
//! picks a component (pbrt style, [`gaussian::select_component`]), draws the Lambert lobe
//! with the concentric map and a Gaussian with Box–Muller, and reports the **full mixture
//! density** at the drawn point (the same function as [`Prepared::pdf_disk`]), so `sample`
//! and `pdf` can never disagree. Gaussian mass that falls outside the disk is refused
//! (`None`): the density is 0 there and integrates over the disk to the mass inside.
//!
//! There is no `invert`: a mixture's sampling map is not injective (every component can reach
//! the same direction), so [`Prepared::invert`] keeps its default `None`.
//!
//! [`Sampler::prepare`]: super::Sampler::prepare
//! [`Prepared::pdf_disk`]: super::Prepared::pdf_disk
//! [`Prepared::invert`]: super::Prepared::invert
//! [`gaussian::select_component`]: crate::distrib::gaussian::select_component

use glam::Vec2;

use crate::distrib::gaussian;
use crate::math::{self, finite_density};
use crate::warp::{self, inside_disk};

use super::{Prepared, Sample};

/// Bound applied to every predicted Gaussian mean coordinate (NaN → −bound).
///
/// A trained model predicts means within a few units of the disk; the clamp only keeps
/// non-finite network outputs from reaching the density (a Gaussian centred this far away
/// has no mass on the disk anyway).
pub const MEAN_BOUND: f32 = 1.0e4;

/// Width of the hidden layers of both lobe networks.
pub(super) const HIDDEN: usize = 32;

/// Lanes per chunk of both mixtures' batched calls.
#[cfg(not(target_arch = "spirv"))]
pub(super) const CHUNK: usize = 32;

#[cfg(not(target_arch = "spirv"))]
pub(crate) mod batch;

/// A predicted mean coordinate, clamped to [`MEAN_BOUND`].
#[inline(always)]
pub(super) fn mean(x: f32) -> f32 {
    math::clamp(x, -MEAN_BOUND, MEAN_BOUND)
}

/// A Gaussian lobe on the disk: its mean and its per-axis standard deviations.
pub(super) type Lobe = (Vec2, Vec2);

/// A point of the mixture of a Lambert lobe and the Gaussian `lobes`, with the weights `w`
/// (Lambert's first, then one per lobe, summing to 1): the component chosen by `u.x` (pbrt
/// style), the Lambert lobe by the concentric map, a Gaussian by Box–Muller. `None` for a
/// `u` outside `[0, 1]²`.
#[inline(always)]
pub(super) fn draw<const K: usize, const G: usize>(
    w: &[f32; K],
    lobes: &[Lobe; G],
    u: Vec2,
) -> Option<Vec2> {
    let u = math::sanitize_u2(u)?;
    let (i, u0) = gaussian::select_component(w, u.x);
    let v = Vec2::new(u0, u.y);
    Some(if i == 0 {
        warp::sample_uniform_disk_concentric(v)
    } else {
        // i ∈ 1 ..= G; clamped so that the index is provably in range.
        let (mu, sigma) = lobes[(i - 1).min(G - 1)];
        mu + sigma * gaussian::box_muller(v)
    })
}

/// The density of that mixture at `p` (Eq. 1 and 2), `w0/π + Σ_g w_g·N(p; μ_g, diag σ_g²)`,
/// with respect to area on the projected disk; 0 outside the open unit disk.
#[inline(always)]
pub(super) fn density<const K: usize, const G: usize>(
    w: &[f32; K],
    lobes: &[Lobe; G],
    p: Vec2,
) -> f32 {
    if !inside_disk(p) {
        return 0.0;
    }
    let mut d = w[0] * math::INV_PI;
    // rust-gpu: an index loop (slice iterators are pointer casts it cannot compile).
    let mut g = 0;
    while g < G {
        let (mu, sigma) = lobes[g];
        d += w[(g + 1).min(K - 1)] * gaussian::normal_pdf(p, mu, sigma);
        g += 1;
    }
    finite_density(d)
}

/// A prepared lobe mixture at one shading point: the weights (Lambert's first, then one per
/// Gaussian lobe, summing to 1; `K = G + 1`) and the `G` Gaussian lobes. The improved
/// baseline's is [`ImprovedBaselinePrepared`](super::ImprovedBaselinePrepared) (`G = 1`,
/// isotropic), the analytic mixture's [`AnalyticMixturePrepared`](super::AnalyticMixturePrepared)
/// (`G = 2`); each is built by its sampler's `from_outputs`.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct LobeMixture<const K: usize, const G: usize> {
    weights: [f32; K],
    lobes: [Lobe; G],
}

impl<const K: usize, const G: usize> LobeMixture<K, G> {
    /// The mixture of `weights` and `lobes`.
    #[inline(always)]
    pub(super) fn new(weights: [f32; K], lobes: [Lobe; G]) -> Self {
        LobeMixture { weights, lobes }
    }

    /// The Gaussian lobes: each one's mean and per-axis standard deviations.
    #[inline(always)]
    pub(super) fn lobes(&self) -> &[Lobe; G] {
        &self.lobes
    }

    /// Mixture weights: Lambert's, then one per Gaussian lobe.
    #[must_use]
    pub fn weights(&self) -> [f32; K] {
        self.weights
    }
}

impl<const K: usize, const G: usize> Prepared for LobeMixture<K, G> {
    /// Component 0 (Lambert) by the concentric map, the Gaussians by Box–Muller; the
    /// reported density is the full mixture (Eq. 1 or 2) at the drawn point.
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let p = draw(&self.weights, &self.lobes, u)?;
        Sample::from_disk(p, self.pdf_disk(p))
    }

    /// Eq. 1 or 2, with respect to area on the projected disk; 0 outside the open unit disk.
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        density(&self.weights, &self.lobes, p)
    }
}
