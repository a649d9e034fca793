//! The measured material as a blob (kind `measured`, `core/BLOB.md`): every fixture `.bsdf`
//! written as a blob gives bit-identical eval, pdf and samples to the file's material, and
//! corrupted blobs — truncated, flipped bytes, bad shapes, non-finite or inconsistent tables,
//! an f16 dtype — are refused with a typed error, never a panic.
//!
//! The blobs are built here from `fixtures/measured/*.bsdf` (none is committed).

use neusample::blob::MEASURED_SHAPE_LEN;
use neusample::wavefront::{RgbMut, SamplesMut, Vec2s, Vec3s, Vec3sMut};
use neusample::{
    Blob, BlobKind, BlobWriter, DType, Error, MeasuredMaterial, MeasuredShape, MeasuredTables,
    SamplerKind, TensorRole, Vec2, Vec3, Weights,
};
use neusample_owned::measured::OwnedMeasured;
use neusample_owned::{OwnedBlob, OwnedMeasuredBlob};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use rand::{RngExt, SeedableRng};

type Rng = rand_pcg::Pcg64Mcg;

mod common;

use common::{fixtures, FILES};

/// Directions per file and check.
const LANES: usize = 3000;

fn blob_of<W: Weights>(m: &MeasuredMaterial<W>) -> Vec<u8> {
    BlobWriter::measured(m, "name=test").to_bytes()
}

/// A direction with a random azimuth and `z` in (−0.2, 1): some below the horizon.
fn direction(r: &mut Rng) -> Vec3 {
    let z: f32 = r.random::<f32>() * 1.2 - 0.2;
    let phi: f32 = r.random::<f32>() * std::f32::consts::TAU;
    let s = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(s * phi.cos(), s * phi.sin(), z)
}

fn bits3(v: [f32; 3]) -> [u32; 3] {
    v.map(f32::to_bits)
}

/// Eval, pdf and sample of `a` and `b` at `LANES` seeded random directions, bit for bit, in
/// the scalar and the batched calls.
fn assert_identical<A: Weights, B: Weights>(a: &MeasuredMaterial<A>, b: &MeasuredMaterial<B>) {
    let mut r = Rng::seed_from_u64(0x6D65_6173);
    let wi: Vec<Vec3> = (0..LANES).map(|_| direction(&mut r)).collect();
    let wo: Vec<Vec3> = (0..LANES).map(|_| direction(&mut r)).collect();
    let u: Vec<Vec2> = (0..LANES)
        .map(|_| Vec2::new(r.random::<f32>(), r.random::<f32>()))
        .collect();
    let mut sampled = 0;
    for i in 0..LANES {
        let (pa, pb) = (a.prepare(wi[i]), b.prepare(wi[i]));
        assert_eq!(pa.is_some(), pb.is_some(), "lane {i}");
        let (Some(pa), Some(pb)) = (pa, pb) else {
            continue;
        };
        assert_eq!(
            bits3(pa.eval(wo[i])),
            bits3(pb.eval(wo[i])),
            "eval, lane {i}"
        );
        assert_eq!(
            bits3(pa.eval_cos(wo[i])),
            bits3(pb.eval_cos(wo[i])),
            "eval_cos, lane {i}"
        );
        assert_eq!(
            pa.pdf(wo[i]).to_bits(),
            pb.pdf(wo[i]).to_bits(),
            "pdf, lane {i}"
        );
        let (sa, sb) = (pa.sample(u[i]), pb.sample(u[i]));
        assert_eq!(sa.is_some(), sb.is_some(), "sample, lane {i}");
        if let (Some(sa), Some(sb)) = (sa, sb) {
            assert_eq!(
                sa.wo.to_array().map(f32::to_bits),
                sb.wo.to_array().map(f32::to_bits)
            );
            assert_eq!(sa.pdf.to_bits(), sb.pdf.to_bits());
            assert_eq!(bits3(sa.weight), bits3(sb.weight));
            sampled += 1;
        }
    }
    assert!(sampled > LANES / 2, "only {sampled} samples");

    // The batched calls over the same lanes.
    let soa3 = |v: &[Vec3]| -> [Vec<f32>; 3] {
        [
            v.iter().map(|d| d.x).collect(),
            v.iter().map(|d| d.y).collect(),
            v.iter().map(|d| d.z).collect(),
        ]
    };
    let (wi3, wo3) = (soa3(&wi), soa3(&wo));
    let (ux, uy): (Vec<f32>, Vec<f32>) = u.iter().map(|v| (v.x, v.y)).unzip();
    let batched = |m: &dyn Fn(&mut [Vec<f32>; 12])| {
        let mut out: [Vec<f32>; 12] = std::array::from_fn(|_| vec![0.0; LANES]);
        m(&mut out);
        out.map(|v| v.into_iter().map(f32::to_bits).collect::<Vec<_>>())
    };
    let run = |m: &dyn BatchMaterial| {
        batched(&|o: &mut [Vec<f32>; 12]| {
            let [f_r, f_g, f_b, pdf, x, y, z, spdf, w_r, w_g, w_b, smis] = o;
            m.eval(
                view(&wi3),
                view(&wo3),
                RgbMut {
                    r: f_r,
                    g: f_g,
                    b: f_b,
                },
            );
            m.pdf(view(&wi3), view(&wo3), pdf);
            m.sample(
                view(&wi3),
                Vec2s { x: &ux, y: &uy },
                SamplesMut {
                    wo: Vec3sMut { x, y, z },
                    pdf: spdf,
                    mis_pdf: smis,
                },
                RgbMut {
                    r: w_r,
                    g: w_g,
                    b: w_b,
                },
            );
        })
    };
    assert!(run(a) == run(b), "batched calls differ");
}

fn view(s: &[Vec<f32>; 3]) -> Vec3s<'_> {
    Vec3s {
        x: &s[0],
        y: &s[1],
        z: &s[2],
    }
}

/// The batched calls of a material behind one object-safe face (for the comparison above).
trait BatchMaterial {
    fn eval(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>);
    fn pdf(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, out: &mut [f32]);
    fn sample(&self, wi: Vec3s<'_>, u: Vec2s<'_>, out: SamplesMut<'_>, w: RgbMut<'_>);
}

impl<W: Weights> BatchMaterial for MeasuredMaterial<W> {
    fn eval(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>) {
        self.eval_batch(wi, wo, out).unwrap();
    }
    fn pdf(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, out: &mut [f32]) {
        self.pdf_batch(wi, wo, out).unwrap();
    }
    fn sample(&self, wi: Vec3s<'_>, u: Vec2s<'_>, out: SamplesMut<'_>, w: RgbMut<'_>) {
        self.sample_batch(wi, u, out, w).unwrap();
    }
}

#[test]
fn fixture_blobs_match_their_files_bit_for_bit() {
    for file in FILES {
        let owned = OwnedMeasured::open(&fixtures().join(file)).unwrap();
        let bytes = blob_of(owned.material());
        let blob = Blob::open(&bytes).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(blob.kind(), BlobKind::Measured);
        assert_eq!(blob.header().dtype, DType::F32);
        let m = blob.measured().unwrap();
        assert_eq!(m.shape(), owned.material().shape());
        assert_eq!(m.jacobian(), owned.material().jacobian());
        // Read in place: the handle's bytes are 16-byte aligned, so tables stay `&[f32]`.
        let handle = OwnedMeasuredBlob::from_bytes(&bytes).unwrap();
        assert!(handle.get().tables().rgb.as_f32_slice().is_some());
        assert_eq!(handle.label(), "name=test");
        assert_identical(owned.material(), handle.get());
        // Written again from the blob's material: the same bytes.
        assert!(blob_of(handle.get()) == bytes, "{file}: not a fixed point");
    }
}

/// A small anisotropic material with fourfold symmetry (φi nodes over a quarter turn), so
/// that the folding of directions goes through the blob too.
fn anisotropic() -> MeasuredMaterial<Vec<f32>> {
    let shape = MeasuredShape {
        n_phi: 4,
        n_theta: 3,
        ndf: [5, 4],
        sigma: [4, 3],
        vndf: [6, 5],
        rgb: [5, 5],
    };
    let s = shape.slices() as usize;
    let wave = |n: usize, k: f32| -> Vec<f32> {
        (0..n)
            .map(|i| 0.2 + (i as f32 * k).sin().abs())
            .collect::<Vec<_>>()
    };
    let half_pi = std::f32::consts::FRAC_PI_2;
    let phi_i: Vec<f32> = (0..4).map(|i| i as f32 * half_pi / 3.0).collect();
    let theta_i = vec![0.0, 0.6, 1.3];
    let (vndf, vm, vc) = neusample::distrib::marginal2d::build(&wave(s * 30, 0.37), 6, 5, true);
    let (lum, lm, lc) = neusample::distrib::marginal2d::build(&wave(s * 25, 0.71), 5, 5, true);
    let tables = MeasuredTables {
        phi_i,
        theta_i,
        ndf: wave(20, 0.3),
        sigma: wave(12, 0.5),
        vndf,
        vndf_marginal: vm,
        vndf_conditional: vc,
        luminance: lum,
        luminance_marginal: lm,
        luminance_conditional: lc,
        rgb: wave(s * 75, 0.13),
    };
    MeasuredMaterial::new(shape, tables, true).unwrap()
}

#[test]
fn an_anisotropic_material_round_trips() {
    let m = anisotropic();
    assert!(!m.isotropic());
    let bytes = blob_of(&m);
    let handle = OwnedMeasuredBlob::from_bytes(&bytes).unwrap();
    assert_identical(&m, handle.get());
}

#[test]
fn measured_blobs_are_not_samplers_and_other_kinds_not_measured() {
    let bytes = blob_of(&anisotropic());
    let blob = Blob::open(&bytes).unwrap();
    assert_eq!(
        blob.sampler().err(),
        Some(Error::NotASampler {
            found: BlobKind::Measured
        })
    );
    assert!(matches!(
        blob.neural_material().err(),
        Some(Error::WrongKind {
            expected: BlobKind::NeuralMaterial,
            found: BlobKind::Measured
        })
    ));
    assert!(BlobKind::Measured.sampler().is_none());
    assert_eq!(BlobKind::from_name("measured"), Some(BlobKind::Measured));
    let cosine = BlobWriter::new(SamplerKind::Cosine, DType::F32, "").to_bytes();
    let err = OwnedMeasuredBlob::new(&OwnedBlob::from_bytes(&cosine).unwrap()).err();
    assert!(matches!(
        err,
        Some(Error::WrongKind {
            expected: BlobKind::Measured,
            found: BlobKind::Sampler(SamplerKind::Cosine)
        })
    ));
}

/// The bytes with a new checksum (so that the check under test, not the CRC, answers).
fn resealed(mut bytes: Vec<u8>) -> Vec<u8> {
    let body = bytes.len() - 4;
    let crc = crc32(&bytes[..body]);
    bytes[body..].copy_from_slice(&crc.to_le_bytes());
    bytes
}

/// CRC-32 (IEEE), bitwise: the tests need no dependency for it.
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

/// The blob's shape and tables tensors as written, to be changed and written again.
fn parts<W: Weights>(m: &MeasuredMaterial<W>) -> (Vec<f32>, Vec<f32>) {
    let bytes = blob_of(m);
    let blob = Blob::open(&bytes).unwrap();
    let read = |role| {
        let t = blob.tensor(role).unwrap();
        (0..t.len()).map(|i| t.at(i)).collect::<Vec<f32>>()
    };
    (read(TensorRole::Shape), read(TensorRole::Tables))
}

fn written(shape: &[f32], tables: &[f32]) -> Vec<u8> {
    let mut w = BlobWriter::new(BlobKind::Measured, DType::F32, "");
    w.tensor(TensorRole::Shape, shape);
    w.tensor(TensorRole::Tables, tables);
    w.to_bytes()
}

fn open_err(bytes: &[u8]) -> Error {
    match Blob::open(bytes) {
        Ok(_) => panic!("a corrupted blob opened"),
        Err(e) => e,
    }
}

/// The offset of the `i`-th table inside the tables tensor.
fn table_start(shape: &MeasuredShape, i: usize) -> usize {
    shape.lens()[..i].iter().map(|(_, n)| *n as usize).sum()
}

#[test]
fn bad_shapes_and_tables_are_typed_errors() {
    let m = anisotropic();
    let (shape, tables) = parts(&m);
    assert_eq!(shape.len(), MEASURED_SHAPE_LEN);
    assert!(Blob::open(&written(&shape, &tables)).is_ok());
    let with_shape = |i: usize, v: f32| {
        let mut s = shape.clone();
        s[i] = v;
        open_err(&written(&s, &tables))
    };
    // Not an exact non-negative integer, or a jacobian flag other than 0 / 1.
    for (i, v) in [(0, 2.5), (1, -1.0), (6, 1e9), (10, 2.0), (10, 0.5)] {
        assert_eq!(with_shape(i, v), Error::HeaderInvalid, "shape[{i}] = {v}");
    }
    // Out of range.
    assert!(matches!(
        with_shape(0, 0.0),
        Error::DimensionMismatch { what: "n_phi", .. }
    ));
    assert!(matches!(
        with_shape(6, 1.0),
        Error::DimensionMismatch {
            what: "vndf width",
            ..
        }
    ));
    assert!(matches!(
        with_shape(9, 4096.0),
        Error::DimensionMismatch {
            what: "rgb height",
            ..
        }
    ));
    // Sizes in range whose tables would not fit a u32 count: refused before anything
    // multiplies them.
    let mut huge = shape.clone();
    huge[..2].copy_from_slice(&[65536.0, 65536.0]);
    assert!(matches!(
        open_err(&written(&huge, &tables)),
        Error::DimensionMismatch {
            what: "table elements",
            ..
        }
    ));
    // Another size: the tables' length no longer matches.
    assert!(matches!(
        with_shape(3, 5.0),
        Error::TensorShape { role: "tables", .. }
    ));
    // The shape tensor's own length.
    assert!(matches!(
        open_err(&written(&shape[..10], &tables)),
        Error::TensorShape { role: "shape", .. }
    ));
    // Tables one short or one long.
    assert!(matches!(
        open_err(&written(&shape, &tables[1..])),
        Error::TensorShape { role: "tables", .. }
    ));
    let mut longer = tables.clone();
    longer.push(0.0);
    assert!(matches!(
        open_err(&written(&shape, &longer)),
        Error::TensorShape { role: "tables", .. }
    ));

    let s = *m.shape();
    let with_table = |i: usize, v: f32| {
        let mut t = tables.clone();
        t[i] = v;
        open_err(&written(&shape, &t))
    };
    // Non-finite anywhere.
    for (k, v) in [
        (0usize, f32::NAN),
        (10, f32::INFINITY),
        (7, f32::NEG_INFINITY),
    ] {
        let i = table_start(&s, k) + 1;
        assert!(
            matches!(with_table(i, v), Error::NonFinite { .. }),
            "table {k}"
        );
    }
    // Unordered nodes, negative distributions.
    assert!(matches!(
        with_table(table_start(&s, 1) + 1, 0.0),
        Error::TableNotNormalized {
            role: "theta_i",
            ..
        }
    ));
    assert!(matches!(
        with_table(table_start(&s, 2), -1.0),
        Error::TableNotNormalized { role: "ndf", .. }
    ));
    // Running integrals that do not match the values, or slices not normalised.
    for (k, role) in [
        (4, "vndf_conditional"),
        (5, "vndf_marginal"),
        (6, "vndf_conditional"),
        (7, "luminance_conditional"),
        (8, "luminance_marginal"),
        (9, "luminance_conditional"),
    ] {
        let i = table_start(&s, k) + 2;
        let err = with_table(i, tables[i] * 1.5 + 0.01);
        assert!(
            matches!(err, Error::TableNotNormalized { role: r, .. } if r == role),
            "table {k}: {err:?}"
        );
    }
}

#[test]
fn f16_storage_is_refused() {
    let (shape, tables) = parts(&anisotropic());
    // The header's dtype.
    let mut w = BlobWriter::new(BlobKind::Measured, DType::F16, "");
    w.tensor(TensorRole::Shape, &shape);
    w.tensor(TensorRole::Tables, &tables);
    assert_eq!(
        open_err(&w.to_bytes()),
        Error::TensorDType {
            role: "tables",
            found: DType::F16
        }
    );
    // The tables stored as f16 under an f32 header.
    w.header_mut().dtype = DType::F32;
    assert_eq!(
        open_err(&w.to_bytes()),
        Error::TensorDType {
            role: "tables",
            found: DType::F16
        }
    );
}

#[test]
fn wrong_header_fields_and_tensors_are_refused() {
    let (shape, tables) = parts(&anisotropic());
    let mut w = BlobWriter::new(BlobKind::Measured, DType::F32, "");
    w.tensor(TensorRole::Shape, &shape);
    w.tensor(TensorRole::Tables, &tables);
    let mut bad = w.clone();
    bad.header_mut().resolution = 4;
    assert!(matches!(
        open_err(&bad.to_bytes()),
        Error::DimensionMismatch { .. }
    ));
    let mut bad = w.clone();
    bad.header_mut().param_count = 1;
    assert!(matches!(
        open_err(&bad.to_bytes()),
        Error::DimensionMismatch { .. }
    ));
    // A defensive weight is for samplers only.
    assert_eq!(
        open_err(&w.clone().defensive(0.1).to_bytes()),
        Error::HeaderInvalid
    );
    // A missing tensor, an unexpected one.
    let mut only_shape = BlobWriter::new(BlobKind::Measured, DType::F32, "");
    only_shape.tensor(TensorRole::Shape, &shape);
    assert_eq!(open_err(&only_shape.to_bytes()), Error::HeaderInvalid);
    let mut extra = w.clone();
    extra.tensor(TensorRole::Params, &[1.0]);
    assert_eq!(open_err(&extra.to_bytes()), Error::HeaderInvalid);
    let mut swapped = BlobWriter::new(BlobKind::Measured, DType::F32, "");
    swapped.tensor(TensorRole::Shape, &shape);
    swapped.tensor(TensorRole::Params, &tables);
    assert!(matches!(
        open_err(&swapped.to_bytes()),
        Error::TensorMissing { .. }
    ));
}

#[test]
fn truncated_blobs_are_refused() {
    let bytes = blob_of(&anisotropic());
    for len in (0..bytes.len()).step_by(37).chain([bytes.len() - 1]) {
        assert!(Blob::open(&bytes[..len]).is_err(), "length {len}");
    }
}

fn small_blob() -> &'static [u8] {
    static BYTES: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    BYTES.get_or_init(|| blob_of(&anisotropic()))
}

/// Where the data section starts (the first tensor's offset).
fn data_start(bytes: &[u8]) -> usize {
    let blob = Blob::open(bytes).unwrap();
    blob.entry(TensorRole::Shape).unwrap().offset as usize
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 400,
        rng_seed: RngSeed::Fixed(0x3ea5),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Any flipped bytes: an error (the checksum) or, resealed, an error or a material
    /// that evaluates and samples without panicking.
    #[test]
    fn flipped_bytes_never_panic(
        flips in prop::collection::vec((any::<prop::sample::Index>(), 1u8..=255), 1..4),
        in_data in any::<bool>(),
    ) {
        let mut bytes = small_blob().to_vec();
        let body = bytes.len() - 4;
        let lo = if in_data { data_start(&bytes) } else { 0 };
        for (at, x) in &flips {
            let i = lo + at.index(body - lo);
            bytes[i] ^= x;
        }
        prop_assert!(Blob::open(&bytes).is_err());
        let bytes = resealed(bytes);
        if let Ok(blob) = Blob::open(&bytes) {
            if let Ok(m) = blob.measured() {
                for k in 0..16 {
                    let t = k as f32 / 16.0;
                    let wi = Vec3::new(t - 0.5, 0.3 - t, 0.4 + t);
                    if let Some(p) = m.prepare(wi) {
                        let _ = p.eval(Vec3::new(0.1, t, 0.8));
                        let _ = p.pdf(Vec3::new(-t, 0.2, 0.5));
                        let _ = p.sample(Vec2::new(t, 1.0 - t));
                    }
                }
            }
        }
    }

    /// Any shape tensor: a typed result, never a panic (sizes up to the limits and past).
    #[test]
    fn any_shape_is_a_typed_result(
        shape in prop::collection::vec(
            prop_oneof![0.0f32..8.0, (0u32..70_000).prop_map(|v| v as f32), any::<f32>()],
            MEASURED_SHAPE_LEN,
        ),
        len in 0usize..2000,
    ) {
        let tables = vec![0.5f32; len];
        let _ = Blob::open(&written(&shape, &tables));
    }
}
