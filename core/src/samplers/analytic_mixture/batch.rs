//! The analytic mixture over wavefronts: the network as matrix products over a chunk's lanes, the lobes
//! per lane.

use super::*;
use crate::samplers::lobes::CHUNK;
use crate::wavefront::chunked::ChunkedSampler;
use crate::wavefront::{self, dense, per_lane_chunks, Features, Soa, Vec3s};

impl<W: Weights> ChunkedSampler for AnalyticMixtureSampler<W> {
    type Lane = Option<AnalyticMixturePrepared>;
    const CHUNK: usize = CHUNK;

    #[inline(always)]
    fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, lanes: &mut [Self::Lane]) {
        let w = &self.params;
        let m = lanes.len();
        let (c, valid) = wavefront::encoded_conditions::<CHUNK>(&phi, &wi);
        let mut o: Soa<ANALYTIC_OUTPUTS, CHUNK> = [[0.0; CHUNK]; ANALYTIC_OUTPUTS];
        let layers = [ANALYTIC_L0, ANALYTIC_L1];
        dense::relu_mlp::<_, _, HIDDEN, _, CHUNK, 2>(w, &layers, &c, &mut o, m);
        wavefront::lanes_from_outputs(&o, &valid, lanes, AnalyticMixturePrepared::from_outputs);
    }

    per_lane_chunks!(AnalyticMixturePrepared);
}
