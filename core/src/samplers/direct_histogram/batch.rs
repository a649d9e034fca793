//! The direct histogram over wavefronts: the network as matrix products over a chunk's
//! lanes, the histogram per lane ([`DirectHistogramPrepared::from_logits`]).

use super::*;
use crate::wavefront::chunked::ChunkedSampler;
use crate::wavefront::{self, dense, per_lane_chunks, Features, Soa, Vec3s};

/// Lanes per chunk (the 256 logits of 16 lanes take 16 KiB).
const CHUNK: usize = 16;

impl<W: Weights> ChunkedSampler for DirectHistogramSampler<W> {
    type Lane = Option<DirectHistogramPrepared>;
    const CHUNK: usize = CHUNK;

    #[inline(always)]
    fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, lanes: &mut [Self::Lane]) {
        let w = &self.params;
        let m = lanes.len();
        let (c, valid) = wavefront::encoded_conditions::<CHUNK>(&phi, &wi);
        let mut o: Soa<DIRECT_CELLS, CHUNK> = [[0.0; CHUNK]; DIRECT_CELLS];
        let layers = [DIRECT_L0, DIRECT_L1, DIRECT_L2];
        dense::relu_mlp::<_, _, DIRECT_HIDDEN, _, CHUNK, 3>(w, &layers, &c, &mut o, m);
        wavefront::lanes_from_outputs(&o, &valid, lanes, DirectHistogramPrepared::from_logits);
    }

    per_lane_chunks!(DirectHistogramPrepared);
}
