//! The runtime's neural material (`neusample::neural_material`, ARCHITECTURES.md §7): bilinear wrap
//! lookup against hand computations, totality of `eval` (no NaN, 0 below the horizon), and
//! typed errors for corrupted neural-material blobs.

use neusample::neural_material::{
    decoder_input, texture_len, wrap_bilinear, NeuralMaterial, DECODER_PARAM_COUNT, LOG_F_MAX,
    LOG_F_MIN, MAX_TEXTURE_SIZE,
};
use neusample::{Blob, BlobKind, BlobWriter, SamplerKind, TensorRole};
use neusample::{DType, Error, Vec2, Vec3};
use neusample_host_tests::rng;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use rand::RngExt;

/// A `w × h` texture whose texel (i, j) channel c holds `100 j + 10 i + c`.
fn ramp_texture(w: u32, h: u32) -> Vec<f32> {
    let mut t = Vec::with_capacity(texture_len(w, h));
    for j in 0..h {
        for i in 0..w {
            for c in 0..8 {
                t.push((100 * j + 10 * i + c) as f32);
            }
        }
    }
    t
}

fn random_params(seed: u64, scale: f32) -> Vec<f32> {
    let mut r = rng(seed);
    (0..DECODER_PARAM_COUNT)
        .map(|_| (r.random::<f32>() * 2.0 - 1.0) * scale)
        .collect()
}

fn texel_value(i: u32, j: u32, c: u32) -> f32 {
    (100 * j + 10 * i + c) as f32
}

#[test]
fn bilinear_lookup_matches_hand_computation() {
    let (w, h) = (4u32, 3u32);
    let tex = ramp_texture(w, h);
    let params = random_params(1, 0.1);
    let m = NeuralMaterial::new(&tex[..], &params[..], w, h).unwrap();

    // Texel centres return the texel exactly.
    for j in 0..h {
        for i in 0..w {
            let uv = Vec2::new((i as f32 + 0.5) / w as f32, (j as f32 + 0.5) / h as f32);
            let phi = m.features(uv);
            for c in 0..8 {
                assert_eq!(phi[c as usize], texel_value(i, j, c), "texel ({i}, {j})");
            }
            assert_eq!(m.texel(i, j)[3], texel_value(i, j, 3));
        }
    }

    // A general point, by hand: u = 0.3 → x = 0.3·4 − 0.5 = 0.7 → texels 0, 1, wx = 0.7;
    // v = 0.55 → y = 0.55·3 − 0.5 = 1.15 → rows 1, 2, wy = 0.15.
    let phi = m.features(Vec2::new(0.3, 0.55));
    for c in 0..8u32 {
        let expect = 0.3 * 0.85 * texel_value(0, 1, c)
            + 0.7 * 0.85 * texel_value(1, 1, c)
            + 0.3 * 0.15 * texel_value(0, 2, c)
            + 0.7 * 0.15 * texel_value(1, 2, c);
        assert!(
            (phi[c as usize] - expect).abs() < 1e-3,
            "channel {c}: {} vs {expect}",
            phi[c as usize]
        );
    }

    // Wrapping: u = 0 lies halfway between the last column and the first.
    let phi = m.features(Vec2::new(0.0, 0.5));
    let expect = 0.5 * texel_value(3, 1, 0) + 0.5 * texel_value(0, 1, 0);
    assert!((phi[0] - expect).abs() < 1e-3, "{} vs {expect}", phi[0]);
    // v = 0.99: y = 2.47 → rows 2 and 0 (wrapped), wy = 0.47.
    let phi = m.features(Vec2::new(0.125, 0.99));
    let expect = 0.53 * texel_value(0, 2, 0) + 0.47 * texel_value(0, 0, 0);
    assert!((phi[0] - expect).abs() < 1e-2, "{} vs {expect}", phi[0]);

    // Periodicity, negative coordinates included.
    let mut r = rng(2);
    for _ in 0..1000 {
        let uv = Vec2::new(r.random::<f32>(), r.random::<f32>());
        let a = m.features(uv);
        for shift in [
            Vec2::new(1.0, 0.0),
            Vec2::new(-1.0, 2.0),
            Vec2::new(-3.0, -1.0),
        ] {
            let b = m.features(uv + shift);
            for c in 0..8 {
                assert!((a[c] - b[c]).abs() < 0.05, "{uv} + {shift}: {a:?} vs {b:?}");
            }
        }
    }

    // Non-finite coordinates read as 0 (and never produce NaN).
    let at0 = m.features(Vec2::ZERO);
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert_eq!(m.features(Vec2::new(bad, 0.0)), at0);
        assert_eq!(m.features(Vec2::new(0.0, bad)), at0);
    }
}

#[test]
fn wrap_bilinear_edge_cases() {
    assert_eq!(wrap_bilinear(0.5, 1), (0, 0, 0.0));
    let (i0, i1, w) = wrap_bilinear(0.0, 8);
    assert_eq!((i0, i1), (7, 0));
    assert!((w - 0.5).abs() < 1e-6);
    // A tiny negative u whose fractional part rounds to 1.
    let (i0, i1, w) = wrap_bilinear(-1e-9, 8);
    assert!(i0 < 8 && i1 < 8 && (0.0..=1.0).contains(&w));
    for t in [1e30f32, -1e30, 4096.999, f32::MAX, f32::MIN_POSITIVE, -0.0] {
        let (i0, i1, w) = wrap_bilinear(t, MAX_TEXTURE_SIZE);
        assert!(i0 < MAX_TEXTURE_SIZE && i1 < MAX_TEXTURE_SIZE && (0.0..=1.0).contains(&w));
    }
}

#[test]
fn eval_is_total() {
    let tex = ramp_texture(2, 2);
    let params = random_params(3, 0.3);
    let m = NeuralMaterial::new(&tex[..], &params[..], 2, 2).unwrap();
    let phi = [0.1f32; 8];
    let up = Vec3::new(0.2, 0.1, 0.9);
    let f = m.eval(&phi, up, Vec3::new(-0.3, 0.2, 0.8));
    assert!(f.iter().all(|&v| v > 0.0 && v.is_finite()), "{f:?}");

    let bad_dirs = [
        Vec3::new(0.3, 0.2, -0.5),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::ZERO,
        Vec3::new(f32::NAN, 0.0, 1.0),
        Vec3::new(0.0, 0.0, f32::INFINITY),
        Vec3::new(f32::INFINITY, 0.0, 1.0),
    ];
    for d in bad_dirs {
        assert_eq!(m.eval(&phi, d, up), [0.0; 3], "wi = {d}");
        assert_eq!(m.eval(&phi, up, d), [0.0; 3], "wo = {d}");
        assert!(decoder_input(&phi, d, up).is_none());
    }
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mut p = phi;
        p[5] = bad;
        assert_eq!(m.eval(&p, up, up), [0.0; 3]);
    }

    // Extreme but finite inputs and weights: finite, within the clamp range.
    let big = random_params(4, 1e30);
    let mb = NeuralMaterial::new(&tex[..], &big[..], 2, 2).unwrap();
    let (lo, hi) = (LOG_F_MIN.exp() * 0.999, LOG_F_MAX.exp() * 1.001);
    let mut r = rng(5);
    for k in 0..5000 {
        let phi: [f32; 8] = std::array::from_fn(|_| {
            let v = r.random::<f32>() * 2.0 - 1.0;
            if k % 3 == 0 {
                v * 3e38
            } else {
                v
            }
        });
        let wi = Vec3::new(
            r.random::<f32>() - 0.5,
            r.random::<f32>() - 0.5,
            r.random::<f32>(),
        ) * if k % 7 == 0 { 1e30 } else { 1.0 };
        let wo = Vec3::new(
            r.random::<f32>() - 0.5,
            r.random::<f32>() - 0.5,
            r.random::<f32>() - 0.1,
        );
        for mat in [&m, &mb] {
            let f = mat.eval(&phi, wi, wo);
            for v in f {
                assert!(
                    v.is_finite() && v >= 0.0,
                    "{v} at φ {phi:?} wi {wi} wo {wo}"
                );
                assert!(v == 0.0 || (v >= lo && v <= hi), "{v} outside the clamp");
            }
        }
    }
}

#[test]
fn constructor_checks_lengths_and_dims() {
    let tex = ramp_texture(3, 2);
    let params = random_params(6, 0.1);
    assert!(NeuralMaterial::new(&tex[..], &params[..], 3, 2).is_some());
    assert!(NeuralMaterial::new(&tex[..], &params[..], 2, 3).is_some()); // same length
    assert!(NeuralMaterial::new(&tex[..], &params[..], 3, 3).is_none());
    assert!(NeuralMaterial::new(&tex[..], &params[..], 0, 2).is_none());
    assert!(NeuralMaterial::new(&tex[..], &params[..1], 3, 2).is_none());
    // Unchecked with nonsense dimensions: no panic, no NaN.
    let u = NeuralMaterial::new_unchecked(&tex[..], &params[..], u32::MAX, 0);
    assert!(u.width() <= MAX_TEXTURE_SIZE && u.height() == 1);
    let phi = u.features(Vec2::new(0.7, 0.2));
    assert!(phi.iter().all(|v| v.is_finite()));
}

fn neural_blob(w: u32, h: u32, dtype: DType) -> (Vec<u8>, Vec<f32>, Vec<f32>) {
    let tex: Vec<f32> = ramp_texture(w, h).iter().map(|v| v * 1e-3).collect();
    let params = random_params(7, 0.2);
    let mut bw = BlobWriter::new(BlobKind::NeuralMaterial, dtype, "name=test").texture_dims(w, h);
    bw.tensor(TensorRole::Params, &params)
        .tensor(TensorRole::Features, &tex);
    (bw.to_bytes(), tex, params)
}

#[test]
fn blob_round_trip_f32_and_f16() {
    for dtype in [DType::F32, DType::F16] {
        let (bytes, tex, params) = neural_blob(5, 3, dtype);
        let blob = Blob::open(&bytes).unwrap();
        assert_eq!(blob.kind(), BlobKind::NeuralMaterial);
        assert!(blob.kind().sampler().is_none());
        assert_eq!(
            BlobKind::from_name("neural-material"),
            Some(BlobKind::NeuralMaterial)
        );
        let m = blob.neural_material().unwrap();
        assert_eq!((m.width(), m.height()), (5, 3));
        let host = NeuralMaterial::new(&tex[..], &params[..], 5, 3).unwrap();
        let tol = if dtype == DType::F32 { 1e-6 } else { 2e-2 };
        let mut r = rng(8);
        for _ in 0..500 {
            let uv = Vec2::new(r.random::<f32>() * 3.0 - 1.0, r.random::<f32>());
            let a = m.features(uv);
            let b = host.features(uv);
            for c in 0..8 {
                assert!(
                    (a[c] - b[c]).abs() <= tol * (1.0 + b[c].abs()),
                    "{a:?} vs {b:?}"
                );
            }
            let wi = Vec3::new(0.3, -0.1, 0.8);
            let wo = Vec3::new(r.random::<f32>() - 0.5, r.random::<f32>() - 0.5, 0.7);
            let fa = m.eval(&b, wi, wo);
            let fb = host.eval(&b, wi, wo);
            for c in 0..3 {
                assert!(
                    (fa[c] - fb[c]).abs() <= 10.0 * tol * fb[c],
                    "{fa:?} vs {fb:?}"
                );
            }
        }
        // Not a sampler, and other accessors refuse it.
        assert!(matches!(
            blob.sampler(),
            Err(Error::NotASampler {
                found: BlobKind::NeuralMaterial,
            })
        ));
        assert!(matches!(
            blob.sampler_as::<neusample::samplers::SplineFlowSampler<_>>(),
            Err(Error::WrongKind { .. })
        ));
    }
    // A sampler blob is not a neural material.
    let params = vec![0.0f32; SamplerKind::AnalyticMixture.param_count()];
    let mut bw = BlobWriter::new(SamplerKind::AnalyticMixture, DType::F32, "");
    bw.tensor(TensorRole::Params, &params);
    let bytes = bw.to_bytes();
    assert!(matches!(
        Blob::open(&bytes).unwrap().neural_material(),
        Err(Error::WrongKind {
            expected: BlobKind::NeuralMaterial,
            ..
        })
    ));
}

fn open_with(dims: (u32, u32), edit: impl FnOnce(&mut BlobWriter<'static>)) -> Result<(), Error> {
    let (w, h) = dims;
    let tex = vec![0.25f32; texture_len(w.clamp(1, 64), h.clamp(1, 64))];
    let params = random_params(9, 0.2);
    let mut bw = BlobWriter::new(BlobKind::NeuralMaterial, DType::F32, "").texture_dims(w, h);
    bw.tensor(TensorRole::Params, &params)
        .tensor(TensorRole::Features, &tex);
    edit(&mut bw);
    let bytes = bw.to_bytes();
    Blob::open(&bytes).map(|_| ())
}

#[test]
fn corrupted_blobs_give_typed_errors() {
    assert!(open_with((4, 4), |_| {}).is_ok());
    // Wrong texture length for the declared dimensions.
    let e = open_with((4, 4), |bw| {
        bw.tensor(TensorRole::Features, &[0.0; 4 * 4 * 8 - 1]);
    });
    assert_eq!(
        e,
        Err(Error::TensorShape {
            role: "features",
            expected: 128,
            found: 127
        })
    );
    // Wrong decoder length.
    let e = open_with((4, 4), |bw| {
        bw.tensor(TensorRole::Params, &[0.0; 10]);
    });
    assert!(
        matches!(e, Err(Error::TensorShape { role: "params", .. })),
        "{e:?}"
    );
    // Dimensions out of range.
    for (dims, what) in [
        ((0, 4), "width"),
        ((4, 0), "height"),
        ((MAX_TEXTURE_SIZE + 1, 4), "width"),
    ] {
        let e = open_with(dims, |_| {});
        assert!(
            matches!(e, Err(Error::DimensionMismatch { what: w, .. }) if w == what),
            "{dims:?}: {e:?}"
        );
    }
    let e = open_with((4, 4), |bw| bw.header_mut().basis = 3);
    assert!(
        matches!(e, Err(Error::DimensionMismatch { what: "basis", .. })),
        "{e:?}"
    );
    let e = open_with((4, 4), |bw| bw.header_mut().param_count = 5);
    assert!(
        matches!(
            e,
            Err(Error::DimensionMismatch {
                what: "param_count",
                ..
            })
        ),
        "{e:?}"
    );
    let e = open_with((4, 4), |bw| bw.header_mut().feature_dim = 7);
    assert!(
        matches!(
            e,
            Err(Error::DimensionMismatch {
                what: "feature_dim",
                ..
            })
        ),
        "{e:?}"
    );
    // Non-finite values.
    let e = open_with((4, 4), |bw| {
        let mut t = vec![0.5f32; 128];
        t[77] = f32::NAN;
        bw.tensor(TensorRole::Features, &t);
    });
    assert_eq!(
        e,
        Err(Error::NonFinite {
            role: "features",
            index: 77
        })
    );
    let e = open_with((4, 4), |bw| {
        let mut p = random_params(10, 0.1);
        p[DECODER_PARAM_COUNT - 1] = f32::INFINITY;
        bw.tensor(TensorRole::Params, &p);
    });
    assert!(
        matches!(e, Err(Error::NonFinite { role: "params", .. })),
        "{e:?}"
    );
    // A tensor of another kind instead of the features.
    let e = open_with((4, 4), |bw| {
        bw.tensor(TensorRole::Mass, &[1.0; 128]);
    });
    assert!(
        matches!(e, Err(Error::HeaderInvalid | Error::TensorMissing { .. })),
        "{e:?}"
    );
    // A sampler blob carrying a features tensor.
    let params = vec![0.0f32; SamplerKind::SplineFlow.param_count()];
    let mut bw = BlobWriter::new(SamplerKind::SplineFlow, DType::F32, "");
    bw.tensor(TensorRole::Params, &params)
        .tensor(TensorRole::Features, &[0.0; 8]);
    let e = Blob::open(&bw.to_bytes()).map(|_| ());
    assert!(
        matches!(e, Err(Error::HeaderInvalid | Error::TensorMissing { .. })),
        "{e:?}"
    );
    // Truncation.
    let (bytes, _, _) = neural_blob(4, 4, DType::F16);
    for cut in [1usize, 4, 100, bytes.len() / 2] {
        assert!(matches!(
            Blob::open(&bytes[..bytes.len() - cut]),
            Err(Error::Truncated { .. })
        ));
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 128,
        rng_seed: RngSeed::Fixed(0x4e55),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Any single bit flip of a neural-material blob is detected.
    #[test]
    fn bit_flips_are_detected(f16 in any::<bool>(), bit in any::<u64>()) {
        let (bytes, _, _) = neural_blob(3, 2, if f16 { DType::F16 } else { DType::F32 });
        let mut b = bytes.clone();
        let bit = (bit % (b.len() as u64 * 8)) as usize;
        b[bit / 8] ^= 1 << (bit % 8);
        prop_assert!(Blob::open(&b).is_err(), "flip of bit {} accepted", bit);
    }

    /// φ at any coordinate is a convex combination of texels: within the texture's range.
    #[test]
    fn features_stay_in_texel_range(u in -10.0f32..10.0, v in -10.0f32..10.0) {
        let tex = ramp_texture(3, 5);
        let params = random_params(11, 0.1);
        let m = NeuralMaterial::new(&tex[..], &params[..], 3, 5).unwrap();
        let phi = m.features(Vec2::new(u, v));
        for c in 0..8u32 {
            let lo = texel_value(0, 0, c) - 1e-3;
            let hi = texel_value(2, 4, c) + 1e-3;
            prop_assert!(phi[c as usize] >= lo && phi[c as usize] <= hi);
        }
    }
}
