//! Both lobe mixtures over wavefronts ([`LaneChunks`]): the density of a chunk's lanes as
//! loops over whole rows (rows of [`NARROW`] lanes for a chunk of at most that many), with
//! the fast `exp` of `math::approx` (the scalar path takes libm's), and the Gaussian draws by
//! the rows' Box–Muller; the component choice and the concentric map stay per lane. Sample
//! and pdf take the same density function, so a sample's pdf is `pdf_batch` at its direction
//! bit for bit; both agree with the scalar path within the `wavefront` tolerances.

use glam::Vec2;

use super::{LobeMixture, CHUNK};
use crate::distrib::gaussian;
use crate::math::{self, approx, finite_density};
use crate::samplers::Sample;
use crate::warp::{self, inside_disk};
use crate::wavefront::chunked::LaneChunks;
use crate::wavefront::lanes::{self, Lanes, NARROW};
use crate::wavefront::{SamplesMut, Vec2s, Vec3s};

/// The mixtures of the first `B` lanes of a chunk as rows: weights, then each Gaussian's
/// mean and standard deviations. Lanes without a mixture have weight 0 and unit deviations.
struct Rows<const K: usize, const G: usize, const B: usize> {
    w: [[f32; B]; K],
    mu: [[[f32; B]; 2]; G],
    sigma: [[[f32; B]; 2]; G],
}

impl<const K: usize, const G: usize, const B: usize> Rows<K, G, B> {
    #[inline(always)]
    fn new(lanes: &[Option<LobeMixture<K, G>>]) -> Self {
        let mut r = Rows {
            w: [[0.0; B]; K],
            mu: [[[0.0; B]; 2]; G],
            sigma: [[[1.0; B]; 2]; G],
        };
        for (l, lane) in lanes.iter().enumerate().take(B) {
            if let Some(x) = lane {
                for k in 0..K {
                    r.w[k][l] = x.weights[k];
                }
                for g in 0..G {
                    let (mu, sigma) = x.lobes[g];
                    (r.mu[g][0][l], r.mu[g][1][l]) = (mu.x, mu.y);
                    (r.sigma[g][0][l], r.sigma[g][1][l]) = (sigma.x, sigma.y);
                }
            }
        }
        r
    }

    /// [`super::density`] of every lane at `(px, py)`, each step over the whole row.
    #[inline(always)]
    fn densities(&self, px: &[f32; B], py: &[f32; B], out: &mut [f32; B]) {
        let mut d = [0.0f32; B];
        for (d, w) in d.iter_mut().zip(&self.w[0]) {
            *d = *w * math::INV_PI;
        }
        let mut e = [0.0f32; B];
        for g in 0..G {
            let ([mx, my], [sx, sy]) = (&self.mu[g], &self.sigma[g]);
            for l in 0..B {
                let dx = (px[l] - mx[l]) / sx[l];
                let dy = (py[l] - my[l]) / sy[l];
                e[l] = approx::exp(-0.5 * (dx * dx + dy * dy));
            }
            let w = &self.w[(g + 1).min(K - 1)];
            for l in 0..B {
                d[l] += w[l] * (e[l] * (math::INV_TWO_PI / (sx[l] * sy[l])));
            }
        }
        for l in 0..B {
            out[l] = if inside_disk(Vec2::new(px[l], py[l])) {
                finite_density(d[l])
            } else {
                0.0
            };
        }
    }
}

/// The softmax of `K` rows of logits (each clamped as `math::clamp_logit`), lane by lane, with
/// the fast `exp` (`gaussian::softmax_lanes` over the whole row).
#[inline(always)]
pub(crate) fn weight_rows<const K: usize, const B: usize>(logits: [&[f32; B]; K]) -> [[f32; B]; K] {
    let mut x = [Lanes::<B>::splat(0.0); K];
    for (x, row) in x.iter_mut().zip(logits) {
        for (v, a) in x.0.iter_mut().zip(row) {
            *v = math::clamp_logit(*a);
        }
    }
    gaussian::softmax_lanes(&mut x);
    x.map(|r| r.0)
}

/// `gaussian::sigma_from_log` of every lane, with the fast `exp`.
#[inline(always)]
pub(crate) fn sigma_row<const B: usize>(log_sigma: &[f32; B]) -> [f32; B] {
    let mut r = [0.0f32; B];
    for (r, x) in r.iter_mut().zip(log_sigma) {
        *r = approx::exp(math::clamp(
            *x,
            gaussian::LOG_SIGMA_MIN,
            gaussian::LOG_SIGMA_MAX,
        ));
    }
    r
}

/// [`mean`](super::mean) of every lane.
#[inline(always)]
pub(crate) fn mean_row<const B: usize>(x: &[f32; B]) -> [f32; B] {
    let mut r = [0.0f32; B];
    for (r, x) in r.iter_mut().zip(x) {
        *r = super::mean(*x);
    }
    r
}

/// Sample of the first `B` lanes of a chunk (at most `B`): each lane's component and its
/// point (module docs), then the mixture's density there.
#[inline(always)]
fn sample_rows<const K: usize, const G: usize, const B: usize>(
    lanes: &[Option<LobeMixture<K, G>>],
    u: Vec2s<'_>,
    mut out: SamplesMut<'_>,
) {
    let m = lanes.len().min(B);
    let mut ok = [false; B];
    let mut gauss = [false; B];
    let (mut v0, mut v1) = ([0.0f32; B], [0.0f32; B]);
    let (mut px, mut py) = ([0.0f32; B], [0.0f32; B]);
    let (mut mx, mut my, mut sx, mut sy) = ([0.0f32; B], [0.0; B], [0.0; B], [0.0; B]);
    for i in 0..m {
        let (Some(x), Some(uu)) = (&lanes[i], math::sanitize_u2(u.at(i))) else {
            continue;
        };
        let (c, u0) = gaussian::select_component(&x.weights, uu.x);
        ok[i] = true;
        (v0[i], v1[i]) = (u0, uu.y);
        if c == 0 {
            let p = warp::sample_uniform_disk_concentric(Vec2::new(u0, uu.y));
            (px[i], py[i]) = (p.x, p.y);
        } else {
            // c ∈ 1 ..= G; clamped so that the index is provably in range.
            let (mu, sigma) = x.lobes[(c - 1).min(G - 1)];
            gauss[i] = true;
            (mx[i], my[i], sx[i], sy[i]) = (mu.x, mu.y, sigma.x, sigma.y);
        }
    }
    let (mut nx, mut ny) = ([0.0f32; B], [0.0f32; B]);
    lanes::box_muller_rows(&v0, &v1, &mut nx, &mut ny);
    for l in 0..B {
        if gauss[l] {
            px[l] = mx[l] + sx[l] * nx[l];
            py[l] = my[l] + sy[l] * ny[l];
        }
    }
    let mut d = [0.0f32; B];
    Rows::<K, G, B>::new(lanes).densities(&px, &py, &mut d);
    for i in 0..m {
        let s = if ok[i] {
            Sample::from_disk(Vec2::new(px[i], py[i]), d[i])
        } else {
            None
        };
        out.set(i, s);
    }
}

/// [`Prepared::pdf`](crate::Prepared::pdf) of the first `B` lanes of a chunk (at most `B`).
#[inline(always)]
fn pdf_rows<const K: usize, const G: usize, const B: usize>(
    lanes: &[Option<LobeMixture<K, G>>],
    wo: Vec3s<'_>,
    pdf: &mut [f32],
) {
    let m = lanes.len().min(B);
    let mut ok = [false; B];
    let (mut px, mut py, mut cos) = ([0.0f32; B], [0.0f32; B], [0.0f32; B]);
    for i in 0..m {
        if let (Some(_), Some(w)) = (&lanes[i], warp::upper_hemisphere(wo.at(i))) {
            ok[i] = true;
            (px[i], py[i], cos[i]) = (w.x, w.y, w.z);
        }
    }
    let mut d = [0.0f32; B];
    Rows::<K, G, B>::new(lanes).densities(&px, &py, &mut d);
    for i in 0..m {
        pdf[i] = if ok[i] {
            warp::disk_to_solid_angle(d[i], cos[i])
        } else {
            0.0
        };
    }
}

/// Sample and pdf over rows of [`NARROW`] lanes for a chunk of at most that many, of the
/// whole chunk otherwise (the same bits either way). No inverse (the default's `None`): the
/// mixtures' sampling maps are not injective.
impl<const K: usize, const G: usize> LaneChunks for LobeMixture<K, G> {
    #[inline(always)]
    fn sample_lanes(lanes: &[Option<Self>], u: Vec2s<'_>, out: SamplesMut<'_>) {
        if lanes.len() <= NARROW {
            sample_rows::<K, G, NARROW>(lanes, u, out);
        } else {
            sample_rows::<K, G, CHUNK>(lanes, u, out);
        }
    }

    #[inline(always)]
    fn pdf_lanes(lanes: &[Option<Self>], wo: Vec3s<'_>, pdf: &mut [f32]) {
        if lanes.len() <= NARROW {
            pdf_rows::<K, G, NARROW>(lanes, wo, pdf);
        } else {
            pdf_rows::<K, G, CHUNK>(lanes, wo, pdf);
        }
    }
}
