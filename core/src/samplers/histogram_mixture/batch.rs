//! The histogram mixture over wavefronts: the network as matrix products over a chunk's
//! lanes, then per lane the scalar path's own functions (`lane_from_outputs`,
//! `lane_sample`, `lane_pdf_disk`, `lane_invert`).

use super::*;
use crate::wavefront::chunked::ChunkedSampler;
use crate::wavefront::lanes::V8;
use crate::wavefront::{self, Features, SamplesMut, Soa, Vec2s, Vec2sMut, Vec3s};

/// Lanes per chunk.
const CHUNK: usize = 32;

impl<W: Weights + Copy> ChunkedSampler for HistogramMixtureSampler<W> {
    type Lane = Option<HistogramMixtureLane>;
    type Scratch = ();
    const CHUNK: usize = CHUNK;

    #[inline(always)]
    fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, lanes: &mut [Self::Lane]) {
        let w = &self.params;
        let m = lanes.len();
        let (c, valid) = wavefront::raw_conditions::<CHUNK>(&phi, &wi);
        let mut o: Soa<MIX_OUTPUTS, CHUNK> = [[0.0; CHUNK]; MIX_OUTPUTS];
        Net::forward_lanes(w, &c, &mut o, m);
        // The softmax of the logits a_k across lanes, eight at a time.
        let mut soft: Soa<BASES, CHUNK> = [[0.0; CHUNK]; BASES];
        let mut g = 0;
        while g < m {
            let mut a: [V8; BASES] = core::array::from_fn(|k| V8::load(&o[4 * k][g..]));
            gaussian::softmax_lanes(&mut a);
            for (k, v) in a.into_iter().enumerate() {
                v.store(&mut soft[k][g..]);
            }
            g += 8;
        }
        for l in 0..m {
            lanes[l] = if valid[l] {
                self.lane_from_softmax(&wavefront::column(&o, l), &wavefront::column(&soft, l))
            } else {
                None
            };
        }
    }

    #[inline(always)]
    fn sample_chunk(
        &self,
        lanes: &[Self::Lane],
        u: Vec2s<'_>,
        mut out: SamplesMut<'_>,
        _scratch: &mut Self::Scratch,
    ) {
        for (i, l) in lanes.iter().enumerate() {
            out.set(i, l.as_ref().and_then(|l| self.lane_sample(l, u.at(i))));
        }
    }

    #[inline(always)]
    fn pdf_chunk(
        &self,
        lanes: &[Self::Lane],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        _scratch: &mut Self::Scratch,
    ) {
        for (i, l) in lanes.iter().enumerate() {
            pdf[i] = match (l, warp::upper_hemisphere(wo.at(i))) {
                (Some(l), Some(w)) => {
                    warp::disk_to_solid_angle(self.lane_pdf_disk(l, warp::to_disk(w)), w.z)
                }
                _ => 0.0,
            };
        }
    }

    #[inline(always)]
    fn invert_chunk(
        &self,
        lanes: &[Self::Lane],
        wo: Vec3s<'_>,
        mut u: Vec2sMut<'_>,
        ok: &mut [bool],
        _scratch: &mut Self::Scratch,
    ) {
        for (i, l) in lanes.iter().enumerate() {
            let r = l.as_ref().and_then(|l| self.lane_invert(l, wo.at(i)));
            ok[i] = r.is_some();
            if let Some(v) = r {
                u.set(i, v);
            }
        }
    }
}
