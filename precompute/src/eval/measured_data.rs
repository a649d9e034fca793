//! A measured material's own sampler (the VNDF and luminance warps) as a [`BatchSampler`],
//! so that the evaluation renders it with the wavefront integrator through
//! [`MeasuredMaterial`]'s batched calls, as it renders the learned samplers through theirs.
//!
//! A lane's state is its incident direction: the measured material's batched calls take
//! `wi` beside each direction and refuse the lanes its scalar `prepare` refuses, so a lane is
//! kept whenever `wi` is finite with `z > 0` and the batched calls decide the rest (a zero
//! density, a zero sample). Densities are with respect to solid angle.

use neusample::wavefront::{BatchSampler, Features, SamplesMut, Vec2s, Vec2sMut, Vec3s, Vec3sMut};
use neusample::{Error, MeasuredMaterial, MeasuredPrepared, Result, Sampler, Vec3, Weights};

/// Lanes gathered from the lane states per call of the measured material's batched path.
const GROUP: usize = 64;

/// [`MeasuredMaterial`]'s own sampler over lanes of incident directions.
#[derive(Clone, Copy, Debug)]
pub struct MeasuredDataSampler<W>(pub MeasuredMaterial<W>);

fn check(what: &'static str, found: usize, expected: usize) -> Result<()> {
    if found == expected {
        Ok(())
    } else {
        Err(Error::BatchLength {
            what,
            expected: u32::try_from(expected).unwrap_or(u32::MAX),
            found: u32::try_from(found).unwrap_or(u32::MAX),
        })
    }
}

/// `lanes` in chunks of at most [`GROUP`], each with its start and end index in `lanes`.
fn groups<T>(lanes: &[T]) -> impl Iterator<Item = (usize, usize, &[T])> {
    lanes.chunks(GROUP).enumerate().map(|(a, group)| {
        let s = a * GROUP;
        (s, s + group.len(), group)
    })
}

/// The incident directions of at most [`GROUP`] lanes as three arrays (refused lanes: the
/// zero vector, which the measured material refuses).
struct Gathered {
    wi: [[f32; GROUP]; 3],
    n: usize,
}

impl Gathered {
    fn new(lanes: &[Option<[f32; 3]>]) -> Self {
        let mut wi = [[0.0; GROUP]; 3];
        for (i, lane) in lanes.iter().enumerate() {
            let w = lane.unwrap_or([0.0; 3]);
            for (c, v) in wi.iter_mut().zip(w) {
                c[i] = v;
            }
        }
        Gathered { wi, n: lanes.len() }
    }

    fn view(&self) -> Vec3s<'_> {
        let [x, y, z] = &self.wi;
        Vec3s {
            x: &x[..self.n],
            y: &y[..self.n],
            z: &z[..self.n],
        }
    }
}

impl<W: Weights> Sampler for MeasuredDataSampler<W> {
    type Prepared<'s>
        = MeasuredPrepared<'s, W>
    where
        Self: 's;

    /// The scalar path: [`MeasuredMaterial::prepare`].
    #[inline]
    fn prepare<'s>(
        &'s self,
        _phi: &[f32; neusample::FEATURE_DIM],
        wi: Vec3,
    ) -> Option<MeasuredPrepared<'s, W>> {
        self.0.prepare(wi)
    }
}

impl<W: Weights> BatchSampler for MeasuredDataSampler<W> {
    type Lane = Option<[f32; 3]>;
    type Scratch = ();

    fn prepare_batch(
        &self,
        phi: Features<'_>,
        wi: Vec3s<'_>,
        lanes: &mut [Self::Lane],
    ) -> Result<()> {
        let n = lanes.len();
        check("phi", phi.len(), n)?;
        check("wi", wi.len(), n)?;
        for (i, lane) in lanes.iter_mut().enumerate() {
            let w = wi.at(i);
            *lane = (w.is_finite() && w.z > 0.0).then_some(w.to_array());
        }
        Ok(())
    }

    fn sample_batch_in(
        &self,
        lanes: &[Self::Lane],
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
        _scratch: &mut (),
    ) -> Result<()> {
        let n = lanes.len();
        check("u", u.len(), n)?;
        check("wo", out.wo.x.len(), n)?;
        check("wo", out.wo.y.len(), n)?;
        check("wo", out.wo.z.len(), n)?;
        check("pdf", out.pdf.len(), n)?;
        check("mis_pdf", out.mis_pdf.len(), n)?;
        let SamplesMut { wo, pdf, mis_pdf } = out;
        let Vec3sMut { x, y, z } = wo;
        for (s, e, group) in groups(lanes) {
            self.0.sample_directions_batch(
                Gathered::new(group).view(),
                Vec2s {
                    x: &u.x[s..e],
                    y: &u.y[s..e],
                },
                SamplesMut {
                    wo: Vec3sMut {
                        x: &mut x[s..e],
                        y: &mut y[s..e],
                        z: &mut z[s..e],
                    },
                    pdf: &mut pdf[s..e],
                    mis_pdf: &mut mis_pdf[s..e],
                },
            )?;
        }
        Ok(())
    }

    fn pdf_batch_in(
        &self,
        lanes: &[Self::Lane],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        _scratch: &mut (),
    ) -> Result<()> {
        let n = lanes.len();
        check("wo", wo.len(), n)?;
        check("pdf", pdf.len(), n)?;
        for (s, e, group) in groups(lanes) {
            self.0.pdf_batch(
                Gathered::new(group).view(),
                Vec3s {
                    x: &wo.x[s..e],
                    y: &wo.y[s..e],
                    z: &wo.z[s..e],
                },
                &mut pdf[s..e],
            )?;
        }
        Ok(())
    }

    /// The renders never invert; no lane has an inverse here.
    fn invert_batch(
        &self,
        lanes: &[Self::Lane],
        wo: Vec3s<'_>,
        u: Vec2sMut<'_>,
        ok: &mut [bool],
    ) -> Result<()> {
        let n = lanes.len();
        check("wo", wo.len(), n)?;
        check("u", u.x.len(), n)?;
        check("u", u.y.len(), n)?;
        check("ok", ok.len(), n)?;
        ok.fill(false);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use neusample::{Prepared, Vec2};
    use neusample_owned::measured::OwnedMeasured;
    use rand::{RngExt, SeedableRng};

    /// The batched sampler gives the scalar sampler's directions and densities bit for bit,
    /// over more lanes than one group, with refused lanes among them.
    #[test]
    fn batched_is_scalar_bit_for_bit() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../fixtures/measured/chm_mint_rgb.bsdf");
        let data = OwnedMeasured::open(&path).unwrap();
        let m = data.material();
        let s = MeasuredDataSampler(m.borrowed());
        let n = 150;
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        let mut f = move || rng.random::<f32>();
        let mut wi = vec![[0.0f32; 3]; n];
        for (i, w) in wi.iter_mut().enumerate() {
            let v = Vec3::new(f() * 2.0 - 1.0, f() * 2.0 - 1.0, f() - 0.1);
            *w = match i % 37 {
                0 => [f32::NAN, 0.0, 1.0],
                1 => [0.0, 0.0, 0.0],
                _ => v.normalize_or_zero().to_array(),
            };
        }
        let col = |v: &[[f32; 3]], c: usize| v.iter().map(|w| w[c]).collect::<Vec<_>>();
        let (wx, wy, wz) = (col(&wi, 0), col(&wi, 1), col(&wi, 2));
        let ux: Vec<f32> = (0..n).map(|_| f()).collect();
        let uy: Vec<f32> = (0..n).map(|_| f()).collect();
        let phi = vec![0.0f32; n * neusample::FEATURE_DIM];
        let mut lanes = vec![None; n];
        s.prepare_batch(
            Features::from_rows(&phi, n).unwrap(),
            Vec3s {
                x: &wx,
                y: &wy,
                z: &wz,
            },
            &mut lanes,
        )
        .unwrap();
        let [mut ox, mut oy, mut oz, mut pdf, mut mis] = [(); 5].map(|_| vec![0.0; n]);
        s.sample_batch(
            &lanes,
            Vec2s { x: &ux, y: &uy },
            SamplesMut {
                wo: Vec3sMut {
                    x: &mut ox,
                    y: &mut oy,
                    z: &mut oz,
                },
                pdf: &mut pdf,
                mis_pdf: &mut mis,
            },
        )
        .unwrap();
        assert_eq!(
            pdf, mis,
            "the data's sampler: its MIS density is its density"
        );
        let mut density = vec![0.0; n];
        s.pdf_batch(
            &lanes,
            Vec3s {
                x: &ox,
                y: &oy,
                z: &oz,
            },
            &mut density,
        )
        .unwrap();
        let mut sampled = 0;
        for i in 0..n {
            let w = Vec3::from_array(wi[i]);
            let scalar = m
                .prepare(w)
                .and_then(|p| Prepared::sample(&p, Vec2::new(ux[i], uy[i])));
            match scalar {
                Some(x) => {
                    sampled += 1;
                    assert_eq!([ox[i], oy[i], oz[i]], x.wo.to_array(), "lane {i}");
                    assert_eq!(pdf[i].to_bits(), x.pdf.to_bits(), "lane {i}");
                    let p = m.prepare(w).unwrap();
                    assert_eq!(
                        density[i].to_bits(),
                        Prepared::pdf(&p, x.wo).to_bits(),
                        "lane {i}"
                    );
                }
                None => assert_eq!(pdf[i], 0.0, "lane {i}"),
            }
        }
        assert!(sampled > n / 2, "{sampled} of {n} lanes sampled");
        // Lengths that disagree are errors, not panics.
        assert!(s
            .pdf_batch(
                &lanes,
                Vec3s {
                    x: &ox[..3],
                    y: &oy[..3],
                    z: &oz[..3]
                },
                &mut density
            )
            .is_err());
    }

    /// The wavefront render with the batched sampler is the scalar render with the scalar
    /// sampler: the same pixels hit and the same image (with MIS and two bounces).
    #[test]
    fn wavefront_render_equals_scalar_render() {
        use neusample_render::{
            demo_scene, render, render_wavefront, Estimator, RenderOptions, SceneParams, Surface,
        };
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../fixtures/measured/paper_white_rgb.bsdf");
        let material = crate::materials::load(&path).unwrap();
        let data = OwnedMeasured::open(&path).unwrap();
        let m = data.material();
        let scene = demo_scene(&SceneParams {
            width: 20,
            height: 14,
            ..SceneParams::default()
        });
        let mut o = RenderOptions::new(4, 3);
        o.estimator = Estimator::Mis;
        o.jitter = true;
        o.max_bounces = 2;
        o.wavefront_pixels = 37;
        let a = render(&scene, &[Surface::new(material.as_ref(), m.borrowed())], &o);
        let b = render_wavefront(
            &scene,
            &[Surface::new(
                material.as_ref(),
                MeasuredDataSampler(m.borrowed()),
            )],
            &o,
        );
        assert_eq!(a.mask, b.mask);
        assert!(a.mask.iter().any(|&h| h));
        let values = |r: &neusample_render::Render| -> Vec<f64> {
            r.image
                .data
                .iter()
                .flat_map(|c| *c)
                .map(f64::from)
                .collect()
        };
        let (x, y) = (values(&a), values(&b));
        let far = x
            .iter()
            .zip(&y)
            .filter(|(p, q)| (*p - *q).abs() > 1e-3 * p.abs().max(q.abs()))
            .count();
        assert!(far * 50 <= x.len(), "{far} of {} values differ", x.len());
        let (ma, mb) = (x.iter().sum::<f64>(), y.iter().sum::<f64>());
        assert!(
            (ma - mb).abs() <= 1e-4 * ma.abs().max(mb.abs()),
            "{ma} vs {mb}"
        );
    }
}
