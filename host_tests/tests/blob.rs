//! Blob container: round trips, golden bytes, and structured corruptions that must all give
//! typed errors (never a panic).

use neusample::{Blob, BlobWriter, Interpolation, SamplerKind, TensorRole};
use neusample::{DType, Error, Prepared, Sampler, Vec2, Vec3};
use neusample_host_tests::{rng, small_blob, uniform2};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

#[test]
fn golden_bytes_of_the_cosine_blob() {
    let bytes = BlobWriter::new(SamplerKind::Cosine, DType::F32, "").to_bytes();
    let expected: &[u8] = &[
        b'N', b'E', b'U', b'S', b'A', b'M', b'P', 0, // magic
        1, 0, 0, 0, // version
        34, 0, 0, 0, // total length
        10, 0, 0, 0, // header + directory length
        0, 0, 8, 0, 0, 0, 0, 0, 0, 0, // header: cosine, f32, φ 8, no params, no table, "", 0
    ];
    assert_eq!(&bytes[..bytes.len() - 4], expected);
    let crc = crc32(&bytes[..bytes.len() - 4]);
    assert_eq!(&bytes[bytes.len() - 4..], &crc.to_le_bytes());
    let blob = Blob::open(&bytes).unwrap();
    assert_eq!(blob.kind(), SamplerKind::Cosine);
}

/// Bitwise CRC-32 (IEEE), written independently of the implementation under test.
fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

#[test]
fn every_kind_round_trips_in_f32_and_f16() {
    for kind in SamplerKind::ALL {
        for dtype in [DType::F32, DType::F16] {
            let (bytes, params) = small_blob(kind, dtype, 7);
            let blob = Blob::open(&bytes).unwrap_or_else(|e| panic!("{kind:?} {dtype:?}: {e}"));
            assert_eq!(blob.kind(), kind);
            assert_eq!(blob.header().dtype, dtype);
            if kind == SamplerKind::Cosine {
                continue;
            }
            // Parameters read back exactly (f32) or as the f16 rounding of the original.
            let t = blob.tensor(TensorRole::Params).unwrap();
            let mut widened = vec![0f32; params.len()];
            blob.widen_into(TensorRole::Params, &mut widened).unwrap();
            let mut max_err = 0f32;
            for (i, &p) in params.iter().enumerate() {
                use neusample::Weights;
                let expect = match dtype {
                    DType::F16 => half::f16::from_f32(p).to_f32(),
                    _ => p,
                };
                assert_eq!(t.at(i as u32), expect);
                assert_eq!(widened[i], expect);
                max_err = max_err.max((widened[i] - p).abs());
            }
            eprintln!(
                "{kind:?} {dtype:?}: {} params, max |stored − original| = {max_err:e}",
                params.len()
            );
            // The sampler works straight from the blob.
            let s = blob.sampler().unwrap();
            let p = s.prepare(&[0.1; 8], Vec3::new(0.3, 0.2, 0.9)).unwrap();
            let mut r = rng(1);
            let mut any = false;
            for _ in 0..64 {
                if let Some(smp) = p.sample(uniform2(&mut r)) {
                    any = true;
                    // The MIS density is the pdf at the sample; the sample's own density
                    // too, for every kind but the reparameterization sampler.
                    let back = p.pdf(smp.wo);
                    assert_eq!(back, smp.mis_pdf, "{kind:?}");
                    if kind != SamplerKind::Reparam {
                        let want = smp.pdf;
                        assert!((back - want).abs() <= 1e-4 * want.max(1.0), "{kind:?}");
                    }
                }
            }
            assert!(any, "{kind:?}: no sample landed in the disk");
        }
    }
}

#[test]
fn aligned_f32_tensors_are_zero_copy() {
    let (bytes, _) = small_blob(SamplerKind::SplineFlow, DType::F32, 3);
    // Copy into a 16-byte aligned buffer.
    let mut store = vec![0u128; bytes.len().div_ceil(16)];
    let aligned: &mut [u8] = bytemuck_cast(&mut store);
    aligned[..bytes.len()].copy_from_slice(&bytes);
    let blob = Blob::open(&aligned[..bytes.len()]).unwrap();
    assert!(matches!(
        blob.tensor(TensorRole::Params),
        Some(neusample::Tensor::F32(_))
    ));
    // And at an odd address the same blob is read unaligned, still in place.
    let mut odd = vec![0u8; bytes.len() + 1];
    odd[1..].copy_from_slice(&bytes);
    let blob = Blob::open(&odd[1..]).unwrap();
    assert!(matches!(
        blob.tensor(TensorRole::Params),
        Some(neusample::Tensor::F32Bytes(_))
    ));
}

fn bytemuck_cast(v: &mut [u128]) -> &mut [u8] {
    // Safe reinterpretation through to_ne_bytes is not in place; use a checked cast.
    bytemuck::cast_slice_mut(v)
}

#[test]
fn truncation_at_every_length_is_a_typed_error() {
    for kind in [
        SamplerKind::Cosine,
        SamplerKind::AnalyticMixture,
        SamplerKind::HistogramMixture,
    ] {
        let (bytes, _) = small_blob(kind, DType::F16, 11);
        for len in 0..bytes.len() {
            match Blob::open(&bytes[..len]) {
                Err(Error::Truncated { needed, got }) => {
                    assert_eq!(got, len as u64);
                    assert!(needed > got);
                }
                Err(Error::BadMagic) if len == 0 => {}
                other => panic!("{kind:?} truncated to {len}: {other:?}"),
            }
        }
    }
}

#[test]
fn wrong_magic_version_and_kind() {
    let (bytes, _) = small_blob(SamplerKind::SplineFlow, DType::F32, 5);
    let mut b = bytes.clone();
    b[0] = b'X';
    assert_eq!(Blob::open(&b).unwrap_err(), Error::BadMagic);
    let mut b = bytes.clone();
    b[8] = 4;
    assert_eq!(
        Blob::open(&b).unwrap_err(),
        Error::UnsupportedVersion {
            found: 4,
            supported: 3
        }
    );
    let mut b = bytes.clone();
    b[8] = 0;
    assert_eq!(
        Blob::open(&b).unwrap_err(),
        Error::UnsupportedVersion {
            found: 0,
            supported: 3
        }
    );
    let blob = Blob::open(&bytes).unwrap();
    assert_eq!(
        blob.sampler_as::<neusample::samplers::HistogramMixtureSampler<_>>()
            .unwrap_err(),
        Error::WrongKind {
            expected: SamplerKind::HistogramMixture.into(),
            found: SamplerKind::SplineFlow.into()
        }
    );
    assert!(blob
        .sampler_as::<neusample::samplers::SplineFlowSampler<_>>()
        .is_ok());
    // Trailing garbage is refused.
    let mut b = bytes.clone();
    b.push(0);
    assert_eq!(Blob::open(&b).unwrap_err(), Error::HeaderInvalid);
}

#[test]
fn wrong_dimensions_are_refused() {
    let params = vec![0.01f32; SamplerKind::SplineFlow.param_count()];
    let mut w = BlobWriter::new(SamplerKind::SplineFlow, DType::F32, "");
    w.tensor(TensorRole::Params, &params);
    w.header_mut().feature_dim = 9;
    assert!(matches!(
        Blob::open(&w.to_bytes()),
        Err(Error::DimensionMismatch {
            what: "feature_dim",
            expected: 8,
            found: 9
        })
    ));
    let mut w = BlobWriter::new(SamplerKind::SplineFlow, DType::F32, "");
    w.tensor(TensorRole::Params, &params[1..]);
    w.header_mut().param_count -= 1;
    assert!(matches!(
        Blob::open(&w.to_bytes()),
        Err(Error::DimensionMismatch {
            what: "param_count",
            ..
        })
    ));
    // A tensor shorter than the header says.
    let mut w = BlobWriter::new(SamplerKind::SplineFlow, DType::F32, "");
    w.tensor(TensorRole::Params, &params[1..]);
    assert!(matches!(
        Blob::open(&w.to_bytes()),
        Err(Error::TensorShape { role: "params", .. })
    ));
    // Missing tensor.
    let w = BlobWriter::new(SamplerKind::SplineFlow, DType::F32, "");
    assert!(matches!(
        Blob::open(&w.to_bytes()),
        Err(Error::HeaderInvalid | Error::TensorMissing { .. })
    ));
    // Zero and huge table dimensions.
    for (t, n) in [(0, 8), (4, 0), (100_000, 8), (4, 1 << 20)] {
        let (bytes, _) = small_blob(SamplerKind::HistogramMixture, DType::F32, 1);
        let blob = Blob::open(&bytes).unwrap();
        let mut w = BlobWriter::new(SamplerKind::HistogramMixture, DType::F32, "").histogram_dims(
            t,
            n,
            Interpolation::Linear,
        );
        for role in [
            TensorRole::Params,
            TensorRole::Mass,
            TensorRole::Table,
            TensorRole::Marginal,
            TensorRole::Conditional,
        ] {
            let mut v = vec![
                0f32;
                blob.tensor(role)
                    .map(|t| {
                        use neusample::Weights;
                        t.len() as usize
                    })
                    .unwrap()
            ];
            blob.widen_into(role, &mut v).unwrap();
            w.tensor(role, &v);
        }
        assert!(
            matches!(
                Blob::open(&w.to_bytes()),
                Err(Error::DimensionMismatch { .. })
            ),
            "t={t} n={n}"
        );
    }
}

#[test]
fn non_finite_weights_are_refused() {
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e6] {
        for dtype in [DType::F32, DType::F16] {
            let mut params = vec![0.01f32; SamplerKind::AnalyticMixture.param_count()];
            params[17] = bad;
            let mut w = BlobWriter::new(SamplerKind::AnalyticMixture, dtype, "");
            w.tensor(TensorRole::Params, &params);
            let bytes = w.to_bytes();
            let r = Blob::open(&bytes).map(|_| ());
            let overflows = dtype == DType::F16 && bad == 1e6; // f16 max is 65504
            if bad.is_finite() && !overflows {
                assert!(r.is_ok());
            } else {
                assert_eq!(
                    r.unwrap_err(),
                    Error::NonFinite {
                        role: "params",
                        index: 17
                    },
                    "{bad} {dtype:?}"
                );
            }
        }
    }
}

#[test]
fn unnormalized_tables_are_refused() {
    let (bytes, _) = small_blob(SamplerKind::HistogramMixture, DType::F32, 2);
    let blob = Blob::open(&bytes).unwrap();
    let h = *blob.header();
    let get = |role| {
        use neusample::Weights;
        let mut v = vec![0f32; blob.tensor(role).unwrap().len() as usize];
        blob.widen_into(role, &mut v).unwrap();
        v
    };
    let rebuild =
        |table: &[f32], marginal: &[f32], conditional: &[f32]| {
            let mut w = BlobWriter::new(SamplerKind::HistogramMixture, DType::F32, "")
                .histogram_dims(h.t_levels, h.resolution, h.interpolation);
            w.tensor(TensorRole::Params, &get(TensorRole::Params))
                .tensor(TensorRole::Mass, &get(TensorRole::Mass))
                .tensor(TensorRole::Table, table)
                .tensor(TensorRole::Marginal, marginal)
                .tensor(TensorRole::Conditional, conditional);
            Blob::open(&w.to_bytes()).map(|_| ())
        };
    let (table, marginal, conditional) = (
        get(TensorRole::Table),
        get(TensorRole::Marginal),
        get(TensorRole::Conditional),
    );
    assert!(rebuild(&table, &marginal, &conditional).is_ok());
    // Scale one slice: no longer integrates to 1.
    let n = h.resolution as usize;
    let mut t2 = table.clone();
    let i = t2.iter().position(|&v| v > 0.0).unwrap();
    t2[i] *= 3.0;
    assert!(matches!(
        rebuild(&t2, &marginal, &conditional),
        Err(Error::TableNotNormalized { .. })
    ));
    // Negative value with the slice still summing to 1.
    let mut t3 = table.clone();
    let j = (i + 1..i + n).find(|&j| t3[j] > 0.0).unwrap_or(i);
    t3[i] += 1.0;
    t3[j] -= 1.0;
    if j != i {
        assert!(matches!(
            rebuild(&t3, &marginal, &conditional),
            Err(Error::TableNotNormalized { .. })
        ));
    }
    // CDF inconsistent with the table.
    let mut c2 = conditional.clone();
    c2[0] += 0.5;
    assert!(matches!(
        rebuild(&table, &marginal, &c2),
        Err(Error::TableNotNormalized { .. })
    ));
    let mut m2 = marginal.clone();
    m2[0] *= 0.5;
    assert!(matches!(
        rebuild(&table, &m2, &conditional),
        Err(Error::TableNotNormalized { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        rng_seed: RngSeed::Fixed(0xb10b),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Any single bit flip is detected (by the checksum, or earlier by the preamble checks).
    #[test]
    fn bit_flips_are_detected(kind_i in 0usize..SamplerKind::ALL.len(), f16 in any::<bool>(), bit in any::<u64>()) {
        let kind = SamplerKind::ALL[kind_i];
        let (bytes, _) = small_blob(kind, if f16 { DType::F16 } else { DType::F32 }, 9);
        let mut b = bytes.clone();
        let bit = (bit % (b.len() as u64 * 8)) as usize;
        b[bit / 8] ^= 1 << (bit % 8);
        let r = Blob::open(&b);
        prop_assert!(r.is_err(), "flip of bit {} accepted", bit);
    }

    /// Arbitrary bytes, and arbitrary bytes behind a valid preamble, never panic.
    #[test]
    fn garbage_never_panics(mut tail in proptest::collection::vec(any::<u8>(), 0..512), fix_crc in any::<bool>()) {
        let _ = Blob::open(&tail);
        let mut b = Vec::from(&b"NEUSAMP\0"[..]);
        b.extend_from_slice(&1u32.to_le_bytes());
        let total = (20 + tail.len() + 4) as u32;
        b.extend_from_slice(&total.to_le_bytes());
        b.append(&mut tail);
        if fix_crc {
            let c = crc32(&b);
            b.extend_from_slice(&c.to_le_bytes());
        }
        if let Ok(blob) = Blob::open(&b) {
            if let Ok(s) = blob.sampler() {
                if let Some(p) = s.prepare(&[0.0; 8], Vec3::Z) {
                    let _ = p.sample(Vec2::splat(0.5));
                    let _ = p.pdf(Vec3::Z);
                }
            }
        }
    }
}

/// Writes the seed corpus of the fuzz target (`fuzz/corpus/blob`): one small blob of every
/// kind in the fuzz input format (mode byte, u16 blob length, blob, query floats).
/// Run with `cargo test -p neusample-host-tests --test blob -- --ignored write_fuzz_corpus`.
#[test]
#[ignore]
fn write_fuzz_corpus() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus/blob");
    std::fs::create_dir_all(&dir).unwrap();
    for kind in SamplerKind::ALL {
        let (bytes, _) = small_blob(kind, DType::F16, 3);
        assert!(bytes.len() < 65536);
        let mut input = vec![1u8];
        input.extend_from_slice(&(bytes.len() as u16).to_le_bytes());
        input.extend_from_slice(&bytes);
        let query: [f32; 32] = core::array::from_fn(|i| ((i as f32) * 0.37).sin() * 0.5 + 0.25);
        for q in query {
            input.extend_from_slice(&q.to_le_bytes());
        }
        std::fs::write(dir.join(kind.name()), input).unwrap();
    }
}
