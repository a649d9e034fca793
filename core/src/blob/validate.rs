//! What [`Blob::open`](super::Blob::open) checks beyond the byte layout: the header's
//! dimensions against the architectures compiled into this build, which tensors each kind
//! needs, and the finiteness of every stored value. The histogram mixture's table checks are
//! [`validate_tables`](crate::samplers::histogram_mixture::validate_tables).

use crate::dtype::DType;
use crate::error::{Error, Result};
use crate::kind::{BlobKind, SamplerKind};
use crate::neural_material;
use crate::nn::FEATURE_DIM;
use crate::samplers::{direct_histogram, histogram_mixture};
use crate::weights::{Tensor, Weights};

use super::format::{Header, TensorRole, MEASURED_SHAPE_LEN, ROLES};

/// A required tensor: role, element count, dtype (`None`: the header's dtype).
pub(crate) type Requirement = Option<(TensorRole, u64, Option<DType>)>;

/// The element count of a [`Requirement`] whose count the header cannot tell: a measured
/// material's tables, whose length follows from its shape tensor and is checked with it.
pub(crate) const COUNT_FROM_SHAPE: u64 = u64::MAX;

/// The tensors a header's kind requires (indexed by role) and how many there are.
pub(crate) fn required(h: &Header<'_>) -> ([Requirement; ROLES], usize) {
    let mut r = [None; ROLES];
    let p = h.param_count as u64;
    let (k, t, n) = (h.basis as u64, h.t_levels as u64, h.resolution as u64);
    let count = match h.kind {
        BlobKind::Sampler(SamplerKind::Cosine) => 0,
        // Four tensors: the compact layout (no values, u16 CDFs); five: values + f32 CDFs.
        BlobKind::Sampler(SamplerKind::HistogramMixture) if h.tensor_count == 4 => {
            r[0] = Some((TensorRole::Params, p, None));
            r[1] = Some((TensorRole::Mass, k * t, Some(DType::F32)));
            r[3] = Some((TensorRole::Marginal, k * t * n, Some(DType::F32)));
            r[4] = Some((TensorRole::Conditional, k * t * n * n, Some(DType::U16)));
            4
        }
        BlobKind::Sampler(SamplerKind::HistogramMixture) => {
            r[0] = Some((TensorRole::Params, p, None));
            r[1] = Some((TensorRole::Mass, k * t, Some(DType::F32)));
            r[2] = Some((TensorRole::Table, k * t * n * n, None));
            r[3] = Some((TensorRole::Marginal, k * t * n, Some(DType::F32)));
            r[4] = Some((TensorRole::Conditional, k * t * n * n, Some(DType::F32)));
            5
        }
        BlobKind::NeuralMaterial => {
            r[0] = Some((TensorRole::Params, p, None));
            r[5] = Some((
                TensorRole::Features,
                neural_material::texture_len(h.resolution, h.t_levels) as u64,
                None,
            ));
            2
        }
        BlobKind::Measured => {
            r[6] = Some((
                TensorRole::Shape,
                MEASURED_SHAPE_LEN as u64,
                Some(DType::F32),
            ));
            r[7] = Some((TensorRole::Tables, COUNT_FROM_SHAPE, Some(DType::F32)));
            2
        }
        _ => {
            r[0] = Some((TensorRole::Params, p, None));
            1
        }
    };
    (r, count)
}

fn check_dim(what: &'static str, found: u32, expected: u32) -> Result<()> {
    if found == expected {
        Ok(())
    } else {
        Err(Error::DimensionMismatch {
            what,
            expected,
            found,
        })
    }
}

fn check_range(what: &'static str, found: u32, lo: u32, hi: u32) -> Result<()> {
    if found >= lo && found <= hi {
        Ok(())
    } else {
        Err(Error::DimensionMismatch {
            what,
            expected: if found < lo { lo } else { hi },
            found,
        })
    }
}

/// The header's dimensions against this build's architectures.
pub(crate) fn check_dims(h: &Header<'_>) -> Result<()> {
    if h.dtype == DType::U16 {
        // Parameters, values and features are floats.
        return Err(Error::TensorDType {
            role: "params",
            found: h.dtype,
        });
    }
    check_dim("feature_dim", h.feature_dim, FEATURE_DIM as u32)?;
    check_dim("param_count", h.param_count, h.kind.param_count() as u32)?;
    match h.kind {
        BlobKind::Sampler(SamplerKind::HistogramMixture) => {
            check_dim("basis", h.basis, histogram_mixture::BASES as u32)?;
            check_range("t_levels", h.t_levels, 1, histogram_mixture::MAX_T as u32)?;
            check_range(
                "resolution",
                h.resolution,
                1,
                histogram_mixture::MAX_N as u32,
            )?;
        }
        BlobKind::Sampler(SamplerKind::DirectHistogram) => {
            check_dim("basis", h.basis, 0)?;
            check_dim("t_levels", h.t_levels, 0)?;
            check_dim(
                "resolution",
                h.resolution,
                direct_histogram::DIRECT_N as u32,
            )?;
        }
        BlobKind::NeuralMaterial => {
            check_dim("basis", h.basis, 0)?;
            check_range("width", h.resolution, 1, neural_material::MAX_TEXTURE_SIZE)?;
            check_range("height", h.t_levels, 1, neural_material::MAX_TEXTURE_SIZE)?;
        }
        BlobKind::Measured => {
            // Sampling tables (CDFs) must stay exact: f32 only.
            if h.dtype != DType::F32 {
                return Err(Error::TensorDType {
                    role: "tables",
                    found: h.dtype,
                });
            }
            check_dim("basis", h.basis, 0)?;
            check_dim("t_levels", h.t_levels, 0)?;
            check_dim("resolution", h.resolution, 0)?;
        }
        _ => {
            check_dim("basis", h.basis, 0)?;
            check_dim("t_levels", h.t_levels, 0)?;
            check_dim("resolution", h.resolution, 0)?;
        }
    }
    Ok(())
}

/// Every value of a tensor is finite.
pub(crate) fn check_finite(role: &'static str, dtype: DType, data: &[u8]) -> Result<()> {
    let t = Tensor::from_bytes(dtype, data);
    let n = t.len();
    let mut i = 0;
    while i < n {
        if !crate::math::is_finite(t.at(i)) {
            return Err(Error::NonFinite { role, index: i });
        }
        i += 1;
    }
    Ok(())
}
