//! Measured materials read from RGL `.bsdf` files (Mitsuba's `tensor_file` format): the
//! reader, its typed errors, and [`OwnedMeasured`], the runtime's
//! [`MeasuredMaterial`] over tables it owns.
//!
//! # The file
//!
//! ```text
//! offset  size  field
//! 0       12    magic b"tensor_file\0"
//! 12      2     version (major, minor): 1, 0
//! 14      4     field count, u32
//! 18      …     per field: name length u16, name, ndim u16, dtype u8, offset u64,
//!               shape u64 × ndim
//! …             each field's little-endian data at its offset
//! ```
//!
//! dtype codes are Mitsuba's `Struct::Type`: 1 u8, 2 i8, 3 u16, 4 i16, 5 u32, 6 i32, 7 u64,
//! 8 i64, 9 f16, 10 f32, 11 f64. A measured material needs these fields (shapes outermost
//! first):
//!
//! | field | dtype | shape |
//! |---|---|---|
//! | `description` | u8 | `[n]` |
//! | `jacobian` | u8 | `[1]` |
//! | `phi_i`, `theta_i` | f32 | `[n_φ]`, `[n_θ]` |
//! | `ndf`, `sigma` | f32 | `[h, w]` |
//! | `vndf` | f32 | `[n_φ, n_θ, h, w]` |
//! | `luminance` | f32 | `[n_φ, n_θ, h, w]`, `h = w` |
//! | `rgb` | f32 | `[n_φ, n_θ, 3, h, w]`, as `luminance` |
//!
//! A spectral file (RGL's `*_spec.bsdf`) has, instead of `rgb`:
//!
//! | field | dtype | shape |
//! |---|---|---|
//! | `wavelengths` | f32 | `[n_λ]`, nm, ascending, `n_λ ≥ 1` |
//! | `spectra` | f32 | `[n_φ, n_θ, n_λ, h, w]`, as `luminance` |
//!
//! and is read in linear sRGB, each texel's spectrum integrated against the CIE 1931
//! observer under D65 ([`spectral`] gives the conversion and its normalisation: a flat
//! spectrum of 1 is white, (1, 1, 1)). A file with both `rgb` and `spectra` is read from
//! `rgb`.

pub mod cie;
pub mod spectral;

use std::collections::HashMap;
use std::fmt;
use std::path::Path;

use neusample::distrib::marginal2d;
use neusample::{MeasuredMaterial, MeasuredShape, MeasuredTables};

/// The magic bytes that open a tensor file.
pub const MAGIC: &[u8; 12] = b"tensor_file\0";

/// Why a measured-material file could not be read: the field at fault (if one is) and what
/// is wrong with it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MeasuredError {
    /// The file, when the error came from [`OwnedMeasured::open`].
    pub file: Option<String>,
    /// The field at fault, `None` for the file as a whole (I/O, header).
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl MeasuredError {
    fn file(message: impl Into<String>) -> Self {
        MeasuredError {
            file: None,
            field: None,
            message: message.into(),
        }
    }

    fn field(field: &str, message: impl Into<String>) -> Self {
        MeasuredError {
            file: None,
            field: Some(field.to_string()),
            message: message.into(),
        }
    }
}

impl fmt::Display for MeasuredError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{file}: ")?;
        }
        if let Some(field) = &self.field {
            write!(f, "field `{field}`: ")?;
        }
        write!(f, "{}", self.message)
    }
}

impl std::error::Error for MeasuredError {}

/// The element type of a tensor-file field.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum FieldType {
    /// Unsigned 8-bit integers.
    U8,
    /// Another integer or half type, read as bytes only.
    Other(u8),
    /// IEEE-754 binary32.
    F32,
    /// IEEE-754 binary64.
    F64,
}

impl FieldType {
    fn from_code(code: u8) -> Option<(FieldType, usize)> {
        Some(match code {
            1 => (FieldType::U8, 1),
            2 => (FieldType::Other(2), 1),
            3 | 4 | 9 => (FieldType::Other(code), 2),
            5 | 6 => (FieldType::Other(code), 4),
            7 | 8 => (FieldType::Other(code), 8),
            10 => (FieldType::F32, 4),
            11 => (FieldType::F64, 8),
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            FieldType::U8 => "u8",
            FieldType::F32 => "f32",
            FieldType::F64 => "f64",
            FieldType::Other(2) => "i8",
            FieldType::Other(3) => "u16",
            FieldType::Other(4) => "i16",
            FieldType::Other(5) => "u32",
            FieldType::Other(6) => "i32",
            FieldType::Other(7) => "u64",
            FieldType::Other(8) => "i64",
            FieldType::Other(_) => "f16",
        }
    }
}

/// One field of a tensor file: its type, shape and bytes.
#[derive(Clone, Debug)]
pub struct Field<'a> {
    /// Element type.
    pub dtype: FieldType,
    /// Shape, outermost first.
    pub shape: Vec<u64>,
    /// The data, `elements × size` bytes.
    pub bytes: &'a [u8],
}

/// A parsed tensor file: its fields by name, viewing the file's bytes.
#[derive(Clone, Debug)]
pub struct TensorFile<'a> {
    fields: HashMap<String, Field<'a>>,
}

/// Reads little-endian integers from a cursor, failing with the header's error.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], MeasuredError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(MeasuredError::file(format!(
                "truncated header: {what} at byte {} needs {n} bytes, the file has {}",
                self.pos,
                self.bytes.len()
            )));
        };
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn u16(&mut self, what: &str) -> Result<u16, MeasuredError> {
        let b = self.take(2, what)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self, what: &str) -> Result<u32, MeasuredError> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&mut self, what: &str) -> Result<u64, MeasuredError> {
        let b = self.take(8, what)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
}

impl<'a> TensorFile<'a> {
    /// Parses the header and checks that every field's data lies inside the file.
    ///
    /// # Errors
    /// A wrong magic or version, a truncated header, an unknown type code, a shape whose
    /// size overflows, or data past the end of the file.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, MeasuredError> {
        let mut c = Cursor { bytes, pos: 0 };
        let magic = c.take(12, "the magic")?;
        if magic != MAGIC {
            return Err(MeasuredError::file(
                "not a tensor file (the first 12 bytes are not `tensor_file\\0`)",
            ));
        }
        let version = c.take(2, "the version")?;
        if version != [1, 0] {
            return Err(MeasuredError::file(format!(
                "tensor file version {}.{} (this reader reads 1.0)",
                version[0], version[1]
            )));
        }
        let n = c.u32("the field count")?;
        let mut fields = HashMap::new();
        for i in 0..n {
            let len = c.u16("a field name's length")? as usize;
            let name = std::str::from_utf8(c.take(len, "a field name")?)
                .map_err(|_| MeasuredError::file(format!("field {i}: its name is not UTF-8")))?
                .to_string();
            let ndim = c.u16("a field's rank")? as usize;
            let code = c.take(1, "a field's type")?[0];
            let offset = c.u64("a field's offset")?;
            let Some((dtype, size)) = FieldType::from_code(code) else {
                return Err(MeasuredError::field(
                    &name,
                    format!("unknown type code {code}"),
                ));
            };
            let mut shape = Vec::with_capacity(ndim.min(16));
            let mut elements = 1u64;
            for _ in 0..ndim {
                let d = c.u64("a field's shape")?;
                shape.push(d);
                elements = elements
                    .checked_mul(d)
                    .ok_or_else(|| MeasuredError::field(&name, "its shape's size overflows"))?;
            }
            let range = elements
                .checked_mul(size as u64)
                .and_then(|len| Some((offset, offset.checked_add(len)?)))
                .filter(|&(_, end)| end <= bytes.len() as u64);
            let Some((start, end)) = range else {
                return Err(MeasuredError::field(
                    &name,
                    format!(
                        "its data (offset {offset}, shape {shape:?}, {}) runs past the end of \
                         the file ({} bytes): truncated?",
                        dtype.name(),
                        bytes.len()
                    ),
                ));
            };
            let field = Field {
                dtype,
                shape,
                bytes: &bytes[start as usize..end as usize],
            };
            if fields.insert(name.clone(), field).is_some() {
                return Err(MeasuredError::field(&name, "appears twice"));
            }
        }
        Ok(TensorFile { fields })
    }

    /// The field `name`, or an error saying it is missing.
    ///
    /// # Errors
    /// The field is absent.
    pub fn field(&self, name: &str) -> Result<&Field<'a>, MeasuredError> {
        self.fields
            .get(name)
            .ok_or_else(|| MeasuredError::field(name, "missing"))
    }

    /// Whether the file has a field `name`.
    #[must_use]
    pub fn has(&self, name: &str) -> bool {
        self.fields.contains_key(name)
    }

    /// The f32 field `name` with `rank` dimensions: its shape and values, every one finite.
    ///
    /// # Errors
    /// Missing, another type or rank, or a non-finite value.
    pub fn f32s(&self, name: &str, rank: usize) -> Result<(Vec<u64>, Vec<f32>), MeasuredError> {
        let f = self.field(name)?;
        if f.dtype != FieldType::F32 {
            return Err(MeasuredError::field(
                name,
                format!("type {} (expected f32)", f.dtype.name()),
            ));
        }
        if f.shape.len() != rank {
            return Err(MeasuredError::field(
                name,
                format!(
                    "shape {:?} has {} dimensions (expected {rank})",
                    f.shape,
                    f.shape.len()
                ),
            ));
        }
        let values: Vec<f32> = f
            .bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(MeasuredError::field(
                name,
                format!("element {i} is {} (values must be finite)", values[i]),
            ));
        }
        Ok((f.shape.clone(), values))
    }

    /// The u8 field `name` (one dimension).
    ///
    /// # Errors
    /// Missing, or another type or rank.
    pub fn bytes(&self, name: &str) -> Result<&'a [u8], MeasuredError> {
        let f = self.field(name)?;
        if f.dtype != FieldType::U8 || f.shape.len() != 1 {
            return Err(MeasuredError::field(
                name,
                format!(
                    "type {} with shape {:?} (expected u8 with one dimension)",
                    f.dtype.name(),
                    f.shape
                ),
            ));
        }
        Ok(f.bytes)
    }
}

/// A measured material owning its tables (built as Mitsuba builds them from the file).
#[derive(Clone, Debug)]
pub struct OwnedMeasured {
    material: MeasuredMaterial<Vec<f32>>,
    description: String,
    wavelengths: Option<Vec<f32>>,
}

/// A shape dimension as a table size, or an error naming the field.
fn dim(field: &str, shape: &[u64], i: usize) -> Result<u32, MeasuredError> {
    u32::try_from(shape[i])
        .ok()
        .filter(|&d| d <= neusample::measured::MAX_TABLE_SIZE)
        .ok_or_else(|| {
            MeasuredError::field(field, format!("dimension {i} of {shape:?} is too large"))
        })
}

/// Checks that `shape[i] == want` for each `(i, want, what)`.
fn expect(field: &str, shape: &[u64], checks: &[(usize, u64, &str)]) -> Result<(), MeasuredError> {
    for &(i, want, what) in checks {
        if shape[i] != want {
            return Err(MeasuredError::field(
                field,
                format!(
                    "shape {shape:?}: dimension {i} is {} (expected {want}, {what})",
                    shape[i]
                ),
            ));
        }
    }
    Ok(())
}

impl OwnedMeasured {
    /// Reads a measured material from the bytes of a `.bsdf` file.
    ///
    /// # Errors
    /// [`MeasuredError`] naming the field for anything the file lacks or holds wrongly:
    /// truncation, a wrong magic, a missing field, non-finite values, inconsistent shapes.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, MeasuredError> {
        let tf = TensorFile::parse(bytes)?;
        let description = String::from_utf8_lossy(tf.bytes("description")?).into_owned();
        let jacobian = tf.bytes("jacobian")?;
        if jacobian.len() != 1 {
            return Err(MeasuredError::field(
                "jacobian",
                format!("{} elements (expected 1)", jacobian.len()),
            ));
        }
        let (_, phi_i) = tf.f32s("phi_i", 1)?;
        let (_, theta_i) = tf.f32s("theta_i", 1)?;
        let (ndf_s, ndf) = tf.f32s("ndf", 2)?;
        let (sigma_s, sigma) = tf.f32s("sigma", 2)?;
        let (vndf_s, vndf) = tf.f32s("vndf", 4)?;
        let (lum_s, luminance) = tf.f32s("luminance", 4)?;
        let (n_phi, n_theta) = (phi_i.len() as u64, theta_i.len() as u64);
        if n_phi == 0 || n_theta == 0 {
            return Err(MeasuredError::field(
                if n_phi == 0 { "phi_i" } else { "theta_i" },
                "empty",
            ));
        }
        let params = [
            (0, n_phi, "the length of phi_i"),
            (1, n_theta, "the length of theta_i"),
        ];
        expect("vndf", &vndf_s, &params)?;
        expect("luminance", &lum_s, &params)?;
        expect(
            "luminance",
            &lum_s,
            &[(3, lum_s[2], "luminance slices are square")],
        )?;
        let (rgb, wavelengths) = colour(&tf, &params, &lum_s)?;
        let shape = MeasuredShape {
            n_phi: n_phi as u32,
            n_theta: n_theta as u32,
            ndf: [dim("ndf", &ndf_s, 1)?, dim("ndf", &ndf_s, 0)?],
            sigma: [dim("sigma", &sigma_s, 1)?, dim("sigma", &sigma_s, 0)?],
            vndf: [dim("vndf", &vndf_s, 3)?, dim("vndf", &vndf_s, 2)?],
            rgb: [dim("luminance", &lum_s, 3)?, dim("luminance", &lum_s, 2)?],
        };
        for (field, [w, h]) in [
            ("ndf", shape.ndf),
            ("sigma", shape.sigma),
            ("vndf", shape.vndf),
            ("luminance", shape.rgb),
        ] {
            if w < 2 || h < 2 {
                return Err(MeasuredError::field(
                    field,
                    format!("slices of {h} x {w} (at least 2 x 2 needed)"),
                ));
            }
        }
        // The RGB values may dip slightly below zero (measurement noise; the runtime reads
        // them as 0); the distributions may not.
        for (field, values) in [
            ("ndf", &ndf),
            ("sigma", &sigma),
            ("vndf", &vndf),
            ("luminance", &luminance),
        ] {
            if let Some(i) = values.iter().position(|&v| v < 0.0) {
                return Err(MeasuredError::field(
                    field,
                    format!("element {i} is negative ({})", values[i]),
                ));
            }
        }
        ascending("phi_i", &phi_i)?;
        ascending("theta_i", &theta_i)?;
        let (vw, vh) = (shape.vndf[0] as usize, shape.vndf[1] as usize);
        let (rw, rh) = (shape.rgb[0] as usize, shape.rgb[1] as usize);
        let (vndf, vndf_marginal, vndf_conditional) = marginal2d::build(&vndf, vw, vh, true);
        let (luminance, luminance_marginal, luminance_conditional) =
            marginal2d::build(&luminance, rw, rh, true);
        let tables = MeasuredTables {
            phi_i,
            theta_i,
            ndf,
            sigma,
            vndf,
            vndf_marginal,
            vndf_conditional,
            luminance,
            luminance_marginal,
            luminance_conditional,
            rgb,
        };
        let material = MeasuredMaterial::new(shape, tables, jacobian[0] != 0)
            .map_err(|e| MeasuredError::file(format!("inconsistent tables: {e}")))?;
        Ok(OwnedMeasured {
            material,
            description,
            wavelengths,
        })
    }

    /// Reads a measured material from a `.bsdf` file; errors name the file.
    ///
    /// # Errors
    /// The file cannot be read, or [`OwnedMeasured::from_bytes`] refuses it; the message
    /// starts with the path.
    pub fn open(path: &Path) -> Result<Self, MeasuredError> {
        let named = |mut e: MeasuredError| {
            e.file = Some(path.display().to_string());
            e
        };
        let bytes = std::fs::read(path).map_err(|e| named(MeasuredError::file(e.to_string())))?;
        Self::from_bytes(&bytes).map_err(named)
    }

    /// The runtime's material.
    #[must_use]
    pub fn material(&self) -> &MeasuredMaterial<Vec<f32>> {
        &self.material
    }

    /// The file's description of the material.
    #[must_use]
    pub fn description(&self) -> &str {
        &self.description
    }

    /// The wavelengths (nm) of a spectral file, whose spectra were read in linear sRGB;
    /// `None` for an RGB file.
    #[must_use]
    pub fn wavelengths(&self) -> Option<&[f32]> {
        self.wavelengths.as_deref()
    }
}

/// Checks that `nodes` ascend strictly (angles, wavelengths).
fn ascending(field: &str, nodes: &[f32]) -> Result<(), MeasuredError> {
    match (1..nodes.len()).find(|&i| !(nodes[i] > nodes[i - 1])) {
        Some(i) => Err(MeasuredError::field(
            field,
            format!(
                "nodes must ascend: element {i} is {} after {}",
                nodes[i],
                nodes[i - 1]
            ),
        )),
        None => Ok(()),
    }
}

/// The RGB table, `[n_φ, n_θ, 3, h, w]`: the `rgb` field, or the `spectra` over
/// `wavelengths` in linear sRGB (then also the wavelengths). `params` checks the two
/// incident-angle dimensions; `lum_s` is the luminance's shape, whose slices the colour's
/// match.
fn colour(
    tf: &TensorFile<'_>,
    params: &[(usize, u64, &str)],
    lum_s: &[u64],
) -> Result<(Vec<f32>, Option<Vec<f32>>), MeasuredError> {
    // Each slice matches the luminance's.
    let hw = [
        (3, lum_s[2], "the luminance's height"),
        (4, lum_s[3], "the luminance's width"),
    ];
    if tf.has("rgb") {
        let (rgb_s, rgb) = tf.f32s("rgb", 5)?;
        expect("rgb", &rgb_s, params)?;
        expect("rgb", &rgb_s, &[(2, 3, "three channels")])?;
        expect("rgb", &rgb_s, &hw)?;
        return Ok((rgb, None));
    }
    if !(tf.has("spectra") || tf.has("wavelengths")) {
        return Err(MeasuredError::field(
            "rgb",
            "missing (and no `spectra` and `wavelengths` either: neither an RGB nor a \
             spectral file)",
        ));
    }
    let (_, wavelengths) = tf.f32s("wavelengths", 1)?;
    if wavelengths.is_empty() {
        return Err(MeasuredError::field("wavelengths", "empty"));
    }
    ascending("wavelengths", &wavelengths)?;
    let (spectra_s, spectra) = tf.f32s("spectra", 5)?;
    expect("spectra", &spectra_s, params)?;
    let n = wavelengths.len() as u64;
    expect(
        "spectra",
        &spectra_s,
        &[(2, n, "the length of wavelengths")],
    )?;
    expect("spectra", &spectra_s, &hw)?;
    let slices = (spectra_s[0] * spectra_s[1]) as usize;
    let pixels = (lum_s[2] * lum_s[3]) as usize;
    let weights = spectral::rgb_weights(&wavelengths);
    let rgb = spectral::spectra_to_rgb(&spectra, &weights, slices, pixels);
    Ok((rgb, Some(wavelengths)))
}
