//! The improved baseline over wavefronts: the network as matrix products over a chunk's lanes, the lobes
//! per lane.

use super::*;
use crate::samplers::lobes::CHUNK;
use crate::wavefront::chunked::ChunkedSampler;
use crate::wavefront::{self, dense, per_lane_chunks, Features, Soa, Vec3s};

impl<W: Weights> ChunkedSampler for ImprovedBaselineSampler<W> {
    type Lane = Option<ImprovedBaselinePrepared>;
    const CHUNK: usize = CHUNK;

    #[inline(always)]
    fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, lanes: &mut [Self::Lane]) {
        let w = &self.params;
        let m = lanes.len();
        let (c, valid) = wavefront::encoded_conditions::<CHUNK>(&phi, &wi);
        let mut h: Soa<HIDDEN, CHUNK> = [[0.0; CHUNK]; HIDDEN];
        let mut g: Soa<HIDDEN, CHUNK> = [[0.0; CHUNK]; HIDDEN];
        let mut o: Soa<BASELINE_OUTPUTS, CHUNK> = [[0.0; CHUNK]; BASELINE_OUTPUTS];
        let relu = Activation::Relu;
        dense::dense(w, BASELINE_L0 as u32, &c, relu, &mut h, m);
        dense::dense(w, BASELINE_L1 as u32, &h, relu, &mut g, m);
        dense::dense(w, BASELINE_L2 as u32, &g, relu, &mut h, m);
        dense::dense(w, BASELINE_L3 as u32, &h, Activation::Identity, &mut o, m);
        for l in 0..m {
            lanes[l] =
                valid[l].then(|| ImprovedBaselinePrepared::from_outputs(&wavefront::column(&o, l)));
        }
    }

    per_lane_chunks!(ImprovedBaselinePrepared);
}
