//! What the measured-material tests share: the committed RGL files.

use std::path::{Path, PathBuf};

/// `fixtures/measured`.
pub fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/measured")
}

/// The five committed RGL files.
#[allow(dead_code)] // each test crate uses its part of this module
pub const FILES: [&str; 5] = [
    "acrylic_felt_green_rgb.bsdf",
    "cc_ibiza_sunset_rgb.bsdf",
    "chm_mint_rgb.bsdf",
    "ilm_l3_37_metallic_rgb.bsdf",
    "paper_white_rgb.bsdf",
];

/// One field of a tensor file to write: u8 or f32 values and a shape.
#[allow(dead_code)] // each test crate uses its part of this module
pub enum Values {
    /// Unsigned bytes.
    U8(Vec<u8>),
    /// IEEE-754 binary32.
    F32(Vec<f32>),
}

/// The bytes of a tensor file (`bindings/owned/src/measured.rs` describes the format) holding
/// `fields` in order, each field's data at an 8-byte-aligned offset.
#[allow(dead_code)]
pub fn tensor_file(fields: &[(&str, Vec<u64>, Values)]) -> Vec<u8> {
    let header_len: usize = 18
        + fields
            .iter()
            .map(|(name, shape, _)| 2 + name.len() + 2 + 1 + 8 + 8 * shape.len())
            .sum::<usize>();
    let mut offset = header_len.div_ceil(8) * 8;
    let mut header = b"tensor_file\0\x01\x00".to_vec();
    header.extend((fields.len() as u32).to_le_bytes());
    let mut data = Vec::new();
    for (name, shape, values) in fields {
        let (code, raw): (u8, Vec<u8>) = match values {
            Values::U8(v) => (1, v.clone()),
            Values::F32(v) => (10, v.iter().flat_map(|x| x.to_le_bytes()).collect()),
        };
        header.extend((name.len() as u16).to_le_bytes());
        header.extend(name.as_bytes());
        header.extend((shape.len() as u16).to_le_bytes());
        header.push(code);
        header.extend((offset as u64).to_le_bytes());
        for d in shape {
            header.extend(d.to_le_bytes());
        }
        let padded = raw.len().div_ceil(8) * 8;
        data.extend(&raw);
        data.resize(data.len() + padded - raw.len(), 0);
        offset += padded;
    }
    assert_eq!(header.len(), header_len);
    header.resize(header_len.div_ceil(8) * 8, 0);
    header.extend(data);
    header
}
