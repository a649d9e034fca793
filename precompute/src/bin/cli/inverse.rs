//! `neusample reparam-exact`: the reparameterization sampler's exact sampling density by
//! inverting its warp, against what its own samples and its pdf network show.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use neusample::Blob;
use neusample_precompute::defend::ALPHA_GRID;
use neusample_precompute::eval::warp_inverse::{exact_fit, DEFAULT_Z_CELLS};
use neusample_precompute::eval::{fit, Fit};
use neusample_precompute::materials::neural::NeuralMaterialModel;
use neusample_precompute::util::io;

use crate::output::print_json;

/// Options of `neusample reparam-exact`.
#[derive(Args, Clone, Debug)]
pub struct ReparamExactArgs {
    /// Folder of the sampler blobs: `<blobs>/<material>_neural/reparam.nsb`.
    #[arg(long, default_value = "fixtures/blobs")]
    blobs: PathBuf,
    /// Folder of the neural materials: `<materials>/<material>_neural.nsb`.
    #[arg(long, default_value = "fixtures/materials/neural")]
    materials: PathBuf,
    /// Materials (names without `_neural`); default: every neural material with a blob.
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Conditions per material.
    #[arg(long, default_value_t = 16)]
    conditions: usize,
    /// Latent cells per side of the inverse's grid.
    #[arg(long, default_value_t = DEFAULT_Z_CELLS)]
    cells: usize,
    /// Radial and angular nodes of the disk quadrature.
    #[arg(long, num_args = 2, default_values_t = [48, 192])]
    quadrature: Vec<usize>,
    /// Seed of the conditions.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// JSON lines instead of a Markdown table.
    #[arg(long)]
    json: bool,
}

pub fn run(a: &ReparamExactArgs) -> Result<()> {
    let names: Vec<String> = if a.only.is_empty() {
        let mut v: Vec<String> = std::fs::read_dir(&a.materials)
            .with_context(|| format!("cannot list {}", a.materials.display()))?
            .filter_map(|e| {
                let name = e.ok()?.file_name().into_string().ok()?;
                let m = name.strip_suffix("_neural.nsb")?.to_owned();
                a.blobs
                    .join(format!("{m}_neural/reparam.nsb"))
                    .is_file()
                    .then_some(m)
            })
            .collect();
        v.sort();
        v
    } else {
        a.only.clone()
    };
    if !a.json {
        println!(
            "| material (neural) | ∫q | missed f: mean / worst | χ²(p*‖q) exact: mean / worst | \
             χ²(p*‖q) sampled | KL(q‖p̂) exact / sampled | χ²(q‖p̂) exact / sampled | \
             overlap | warp evals per q | q / p̂ ns | best α (2nd moment ÷ α = 0's) |"
        );
        println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    }
    for name in names {
        let m = NeuralMaterialModel::load(&a.materials.join(format!("{name}_neural.nsb")))?;
        let bytes = io::read_blob(&a.blobs.join(format!("{name}_neural/reparam.nsb")))?;
        let e = exact_fit(
            &bytes,
            &m,
            a.conditions,
            a.seed,
            a.cells,
            (a.quadrature[0], a.quadrature[1]),
        )
        .with_context(|| name.clone())?;
        let blob = Blob::open(&bytes)?;
        let sampled: Fit = fit(
            &blob.sampler_as::<neusample::samplers::ReparamSampler<_>>()?,
            &m,
            a.conditions,
            32,
            a.seed,
        );
        let s = sampled.sampled.context("no sampled fit")?;
        let best = (0..ALPHA_GRID.len())
            .min_by(|&i, &j| e.alpha_second_moment[i].total_cmp(&e.alpha_second_moment[j]))
            .unwrap_or(0);
        if a.json {
            print_json(&serde_json::json!({"material": name, "exact": e, "sampled": s}))?;
        } else {
            println!(
                "| {name} | {:.4} | {:.4} / {:.4} | {:.3} / {:.3} | {:.3} | {:.3} / {:.3} | \
                 {:.3} / {:.3} | {:.4} | {:.0} | {:.0} / {:.0} | {} ({:.3}) |",
                e.mass,
                e.missed,
                e.missed_worst,
                e.chi2,
                e.chi2_worst,
                s.chi2,
                e.mis_kl,
                s.mis_kl,
                e.mis_chi2,
                s.mis_chi2,
                e.overlap,
                e.evaluations_per_query,
                e.query_ns,
                e.network_ns,
                ALPHA_GRID[best],
                e.alpha_second_moment[best]
            );
        }
    }
    Ok(())
}
