//! Opens arbitrary bytes as a blob; when one opens, prepares, samples and evaluates pdfs on
//! inputs taken from the tail of the fuzz input (a neural-material blob: looks up features
//! and evaluates the decoder instead; a measured material: evaluates, samples and evaluates
//! pdfs with the data's own sampler). Any panic, or a NaN/negative/infinite pdf,
//! is a finding.
#![no_main]

use libfuzzer_sys::fuzz_target;
use neusample::Blob;
use neusample::{Prepared, Sampler, Vec2, Vec3};

fn f32_at(d: &[u8], i: usize) -> f32 {
    match d.get(4 * i..4 * i + 4) {
        Some(b) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        None => 0.5,
    }
}

/// Makes `total_len` and the trailing CRC-32 consistent, so that the fuzzer explores the
/// header and tensor validation instead of stopping at the checksum.
fn fix_checksum(b: &mut [u8]) {
    if b.len() < 24 {
        return;
    }
    let n = b.len();
    b[12..16].copy_from_slice(&(n as u32).to_le_bytes());
    let c = crc32fast::hash(&b[..n - 4]);
    b[n - 4..].copy_from_slice(&c.to_le_bytes());
}

fuzz_target!(|data: &[u8]| {
    // Byte 0: mode (bit 0: fix the checksum); bytes 1–2: length of the blob part; the rest
    // is the blob followed by the query (φ, wi, u, wo as little-endian f32).
    if data.len() < 3 {
        return;
    }
    let fix = data[0] & 1 == 1;
    let split = u16::from_le_bytes([data[1], data[2]]) as usize;
    let rest = &data[3..];
    let (blob_part, query) = rest.split_at(split.min(rest.len()));
    let mut owned = blob_part.to_vec();
    if fix {
        fix_checksum(&mut owned);
    }
    let Ok(blob) = Blob::open(&owned) else {
        return;
    };
    // A neural material: features and eval must be finite and non-negative (never NaN).
    if let Ok(m) = blob.neural_material() {
        for j in 0..4 {
            let uv = Vec2::new(f32_at(query, 2 * j), f32_at(query, 2 * j + 1));
            let phi = m.features(uv);
            let wi = Vec3::new(f32_at(query, 8 + 3 * j), f32_at(query, 9 + 3 * j), f32_at(query, 10 + 3 * j));
            let wo = Vec3::new(f32_at(query, 20 + 3 * j), f32_at(query, 21 + 3 * j), f32_at(query, 22 + 3 * j));
            for v in m.eval(&phi, wi, wo) {
                assert!(v.is_finite() && v >= 0.0, "neural eval {v}");
            }
        }
        return;
    }
    // A measured material: eval, the data's sampler and its pdf must be finite and
    // non-negative (never NaN), whatever tables passed validation.
    if let Ok(m) = blob.measured() {
        for j in 0..4 {
            let wi = Vec3::new(f32_at(query, 3 * j), f32_at(query, 1 + 3 * j), f32_at(query, 2 + 3 * j));
            let wo = Vec3::new(f32_at(query, 20 + 3 * j), f32_at(query, 21 + 3 * j), f32_at(query, 22 + 3 * j));
            let Some(p) = m.prepare(wi) else {
                continue;
            };
            for v in p.eval(wo) {
                assert!(v.is_finite() && v >= 0.0, "measured eval {v}");
            }
            let pdf = p.pdf(wo);
            assert!(pdf.is_finite() && pdf >= 0.0, "measured pdf {pdf}");
            if let Some(s) = p.sample(Vec2::new(f32_at(query, 12 + 2 * j), f32_at(query, 13 + 2 * j))) {
                assert!(s.pdf.is_finite() && s.pdf > 0.0, "measured sample pdf {}", s.pdf);
            }
        }
        return;
    }
    let Ok(sampler) = blob.sampler() else {
        return;
    };
    let mut phi = [0.0f32; 8];
    for (k, p) in phi.iter_mut().enumerate() {
        *p = f32_at(query, k);
    }
    let wi = Vec3::new(f32_at(query, 8), f32_at(query, 9), f32_at(query, 10));
    let Some(p) = sampler.prepare(&phi, wi) else {
        return;
    };
    for j in 0..4 {
        let u = Vec2::new(f32_at(query, 11 + 2 * j), f32_at(query, 12 + 2 * j));
        if let Some(s) = p.sample(u) {
            assert!(s.pdf.is_finite() && s.pdf > 0.0, "sample pdf {}", s.pdf);
            let back = p.pdf(s.wo);
            assert!(back.is_finite() && back >= 0.0);
        }
        let wo = Vec3::new(f32_at(query, 20 + 3 * j), f32_at(query, 21 + 3 * j), f32_at(query, 22 + 3 * j));
        let pdf = p.pdf(wo);
        assert!(pdf.is_finite() && pdf >= 0.0, "pdf {pdf}");
        let _ = p.invert(wo);
    }
});
