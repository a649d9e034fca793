//! Training: every method learns (its loss falls in a short run), exports the runtime's
//! layout, and the runtime samplers built from the exported arrays reproduce the trained
//! model's density (`model_pdf_disk`) and the training graph to 1e−3 relative.
//!
//! Heavier runs (default configurations, KL on materials) are gated by
//! `NEUSAMPLE_FULL_TESTS=1`.

use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

use neusample::samplers::ReparamSampler;
use neusample::samplers::{AffineFlowSampler, DiskFlowSampler, SplineFlowSampler};
use neusample::samplers::{AnalyticMixtureSampler, ImprovedBaselineSampler};
use neusample::samplers::{DirectHistogramSampler, HistogramMixtureSampler};
use neusample::SamplerKind;
use neusample::{Prepared, Sampler, Vec2, Vec3};
use neusample_precompute::train::{
    self, graph_log_pdf, model_pdf_disk, parse_method, train_with, SyntheticSource, TargetSource,
    TrainConfig, Trained, WarmStart, METHODS,
};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Quick-trained models on the synthetic target, shared between tests.
fn quick(method: SamplerKind) -> Trained {
    static CACHE: OnceLock<Mutex<HashMap<SamplerKind, Trained>>> = OnceLock::new();
    let cache = CACHE.get_or_init(|| Mutex::new(HashMap::new()));
    if let Some(t) = cache.lock().unwrap().get(&method) {
        return t.clone();
    }
    let t = train_with(&SyntheticSource, method, &TrainConfig::quick()).unwrap();
    cache.lock().unwrap().insert(method, t.clone());
    t
}

fn mean(v: &[f32]) -> f64 {
    v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64
}

/// Runtime density at `p` of the sampler built from `t`'s exported arrays.
fn core_pdf(t: &Trained, phi: &[f32; 8], wi: Vec3, p: Vec2) -> f32 {
    let w: &[f32] = &t.params;
    match t.method {
        SamplerKind::ImprovedBaseline => ImprovedBaselineSampler::new(w)
            .expect("baseline parameter count")
            .prepare(phi, wi)
            .map_or(0.0, |s| s.pdf_disk(p)),
        SamplerKind::AnalyticMixture => AnalyticMixtureSampler::new(w)
            .expect("analytic parameter count")
            .prepare(phi, wi)
            .map_or(0.0, |s| s.pdf_disk(p)),
        SamplerKind::SplineFlow => SplineFlowSampler::new(w)
            .expect("flow parameter count")
            .prepare(phi, wi)
            .map_or(0.0, |s| s.pdf_disk(p)),
        SamplerKind::DiskFlow => DiskFlowSampler::new(w)
            .expect("disk flow parameter count")
            .prepare(phi, wi)
            .map_or(0.0, |s| s.pdf_disk(p)),
        SamplerKind::AffineFlow => AffineFlowSampler::new(w)
            .expect("affine parameter count")
            .prepare(phi, wi)
            .map_or(0.0, |s| s.pdf_disk(p)),
        SamplerKind::DirectHistogram => DirectHistogramSampler::new(w)
            .expect("direct histogram parameter count")
            .prepare(phi, wi)
            .map_or(0.0, |s| s.pdf_disk(p)),
        SamplerKind::HistogramMixture => {
            let tables = t.tables.as_ref().expect("histogram mixture has tables");
            let b = &tables.baked;
            HistogramMixtureSampler::new(
                w,
                b.mass.as_slice(),
                b.table.as_slice(),
                b.marginal.as_slice(),
                b.conditional.as_slice(),
                b.t_levels,
                b.resolution,
                tables.interpolation,
            )
            .expect("histogram mixture shapes")
            .prepare(phi, wi)
            .map_or(0.0, |s| s.pdf_disk(p))
        }
        SamplerKind::Reparam => ReparamSampler::new(w)
            .expect("reparam parameter count")
            .prepare(phi, wi)
            .map_or(0.0, |s| s.pdf_disk(p)),
        SamplerKind::Cosine => unreachable!("not trained"),
    }
}

fn expected_len(m: SamplerKind) -> usize {
    match m {
        SamplerKind::ImprovedBaseline => ImprovedBaselineSampler::<&[f32]>::PARAM_COUNT,
        SamplerKind::AnalyticMixture => AnalyticMixtureSampler::<&[f32]>::PARAM_COUNT,
        SamplerKind::SplineFlow => SplineFlowSampler::<&[f32]>::PARAM_COUNT,
        SamplerKind::DiskFlow => DiskFlowSampler::<&[f32]>::PARAM_COUNT,
        SamplerKind::AffineFlow => AffineFlowSampler::<&[f32]>::PARAM_COUNT,
        SamplerKind::DirectHistogram => DirectHistogramSampler::<&[f32]>::PARAM_COUNT,
        SamplerKind::HistogramMixture => HistogramMixtureSampler::<&[f32]>::PARAM_COUNT,
        SamplerKind::Reparam => ReparamSampler::<&[f32]>::PARAM_COUNT,
        SamplerKind::Cosine => unreachable!("not trained"),
    }
}

/// Random test points of a condition: half from its target, half uniform on the disk.
fn test_points(
    target: &neusample_precompute::groundtruth::TargetPdf,
    rng: &mut Pcg64,
) -> Vec<Vec2> {
    let mut pts = Vec::new();
    while pts.len() < 40 {
        let p = if pts.len() % 2 == 0 {
            target.sample(Vec2::new(rng.random(), rng.random()))
        } else {
            Some(Vec2::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ))
        };
        if let Some(p) = p.filter(|p| p.length_squared() < 0.999) {
            pts.push(p);
        }
    }
    pts
}

fn rel_err(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-6)
}

/// The shared checks for one method.
fn check(kind: SamplerKind) {
    let method = kind.name();
    let t = quick(kind);
    assert_eq!(t.method, kind);
    assert_eq!(
        t.params.len(),
        expected_len(kind),
        "{method}: parameter count"
    );
    assert!(
        t.params.iter().all(|v| v.is_finite()),
        "{method}: finite params"
    );

    // The loss falls (the reparameterization sampler's history is the warp's run, then the
    // pdf network's: the warp's is checked here; the synthetic target has a latent, so the
    // default settings give the warp no warm start).
    let steps = TrainConfig::quick().schedule(kind).unwrap().steps;
    let extra = if kind == SamplerKind::Reparam {
        TrainConfig::quick().reparam.density_schedule.steps
    } else {
        0
    };
    assert_eq!(t.loss_history.len(), steps + extra);
    assert_eq!(t.steps, steps, "{method}: main phase steps");
    let h = &t.loss_history[..steps];
    let k = 20;
    let (first, last) = (mean(&h[..k]), mean(&h[h.len() - k..]));
    eprintln!(
        "{method}: loss {first:.4} → {last:.4} in {:.2} s",
        t.seconds
    );
    if kind == SamplerKind::HistogramMixture {
        assert!(last < 0.8 * first, "{method}: loss {first} → {last}");
    } else {
        assert!(last < first - 0.1, "{method}: loss {first} → {last}");
    }

    // Runtime ≡ model_pdf_disk ≡ training graph at random conditions and points.
    let gts = SyntheticSource.draw(6, 32, 777).unwrap();
    let mut rng = Pcg64::seed_from_u64(5);
    let (mut worst_core, mut worst_graph, mut n) = (0.0f64, 0.0f64, 0);
    for g in &gts {
        let pts = test_points(&g.target, &mut rng);
        let graph = graph_log_pdf(kind, &t.params, &g.phi, g.wi, &pts);
        for (i, &p) in pts.iter().enumerate() {
            let model = f64::from(model_pdf_disk(&t, &g.phi, g.wi, p));
            let core = f64::from(core_pdf(&t, &g.phi, g.wi, p));
            assert!(model > 0.0, "{method}: model density 0 at {p}");
            let e = rel_err(core, model);
            worst_core = worst_core.max(e);
            assert!(
                e < 1e-3,
                "{method}: core {core} vs model {model} at {p} (φ {:?}, wi {})",
                g.phi,
                g.wi
            );
            if let Some(graph) = &graph {
                let gv = f64::from(graph[i]).exp();
                let e = rel_err(gv, model);
                worst_graph = worst_graph.max(e);
                assert!(e < 1e-3, "{method}: graph {gv} vs model {model} at {p}");
            }
            n += 1;
        }
    }
    eprintln!(
        "{method}: {n} points, worst relative error core/model {worst_core:.2e}, graph/model {worst_graph:.2e}"
    );
}

#[test]
fn baseline_learns_and_matches_runtime() {
    check(SamplerKind::ImprovedBaseline);
}

#[test]
fn analytic_learns_and_matches_runtime() {
    check(SamplerKind::AnalyticMixture);
}

#[test]
fn flow_learns_and_matches_runtime() {
    check(SamplerKind::SplineFlow);
}

#[test]
fn disk_flow_learns_and_matches_runtime() {
    check(SamplerKind::DiskFlow);
}

#[test]
fn affine_flow_learns_and_matches_runtime() {
    check(SamplerKind::AffineFlow);
}

#[test]
fn direct_histogram_learns_and_matches_runtime() {
    check(SamplerKind::DirectHistogram);
}

#[test]
fn reparam_warm_start_regresses_onto_the_target_map() {
    let mut cfg = TrainConfig::quick();
    cfg.reparam.warm_start = WarmStart::Always;
    // After the warm start the warp runs the refining schedule, not its own.
    cfg.reparam.refine.steps = cfg.reparam.schedule.steps + 7;
    let t = train_with(&SyntheticSource, SamplerKind::Reparam, &cfg).unwrap();
    let r = &cfg.reparam;
    assert_eq!(
        t.loss_history.len(),
        r.prefit.steps + r.refine.steps + r.density_schedule.steps
    );
    assert_eq!(
        t.steps, r.refine.steps,
        "the steps reported are the refining run's"
    );
    let h = &t.loss_history[..r.prefit.steps];
    let (first, last) = (mean(&h[..20]), mean(&h[h.len() - 20..]));
    eprintln!("reparam warm start: squared distance {first:.4} → {last:.4}");
    assert!(last < 0.5 * first, "warm start {first} → {last}");
    assert!(t.params.iter().all(|v| v.is_finite()));
    assert!(ReparamSampler::new(t.params.as_slice()).is_some());
}

#[test]
fn reparam_learns_and_matches_runtime() {
    check(SamplerKind::Reparam);
    // The warp: the runtime's point and Jacobian determinant equal the f64 mirror of the
    // trained model, and the samples' density is N(z)/det J.
    let t = quick(SamplerKind::Reparam);
    let s = ReparamSampler::new(t.params.as_slice()).unwrap();
    let gts = SyntheticSource.draw(6, 8, 778).unwrap();
    let mut rng = Pcg64::seed_from_u64(6);
    let (mut worst_point, mut worst_det, mut positive, mut n) = (0.0f64, 0.0f64, 0usize, 0usize);
    for g in &gts {
        let p = s.prepare(&g.phi, g.wi).unwrap();
        for _ in 0..200 {
            let u = Vec2::new(rng.random(), rng.random());
            let z = neusample::distrib::gaussian::box_muller(u);
            let w = p.warp(z);
            let (point, det) = train::reparam::warp_f64(&t.params, &g.phi, g.wi, z);
            worst_point = worst_point.max(f64::from((w.point - point).length()));
            worst_det = worst_det.max(rel_err(f64::from(w.det), det));
            n += 1;
            if let Some(smp) = p.sample(u) {
                positive += 1;
                assert!(w.det > 0.0);
                let q = (-0.5 * f64::from(z.length_squared())).exp()
                    / (std::f64::consts::TAU * f64::from(w.det));
                assert!(rel_err(f64::from(smp.pdf_disk), q) < 1e-4);
                assert_eq!(smp.wo.x, w.point.x);
            } else {
                assert!(!(w.det > 0.0) || w.point.length_squared() >= 1.0);
            }
        }
    }
    eprintln!(
        "reparam warp: {n} points, worst |Δpoint| {worst_point:.2e}, worst relative Δdet \
         {worst_det:.2e}, {positive} orientation-preserving"
    );
    assert!(worst_point < 1e-4 && worst_det < 1e-3);
    // Most of the trained warp preserves orientation.
    assert!(positive * 10 > 9 * n, "{positive} of {n} samples kept");
}

#[test]
fn histogram_mixture_learns_and_matches_runtime() {
    check(SamplerKind::HistogramMixture);
    let t = quick(SamplerKind::HistogramMixture);
    let tables = t.tables.as_ref().unwrap();
    tables.baked.validate().expect("baked tables validate");
    let cfg = TrainConfig::quick();
    let b = &tables.baked;
    assert_eq!(
        (b.bases, b.t_levels, b.resolution),
        (
            10,
            cfg.histogram_mixture.t_levels as u32,
            cfg.histogram_mixture.res as u32
        )
    );
    // The baked density integrates to ≤ 1 on the disk (boundary cells lose their part outside
    // the disk: ~10 % at N = 16) and close to 1.
    let gts = SyntheticSource.draw(3, 32, 99).unwrap();
    for g in &gts {
        let n = 200;
        let h = 2.0 / n as f64;
        let mut total = 0.0;
        for r in 0..n {
            for c in 0..n {
                let p = Vec2::new(
                    (-1.0 + (c as f64 + 0.5) * h) as f32,
                    (-1.0 + (r as f64 + 0.5) * h) as f32,
                );
                total += f64::from(model_pdf_disk(&t, &g.phi, g.wi, p)) * h * h;
            }
        }
        eprintln!("histogram-mixture: ∫ p over the disk = {total:.4}");
        assert!(total > 0.85 && total < 1.001, "integral {total}");
    }
}

#[test]
fn names_round_trip() {
    for m in METHODS {
        assert_eq!(parse_method(m.name()).unwrap(), m);
    }
    assert!(parse_method("histogram").is_err());
}

#[test]
fn training_is_reproducible() {
    let mut cfg = TrainConfig::quick();
    cfg.max_likelihood[SamplerKind::SplineFlow].schedule.steps = 30;
    let a = train_with(&SyntheticSource, SamplerKind::SplineFlow, &cfg).unwrap();
    let b = train_with(&SyntheticSource, SamplerKind::SplineFlow, &cfg).unwrap();
    assert!(a
        .params
        .iter()
        .zip(&b.params)
        .all(|(x, y)| x.to_bits() == y.to_bits()));
    assert_eq!(a.loss_history, b.loss_history);
    cfg.common.seed = 2;
    let c = train_with(&SyntheticSource, SamplerKind::SplineFlow, &cfg).unwrap();
    assert!(a.params != c.params);
}

/// Default-size training of every method on the synthetic target and on built-in materials,
/// reporting ms/step and KL(p* ‖ p). Slow (minutes): full tests only.
#[test]
fn default_training_kl() {
    if !neusample_host_tests::full_tests() {
        return;
    }
    let methods: Vec<SamplerKind> = match std::env::var("NEUSAMPLE_TRAIN_METHODS") {
        Ok(s) => s.split(',').map(|m| parse_method(m).unwrap()).collect(),
        Err(_) => METHODS.to_vec(),
    };
    let materials: Vec<String> = match std::env::var("NEUSAMPLE_TRAIN_MATERIALS") {
        Ok(s) => s.split(',').map(str::to_string).collect(),
        Err(_) => vec!["synthetic".into(), "goat_leather".into()],
    };
    for name in &materials {
        let material =
            (name != "synthetic").then(|| neusample_precompute::materials::builtin(name).unwrap());
        let source: Box<dyn TargetSource + '_> = match &material {
            Some(m) => Box::new(train::MaterialSource::new(m.as_ref())),
            None => Box::new(SyntheticSource),
        };
        for &m in &methods {
            let mut cfg = TrainConfig::default();
            if let Ok(s) = std::env::var("NEUSAMPLE_TRAIN_STEPS") {
                cfg.schedule_mut(m).unwrap().steps = s.parse().unwrap();
            }
            let steps = cfg.schedule(m).unwrap().steps;
            let t = train_with(source.as_ref(), m, &cfg).unwrap();
            let kl = train::mean_kl(&t, &source.draw(64, 64, 12345).unwrap());
            let ms = 1000.0 * t.seconds / steps as f64;
            let m = m.name();
            eprintln!(
                "{name:>16} {m:>18}: {} steps in {:.1} s ({ms:.1} ms/step incl. data), final loss {:.4}, KL {kl:.4}",
                steps,
                t.seconds,
                mean(&t.loss_history[t.loss_history.len() - 50..])
            );
        }
    }
}

/// Histogram-mixture diagnostics (manual: `cargo test --release --test train -- --ignored
/// histogram_mixture_diagnostics --nocapture`). Trains with the default configuration
/// modified by `HM_*` environment variables and prints the KL of the baked model, of the
/// un-baked network, and of re-bakes at other T / N.
#[test]
#[ignore]
fn histogram_mixture_diagnostics() {
    use neusample::Interpolation;
    use neusample_precompute::train::histogram_mixture::bake;
    use neusample_precompute::train::network_mean_kl;
    let env = |k: &str| std::env::var(k).ok();
    let materials: Vec<String> = env("HM_MATERIALS")
        .unwrap_or_else(|| "goat_leather".into())
        .split(',')
        .map(str::to_string)
        .collect();
    let mut cfg = TrainConfig::default();
    let hm = &mut cfg.histogram_mixture;
    if let Some(v) = env("HM_STEPS") {
        hm.schedule.steps = v.parse().unwrap();
    }
    if let Some(v) = env("HM_NLL") {
        hm.nll_weight = v.parse().unwrap();
    }
    if let Some(v) = env("HM_LR") {
        hm.schedule.lr = v.parse().unwrap();
    }
    if let Some(v) = env("HM_BATCH") {
        hm.batch_conditions = v.parse().unwrap();
    }
    if let Some(v) = env("HM_POINTS") {
        hm.points_per_condition = v.parse().unwrap();
    }
    if let Some(v) = env("HM_QUANT") {
        hm.quant_weight = v.parse().unwrap();
    }
    if let Some(v) = env("HM_T") {
        hm.t_levels = v.parse().unwrap();
    }
    if let Some(v) = env("HM_N") {
        hm.res = v.parse().unwrap();
    }
    if let Some(v) = env("HM_SS") {
        hm.supersample = v.parse().unwrap();
    }
    if let Some(v) = env("HM_POOL") {
        cfg.common.pool_conditions = v.parse().unwrap();
    }
    if let Some(v) = env("HM_GTRES") {
        cfg.common.gt_res = v.parse().unwrap();
    }
    eprintln!("{cfg:?}");
    for name in &materials {
        let m = neusample_precompute::materials::builtin(name).unwrap();
        let source = train::MaterialSource::new(m.as_ref());
        let t0 = std::time::Instant::now();
        let mut one_step = cfg.clone();
        one_step.max_likelihood[SamplerKind::ImprovedBaseline]
            .schedule
            .steps = 1;
        let pool_only = train_with(&source, SamplerKind::ImprovedBaseline, &one_step).unwrap();
        let t_pool = t0.elapsed().as_secs_f64();
        drop(pool_only);
        let t = train_with(&source, SamplerKind::HistogramMixture, &cfg).unwrap();
        let tb = std::time::Instant::now();
        let tables = t.tables.as_ref().unwrap();
        let _ = bake(
            &tables.basis_params,
            cfg.histogram_mixture.t_levels,
            cfg.histogram_mixture.res,
            cfg.histogram_mixture.supersample,
            Interpolation::Linear,
        )
        .unwrap();
        let t_bake = tb.elapsed().as_secs_f64();
        let n = 24;
        let gts = source.draw(n, 64, 12345).unwrap();
        let kl = train::mean_kl(&t, &gts);
        let kl_net = network_mean_kl(&t, &gts).unwrap();
        let h = &t.loss_history;
        eprintln!(
            "{name}: train {:.1} s (pool ≈ {t_pool:.1} s, bake ≈ {t_bake:.1} s), loss {:.4} → {:.4}; KL baked {kl:.4}, network {kl_net:.4}",
            t.seconds,
            mean(&h[..50.min(h.len())]),
            mean(&h[h.len().saturating_sub(50)..]),
        );
        for (tl, res, ss, interp) in [
            (8, 32, 2, Interpolation::Linear),
            (32, 64, 2, Interpolation::Nearest),
            (100, 64, 2, Interpolation::Linear),
            (32, 64, 4, Interpolation::Linear),
        ] {
            let mut t2 = t.clone();
            t2.tables = Some(bake(&tables.basis_params, tl, res, ss, interp).unwrap());
            let kl2 = train::mean_kl(&t2, &gts);
            eprintln!("  rebake T={tl} N={res} ss={ss} {interp:?}: KL {kl2:.4}");
        }
    }
}

/// Baking writes compact histogram-mixture tables by default; both layouts reproduce the
/// trained model (`bake::verify`), and a blob that stores values converts to the compact
/// layout (`bake::compact_blob`), which also reproduces it.
#[test]
fn histogram_mixture_bakes_compact_tables_that_verify() {
    use neusample::distrib::table2d::TableLayout;
    use neusample::{Blob, DType};
    use neusample_precompute::bake;

    let t = quick(SamplerKind::HistogramMixture);
    let m = neusample_precompute::materials::builtin("goat_leather").unwrap();
    let compact = bake::blob_bytes(&t, DType::F32, "test").unwrap();
    assert!(Blob::open(&compact).unwrap().is_compact());
    let v = bake::verify(&t, &compact, m.as_ref(), 8, 1).unwrap();
    assert_eq!(v.tolerance, bake::COMPACT_TOLERANCE);
    let values = bake::blob_bytes_with(&t, DType::F32, TableLayout::Values, "test").unwrap();
    assert!(!Blob::open(&values).unwrap().is_compact());
    let v = bake::verify(&t, &values, m.as_ref(), 8, 1).unwrap();
    assert_eq!(v.tolerance, bake::F32_TOLERANCE);
    assert!(
        compact.len() < values.len() / 2,
        "{} vs {}",
        compact.len(),
        values.len()
    );
    let converted = bake::compact_blob(&values).unwrap();
    assert!(Blob::open(&converted).unwrap().is_compact());
    bake::verify(&t, &converted, m.as_ref(), 8, 2).unwrap();
    // Nothing to convert: compact already, or another kind.
    assert!(bake::compact_blob(&compact).is_err());
    let flow = bake::blob_bytes(&quick(SamplerKind::SplineFlow), DType::F32, "test").unwrap();
    assert!(bake::compact_blob(&flow).is_err());
}

/// The fallback of `bake::checked_blob_bytes`: a compact blob that fails its check is baked
/// again with value tables, which are checked in turn; if those fail too, the error names
/// both failures. A check that refuses compact blobs forces the first failure.
#[test]
fn histogram_mixture_falls_back_to_value_tables() {
    use neusample::{Blob, DType};
    use neusample_precompute::bake;

    let t = quick(SamplerKind::HistogramMixture);
    let m = neusample_precompute::materials::builtin("goat_leather").unwrap();
    let compact_fails = |bytes: &[u8]| {
        if Blob::open(bytes)?.is_compact() {
            anyhow::bail!("compact tables refused by the test");
        }
        bake::verify(&t, bytes, m.as_ref(), 8, 1)
    };
    let (bytes, v) = bake::checked_blob_bytes_by(&t, DType::F32, "test", compact_fails).unwrap();
    let blob = Blob::open(&bytes).unwrap();
    assert!(!blob.is_compact());
    assert_eq!(v.tolerance, bake::F32_TOLERANCE);
    assert!(v.points > 0 && v.max_relative <= v.tolerance);
    // Without a failure the blob stays compact.
    let (bytes, _) = bake::checked_blob_bytes(&t, DType::F32, "test", m.as_ref(), 8, 1).unwrap();
    assert!(Blob::open(&bytes).unwrap().is_compact());
    // Both layouts refused: an error that names both.
    let e = bake::checked_blob_bytes_by(&t, DType::F32, "test", |_| {
        anyhow::bail!("refused by the test")
    })
    .unwrap_err();
    let msg = format!("{e:#}");
    assert!(
        msg.contains("value tables, after the compact ones failed"),
        "{msg}"
    );
    // Another kind has no fallback: its failure is the error.
    let flow = quick(SamplerKind::SplineFlow);
    assert!(bake::checked_blob_bytes_by(&flow, DType::F32, "test", |_| {
        anyhow::bail!("refused by the test")
    })
    .is_err());
}

#[test]
fn isotropic_materials_train_at_azimuth_zero_and_blobs_turn_back() {
    use neusample::Blob;
    use neusample_precompute::{bake, groundtruth, materials};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/measured");
    let m = materials::load(&dir.join("paper_white.toml")).unwrap();
    assert!(m.isotropic());
    let mut rng = Pcg64::seed_from_u64(3);
    for _ in 0..64 {
        let c = groundtruth::training_condition(m.as_ref(), &mut rng);
        let r = groundtruth::random_condition(m.as_ref(), &mut rng);
        assert_eq!(c.wi.y, 0.0);
        assert!(c.wi.x >= 0.0 && (c.wi.length() - 1.0).abs() < 1e-5);
        assert_ne!(r.wi.y, 0.0);
    }
    let t = train::train(
        m.as_ref(),
        SamplerKind::AnalyticMixture,
        &TrainConfig::quick(),
    )
    .unwrap();
    assert!(t.isotropic);
    let bytes = bake::blob_bytes(&t, neusample::DType::F32, "iso").unwrap();
    let blob = Blob::open(&bytes).unwrap();
    assert_eq!((blob.version(), blob.isotropic()), (3, true));
    // The runtime turns conditions at any azimuth as the f64 mirror does (random `wi`).
    let v = bake::verify(&t, &bytes, m.as_ref(), 16, 5).unwrap();
    eprintln!("isotropic analytic mixture: {v:?}");
    // The same model read without the turn differs away from azimuth 0: the check can fail.
    let plain = neusample::BlobWriter::from_blob(&blob)
        .isotropic(false)
        .to_bytes();
    assert!(bake::verify(&t, &plain, m.as_ref(), 16, 5).is_err());
    // A material that is not isotropic trains and writes as before.
    let t = quick(SamplerKind::AnalyticMixture);
    assert!(!t.isotropic);
    let bytes = bake::blob_bytes(&t, neusample::DType::F32, "plain").unwrap();
    let blob = Blob::open(&bytes).unwrap();
    assert_eq!((blob.version(), blob.isotropic()), (1, false));
}
