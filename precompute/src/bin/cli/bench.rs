//! `neusample bench`: arguments of the runtime cost benchmark.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use neusample::wavefront::Isa;
use neusample_precompute::jobs::bench::{self, BenchConfig};

use crate::output::print_json;

/// The runtime's cost per shading point: every sampler and the neural material, scalar and
/// batched, with the dense layers' throughput against the CPU's peak.
#[derive(Args)]
pub struct BenchArgs {
    /// A folder of sampler blobs (`<method>.nsb`) with its `conditions.txt`; default: the
    /// committed goat-leather fixtures.
    #[arg(long)]
    blobs: Option<PathBuf>,
    /// The neural material (`.nsb`); default: the committed goat leather.
    #[arg(long)]
    material: Option<PathBuf>,
    /// A measured material (RGL `.bsdf`) whose eval and own sampler are measured too;
    /// default: the committed mint (`fixtures/measured/chm_mint_rgb.bsdf`).
    #[arg(long)]
    measured: Option<PathBuf>,
    /// Fewer lanes and passes (a smoke run; noisier figures).
    #[arg(long)]
    quick: bool,
    /// Only these sampler methods, comma-separated (e.g. `flow,histogram-mixture`; a profile
    /// of one method): default every blob of the folder.
    #[arg(long, value_delimiter = ',')]
    methods: Vec<String>,
    /// Instead of the report, run only the batched hot path of `--methods` for this many
    /// seconds each (for a sampling profiler such as `perf record`); the method `material`
    /// is the neural material's batched eval, `measured` the measured material's batched
    /// eval, pdf and sample.
    #[arg(long, value_name = "SECONDS")]
    profile_seconds: Option<f64>,
    /// Run the dispatched figures with this instruction set (`x86-64-v3`, `x86-64-v4`,
    /// `aarch64-neon`, `portable`) instead of the best this CPU has, e.g. to compare AVX2
    /// with AVX-512 on one machine.
    #[arg(long, value_parser = parse_isa)]
    isa: Option<Isa>,
    /// Machine-readable output (`BenchReport` in `precompute/src/jobs/bench.rs`).
    #[arg(long)]
    json: bool,
}

impl From<&BenchArgs> for BenchConfig {
    fn from(a: &BenchArgs) -> Self {
        let mut c = Self::fixtures();
        if let Some(b) = &a.blobs {
            c.blobs = b.clone();
        }
        if let Some(m) = &a.material {
            c.material = m.clone();
        }
        if let Some(m) = &a.measured {
            c.measured = Some(m.clone());
        }
        c.methods.clone_from(&a.methods);
        c.isa = a.isa;
        if a.quick {
            c.lanes_per_pass = 1 << 11;
            c.passes = 3;
        }
        c
    }
}

/// Runs the benchmark and prints its report.
pub fn run(a: &BenchArgs) -> Result<()> {
    if let Some(secs) = a.profile_seconds {
        if !(secs > 0.0 && secs.is_finite()) {
            anyhow::bail!("--profile-seconds must be a positive number of seconds, not {secs}");
        }
        for (m, passes) in bench::profile(&a.into(), secs)? {
            println!("{m}: {passes} passes of batched prepare + sample + pdf at N = 64");
        }
        return Ok(());
    }
    let report = bench::run(&a.into())?;
    if a.json {
        print_json(&report)
    } else {
        print!("{}", bench::text(&report));
        Ok(())
    }
}

/// An instruction set by its [`Isa::name`].
fn parse_isa(s: &str) -> Result<Isa, String> {
    (Isa::ALL.into_iter().find(|i| i.name() == s)).ok_or_else(|| {
        let names: Vec<_> = Isa::ALL.iter().map(|i| i.name()).collect();
        format!(
            "unknown instruction set `{s}` (one of: {})",
            names.join(", ")
        )
    })
}
