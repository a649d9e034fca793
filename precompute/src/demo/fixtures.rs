//! The committed fixtures (`neusample fixtures`): every method trained with fixed seeds on the
//! default materials, and the neural versions of those materials. Deterministic: a run
//! reproduces the committed blobs byte for byte on the same machine.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use neusample::DType;
use neusample::{BlobWriter, SamplerKind};

pub use super::config::fixtures_dir;
use super::config::NEURAL_SUFFIX;
use crate::bake;
use crate::defend;
use crate::groundtruth;
use crate::jobs::material::{train_material, TrainMaterialJob};
use crate::materials::neural::NeuralMaterialModel;
use crate::materials::{self, Material};
use crate::train::neural_material::NeuralTrainConfig;
use crate::train::{self, has_integrand, needs_integrand, TrainConfig, METHODS};
use crate::util::io;
use crate::util::progress::stages_bar;

/// How much longer than `neusample train`'s defaults the fixtures train the flow, the
/// histogram mixture and the reparameterization sampler's warp: all three are still improving
/// at the default step counts (`docs/results.md`, "Fits" and the reparameterization ablation).
pub const FIXTURE_SLOW_LEARNER_STEPS: usize = 3;

/// The training settings of the committed fixtures: the default run (histogram tables T = 8,
/// N = 64, nearest latent level) with [`FIXTURE_SLOW_LEARNER_STEPS`]× the steps for the flow,
/// the histogram mixture and the reparameterization sampler's warp, seed 1 (the disk flow's
/// fixtures are trained with its default steps, and so is the reparameterization sampler's
/// pdf network).
fn fixture_config() -> TrainConfig {
    let mut c = TrainConfig::default();
    for kind in [
        SamplerKind::SplineFlow,
        SamplerKind::HistogramMixture,
        SamplerKind::Reparam,
    ] {
        c.scale_steps(kind, FIXTURE_SLOW_LEARNER_STEPS as f64);
    }
    c.reparam.density_schedule = TrainConfig::default().reparam.density_schedule;
    c
}

/// `<dir>/<material>/<method>.nsb`.
pub(crate) fn fixture_path(dir: &Path, material: &str, method: &str) -> PathBuf {
    dir.join(material).join(format!("{method}.nsb"))
}

/// Which fixtures `neusample fixtures` regenerates.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum FixtureSet {
    /// Samplers on the procedural default materials.
    Procedural,
    /// The neural versions of the default materials and the samplers trained on them.
    Neural,
    /// Both.
    All,
    /// Only the `conditions.txt` files of the neural versions' sampler folders (for the
    /// runtime's statistical tests), without training.
    Conditions,
    /// The samplers of the committed neural versions, without refitting the neural
    /// materials.
    NeuralSamplers,
}

impl FixtureSet {
    /// Every set with its command-line name.
    pub const NAMES: [(&'static str, FixtureSet); 5] = [
        ("procedural", FixtureSet::Procedural),
        ("neural", FixtureSet::Neural),
        ("all", FixtureSet::All),
        ("conditions", FixtureSet::Conditions),
        ("neural-samplers", FixtureSet::NeuralSamplers),
    ];
}

impl std::str::FromStr for FixtureSet {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<FixtureSet> {
        FixtureSet::NAMES
            .iter()
            .find(|(n, _)| *n == s)
            .map(|&(_, set)| set)
            .ok_or_else(|| {
                let names: Vec<&str> = FixtureSet::NAMES.iter().map(|(n, _)| *n).collect();
                anyhow::anyhow!("unknown fixture set `{s}` ({})", names.join(", "))
            })
    }
}

/// Seed of the conditions on which the fixtures' defensive weights are chosen
/// ([`defend::defend_baked`]); neither the demo's evaluation seeds nor the χ² suites' draw them.
pub const DEFEND_SEED: u64 = 0xDEF;

/// `neusample fixtures`: trains the methods `methods` (every trainable method when empty) on
/// the built-ins `names` with fixed seeds and writes `<out>/<material>/<method>.nsb` (f32,
/// the settings of `fixture_config`) plus `<out>/cosine.nsb`; for the neural set, first fits the
/// neural version of each material (`train-material` defaults, seed 1, f32) into
/// `<materials>/<name>_neural.nsb` and then trains the samplers on it into
/// `<out>/<name>_neural/`.
pub fn regenerate_fixtures(
    out: &Path,
    materials_out: &Path,
    set: FixtureSet,
    names: &[&str],
    methods: &[SamplerKind],
    quick: bool,
) -> Result<()> {
    let methods = methods_or_all(methods);
    io::atomic_write(
        &out.join("cosine.nsb"),
        &BlobWriter::new(SamplerKind::Cosine, DType::F32, "cosine").to_bytes(),
    )?;
    if set == FixtureSet::Conditions {
        for name in names {
            let path = materials_out.join(format!("{name}{NEURAL_SUFFIX}.nsb"));
            write_conditions(out, &NeuralMaterialModel::load(&path)?)?;
        }
        return Ok(());
    }
    if set == FixtureSet::NeuralSamplers {
        for name in names {
            let path = materials_out.join(format!("{name}{NEURAL_SUFFIX}.nsb"));
            let m = NeuralMaterialModel::load(&path)
                .with_context(|| format!("the committed neural version of {name}"))?;
            fixture_samplers(out, &m, &methods, quick)?;
        }
        eprintln!("fixtures written to {}", out.display());
        return Ok(());
    }
    if set != FixtureSet::Neural {
        for name in names {
            fixture_samplers(out, materials::builtin(name)?.as_ref(), &methods, quick)?;
        }
    }
    if set != FixtureSet::Procedural {
        neural_fixtures(out, materials_out, names, &methods, quick)?;
    }
    eprintln!("fixtures written to {}", out.display());
    Ok(())
}

/// The neural version of each built-in in `names` (`train-material` defaults, seed 1) into
/// `<materials_out>/<name>_neural.nsb`, then every method trained on it into
/// `<out>/<name>_neural/`.
pub(crate) fn neural_fixtures(
    out: &Path,
    materials_out: &Path,
    names: &[&str],
    methods: &[SamplerKind],
    quick: bool,
) -> Result<()> {
    let methods = methods_or_all(methods);
    for name in names {
        let path = materials_out.join(format!("{name}{NEURAL_SUFFIX}.nsb"));
        let mut job = TrainMaterialJob::new(*name, path.clone());
        if quick {
            job.training = NeuralTrainConfig::quick();
        }
        job.training.progress = true;
        train_material(&job).with_context(|| format!("neural fixture of {name}"))?;
        let m = NeuralMaterialModel::load(&path)?;
        fixture_samplers(out, &m, &methods, quick)?;
    }
    Ok(())
}

/// Conditions drawn from the material, for the runtime's statistical tests (which do not
/// link the materials): `<out>/<m.name()>/conditions.txt`, one "φ0 … φ7 wi.x wi.y wi.z" line
/// each.
fn write_conditions(out: &Path, m: &dyn Material) -> Result<()> {
    let conds = groundtruth::conditions(m, 256, 0xC0DE);
    let mut text = String::from("# phi0..phi7 wi.x wi.y wi.z (local frame), from the material\n");
    for c in &conds {
        for v in c.phi {
            text.push_str(&format!("{v:e} "));
        }
        text.push_str(&format!("{:e} {:e} {:e}\n", c.wi.x, c.wi.y, c.wi.z));
    }
    io::atomic_write(
        &out.join(io::slug(m.name())).join("conditions.txt"),
        text.as_bytes(),
    )
}

/// `methods`, or every trainable method when it is empty.
fn methods_or_all(methods: &[SamplerKind]) -> Vec<SamplerKind> {
    if methods.is_empty() {
        METHODS.to_vec()
    } else {
        methods.to_vec()
    }
}

/// The methods `methods` trained on `m` into `<out>/<m.name()>/`, plus the conditions file
/// (the reparameterization sampler only on a neural or measured material: it trains on the
/// integrand).
fn fixture_samplers(
    out: &Path,
    m: &dyn Material,
    methods: &[SamplerKind],
    quick: bool,
) -> Result<()> {
    let name = io::slug(m.name());
    let methods: Vec<SamplerKind> = methods
        .iter()
        .copied()
        .filter(|&k| !needs_integrand(k) || has_integrand(m))
        .collect();
    let pb = stages_bar(methods.len() as u64, &format!("fixtures {name}"));
    write_conditions(out, m)?;
    for &method in &methods {
        let method_name = method.name();
        pb.set_message(format!("{name}/{method_name}"));
        let mut cfg = if quick {
            TrainConfig::quick()
        } else {
            fixture_config()
        };
        cfg.common.seed = 1;
        if needs_integrand(method) {
            // A short run: one thread, so that it reproduces on any machine's core count.
            cfg.common.threads = 1;
        }
        let trained = train::train(m, method, &cfg)?;
        let label = format!(
            "fixture material={name} method={method_name} steps={} seed=1",
            trained.steps
        );
        let (bytes, _) = bake::checked_blob_bytes(&trained, DType::F32, &label, m, 8, 7)
            .with_context(|| format!("fixture {name}/{method_name}"))?;
        let (bytes, _) = defend::defend_baked(bytes, m, DEFEND_SEED)?;
        io::atomic_write(&fixture_path(out, &name, method_name), &bytes)?;
        pb.inc(1);
    }
    pb.finish_with_message(format!("{name} done"));
    Ok(())
}
