//! `neusample train`: one method, or a sweep over several with `summary.json`.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use neusample::samplers::histogram_mixture::{MAX_N, MAX_T};
use neusample::DType;
use neusample::SamplerKind;
use neusample_precompute::jobs::sampler::{sweep, train_sampler, SweepJob};
use neusample_precompute::materials;
use neusample_precompute::train::{parse_method, TrainConfig, WarmStart, METHODS};

/// Options of `neusample train`.
#[derive(Args, Clone, Debug)]
pub struct TrainArgs {
    /// A material file (TOML/JSON) or the name of a built-in material.
    #[arg(long)]
    material: String,
    /// The method, by its name (an unknown name is answered with the list of names), `all`
    /// (every method in turn, evaluated; needs --out-dir) or a comma-separated list (`flow,`
    /// for a one-method sweep).
    #[arg(long)]
    method: MethodArg,
    /// Where to write the blob (atomically); one method.
    #[arg(long, required_unless_present = "out_dir")]
    out: Option<PathBuf>,
    /// With `--method all`: folder receiving `<method>.nsb` and `summary.json`.
    #[arg(long)]
    out_dir: Option<PathBuf>,
    /// Multiplies every method's default step count (e.g. 0.5 for a shorter sweep).
    #[arg(long)]
    steps_scale: Option<f64>,
    /// With `--method all`: evaluation conditions for KL(p*‖p) and pdf MSE (grid 64²).
    #[arg(long, default_value_t = 24)]
    eval_conditions: usize,
    /// Store the network weights as f16 instead of f32 (histogram-mixture tables are stored
    /// as compact u16 row CDFs either way).
    #[arg(long)]
    f16: bool,
    /// A short run (seconds) instead of the default (about a minute).
    #[arg(long)]
    quick: bool,
    /// Optimisation steps (overrides the preset).
    #[arg(long)]
    steps: Option<usize>,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Training threads (results are reproducible for a fixed count).
    #[arg(long)]
    threads: Option<usize>,
    /// Histogram mixture: latent-code levels T.
    #[arg(long)]
    t_levels: Option<usize>,
    /// Histogram mixture: table resolution N.
    #[arg(long)]
    hist_res: Option<usize>,
    /// Histogram mixture: the nearest latent level (the default; kept for scripts).
    #[arg(long, conflicts_with = "interpolate_t")]
    nearest_t: bool,
    /// Histogram mixture: interpolate linearly between the two nearest latent levels
    /// (twice the table reads; the default is the nearest level).
    #[arg(long)]
    interpolate_t: bool,
    /// Train on the fit metrics' targets (cells wholly inside the disk, the release's 0.98
    /// cut-off) instead of targets up to the horizon.
    #[arg(long)]
    no_horizon: bool,
    /// Weight λ of the χ² term: the flows' fine-tuning phase (0: maximum likelihood only), the
    /// histogram mixture's and the reparameterization warp's added loss term (0: the release's
    /// objective).
    #[arg(long)]
    chi2: Option<f32>,
    /// Flows: length of the χ² fine-tuning phase as a fraction of the steps.
    #[arg(long)]
    chi2_fraction: Option<f64>,
    /// Resolution (per side, 8 to 128) of the tabulated ground truth the methods train on.
    #[arg(long)]
    gt_res: Option<usize>,
    /// Reparameterization sampler: steps of the warp's warm start on the tabulated target, on
    /// any material (0: never, the release's random start). By default 3000 steps on
    /// materials without a latent (measured files) and none on the others; the warp's own
    /// phase runs longer at a lower learning rate after it.
    #[arg(long)]
    reparam_prefit: Option<usize>,
    /// Reparameterization sampler: steps of the pdf network's phase (after the warp's; the
    /// network is the density MIS uses).
    #[arg(long)]
    reparam_pdf_steps: Option<usize>,
    /// Reparameterization sampler: weight λ of the generalised χ² `∫ q²/p̂ − 2q + p̂` in the
    /// pdf network's loss, beside its KL (0: the KL alone): how far the MIS density may fall
    /// below the warp's where the warp samples.
    #[arg(long)]
    reparam_pdf_chi2: Option<f32>,
}

/// `--method`: one method, `all`, or a comma-separated list (a sweep, like `all`).
#[derive(Clone, Debug)]
enum MethodArg {
    One(SamplerKind),
    Sweep(Vec<SamplerKind>),
}

impl std::str::FromStr for MethodArg {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<MethodArg> {
        if s == "all" {
            Ok(MethodArg::Sweep(METHODS.to_vec()))
        } else if s.contains(',') {
            let mut list = Vec::new();
            for m in s.split(',').map(str::trim).filter(|m| !m.is_empty()) {
                let m = parse_method(m)?;
                if !list.contains(&m) {
                    list.push(m);
                }
            }
            Ok(MethodArg::Sweep(list))
        } else {
            parse_method(s).map(MethodArg::One)
        }
    }
}

impl TryFrom<&TrainArgs> for TrainConfig {
    type Error = anyhow::Error;

    /// The preset (`--quick` or the defaults) with the command line's changes.
    fn try_from(a: &TrainArgs) -> Result<TrainConfig> {
        let mut cfg = if a.quick {
            TrainConfig::quick()
        } else {
            TrainConfig::default()
        };
        cfg.common.seed = a.seed;
        cfg.common.progress = true;
        if let Some(f) = a.steps_scale {
            if !(f > 0.0 && f.is_finite()) {
                bail!("--steps-scale must be positive");
            }
            cfg = cfg.with_steps_scaled(f);
        }
        if let Some(s) = a.steps {
            if s == 0 {
                bail!("--steps must be positive");
            }
            for m in METHODS {
                cfg.set_steps(m, s);
            }
        }
        if let Some(t) = a.threads {
            if t == 0 {
                bail!("--threads must be positive");
            }
            cfg.common.threads = t;
        }
        if let Some(t) = a.t_levels {
            if !(1..=MAX_T).contains(&t) {
                bail!("--t-levels must be in 1..={MAX_T}");
            }
            cfg.histogram_mixture.t_levels = t;
        }
        if let Some(n) = a.hist_res {
            if !(1..=MAX_N).contains(&n) {
                bail!("--hist-res must be in 1..={MAX_N}");
            }
            cfg.histogram_mixture.res = n;
        }
        if a.nearest_t {
            cfg.histogram_mixture.interpolate_t = false;
        }
        if a.interpolate_t {
            cfg.histogram_mixture.interpolate_t = true;
        }
        if a.no_horizon {
            cfg.common.horizon_targets = false;
        }
        if let Some(r) = a.gt_res {
            if !(8..=MAX_N).contains(&r) {
                bail!(
                    "--gt-res must be in 8..={MAX_N} (the tabulated target's largest resolution)"
                );
            }
            cfg.common.gt_res = r;
        }
        if let Some(w) = a.chi2 {
            if !(w >= 0.0 && w.is_finite()) {
                bail!("--chi2 must be a non-negative number");
            }
            cfg.histogram_mixture.chi2_weight = w;
            cfg.reparam.chi2_weight = w;
        }
        if let Some(steps) = a.reparam_prefit {
            cfg.reparam.prefit.steps = steps;
            cfg.reparam.warm_start = if steps > 0 {
                WarmStart::Always
            } else {
                WarmStart::Never
            };
        }
        if let Some(steps) = a.reparam_pdf_steps {
            if steps == 0 {
                bail!("--reparam-pdf-steps must be positive");
            }
            cfg.reparam.density_schedule.steps = steps;
        }
        if let Some(w) = a.reparam_pdf_chi2 {
            if !(w >= 0.0 && w.is_finite()) {
                bail!("--reparam-pdf-chi2 must be a non-negative number");
            }
            cfg.reparam.density_chi2_weight = w;
        }
        for flow in cfg.fine_tuned_mut() {
            if let Some(w) = a.chi2 {
                flow.chi2_weight = w;
            }
            if let Some(f) = a.chi2_fraction {
                if !(f >= 0.0 && f.is_finite()) {
                    bail!("--chi2-fraction must be a non-negative number");
                }
                flow.chi2_fraction = f;
            }
        }
        Ok(cfg)
    }
}

/// `neusample train`.
pub fn run(a: &TrainArgs) -> Result<()> {
    let material = materials::resolve(&a.material)?;
    let cfg = TrainConfig::try_from(a)?;
    let dtype = if a.f16 { DType::F16 } else { DType::F32 };
    let method = match &a.method {
        MethodArg::Sweep(list) => {
            let job = SweepJob {
                methods: list.clone(),
                config: cfg,
                dtype,
                out_dir: a.out_dir.clone().context("--method all needs --out-dir")?,
                eval_conditions: a.eval_conditions,
                quick: a.quick,
                steps_scale: a.steps_scale.unwrap_or(1.0),
            };
            return print_sweep(&sweep(material.as_ref(), &job)?);
        }
        MethodArg::One(m) => *m,
    };
    let out = a
        .out
        .clone()
        .context("--out is required for a single method")?;
    let (trained, bytes, v) = train_sampler(material.as_ref(), method, &cfg, dtype, &out)?;
    eprintln!(
        "wrote {} ({} bytes): trained in {:.1} s, final loss {:.4}, blob matches model to {:.2e} (tolerance {:.0e})",
        out.display(),
        bytes.len(),
        trained.seconds,
        trained.loss_history.last().copied().unwrap_or(f32::NAN),
        v.max_relative,
        v.tolerance
    );
    Ok(())
}

/// The sweep's table on stdout; an error when a method failed.
fn print_sweep(s: &neusample_precompute::jobs::sampler::Summary) -> Result<()> {
    println!(
        "{} ({} evaluation conditions)",
        s.material, s.eval_conditions
    );
    println!(
        "{:<18} {:>9} {:>11} {:>11} {:>12} {:>11} {:>9}",
        "method", "KL", "chi2", "chi2 worst", "sampled chi2", "pdf MSE", "train s"
    );
    let mut failures = 0;
    for r in &s.methods {
        match (&r.error, &r.fit) {
            (Some(e), _) => {
                failures += 1;
                println!("{:<18} failed: {e}", r.method);
            }
            // The χ² of the density the samples are drawn with, where it is not `pdf`'s.
            (None, Some(f)) => println!(
                "{:<18} {:>9.4} {:>11.4} {:>11.4} {:>12} {:>11.3e} {:>9.1}",
                r.method,
                f.kl_divergence,
                f.chi2,
                f.chi2_worst,
                f.sampled
                    .map_or("-".to_string(), |s| format!("{:.4}", s.chi2)),
                f.pdf_mse,
                r.train_seconds.unwrap_or(0.0)
            ),
            (None, None) => println!("{:<18} (no fit)", r.method),
        }
    }
    if failures > 0 {
        bail!("{failures} method(s) failed on {}", s.material);
    }
    Ok(())
}
