//! The blob container: one versioned, checksummed file format for every sampler, and for
//! the neural materials they sample ([`SamplerKind::NeuralMaterial`], [`Blob::neural_material`]).
//!
//! The byte layout is specified in `core/BLOB.md`. In short:
//!
//! ```text
//! magic "NEUSAMP\0" | version u32 | total_len u32 | header_len u32 | header (postcard)
//! | tensor directory (postcard, one entry per tensor) | zero padding to 16
//! | tensor data, each tensor 16-byte aligned | CRC-32 of everything before it (u32)
//! ```
//!
//! [`Blob::open`] validates everything once — lengths, checksum, header, dimensions against
//! the architectures compiled into this build, tensor bounds, finiteness, table
//! normalisation — and returns a typed [`Error`] otherwise. It never panics, whatever the
//! bytes. After that, the samplers built from the blob read the tensors in place (zero-copy;
//! f32 tensors are used as `&[f32]` when the blob's buffer is 4-byte aligned).

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::flow::{AffineFlowSampler, FlowSampler};
use crate::histogram::{self, DirectHistogramSampler, HistogramMixtureSampler, Interpolation};
use crate::lobes::{AnalyticMixtureSampler, ImprovedBaselineSampler};
use crate::neural::{self, NeuralMaterial};
use crate::sampler::{CosineSampler, Prepared, Sample, Sampler, FEATURE_DIM};
use crate::weights::{DType, Tensor, Weights};
use glam::{Vec2, Vec3};

/// The 8 bytes every blob starts with.
pub const MAGIC: [u8; 8] = *b"NEUSAMP\0";
/// The format version this build reads and writes.
pub const FORMAT_VERSION: u32 = 1;
/// Bytes before the header: magic, version, total length, header length.
pub const PREAMBLE_LEN: usize = 20;
/// Alignment of the data section and of every tensor, relative to the blob start.
pub const DATA_ALIGN: usize = 16;
/// Bytes of the trailing checksum.
pub const CHECKSUM_LEN: usize = 4;
/// Most tensors a blob may declare.
pub const MAX_TENSORS: usize = 8;
/// Longest label accepted, in bytes.
pub const MAX_LABEL_LEN: usize = 4096;

/// The kind of sampler a blob holds.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum SamplerKind {
    /// Cosine-hemisphere sampling (no parameters).
    Cosine,
    /// Improved baseline: Lambert + isotropic Gaussian (paper Eq. 1).
    ImprovedBaseline,
    /// Analytic mixture: Lambert + two anisotropic Gaussians (paper Eq. 2).
    AnalyticMixture,
    /// Conditional rational-quadratic spline flow (paper Eq. 3–4).
    Flow,
    /// Affine-coupling flow baseline (Xie et al. 2019).
    AffineFlow,
    /// Direct histogram baseline (Zhu et al. 2021).
    DirectHistogram,
    /// Histogram mixture (paper Eq. 5–6).
    HistogramMixture,
    /// Not a sampler: a NeuMIP-style neural material (feature texture + decoder,
    /// [`crate::neural`]), the BRDF the samplers are trained for. Opened with
    /// [`Blob::neural_material`]; [`Blob::sampler`] refuses it. Not in [`SamplerKind::ALL`].
    NeuralMaterial,
}

impl SamplerKind {
    /// Every sampler kind, in a stable order ([`SamplerKind::NeuralMaterial`], which is not a
    /// sampler, is not listed).
    pub const ALL: [SamplerKind; 7] = [
        SamplerKind::Cosine,
        SamplerKind::ImprovedBaseline,
        SamplerKind::AnalyticMixture,
        SamplerKind::Flow,
        SamplerKind::AffineFlow,
        SamplerKind::DirectHistogram,
        SamplerKind::HistogramMixture,
    ];

    /// The kind's stable name (CLI and JSON).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            SamplerKind::Cosine => "cosine",
            SamplerKind::ImprovedBaseline => "baseline",
            SamplerKind::AnalyticMixture => "analytic",
            SamplerKind::Flow => "flow",
            SamplerKind::AffineFlow => "affine-flow",
            SamplerKind::DirectHistogram => "direct-histogram",
            SamplerKind::HistogramMixture => "histogram-mixture",
            SamplerKind::NeuralMaterial => "neural-material",
        }
    }

    /// Whether the kind is a sampler (every kind but [`SamplerKind::NeuralMaterial`]).
    #[must_use]
    pub const fn is_sampler(self) -> bool {
        !matches!(self, SamplerKind::NeuralMaterial)
    }

    /// The kind with the given [`SamplerKind::name`] (the neural material included).
    #[must_use]
    pub fn from_name(name: &str) -> Option<SamplerKind> {
        if name.as_bytes() == SamplerKind::NeuralMaterial.name().as_bytes() {
            return Some(SamplerKind::NeuralMaterial);
        }
        let mut i = 0;
        while i < Self::ALL.len() {
            if Self::ALL[i].name().as_bytes() == name.as_bytes() {
                return Some(Self::ALL[i]);
            }
            i += 1;
        }
        None
    }

    /// Number of network parameters this build's architecture of the kind has.
    #[must_use]
    pub const fn param_count(self) -> usize {
        match self {
            SamplerKind::Cosine => 0,
            SamplerKind::ImprovedBaseline => ImprovedBaselineSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::AnalyticMixture => AnalyticMixtureSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::Flow => FlowSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::AffineFlow => AffineFlowSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::DirectHistogram => DirectHistogramSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::HistogramMixture => HistogramMixtureSampler::<&[f32]>::PARAM_COUNT,
            SamplerKind::NeuralMaterial => NeuralMaterial::<&[f32]>::PARAM_COUNT,
        }
    }
}

/// Number of tensor roles.
const ROLES: usize = 6;

/// What a tensor holds.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum TensorRole {
    /// The flat network parameter array (layouts in `core/ARCHITECTURES.md`).
    Params,
    /// Histogram mixture: per-(basis, level) mass of the training model, K × T.
    Mass,
    /// Histogram mixture: normalised densities, K × T × N × N.
    Table,
    /// Histogram mixture: running row totals, K × T × N.
    Marginal,
    /// Histogram mixture: running sums within rows, K × T × N × N.
    Conditional,
    /// Neural material: the feature texture, H × W × 8 (texel-major, channels last).
    Features,
}

impl TensorRole {
    /// The role's stable name.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            TensorRole::Params => "params",
            TensorRole::Mass => "mass",
            TensorRole::Table => "table",
            TensorRole::Marginal => "marginal",
            TensorRole::Conditional => "conditional",
            TensorRole::Features => "features",
        }
    }

    const fn index(self) -> usize {
        match self {
            TensorRole::Params => 0,
            TensorRole::Mass => 1,
            TensorRole::Table => 2,
            TensorRole::Marginal => 3,
            TensorRole::Conditional => 4,
            TensorRole::Features => 5,
        }
    }

    /// Every role, in directory order.
    pub const ALL: [TensorRole; ROLES] = [
        TensorRole::Params,
        TensorRole::Mass,
        TensorRole::Table,
        TensorRole::Marginal,
        TensorRole::Conditional,
        TensorRole::Features,
    ];
}

/// How the histogram mixture reads its latent-code axis.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum TableInterpolation {
    /// Nearest level (the paper's rounding).
    Nearest,
    /// Linear interpolation between the two nearest levels, exactly normalised.
    Linear,
}

/// The blob header (postcard-encoded after the preamble).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header<'a> {
    /// The sampler kind.
    pub kind: SamplerKind,
    /// Storage type of the network parameters and of the histogram table.
    pub dtype: DType,
    /// Length of φ the sampler was trained for (this build: [`FEATURE_DIM`]).
    pub feature_dim: u32,
    /// Number of network parameters ([`SamplerKind::param_count`]).
    pub param_count: u32,
    /// Histogram mixture: number of bases K; 0 otherwise.
    pub basis: u32,
    /// Histogram mixture: number of latent-code levels T; neural material: texture height
    /// (texels along v); 0 otherwise.
    pub t_levels: u32,
    /// Histogram mixture / direct histogram: grid resolution N; neural material: texture
    /// width (texels along u); 0 otherwise.
    pub resolution: u32,
    /// Histogram mixture: how t is looked up.
    pub interpolation: TableInterpolation,
    /// Free text: material, method, training settings (UTF-8, ≤ [`MAX_LABEL_LEN`] bytes).
    #[serde(borrow)]
    pub label: &'a str,
    /// Number of tensor directory entries that follow the header.
    pub tensor_count: u32,
}

/// One entry of the tensor directory.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TensorEntry {
    /// What the tensor holds.
    pub role: TensorRole,
    /// Element type.
    pub dtype: DType,
    /// Byte offset from the start of the blob (a multiple of [`DATA_ALIGN`]).
    pub offset: u32,
    /// Number of elements.
    pub count: u32,
}

/// A validated blob, borrowing its bytes.
#[derive(Copy, Clone, Debug)]
pub struct Blob<'a> {
    header: Header<'a>,
    tensors: [Option<(TensorEntry, &'a [u8])>; ROLES],
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    match bytes.get(at..at + 4) {
        Some(b) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        None => 0,
    }
}

/// Required tensors of a kind: (role, element count, allowed dtype: None = header dtype).
/// A required tensor: role, element count, dtype (`None`: the header's dtype).
type Requirement = Option<(TensorRole, u64, Option<DType>)>;

fn required(h: &Header<'_>) -> ([Requirement; ROLES], usize) {
    let mut r = [None; ROLES];
    let p = h.param_count as u64;
    let (k, t, n) = (h.basis as u64, h.t_levels as u64, h.resolution as u64);
    let count = match h.kind {
        SamplerKind::Cosine => 0,
        SamplerKind::HistogramMixture => {
            r[0] = Some((TensorRole::Params, p, None));
            r[1] = Some((TensorRole::Mass, k * t, Some(DType::F32)));
            r[2] = Some((TensorRole::Table, k * t * n * n, None));
            r[3] = Some((TensorRole::Marginal, k * t * n, Some(DType::F32)));
            r[4] = Some((TensorRole::Conditional, k * t * n * n, Some(DType::F32)));
            5
        }
        SamplerKind::NeuralMaterial => {
            r[0] = Some((TensorRole::Params, p, None));
            r[5] = Some((
                TensorRole::Features,
                neural::texture_len(h.resolution, h.t_levels) as u64,
                None,
            ));
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

impl<'a> Blob<'a> {
    /// Opens and validates a blob. Never panics; every defect is a typed [`Error`].
    ///
    /// Checks, in order: preamble (length, magic, version, total length), CRC-32, header,
    /// dimensions against this build's architectures, the tensor directory (roles, counts,
    /// types, alignment, bounds), finiteness of every value, and for the histogram mixture
    /// the normalisation of every table slice and its CDFs.
    pub fn open(bytes: &'a [u8]) -> Result<Blob<'a>> {
        let got = bytes.len() as u64;
        let min = (PREAMBLE_LEN + CHECKSUM_LEN) as u64;
        if got < 8 {
            // Too short to tell anything but a prefix of the magic.
            if bytes == &MAGIC[..bytes.len()] {
                return Err(Error::Truncated { needed: min, got });
            }
            return Err(Error::BadMagic);
        }
        // Element-wise: `[u8] == [u8; N]` lowers to the `raw_eq` intrinsic, which rust-gpu
        // does not implement (ICE), and this crate is compiled for SPIR-V too.
        let mut k = 0;
        while k < MAGIC.len() {
            if bytes[k] != MAGIC[k] {
                return Err(Error::BadMagic);
            }
            k += 1;
        }
        if got < 12 {
            return Err(Error::Truncated { needed: min, got });
        }
        let version = u32_at(bytes, 8);
        if version != FORMAT_VERSION {
            return Err(Error::UnsupportedVersion {
                found: version,
                supported: FORMAT_VERSION,
            });
        }
        if got < min {
            return Err(Error::Truncated { needed: min, got });
        }
        let total = u32_at(bytes, 12) as u64;
        if total < min {
            return Err(Error::HeaderInvalid);
        }
        if got < total {
            return Err(Error::Truncated { needed: total, got });
        }
        if got > total {
            // Trailing bytes after the checksum: not a blob we wrote.
            return Err(Error::HeaderInvalid);
        }
        let body = bytes.len() - CHECKSUM_LEN;
        let stored = u32_at(bytes, body);
        let computed = crc32fast::hash(&bytes[..body]);
        if stored != computed {
            return Err(Error::ChecksumMismatch { stored, computed });
        }

        let header_len = u32_at(bytes, 16) as usize;
        let header_end = PREAMBLE_LEN
            .checked_add(header_len)
            .filter(|&e| e <= body)
            .ok_or(Error::HeaderInvalid)?;
        let header_bytes = &bytes[PREAMBLE_LEN..header_end];
        let (header, mut rest): (Header<'a>, &'a [u8]) =
            postcard::take_from_bytes(header_bytes).map_err(|_| Error::HeaderDecode)?;
        if header.label.len() > MAX_LABEL_LEN {
            return Err(Error::HeaderInvalid);
        }
        Self::check_dims(&header)?;

        let (req, req_count) = required(&header);
        if header.tensor_count as usize != req_count {
            return Err(Error::HeaderInvalid);
        }
        let data_start = header_end.div_ceil(DATA_ALIGN) * DATA_ALIGN;
        let mut tensors: [Option<(TensorEntry, &'a [u8])>; ROLES] = [None; ROLES];
        for _ in 0..req_count {
            let (e, r): (TensorEntry, &'a [u8]) =
                postcard::take_from_bytes(rest).map_err(|_| Error::HeaderDecode)?;
            rest = r;
            let slot = e.role.index();
            let role = e.role.name();
            let Some((_, expected, dtype)) = req[slot] else {
                return Err(Error::TensorMissing { role });
            };
            if tensors[slot].is_some() {
                return Err(Error::TensorMissing { role });
            }
            let want_dtype = dtype.unwrap_or(header.dtype);
            if e.dtype != want_dtype {
                return Err(Error::TensorDType {
                    role,
                    found: e.dtype,
                });
            }
            if e.count as u64 != expected {
                return Err(Error::TensorShape {
                    role,
                    expected: expected.min(u32::MAX as u64) as u32,
                    found: e.count,
                });
            }
            let start = e.offset as usize;
            let len = (e.count as usize)
                .checked_mul(e.dtype.size())
                .ok_or(Error::TensorBounds { role })?;
            let end = start.checked_add(len).ok_or(Error::TensorBounds { role })?;
            if start % DATA_ALIGN != 0 || start < data_start || end > body {
                return Err(Error::TensorBounds { role });
            }
            let data = &bytes[start..end];
            check_finite(role, e.dtype, data)?;
            tensors[slot] = Some((e, data));
        }
        if !rest.is_empty() {
            return Err(Error::HeaderInvalid);
        }
        for (slot, r) in req.iter().enumerate() {
            if let Some((role, _, _)) = r {
                if tensors[slot].is_none() {
                    return Err(Error::TensorMissing { role: role.name() });
                }
            }
        }
        let blob = Blob { header, tensors };
        if header.kind == SamplerKind::HistogramMixture {
            histogram::validate_tables(
                &blob.tensor_or_empty(TensorRole::Mass),
                &blob.tensor_or_empty(TensorRole::Table),
                &blob.tensor_or_empty(TensorRole::Marginal),
                &blob.tensor_or_empty(TensorRole::Conditional),
                header.basis,
                header.t_levels,
                header.resolution,
            )?;
        }
        Ok(blob)
    }

    fn check_dims(h: &Header<'_>) -> Result<()> {
        check_dim("feature_dim", h.feature_dim, FEATURE_DIM as u32)?;
        check_dim("param_count", h.param_count, h.kind.param_count() as u32)?;
        match h.kind {
            SamplerKind::HistogramMixture => {
                check_dim("basis", h.basis, histogram::BASES as u32)?;
                check_range("t_levels", h.t_levels, 1, histogram::MAX_T as u32)?;
                check_range("resolution", h.resolution, 1, histogram::MAX_N as u32)?;
            }
            SamplerKind::DirectHistogram => {
                check_dim("basis", h.basis, 0)?;
                check_dim("t_levels", h.t_levels, 0)?;
                check_dim("resolution", h.resolution, histogram::DIRECT_N as u32)?;
            }
            SamplerKind::NeuralMaterial => {
                check_dim("basis", h.basis, 0)?;
                check_range("width", h.resolution, 1, neural::MAX_TEXTURE_SIZE)?;
                check_range("height", h.t_levels, 1, neural::MAX_TEXTURE_SIZE)?;
            }
            _ => {
                check_dim("basis", h.basis, 0)?;
                check_dim("t_levels", h.t_levels, 0)?;
                check_dim("resolution", h.resolution, 0)?;
            }
        }
        Ok(())
    }

    /// The header.
    #[must_use]
    pub fn header(&self) -> &Header<'a> {
        &self.header
    }

    /// The sampler kind.
    #[must_use]
    pub fn kind(&self) -> SamplerKind {
        self.header.kind
    }

    /// The directory entry of a tensor, if the blob has it.
    #[must_use]
    pub fn entry(&self, role: TensorRole) -> Option<TensorEntry> {
        self.tensors[role.index()].map(|(e, _)| e)
    }

    /// A tensor, read in place, if the blob has it.
    #[must_use]
    pub fn tensor(&self, role: TensorRole) -> Option<Tensor<'a>> {
        self.tensors[role.index()].map(|(e, d)| Tensor::from_bytes(e.dtype, d))
    }

    fn tensor_or_empty(&self, role: TensorRole) -> Tensor<'a> {
        self.tensor(role).unwrap_or(Tensor::F32(&[]))
    }

    /// Copies a tensor, widened to f32, into `out` (which must have exactly its length):
    /// how a host fills GPU storage buffers or builds a fast f32 copy of an f16 blob.
    pub fn widen_into(&self, role: TensorRole, out: &mut [f32]) -> Result<()> {
        let t = self
            .tensor(role)
            .ok_or(Error::TensorMissing { role: role.name() })?;
        if out.len() != t.len() as usize {
            return Err(Error::TensorShape {
                role: role.name(),
                expected: t.len(),
                found: out.len() as u32,
            });
        }
        for (i, o) in out.iter_mut().enumerate() {
            *o = t.at(i as u32);
        }
        Ok(())
    }

    fn expect(&self, kind: SamplerKind) -> Result<()> {
        if self.header.kind == kind {
            Ok(())
        } else {
            Err(Error::WrongKind {
                expected: kind,
                found: self.header.kind,
            })
        }
    }

    fn params(&self) -> Tensor<'a> {
        self.tensor_or_empty(TensorRole::Params)
    }

    /// The improved baseline sampler, or [`Error::WrongKind`].
    pub fn improved_baseline(&self) -> Result<ImprovedBaselineSampler<Tensor<'a>>> {
        self.expect(SamplerKind::ImprovedBaseline)?;
        ImprovedBaselineSampler::new(self.params()).ok_or(Error::HeaderInvalid)
    }

    /// The analytic mixture sampler, or [`Error::WrongKind`].
    pub fn analytic_mixture(&self) -> Result<AnalyticMixtureSampler<Tensor<'a>>> {
        self.expect(SamplerKind::AnalyticMixture)?;
        AnalyticMixtureSampler::new(self.params()).ok_or(Error::HeaderInvalid)
    }

    /// The RQ-spline flow sampler, or [`Error::WrongKind`].
    pub fn flow(&self) -> Result<FlowSampler<Tensor<'a>>> {
        self.expect(SamplerKind::Flow)?;
        FlowSampler::new(self.params()).ok_or(Error::HeaderInvalid)
    }

    /// The affine-coupling flow sampler, or [`Error::WrongKind`].
    pub fn affine_flow(&self) -> Result<AffineFlowSampler<Tensor<'a>>> {
        self.expect(SamplerKind::AffineFlow)?;
        AffineFlowSampler::new(self.params()).ok_or(Error::HeaderInvalid)
    }

    /// The direct histogram sampler, or [`Error::WrongKind`].
    pub fn direct_histogram(&self) -> Result<DirectHistogramSampler<Tensor<'a>>> {
        self.expect(SamplerKind::DirectHistogram)?;
        DirectHistogramSampler::new(self.params()).ok_or(Error::HeaderInvalid)
    }

    /// The histogram mixture sampler, or [`Error::WrongKind`].
    pub fn histogram_mixture(&self) -> Result<HistogramMixtureSampler<Tensor<'a>>> {
        self.expect(SamplerKind::HistogramMixture)?;
        let interp = match self.header.interpolation {
            TableInterpolation::Nearest => Interpolation::Nearest,
            TableInterpolation::Linear => Interpolation::Linear,
        };
        HistogramMixtureSampler::new(
            self.params(),
            self.tensor_or_empty(TensorRole::Mass),
            self.tensor_or_empty(TensorRole::Table),
            self.tensor_or_empty(TensorRole::Marginal),
            self.tensor_or_empty(TensorRole::Conditional),
            self.header.t_levels,
            self.header.resolution,
            interp,
        )
        .ok_or(Error::HeaderInvalid)
    }

    /// The neural material (feature texture + decoder, [`crate::neural`]), or
    /// [`Error::WrongKind`]. Its texture is `header().resolution` texels wide and
    /// `header().t_levels` high.
    pub fn neural_material(&self) -> Result<NeuralMaterial<Tensor<'a>>> {
        self.expect(SamplerKind::NeuralMaterial)?;
        NeuralMaterial::new(
            self.tensor_or_empty(TensorRole::Features),
            self.params(),
            self.header.resolution,
            self.header.t_levels,
        )
        .ok_or(Error::HeaderInvalid)
    }

    /// Whichever sampler the blob holds. A neural-material blob holds no sampler:
    /// [`Error::NotASampler`].
    pub fn sampler(&self) -> Result<AnySampler<'a>> {
        Ok(match self.header.kind {
            SamplerKind::Cosine => AnySampler::Cosine(CosineSampler),
            SamplerKind::ImprovedBaseline => {
                AnySampler::ImprovedBaseline(self.improved_baseline()?)
            }
            SamplerKind::AnalyticMixture => AnySampler::AnalyticMixture(self.analytic_mixture()?),
            SamplerKind::Flow => AnySampler::Flow(self.flow()?),
            SamplerKind::AffineFlow => AnySampler::AffineFlow(self.affine_flow()?),
            SamplerKind::DirectHistogram => AnySampler::DirectHistogram(self.direct_histogram()?),
            SamplerKind::HistogramMixture => {
                AnySampler::HistogramMixture(self.histogram_mixture()?)
            }
            SamplerKind::NeuralMaterial => {
                return Err(Error::NotASampler {
                    found: SamplerKind::NeuralMaterial,
                })
            }
        })
    }
}

fn check_finite(role: &'static str, dtype: DType, data: &[u8]) -> Result<()> {
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

/// Any sampler held by a blob (static dispatch by `match`; no `dyn`).
#[derive(Copy, Clone, Debug)]
#[allow(clippy::large_enum_variant)]
pub enum AnySampler<'a> {
    /// [`SamplerKind::Cosine`].
    Cosine(CosineSampler),
    /// [`SamplerKind::ImprovedBaseline`].
    ImprovedBaseline(ImprovedBaselineSampler<Tensor<'a>>),
    /// [`SamplerKind::AnalyticMixture`].
    AnalyticMixture(AnalyticMixtureSampler<Tensor<'a>>),
    /// [`SamplerKind::Flow`].
    Flow(FlowSampler<Tensor<'a>>),
    /// [`SamplerKind::AffineFlow`].
    AffineFlow(AffineFlowSampler<Tensor<'a>>),
    /// [`SamplerKind::DirectHistogram`].
    DirectHistogram(DirectHistogramSampler<Tensor<'a>>),
    /// [`SamplerKind::HistogramMixture`].
    HistogramMixture(HistogramMixtureSampler<Tensor<'a>>),
}

/// The prepared state of an [`AnySampler`].
#[allow(clippy::large_enum_variant)]
pub enum AnyPrepared<'s, 'a: 's> {
    /// See [`AnySampler::Cosine`].
    Cosine(<CosineSampler as Sampler>::Prepared<'s>),
    /// See [`AnySampler::ImprovedBaseline`].
    ImprovedBaseline(<ImprovedBaselineSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::AnalyticMixture`].
    AnalyticMixture(<AnalyticMixtureSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::Flow`].
    Flow(<FlowSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::AffineFlow`].
    AffineFlow(<AffineFlowSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::DirectHistogram`].
    DirectHistogram(<DirectHistogramSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
    /// See [`AnySampler::HistogramMixture`].
    HistogramMixture(<HistogramMixtureSampler<Tensor<'a>> as Sampler>::Prepared<'s>),
}

impl<'a> AnySampler<'a> {
    /// The kind of the sampler.
    #[must_use]
    pub fn kind(&self) -> SamplerKind {
        match self {
            AnySampler::Cosine(_) => SamplerKind::Cosine,
            AnySampler::ImprovedBaseline(_) => SamplerKind::ImprovedBaseline,
            AnySampler::AnalyticMixture(_) => SamplerKind::AnalyticMixture,
            AnySampler::Flow(_) => SamplerKind::Flow,
            AnySampler::AffineFlow(_) => SamplerKind::AffineFlow,
            AnySampler::DirectHistogram(_) => SamplerKind::DirectHistogram,
            AnySampler::HistogramMixture(_) => SamplerKind::HistogramMixture,
        }
    }
}

impl<'a> Sampler for AnySampler<'a> {
    type Prepared<'s>
        = AnyPrepared<'s, 'a>
    where
        Self: 's;

    #[inline]
    fn prepare<'s>(&'s self, phi: &[f32; FEATURE_DIM], wi: Vec3) -> Option<AnyPrepared<'s, 'a>> {
        Some(match self {
            AnySampler::Cosine(s) => AnyPrepared::Cosine(s.prepare(phi, wi)?),
            AnySampler::ImprovedBaseline(s) => AnyPrepared::ImprovedBaseline(s.prepare(phi, wi)?),
            AnySampler::AnalyticMixture(s) => AnyPrepared::AnalyticMixture(s.prepare(phi, wi)?),
            AnySampler::Flow(s) => AnyPrepared::Flow(s.prepare(phi, wi)?),
            AnySampler::AffineFlow(s) => AnyPrepared::AffineFlow(s.prepare(phi, wi)?),
            AnySampler::DirectHistogram(s) => AnyPrepared::DirectHistogram(s.prepare(phi, wi)?),
            AnySampler::HistogramMixture(s) => AnyPrepared::HistogramMixture(s.prepare(phi, wi)?),
        })
    }
}

macro_rules! dispatch {
    ($self:expr, $p:ident => $e:expr) => {
        match $self {
            AnyPrepared::Cosine($p) => $e,
            AnyPrepared::ImprovedBaseline($p) => $e,
            AnyPrepared::AnalyticMixture($p) => $e,
            AnyPrepared::Flow($p) => $e,
            AnyPrepared::AffineFlow($p) => $e,
            AnyPrepared::DirectHistogram($p) => $e,
            AnyPrepared::HistogramMixture($p) => $e,
        }
    };
}

impl Prepared for AnyPrepared<'_, '_> {
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        dispatch!(self, p => p.sample(u))
    }
    #[inline]
    fn pdf_disk(&self, q: Vec2) -> f32 {
        dispatch!(self, p => p.pdf_disk(q))
    }
    #[inline]
    fn pdf(&self, wo: Vec3) -> f32 {
        dispatch!(self, p => p.pdf(wo))
    }
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        dispatch!(self, p => p.invert(wo))
    }
}

/// Builds blobs (needs the `alloc` feature). The trainer in `neusample-precompute` and the
/// tests use it; the runtime only reads.
#[cfg(feature = "alloc")]
#[derive(Clone, Debug)]
pub struct BlobWriter<'l> {
    header: Header<'l>,
    tensors: alloc::vec::Vec<(TensorRole, DType, alloc::vec::Vec<u8>)>,
}

#[cfg(feature = "alloc")]
impl<'l> BlobWriter<'l> {
    /// A writer for a sampler of `kind` whose parameters (and table) are stored as `dtype`.
    /// Dimensions are this build's; the histogram mixture also needs
    /// [`BlobWriter::histogram_dims`].
    #[must_use]
    pub fn new(kind: SamplerKind, dtype: DType, label: &'l str) -> Self {
        let resolution = if kind == SamplerKind::DirectHistogram {
            histogram::DIRECT_N as u32
        } else {
            0
        };
        BlobWriter {
            header: Header {
                kind,
                dtype,
                feature_dim: FEATURE_DIM as u32,
                param_count: kind.param_count() as u32,
                basis: if kind == SamplerKind::HistogramMixture {
                    histogram::BASES as u32
                } else {
                    0
                },
                t_levels: 0,
                resolution,
                interpolation: TableInterpolation::Nearest,
                label,
                tensor_count: 0,
            },
            tensors: alloc::vec::Vec::new(),
        }
    }

    /// Sets the histogram mixture's table dimensions and latent-code lookup.
    #[must_use]
    pub fn histogram_dims(
        mut self,
        t_levels: u32,
        resolution: u32,
        interpolation: TableInterpolation,
    ) -> Self {
        self.header.t_levels = t_levels;
        self.header.resolution = resolution;
        self.header.interpolation = interpolation;
        self
    }

    /// Sets the neural material's texture dimensions (`width × height` texels; stored in the
    /// header's `resolution` and `t_levels` fields).
    #[must_use]
    pub fn texture_dims(mut self, width: u32, height: u32) -> Self {
        self.header.resolution = width;
        self.header.t_levels = height;
        self
    }

    /// Overrides a header field for tests of the validator (wrong dimensions and the like).
    #[doc(hidden)]
    #[must_use]
    pub fn header_mut(&mut self) -> &mut Header<'l> {
        &mut self.header
    }

    /// The element type a role is stored with: the blob's `dtype` for parameters, the
    /// histogram table and the neural material's features, f32 for masses and CDFs.
    #[must_use]
    pub fn dtype_of(&self, role: TensorRole) -> DType {
        match role {
            TensorRole::Params | TensorRole::Table | TensorRole::Features => self.header.dtype,
            TensorRole::Mass | TensorRole::Marginal | TensorRole::Conditional => DType::F32,
        }
    }

    /// Adds (or replaces) a tensor, converting to its storage type (f16 rounds to nearest).
    pub fn tensor(&mut self, role: TensorRole, values: &[f32]) -> &mut Self {
        let dtype = self.dtype_of(role);
        let mut bytes = alloc::vec::Vec::with_capacity(values.len() * dtype.size());
        for &v in values {
            match dtype {
                DType::F32 => bytes.extend_from_slice(&v.to_le_bytes()),
                DType::F16 => bytes.extend_from_slice(&half::f16::from_f32(v).to_le_bytes()),
            }
        }
        self.tensors.retain(|(r, _, _)| *r != role);
        self.tensors.push((role, dtype, bytes));
        self
    }

    /// Serialises the blob. Tensors are written in role order.
    #[must_use]
    pub fn to_bytes(&self) -> alloc::vec::Vec<u8> {
        let mut tensors = self.tensors.clone();
        tensors.sort_by_key(|(r, _, _)| r.index());
        let mut header = self.header;
        header.tensor_count = tensors.len() as u32;

        // Header and directory sizes do not depend on the offsets' values only through
        // varint lengths, so lay out with a first pass and fix up until stable.
        let mut offsets = alloc::vec![0u32; tensors.len()];
        loop {
            let mut head = postcard::to_allocvec(&header).unwrap_or_default();
            for (i, (role, dtype, bytes)) in tensors.iter().enumerate() {
                let e = TensorEntry {
                    role: *role,
                    dtype: *dtype,
                    offset: offsets[i],
                    count: (bytes.len() / dtype.size()) as u32,
                };
                head.extend_from_slice(&postcard::to_allocvec(&e).unwrap_or_default());
            }
            let mut at = (PREAMBLE_LEN + head.len()).div_ceil(DATA_ALIGN) * DATA_ALIGN;
            let mut changed = false;
            for (i, (_, _, bytes)) in tensors.iter().enumerate() {
                if offsets[i] != at as u32 {
                    offsets[i] = at as u32;
                    changed = true;
                }
                at = (at + bytes.len()).div_ceil(DATA_ALIGN) * DATA_ALIGN;
            }
            if changed {
                continue;
            }
            let end = tensors
                .last()
                .map(|(_, _, b)| offsets[offsets.len() - 1] as usize + b.len())
                .unwrap_or(PREAMBLE_LEN + head.len());
            let total = end + CHECKSUM_LEN;
            let mut out = alloc::vec::Vec::with_capacity(total);
            out.extend_from_slice(&MAGIC);
            out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
            out.extend_from_slice(&(total as u32).to_le_bytes());
            out.extend_from_slice(&(head.len() as u32).to_le_bytes());
            out.extend_from_slice(&head);
            for (i, (_, _, bytes)) in tensors.iter().enumerate() {
                out.resize(offsets[i] as usize, 0);
                out.extend_from_slice(bytes);
            }
            let crc = crc32fast::hash(&out);
            out.extend_from_slice(&crc.to_le_bytes());
            return out;
        }
    }
}
