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
        let mut h: Soa<DIRECT_HIDDEN, CHUNK> = [[0.0; CHUNK]; DIRECT_HIDDEN];
        let mut g: Soa<DIRECT_HIDDEN, CHUNK> = [[0.0; CHUNK]; DIRECT_HIDDEN];
        let mut o: Soa<DIRECT_CELLS, CHUNK> = [[0.0; CHUNK]; DIRECT_CELLS];
        let relu = Activation::Relu;
        dense::dense(w, DIRECT_L0 as u32, &c, relu, &mut h, m);
        dense::dense(w, DIRECT_L1 as u32, &h, relu, &mut g, m);
        dense::dense(w, DIRECT_L2 as u32, &g, Activation::Identity, &mut o, m);
        for l in 0..m {
            lanes[l] =
                valid[l].then(|| DirectHistogramPrepared::from_logits(&wavefront::column(&o, l)));
        }
    }

    per_lane_chunks!(DirectHistogramPrepared);
}
