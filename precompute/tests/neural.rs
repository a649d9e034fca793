//! Neural materials in precompute (`NEURAL.md`): core's features and eval equal the burn
//! training graph to 1e−4, safetensors round trips and names bad tensors, a short
//! `train-material` run reduces its loss, and a neural material loads as a material and
//! trains a sampler unchanged.

use neusample::neural_material::{NeuralMaterial, DECODER_PARAM_COUNT};
use neusample::DType;
use neusample::SamplerKind;
use neusample::{Vec2, Vec3};
use neusample_precompute::eval::fit_report;
use neusample_precompute::materials::neural::safetensors::{self as st, ExportDtype};
use neusample_precompute::materials::neural::{NeuralMaterialModel, NeuralParts, DECODER_SIZES};
use neusample_precompute::materials::{self, Material};
use neusample_precompute::train::neural_material::{
    self as nt, graph_eval, verify_blob, NeuralTrainConfig,
};
use neusample_precompute::train::{self, TrainConfig};
use rand::{RngExt, SeedableRng};
use safetensors::tensor::{Dtype, TensorView};

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn random_parts(w: u32, h: u32, seed: u64) -> NeuralParts {
    let mut r = rand_pcg::Pcg64::seed_from_u64(seed);
    NeuralParts {
        width: w,
        height: h,
        texture: (0..w as usize * h as usize * 8)
            .map(|_| r.random_range(-1.0f32..1.0))
            .collect(),
        params: (0..DECODER_PARAM_COUNT)
            .map(|_| r.random_range(-0.4f32..0.4))
            .collect(),
    }
}

fn queries(n: usize, seed: u64) -> Vec<(Vec2, Vec3, Vec3)> {
    let mut r = rand_pcg::Pcg64::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let uv = Vec2::new(r.random_range(-2.0f32..2.0), r.random_range(-2.0f32..2.0));
            let wi = Vec3::new(
                r.random_range(-0.7f32..0.7),
                r.random_range(-0.7f32..0.7),
                r.random_range(0.05f32..1.0),
            );
            let wo = Vec3::new(
                r.random_range(-0.7f32..0.7),
                r.random_range(-0.7f32..0.7),
                r.random_range(-0.2f32..1.0),
            );
            (uv, wi, wo)
        })
        .collect()
}

#[test]
fn core_matches_the_burn_graph() {
    for (w, h, seed) in [(7u32, 5u32, 1u64), (1, 1, 2), (16, 16, 3)] {
        let parts = random_parts(w, h, seed);
        let q = queries(2000, seed + 10);
        let (gphi, gf) = graph_eval(&parts, &q);
        let core = NeuralMaterial::new(&parts.texture[..], &parts.params[..], w, h).unwrap();
        let (mut fe, mut ee, mut zeros) = (0f64, 0f64, 0);
        for (k, &(uv, wi, wo)) in q.iter().enumerate() {
            let phi = core.features(uv);
            for c in 0..8 {
                let (a, b) = (f64::from(phi[c]), f64::from(gphi[k][c]));
                fe = fe.max((a - b).abs() / b.abs().max(1e-3));
            }
            let f = core.eval(&phi, wi, wo);
            if f == [0.0; 3] {
                zeros += 1;
            }
            for c in 0..3 {
                let (a, b) = (f64::from(f[c]), f64::from(gf[k][c]));
                ee = ee.max((a - b).abs() / b.abs().max(1e-6));
            }
        }
        eprintln!(
            "{w}×{h}: features max rel {fe:.2e}, eval max rel {ee:.2e}, {zeros} below-horizon"
        );
        assert!(fe <= 1e-4 && ee <= 1e-4, "features {fe:e}, eval {ee:e}");
        assert!(zeros > 0 && zeros < q.len() / 2);
        // And through a blob (the check train-material runs).
        let bytes = parts.blob_bytes(DType::F32, "name=t").unwrap();
        let check = verify_blob(&bytes, 256, seed).unwrap();
        assert!(check.eval_max_relative <= 1e-4);
    }
}

#[test]
fn safetensors_round_trip() {
    let parts = random_parts(6, 4, 4);
    let bytes = st::write(&parts, ExportDtype::F32, "rt", &[("source", "test".into())]).unwrap();
    let back = st::read(&bytes).unwrap();
    assert_eq!(back.parts, parts, "f32 round trip is exact");
    assert!(back.ignored.is_empty());
    assert_eq!(
        back.metadata.get("format").map(String::as_str),
        Some(st::FORMAT)
    );
    assert_eq!(back.metadata.get("name").map(String::as_str), Some("rt"));

    // PyTorch layout: decoder.0.weight is [out, in], i.e. the transpose of the runtime's.
    let raw = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let w0 = raw.tensor("decoder.0.weight").unwrap();
    assert_eq!(w0.shape(), [DECODER_SIZES[1], DECODER_SIZES[0]]);
    let first = f32::from_le_bytes(w0.data()[4..8].try_into().unwrap()); // [out 0, in 1]
    assert_eq!(first, parts.params[DECODER_SIZES[1]]); // runtime W[1][0]
    assert_eq!(raw.tensor("features").unwrap().shape(), [4, 6, 8]);

    // f16: the values come back as their f16 roundings, and the blob built from them
    // evaluates like the f16 blob of the original.
    let bytes16 = st::write(&parts, ExportDtype::F16, "rt", &[]).unwrap();
    let back16 = st::read(&bytes16).unwrap();
    for (a, b) in back16.parts.params.iter().zip(&parts.params) {
        assert_eq!(*a, half::f16::from_f32(*b).to_f32());
    }
    let m = NeuralMaterialModel::new("rt", back16.parts.clone()).unwrap();
    let o =
        NeuralMaterialModel::from_blob(&parts.blob_bytes(DType::F16, "").unwrap(), "x").unwrap();
    for (uv, wi, wo) in queries(200, 5) {
        assert_eq!(
            m.eval(&m.features(uv), wi, wo),
            o.eval(&o.features(uv), wi, wo)
        );
    }

    // Extra tensors are ignored and reported.
    let extra = [1.0f32, 2.0];
    let eb: Vec<u8> = extra.iter().flat_map(|v| v.to_le_bytes()).collect();
    let mut tensors = owned_tensors(&bytes);
    tensors.push(("offset_net.weight".into(), Dtype::F32, vec![2], eb));
    let b = build(&tensors);
    assert_eq!(
        st::read(&b).unwrap().ignored,
        vec!["offset_net.weight".to_string()]
    );
}

type Owned = Vec<(String, Dtype, Vec<usize>, Vec<u8>)>;

fn owned_tensors(bytes: &[u8]) -> Owned {
    let s = safetensors::SafeTensors::deserialize(bytes).unwrap();
    s.tensors()
        .into_iter()
        .map(|(n, t)| (n, t.dtype(), t.shape().to_vec(), t.data().to_vec()))
        .collect()
}

fn build(t: &Owned) -> Vec<u8> {
    let views: Vec<_> = t
        .iter()
        .map(|(n, d, s, b)| (n.clone(), TensorView::new(*d, s.clone(), b).unwrap()))
        .collect();
    safetensors::tensor::serialize(views, None).unwrap()
}

fn read_err(t: &Owned) -> String {
    format!("{:#}", st::read(&build(t)).unwrap_err())
}

#[test]
fn bad_safetensors_give_clear_errors() {
    let parts = random_parts(4, 4, 6);
    let good = owned_tensors(&st::write(&parts, ExportDtype::F32, "x", &[]).unwrap());

    // Missing tensor: named, with its expected shape.
    let t: Owned = good
        .iter()
        .filter(|x| x.0 != "decoder.2.bias")
        .cloned()
        .collect();
    let e = read_err(&t);
    assert!(
        e.contains("missing tensor `decoder.2.bias`")
            && e.contains(&format!("[{}]", DECODER_SIZES[3])),
        "{e}"
    );

    // Transposed weight: both shapes in the message.
    let mut t = good.clone();
    let w = t.iter_mut().find(|x| x.0 == "decoder.0.weight").unwrap();
    w.2 = vec![DECODER_SIZES[0], DECODER_SIZES[1]];
    let e = read_err(&t);
    let (i, o) = (DECODER_SIZES[0], DECODER_SIZES[1]);
    assert!(
        e.contains("`decoder.0.weight`")
            && e.contains(&format!("[{i}, {o}]"))
            && e.contains(&format!("expected [{o}, {i}]")),
        "{e}"
    );

    // Features with the wrong channel count, and in CHW order.
    for shape in [vec![4usize, 8, 4], vec![2, 4, 16], vec![128]] {
        let mut t = good.clone();
        t.iter_mut().find(|x| x.0 == "features").unwrap().2 = shape.clone();
        let e = read_err(&t);
        let s = format!(
            "[{}]",
            shape
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        );
        assert!(
            e.contains("`features`") && e.contains(&s) && e.contains("expected [H, W, 8]"),
            "{e}"
        );
    }

    // Wrong element type.
    let mut t = good.clone();
    let b = t.iter_mut().find(|x| x.0 == "decoder.3.bias").unwrap();
    b.1 = Dtype::I32;
    let e = read_err(&t);
    assert!(e.contains("`decoder.3.bias`") && e.contains("I32"), "{e}");

    // A NaN.
    let mut t = good.clone();
    let f = t.iter_mut().find(|x| x.0 == "features").unwrap();
    f.3[40..44].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = read_err(&t);
    assert!(e.contains("`features`") && e.contains("index 10"), "{e}");

    // Not safetensors at all.
    let e = format!("{:#}", st::read(b"definitely not safetensors").unwrap_err());
    assert!(e.contains("not a valid safetensors file"), "{e}");
}

#[test]
fn short_training_reduces_the_loss_and_loads_as_a_material() {
    let source = materials::builtin("goat_leather").unwrap();
    let cfg = NeuralTrainConfig::quick();
    let t = nt::train(source.as_ref(), &cfg).unwrap();
    let h = &t.loss_history;
    let k = h.len() / 10;
    let first = h[..10].iter().sum::<f32>() / 10.0;
    let last = h[h.len() - k..].iter().sum::<f32>() / k as f32;
    eprintln!(
        "quick train-material: {} steps, loss {first:.4} (first 10 steps) → {last:.4} (last 10 %) in {:.1} s",
        h.len(),
        t.seconds
    );
    assert!(last < 0.75 * first, "loss {first} → {last}");

    // Reproducible per seed.
    let again = nt::train(source.as_ref(), &cfg).unwrap();
    assert_eq!(again.parts, t.parts);

    let bytes = t
        .parts
        .blob_bytes(DType::F32, "name=leather_quick source=goat_leather")
        .unwrap();
    let check = verify_blob(&bytes, 256, 1).unwrap();
    eprintln!("core vs graph: {check:?}");

    // Loadable wherever materials are loaded: the .nsb file, and a TOML `model = "neural"`.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("leather.nsb");
    std::fs::write(&path, &bytes).unwrap();
    let m = materials::load(&path).unwrap();
    assert_eq!(m.name(), "leather_quick");
    let toml = dir.path().join("leather.toml");
    std::fs::write(
        &toml,
        "name = \"my_leather\"\nmodel = \"neural\"\n[params]\nblob = \"leather.nsb\"\n",
    )
    .unwrap();
    let m2 = materials::load(&toml).unwrap();
    assert_eq!(m2.name(), "my_leather");
    std::fs::write(
        &toml,
        "name = \"x\"\nmodel = \"neural\"\n[params]\nblob = \"nope.nsb\"\n",
    )
    .unwrap();
    let e = format!("{:#}", materials::load(&toml).err().unwrap());
    assert!(e.contains("nope.nsb"), "{e}");

    let uv = Vec2::new(0.3, 0.7);
    let (wi, wo) = (Vec3::new(0.3, 0.1, 0.9), Vec3::new(-0.2, -0.1, 0.95));
    assert_eq!(m.features(uv), m2.features(uv));
    let f = m.eval(&m.features(uv), wi, wo);
    assert!(f.iter().all(|v| v.is_finite() && *v > 0.0), "{f:?}");
    assert_eq!(
        m.eval(&m.features(uv), wi, Vec3::new(0.0, 0.5, -0.5)),
        [0.0; 3]
    );

    // The fit measures run and are finite.
    let fit = fit_report(source.as_ref(), m.as_ref(), 2000, 8, 32, cfg.epsilon, 3);
    eprintln!("quick fit: {fit:?}");
    assert!(fit.relative_rgb_error.is_finite() && fit.kl_pstar.is_finite() && fit.kl_pstar >= 0.0);

    // A sampler trains on the neural material unchanged (ground truth from the decoder).
    let s = train::train(
        m.as_ref(),
        SamplerKind::ImprovedBaseline,
        &TrainConfig::quick(),
    )
    .unwrap();
    let sh = &s.loss_history;
    assert!(sh.iter().all(|v| v.is_finite()));
    eprintln!(
        "baseline on the neural material: loss {:.3} → {:.3}",
        sh[0],
        sh[sh.len() - 1]
    );
}
