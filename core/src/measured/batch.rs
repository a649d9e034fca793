//! The measured material over `N` lanes at once ([`crate::wavefront`]'s conventions:
//! structure-of-arrays views, every buffer the caller's, a bad lane never disturbs another).

use crate::batch::{check_len, RgbMut, SamplesMut, Vec2s, Vec3s};
use crate::error::Result;
use crate::weights::Weights;

use super::MeasuredMaterial;

impl<W: Weights> MeasuredMaterial<W> {
    /// [`MeasuredPrepared::eval`](super::MeasuredPrepared::eval) of every `(wi[i], wo[i])`:
    /// the RGB BRDF without the cosine, `[0, 0, 0]` for refused lanes.
    ///
    /// # Errors
    /// [`Error::BatchLength`](crate::Error::BatchLength) when the slices' lengths differ
    /// (nothing is written).
    pub fn eval_batch(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>) -> Result<()> {
        let n = wi.len();
        wi.check(n)?;
        wo.check(n)?;
        check_rgb(&out, n)?;
        for i in 0..n {
            let f = match self.prepare(wi.at(i)) {
                Some(p) => p.eval(wo.at(i)),
                None => [0.0; 3],
            };
            out.r[i] = f[0];
            out.g[i] = f[1];
            out.b[i] = f[2];
        }
        Ok(())
    }

    /// [`MeasuredPrepared::pdf`](super::MeasuredPrepared::pdf) of every `(wi[i], wo[i])`:
    /// the data sampler's density with respect to solid angle, 0 for refused lanes.
    ///
    /// # Errors
    /// [`Error::BatchLength`](crate::Error::BatchLength) when the slices' lengths differ.
    pub fn pdf_batch(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, pdf: &mut [f32]) -> Result<()> {
        let n = wi.len();
        wi.check(n)?;
        wo.check(n)?;
        check_len("pdf", pdf.len(), n)?;
        for (i, p) in pdf.iter_mut().enumerate() {
            *p = match self.prepare(wi.at(i)) {
                Some(prep) => prep.pdf(wo.at(i)),
                None => 0.0,
            };
        }
        Ok(())
    }

    /// [`MeasuredPrepared::sample`](super::MeasuredPrepared::sample) of every `(wi[i], u[i])`:
    /// directions and solid-angle densities in `out`, `f · cos θo / pdf` per channel in
    /// `weight`; a refused lane gets `wo = 0`, `pdf = 0` and a zero weight.
    ///
    /// # Errors
    /// [`Error::BatchLength`](crate::Error::BatchLength) when the slices' lengths differ.
    pub fn sample_batch(
        &self,
        wi: Vec3s<'_>,
        u: Vec2s<'_>,
        mut out: SamplesMut<'_>,
        weight: RgbMut<'_>,
    ) -> Result<()> {
        let n = wi.len();
        wi.check(n)?;
        u.check(n)?;
        out.check(n)?;
        check_rgb(&weight, n)?;
        for i in 0..n {
            let s = self.prepare(wi.at(i)).and_then(|p| p.sample(u.at(i)));
            let w = s.map_or([0.0; 3], |s| s.weight);
            out.set(
                i,
                s.map(|s| crate::Sample {
                    wo: s.wo,
                    pdf: s.pdf,
                    pdf_disk: s.pdf / s.wo.z,
                }),
            );
            weight.r[i] = w[0];
            weight.g[i] = w[1];
            weight.b[i] = w[2];
        }
        Ok(())
    }
}

fn check_rgb(out: &RgbMut<'_>, n: usize) -> Result<()> {
    check_len("r", out.r.len(), n)?;
    check_len("g", out.g.len(), n)?;
    check_len("b", out.b.len(), n)
}
