//! `neusample defend`: a blob's defensive weight α, chosen on a material or given.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use neusample_precompute::defend::{
    choose_alpha, with_defensive, DEFAULT_CONDITIONS, DEFAULT_RADIAL,
};
use neusample_precompute::materials;
use neusample_precompute::util::io;

/// Options of `neusample defend`.
#[derive(Args, Clone, Debug)]
pub struct DefendArgs {
    /// The sampler blobs.
    #[arg(required = true)]
    blobs: Vec<PathBuf>,
    /// The material the samplers are for (file or built-in name); needed unless --alpha.
    #[arg(long, required_unless_present = "alpha")]
    material: Option<String>,
    /// Use this α instead of choosing one (0 removes the cosine part).
    #[arg(long)]
    alpha: Option<f32>,
    /// Where to write the blob (one input blob); otherwise --in-place.
    #[arg(long, conflicts_with = "in_place")]
    out: Option<PathBuf>,
    /// Rewrite each input blob (atomically).
    #[arg(long)]
    in_place: bool,
    /// Conditions the choice averages over.
    #[arg(long, default_value_t = DEFAULT_CONDITIONS)]
    conditions: usize,
    /// Seed of the conditions.
    #[arg(long, default_value_t = 0xDEF)]
    seed: u64,
    /// Print the search as JSON instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(a: &DefendArgs) -> Result<()> {
    if a.out.is_none() && !a.in_place {
        bail!("say where to write: --out FILE (one blob) or --in-place");
    }
    if a.out.is_some() && a.blobs.len() != 1 {
        bail!(
            "--out takes one blob ({} given); use --in-place",
            a.blobs.len()
        );
    }
    if let Some(alpha) = a.alpha {
        if !(alpha >= 0.0 && alpha < 1.0) {
            bail!("--alpha must be in [0, 1), not {alpha}");
        }
    }
    let material = a.material.as_deref().map(materials::resolve).transpose()?;
    for path in &a.blobs {
        let bytes = io::read_blob(path)?;
        let alpha = match (a.alpha, &material) {
            (Some(x), _) => x,
            (None, Some(m)) => {
                let c = choose_alpha(&bytes, m.as_ref(), a.conditions, DEFAULT_RADIAL, a.seed)
                    .with_context(|| path.display().to_string())?;
                if a.json {
                    println!("{}", serde_json::to_string(&c)?);
                } else {
                    println!("{}: α = {}", path.display(), c.alpha);
                    println!("  α      2nd moment  χ² mean    χ² worst");
                    for s in &c.scores {
                        println!(
                            "  {:<6} {:>10.4}  {:>9.4}  {:>9.3e}",
                            s.alpha, s.relative_second_moment, s.chi2, s.chi2_worst
                        );
                    }
                }
                c.alpha
            }
            (None, None) => bail!("--material or --alpha is needed"),
        };
        let out = with_defensive(&bytes, alpha).with_context(|| path.display().to_string())?;
        let dest = a.out.clone().unwrap_or_else(|| path.clone());
        io::atomic_write(&dest, &out)?;
    }
    Ok(())
}
