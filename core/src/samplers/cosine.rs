//! Cosine-hemisphere sampling as a [`Sampler`]: the uniform density 1/π on the projected disk.

use glam::{Vec2, Vec3};

use crate::math;
use crate::nn::{check_condition, FEATURE_DIM};
use crate::warp;

use super::{Prepared, Sample, Sampler};

/// Cosine-hemisphere sampling as a [`Sampler`]: the density is 1/π on the disk for every
/// condition. It has no parameters, so it needs no blob.
#[derive(Copy, Clone, Debug, Default)]
pub struct CosineSampler;

/// The prepared state of [`CosineSampler`] (nothing).
#[derive(Copy, Clone, Debug, Default)]
pub struct CosinePrepared;

impl CosineSampler {
    /// Number of parameters: none.
    pub const PARAM_COUNT: usize = 0;
}

impl<'a> super::FromBlob<'a> for CosineSampler {
    const KIND: crate::SamplerKind = crate::SamplerKind::Cosine;
    fn from_blob(_: &impl super::BlobSource<'a>) -> Option<Self> {
        Some(CosineSampler)
    }
}

impl Sampler for CosineSampler {
    type Prepared<'s> = CosinePrepared;
    #[inline]
    fn prepare(&self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<CosinePrepared> {
        check_condition(phi, wi)?;
        Some(CosinePrepared)
    }
}

impl Prepared for CosinePrepared {
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        let u = math::sanitize_u2(u)?;
        let p = warp::sample_uniform_disk_concentric(u);
        Sample::from_disk(p, self.pdf_disk(p))
    }
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        warp::uniform_disk_pdf(p)
    }
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        let w = warp::upper_hemisphere(wo)?;
        Some(warp::invert_uniform_disk_concentric(warp::to_disk(w)))
    }
}

#[cfg(not(target_arch = "spirv"))]
impl crate::wavefront::chunked::ChunkedSampler for CosineSampler {
    type Lane = Option<CosinePrepared>;
    type Scratch = ();
    const CHUNK: usize = 64;

    #[inline(always)]
    fn prepare_chunk(
        &self,
        phi: crate::wavefront::Features<'_>,
        wi: crate::wavefront::Vec3s<'_>,
        lanes: &mut [Option<CosinePrepared>],
    ) {
        for (i, lane) in lanes.iter_mut().enumerate() {
            *lane = self.prepare(&phi.at(i), wi.at(i));
        }
    }

    crate::wavefront::per_lane_chunks!(CosinePrepared);
}

#[cfg(not(target_arch = "spirv"))]
impl crate::wavefront::chunked::LaneChunks for CosinePrepared {}
