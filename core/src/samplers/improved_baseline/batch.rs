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
        let mut o: Soa<BASELINE_OUTPUTS, CHUNK> = [[0.0; CHUNK]; BASELINE_OUTPUTS];
        let layers = [BASELINE_L0, BASELINE_L1, BASELINE_L2, BASELINE_L3];
        dense::relu_mlp::<_, _, HIDDEN, _, CHUNK, 4>(w, &layers, &c, &mut o, m);
        wavefront::lanes_from_outputs(&o, &valid, lanes, ImprovedBaselinePrepared::from_outputs);
    }

    per_lane_chunks!(ImprovedBaselinePrepared);
}
