//! [`Defensive`] over wavefronts: the learned part's batched kernels, the cosine lanes
//! gathered into one `pdf_batch` of the learned part per chunk; for isotropic blobs the
//! directions turned per lane around them.

use super::*;
use crate::error::Result;
use crate::wavefront::{
    check_invert_args, check_pdf_args, check_prepare_args, check_sample_args, chunks, BatchSampler,
    Features, LaneState, SamplesMut, Vec2s, Vec2sMut, Vec3s, FUSED_CHUNK,
};

impl<L: LaneState> LaneState for DefensiveLane<L> {
    #[inline(always)]
    fn is_prepared(&self) -> bool {
        self.inner.is_prepared()
    }
}

/// Lanes `a..b`'s learned parts, copied into `buf`.
#[inline(always)]
fn inner_lanes<'b, L: Copy>(
    lanes: &[DefensiveLane<L>],
    a: usize,
    b: usize,
    buf: &'b mut [L; FUSED_CHUNK],
) -> &'b [L] {
    for (t, l) in buf.iter_mut().zip(&lanes[a..b]) {
        *t = l.inner;
    }
    &buf[..b - a]
}

/// Directions `a..b` of `w` turned into their lanes' local frames, in `buf`.
#[inline(always)]
fn to_local<'b, L>(
    lanes: &[DefensiveLane<L>],
    w: Vec3s<'b>,
    a: usize,
    b: usize,
    buf: &'b mut [[f32; FUSED_CHUNK]; 2],
) -> Vec3s<'b> {
    let m = b - a;
    let [x, y] = buf;
    for i in 0..m {
        let p = lanes[a + i]
            .turn
            .to_local_2d(Vec2::new(w.x[a + i], w.y[a + i]));
        (x[i], y[i]) = (p.x, p.y);
    }
    Vec3s {
        x: &x[..m],
        y: &y[..m],
        z: &w.z[a..b],
    }
}

/// Runs `f(learned lanes, directions in their frames, a, b)` on chunks `a..b` of `lanes` and
/// `wo` (turned into the lanes' frames where `turned`).
#[inline(always)]
fn local_chunks<L: LaneState>(
    lanes: &[DefensiveLane<L>],
    wo: Vec3s<'_>,
    turned: bool,
    mut f: impl FnMut(&[L], Vec3s<'_>, usize, usize) -> Result<()>,
) -> Result<()> {
    let mut buf = [L::default(); FUSED_CHUNK];
    let mut w = [[0.0f32; FUSED_CHUNK]; 2];
    for (a, b) in chunks(lanes.len(), FUSED_CHUNK) {
        let inner = inner_lanes(lanes, a, b, &mut buf);
        let local = if turned {
            to_local(lanes, wo, a, b, &mut w)
        } else {
            wo.range(a, b)
        };
        f(inner, local, a, b)?;
    }
    Ok(())
}

impl<S: BatchSampler> BatchSampler for Defensive<S> {
    type Lane = DefensiveLane<S::Lane>;
    type Scratch = S::Scratch;

    fn prepare_batch(
        &self,
        phi: Features<'_>,
        wi: Vec3s<'_>,
        lanes: &mut [Self::Lane],
    ) -> Result<()> {
        let n = check_prepare_args(&phi, &wi, lanes)?;
        let mut inner = [S::Lane::default(); FUSED_CHUNK];
        for (a, b) in chunks(n, FUSED_CHUNK) {
            let m = b - a;
            let mut turn = [Turn::IDENTITY; FUSED_CHUNK];
            let mut w = [[0.0f32; FUSED_CHUNK]; 3];
            let local = if self.isotropic {
                for i in 0..m {
                    let (t, v) = Turn::aligning(wi.at(a + i));
                    turn[i] = t;
                    (w[0][i], w[1][i], w[2][i]) = (v.x, v.y, v.z);
                }
                Vec3s {
                    x: &w[0][..m],
                    y: &w[1][..m],
                    z: &w[2][..m],
                }
            } else {
                wi.range(a, b)
            };
            self.inner
                .prepare_batch(phi.range(a, b), local, &mut inner[..m])?;
            for i in 0..m {
                lanes[a + i] = DefensiveLane {
                    inner: inner[i],
                    turn: turn[i],
                };
            }
        }
        Ok(())
    }

    fn sample_batch_in(
        &self,
        lanes: &[Self::Lane],
        u: Vec2s<'_>,
        mut out: SamplesMut<'_>,
        scratch: &mut S::Scratch,
    ) -> Result<()> {
        let n = check_sample_args(lanes, &u, &out)?;
        let mut buf = [S::Lane::default(); FUSED_CHUNK];
        for (a, b) in chunks(n, FUSED_CHUNK) {
            let inner = inner_lanes(lanes, a, b, &mut buf);
            let mut chunk = out.range(a, b);
            self.sample_local(inner, u.range(a, b), chunk.range(0, b - a), scratch)?;
            if self.isotropic {
                for i in 0..b - a {
                    let p = lanes[a + i]
                        .turn
                        .to_world_2d(Vec2::new(chunk.wo.x[i], chunk.wo.y[i]));
                    (chunk.wo.x[i], chunk.wo.y[i]) = (p.x, p.y);
                }
            }
        }
        Ok(())
    }

    fn pdf_batch_in(
        &self,
        lanes: &[Self::Lane],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        scratch: &mut S::Scratch,
    ) -> Result<()> {
        check_pdf_args(lanes, &wo, pdf)?;
        local_chunks(lanes, wo, self.isotropic, |inner, local, a, b| {
            self.pdf_local(inner, local, &mut pdf[a..b], scratch)
        })
    }

    fn invert_batch(
        &self,
        lanes: &[Self::Lane],
        wo: Vec3s<'_>,
        mut u: Vec2sMut<'_>,
        ok: &mut [bool],
    ) -> Result<()> {
        check_invert_args(lanes, &wo, &u, ok)?;
        if self.is_mixed() {
            ok.fill(false);
            return Ok(());
        }
        local_chunks(lanes, wo, self.isotropic, |inner, local, a, b| {
            self.inner
                .invert_batch(inner, local, u.range(a, b), &mut ok[a..b])
        })
    }

    fn sample_fused(
        &self,
        phi: Features<'_>,
        wi: Vec3s<'_>,
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
    ) -> Result<()> {
        if !self.is_mixed() && !self.isotropic {
            return self.inner.sample_fused(phi, wi, u, out);
        }
        crate::wavefront::sample_fused_chunks(self, phi, wi, u, out)
    }

    fn pdf_fused(
        &self,
        phi: Features<'_>,
        wi: Vec3s<'_>,
        wo: Vec3s<'_>,
        pdf: &mut [f32],
    ) -> Result<()> {
        if !self.is_mixed() && !self.isotropic {
            return self.inner.pdf_fused(phi, wi, wo, pdf);
        }
        crate::wavefront::pdf_fused_chunks(self, phi, wi, wo, pdf)
    }
}

impl<S: BatchSampler> Defensive<S> {
    /// The mixture's samples in the learned part's frame.
    fn sample_local(
        &self,
        lanes: &[S::Lane],
        u: Vec2s<'_>,
        mut out: SamplesMut<'_>,
        scratch: &mut S::Scratch,
    ) -> Result<()> {
        if !self.is_mixed() {
            return self.inner.sample_batch_in(lanes, u, out, scratch);
        }
        let n = check_sample_args(lanes, &u, &out)?;
        let alpha = self.alpha;
        for (a, b) in chunks(n, FUSED_CHUNK) {
            let m = b - a;
            // Uniforms for the learned part (NaN refuses a lane whose `u` is invalid or
            // that chose cosine: the learned kernel's result there is not used).
            let mut ux = [f32::NAN; FUSED_CHUNK];
            let mut uy = [0.0f32; FUSED_CHUNK];
            // The cosine lanes, gathered: lane index, prepared state, direction.
            let mut at = [0usize; FUSED_CHUNK];
            let mut cl = [S::Lane::default(); FUSED_CHUNK];
            let (mut cx, mut cy, mut cz) = (
                [0.0f32; FUSED_CHUNK],
                [0.0f32; FUSED_CHUNK],
                [0.0f32; FUSED_CHUNK],
            );
            let mut c = 0;
            for i in 0..m {
                let Some(v) = math::sanitize_u2(u.at(a + i)) else {
                    continue;
                };
                let (cosine, v) = split(alpha, v);
                uy[i] = v.y;
                if !cosine {
                    ux[i] = v.x;
                } else if lanes[a + i].is_prepared() {
                    if let Some(wo) = cosine_direction(v) {
                        at[c] = i;
                        cl[c] = lanes[a + i];
                        (cx[c], cy[c], cz[c]) = (wo.x, wo.y, wo.z);
                        c += 1;
                    }
                }
            }
            let mut chunk = out.range(a, b);
            self.inner.sample_batch_in(
                &lanes[a..b],
                Vec2s {
                    x: &ux[..m],
                    y: &uy[..m],
                },
                chunk.range(0, m),
                scratch,
            )?;
            for i in 0..m {
                // Learned lanes: the mixture's densities; refused and cosine lanes:
                // refused here, the cosine ones filled in below.
                let s = if ux[i].is_nan() || !(chunk.pdf[i] > 0.0) {
                    None
                } else {
                    let wo = Vec3::new(chunk.wo.x[i], chunk.wo.y[i], chunk.wo.z[i]);
                    mixed_learned(alpha, wo, chunk.pdf[i], chunk.mis_pdf[i])
                };
                chunk.set(i, s);
            }
            if c > 0 {
                let mut pl = [0.0f32; FUSED_CHUNK];
                self.inner.pdf_batch_in(
                    &cl[..c],
                    Vec3s {
                        x: &cx[..c],
                        y: &cy[..c],
                        z: &cz[..c],
                    },
                    &mut pl[..c],
                    scratch,
                )?;
                for j in 0..c {
                    let wo = Vec3::new(cx[j], cy[j], cz[j]);
                    chunk.set(at[j], Sample::from_solid_angle(wo, mix(alpha, pl[j], wo.z)));
                }
            }
        }
        Ok(())
    }

    /// The mixture's densities in the learned part's frame.
    fn pdf_local(
        &self,
        lanes: &[S::Lane],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        scratch: &mut S::Scratch,
    ) -> Result<()> {
        if !self.is_mixed() {
            return self.inner.pdf_batch_in(lanes, wo, pdf, scratch);
        }
        let n = check_pdf_args(lanes, &wo, pdf)?;
        self.inner.pdf_batch_in(lanes, wo, pdf, scratch)?;
        for i in 0..n {
            pdf[i] = match warp::upper_hemisphere(wo.at(i)) {
                Some(w) if lanes[i].is_prepared() => mix(self.alpha, pdf[i], w.z),
                _ => 0.0,
            };
        }
        Ok(())
    }
}
