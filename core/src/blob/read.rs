//! [`Blob`]: a validated blob borrowing its bytes, and the samplers built from it.

use crate::error::{Error, Result};
use crate::kind::{BlobKind, SamplerKind};
use crate::neural_material::NeuralMaterial;
use crate::samplers::histogram_mixture;
use crate::samplers::{AnySampler, BlobSource, Defensive, FromBlob};
use crate::weights::{Tensor, Weights};

use super::format::{
    u32_at, Extension, Header, TensorEntry, TensorRole, CHECKSUM_LEN, DATA_ALIGN, FORMAT_VERSION,
    MAGIC, MAX_LABEL_LEN, MIN_FORMAT_VERSION, PREAMBLE_LEN, ROLES,
};
use super::validate::{check_dims, check_finite, required, COUNT_FROM_SHAPE};

/// Each role's directory entry and stored bytes, where the blob has that tensor.
type Tensors<'a> = [Option<(TensorEntry, &'a [u8])>; ROLES];

/// A validated blob, borrowing its bytes.
#[derive(Copy, Clone, Debug)]
pub struct Blob<'a> {
    header: Header<'a>,
    version: u32,
    extension: Extension,
    tensors: Tensors<'a>,
}

impl<'a> Blob<'a> {
    /// Opens and validates a blob. Never panics; every defect is a typed [`Error`].
    ///
    /// Checks, in order: preamble (length, magic, version, total length), CRC-32, header,
    /// dimensions against this build's architectures, the tensor directory (roles, counts,
    /// types, alignment, bounds), finiteness of every value, for the histogram mixture the
    /// normalisation of every table slice and its CDFs, and for a measured material its
    /// shape (exact integers in range), its tables' lengths, everything
    /// [`MeasuredMaterial::new`](crate::MeasuredMaterial::new) checks and the running
    /// integrals of its VNDF and luminance slices.
    pub fn open(bytes: &'a [u8]) -> Result<Blob<'a>> {
        let (version, body) = check_preamble(bytes)?;
        let (header, extension, directory, header_end) = decode_header(bytes, version, body)?;
        let tensors = read_directory(bytes, &header, directory, header_end, body)?;
        let blob = Blob {
            header,
            version,
            extension,
            tensors,
        };
        blob.check_tables()?;
        Ok(blob)
    }

    /// The kind's table checks, once the layout is valid: the histogram mixture's slices
    /// and CDFs, a measured material's shape, tables and integrals.
    fn check_tables(&self) -> Result<()> {
        let header = &self.header;
        if header.kind == BlobKind::Measured {
            self.check_measured()?;
        } else if header.kind == SamplerKind::HistogramMixture {
            let mass = self.tensor_or_empty(TensorRole::Mass);
            let marginal = self.tensor_or_empty(TensorRole::Marginal);
            let conditional = self.tensor_or_empty(TensorRole::Conditional);
            let (k, t, n) = (header.basis, header.t_levels, header.resolution);
            if self.is_compact() {
                histogram_mixture::validate_compact_tables(
                    &mass,
                    &marginal,
                    &conditional,
                    k,
                    t,
                    n,
                )?;
            } else {
                let table = self.tensor_or_empty(TensorRole::Table);
                histogram_mixture::validate_tables(
                    &mass,
                    &table,
                    &marginal,
                    &conditional,
                    k,
                    t,
                    n,
                )?;
            }
        }
        Ok(())
    }

    /// The header.
    #[must_use]
    pub fn header(&self) -> &Header<'a> {
        &self.header
    }

    /// What the blob holds.
    #[must_use]
    pub fn kind(&self) -> BlobKind {
        self.header.kind
    }

    /// The format version the blob was written in (1, 2 or 3).
    #[must_use]
    pub fn version(&self) -> u32 {
        self.version
    }

    /// The defensive weight α of the sampler ([`Defensive`]): 0 for version-1 blobs.
    #[must_use]
    pub fn defensive(&self) -> f32 {
        self.extension.defensive
    }

    /// Whether the sampler sees `wi` at azimuth 0 ([`Defensive::with_isotropic`]): false
    /// before version 3.
    #[must_use]
    pub fn isotropic(&self) -> bool {
        self.extension.isotropic
    }

    /// Every tensor the blob holds, in role order, with its stored bytes.
    #[cfg(feature = "alloc")]
    pub(crate) fn stored_tensors(&self) -> impl Iterator<Item = (TensorEntry, &'a [u8])> + '_ {
        self.tensors.iter().flatten().copied()
    }

    fn defend<S>(&self, s: S) -> Defensive<S> {
        Defensive::new_unchecked(s, self.extension.defensive)
            .with_isotropic(self.extension.isotropic)
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

    /// Whether a histogram mixture's tables are in the compact layout (no values tensor,
    /// u16 CDFs: [`TableLayout::Compact`](crate::distrib::table2d::TableLayout::Compact)).
    #[must_use]
    pub fn is_compact(&self) -> bool {
        self.header.kind == SamplerKind::HistogramMixture
            && self.tensors[TensorRole::Table.index()].is_none()
    }

    fn expect(&self, kind: BlobKind) -> Result<()> {
        if self.header.kind == kind {
            Ok(())
        } else {
            Err(Error::WrongKind {
                expected: kind,
                found: self.header.kind,
            })
        }
    }

    /// The sampler of type `S` (with the blob's defensive weight), or [`Error::WrongKind`]
    /// when the blob holds another kind: `blob.sampler_as::<SplineFlowSampler<_>>()`.
    pub fn sampler_as<S: FromBlob<'a>>(&self) -> Result<Defensive<S>> {
        self.expect(BlobKind::Sampler(S::KIND))?;
        let s = S::from_blob(self).ok_or(Error::HeaderInvalid)?;
        Ok(self.defend(s))
    }

    /// The neural material (feature texture + decoder, [`crate::neural_material`]), or
    /// [`Error::WrongKind`]. Its texture is `header().resolution` texels wide and
    /// `header().t_levels` high.
    pub fn neural_material(&self) -> Result<NeuralMaterial<Tensor<'a>>> {
        self.expect(BlobKind::NeuralMaterial)?;
        NeuralMaterial::new(
            self.tensor_or_empty(TensorRole::Features),
            self.params(),
            self.header.resolution,
            self.header.t_levels,
        )
        .ok_or(Error::HeaderInvalid)
    }

    /// The measured material ([`crate::measured`]: an RGL BRDF and its own VNDF sampler, whose
    /// densities are with respect to solid angle), reading the blob's tables in place, or
    /// [`Error::WrongKind`]. [`Blob::open`] has checked everything; this re-runs
    /// [`MeasuredMaterial::new`](crate::MeasuredMaterial::new)'s linear scan of the tables,
    /// so call it once per material.
    #[cfg(not(target_arch = "spirv"))]
    pub fn measured(&self) -> Result<crate::measured::MeasuredMaterial<Tensor<'a>>> {
        self.expect(BlobKind::Measured)?;
        super::measured::material(
            &self.tensor_or_empty(TensorRole::Shape),
            &self.tensor_or_empty(TensorRole::Tables),
        )
    }

    /// A measured blob's shape, tables and running integrals ([`Blob::open`]'s last step).
    fn check_measured(&self) -> Result<()> {
        #[cfg(not(target_arch = "spirv"))]
        return super::measured::check_integrals(&self.measured()?);
        // Shaders take a measured material's tables as storage buffers: no blob of it
        // opens there.
        #[cfg(target_arch = "spirv")]
        Err(Error::WrongKind {
            expected: BlobKind::Sampler(SamplerKind::Cosine),
            found: BlobKind::Measured,
        })
    }

    /// Whichever sampler the blob holds, with the blob's defensive weight α
    /// ([`Blob::defensive`]; 0, a plain pass-through, for version-1 blobs). A neural-material
    /// or measured-material blob holds no sampler: [`Error::NotASampler`].
    pub fn sampler(&self) -> Result<crate::samplers::BlobSampler<'a>> {
        let BlobKind::Sampler(kind) = self.header.kind else {
            return Err(Error::NotASampler {
                found: self.header.kind,
            });
        };
        let any = AnySampler::from_blob(kind, self).ok_or(Error::HeaderInvalid)?;
        Ok(self.defend(any))
    }
}

impl<'a> BlobSource<'a> for Blob<'a> {
    fn tensor(&self, role: TensorRole) -> Option<Tensor<'a>> {
        Blob::tensor(self, role)
    }
    fn header(&self) -> &Header<'a> {
        &self.header
    }
}

/// The preamble (magic, version, lengths) and the checksum: the blob's version and where its
/// body (everything before the checksum) ends.
fn check_preamble(bytes: &[u8]) -> Result<(u32, usize)> {
    let got = bytes.len() as u64;
    let min = (PREAMBLE_LEN + CHECKSUM_LEN) as u64;
    if got < 8 {
        // Too short to tell anything but a prefix of the magic.
        if bytes == &MAGIC[..bytes.len()] {
            return Err(Error::Truncated { needed: min, got });
        }
        return Err(Error::BadMagic);
    }
    // rust-gpu: element-wise, because `[u8] == [u8; N]` lowers to the `raw_eq` intrinsic,
    // which rust-gpu does not implement (ICE).
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
    if version < MIN_FORMAT_VERSION || version > FORMAT_VERSION {
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
    Ok((version, body))
}

/// The postcard header and, from version 2, its extension: the header, the extension, the
/// bytes of the tensor directory that follows and where the header ends.
fn decode_header<'a>(
    bytes: &'a [u8],
    version: u32,
    body: usize,
) -> Result<(Header<'a>, Extension, &'a [u8], usize)> {
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
    check_dims(&header)?;
    let mut extension = Extension::default();
    if version >= 2 {
        let (alpha, r): (f32, &'a [u8]) =
            postcard::take_from_bytes(rest).map_err(|_| Error::HeaderDecode)?;
        check_defensive(header.kind, alpha)?;
        extension.defensive = alpha;
        rest = r;
    }
    if version >= 3 {
        let (isotropic, r): (bool, &'a [u8]) =
            postcard::take_from_bytes(rest).map_err(|_| Error::HeaderDecode)?;
        if isotropic && header.kind.sampler().is_none() {
            return Err(Error::HeaderInvalid);
        }
        extension.isotropic = isotropic;
        rest = r;
    }
    Ok((header, extension, rest, header_end))
}

/// The tensor directory: every tensor the header's kind requires, with its role, type,
/// count, alignment, bounds and finiteness checked.
fn read_directory<'a>(
    bytes: &'a [u8],
    header: &Header<'a>,
    mut rest: &'a [u8],
    header_end: usize,
    body: usize,
) -> Result<Tensors<'a>> {
    let (req, req_count) = required(header);
    if header.tensor_count as usize != req_count {
        return Err(Error::HeaderInvalid);
    }
    let data_start = header_end.div_ceil(DATA_ALIGN) * DATA_ALIGN;
    let mut tensors: Tensors<'a> = [None; ROLES];
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
        if expected != COUNT_FROM_SHAPE && e.count as u64 != expected {
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
        if !start.is_multiple_of(DATA_ALIGN) || start < data_start || end > body {
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
    Ok(tensors)
}

/// The defensive weight must be a number in [0, 1), and 0 for a neural material.
fn check_defensive(kind: BlobKind, alpha: f32) -> Result<()> {
    let ok = if kind.sampler().is_some() {
        alpha >= 0.0 && alpha < 1.0
    } else {
        alpha == 0.0
    };
    if ok {
        Ok(())
    } else {
        Err(Error::HeaderInvalid)
    }
}
