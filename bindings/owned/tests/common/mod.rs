//! What the measured-material tests share: the committed RGL files.

use std::path::{Path, PathBuf};

/// `fixtures/measured`.
pub fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/measured")
}

/// The five committed RGL files.
pub const FILES: [&str; 5] = [
    "acrylic_felt_green_rgb.bsdf",
    "cc_ibiza_sunset_rgb.bsdf",
    "chm_mint_rgb.bsdf",
    "ilm_l3_37_metallic_rgb.bsdf",
    "paper_white_rgb.bsdf",
];
