//! [`Defensive`] over wavefronts: the learned part's batched kernels, the cosine lanes
//! gathered into one `pdf_batch` of the learned part per chunk.

use super::*;
use crate::error::Result;
use crate::wavefront::{
    check_invert_args, check_pdf_args, check_sample_args, chunks, BatchSampler, Features,
    LaneState, SamplesMut, Vec2s, Vec2sMut, Vec3s, FUSED_CHUNK,
};

impl<S: BatchSampler> BatchSampler for Defensive<S> {
    type Lane = S::Lane;
    type Scratch = S::Scratch;

    #[inline]
    fn prepare_batch(&self, phi: Features<'_>, wi: Vec3s<'_>, lanes: &mut [S::Lane]) -> Result<()> {
        self.inner.prepare_batch(phi, wi, lanes)
    }

    fn sample_batch_in(
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

    fn pdf_batch_in(
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

    fn invert_batch(
        &self,
        lanes: &[S::Lane],
        wo: Vec3s<'_>,
        u: Vec2sMut<'_>,
        ok: &mut [bool],
    ) -> Result<()> {
        if !self.is_mixed() {
            return self.inner.invert_batch(lanes, wo, u, ok);
        }
        check_invert_args(lanes, &wo, &u, ok)?;
        ok.fill(false);
        Ok(())
    }

    fn sample_fused(
        &self,
        phi: Features<'_>,
        wi: Vec3s<'_>,
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
    ) -> Result<()> {
        if !self.is_mixed() {
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
        if !self.is_mixed() {
            return self.inner.pdf_fused(phi, wi, wo, pdf);
        }
        crate::wavefront::pdf_fused_chunks(self, phi, wi, wo, pdf)
    }
}
