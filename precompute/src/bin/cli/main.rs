//! The `neusample` command-line tool: materials → ground truth → training → baking →
//! evaluation. Every subcommand parses its arguments into the typed settings of the library
//! (`neusample_precompute::jobs`, `neusample_precompute::demo`) and prints what it returns.

mod bench;
mod defend;
mod demo;
mod inverse;
mod material;
mod measured;
mod output;
mod scene;
mod sky;
mod train;

use std::path::PathBuf;

use anyhow::Result;
use clap::{Parser, Subcommand};
use neusample_precompute::jobs::inspect::inspect;
use neusample_precompute::materials;
use output::print_json;

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(
    name = "neusample",
    version,
    about = "Learned importance sampling for neural materials: train, bake, inspect, evaluate."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the built-in materials.
    Materials {
        /// Machine-readable output.
        #[arg(long)]
        json: bool,
    },
    /// Train a sampler for a material and write its blob (verified against the model).
    Train(train::TrainArgs),
    /// Set a blob's defensive weight α (mix its sampler with cosine sampling), chosen by the
    /// render's second moment on a material or given.
    Defend(defend::DefendArgs),
    /// Describe a blob: kind, dimensions, tensors, checksum status.
    Inspect {
        /// The blob file.
        blob: PathBuf,
        /// Machine-readable output (schema in `docs/usage.md`).
        #[arg(long)]
        json: bool,
    },
    /// Convert a measured material of the RGL database (`.bsdf`) into a blob (kind
    /// `measured`), checked to open and to hold the file's tables bit for bit.
    MeasuredBlob(measured::MeasuredBlobArgs),
    /// Regenerate the committed fixture blobs (deterministic).
    Fixtures(demo::FixturesArgs),
    /// The main job: evaluate every method on the default materials (committed pretrained
    /// samplers, or --train), report with intervals.
    Demo(demo::DemoArgs),
    /// Table 2 and Table 1 over every built-in material under two lightings (the demo
    /// pipeline on each neural version, committed samplers), or over built-ins and material
    /// files mixed.
    Table(demo::TableArgs),
    /// Several neural materials in one scene (sky, MIS, global illumination): the baseline
    /// against the best sampler per material at equal time, with a reference.
    Scene(scene::SceneArgs),
    /// Fit a neural material (feature texture + decoder) to a material (NEURAL.md).
    TrainMaterial(material::TrainMaterialArgs),
    /// Import a neural material from safetensors (NEURAL.md).
    ImportMaterial(material::ImportMaterialArgs),
    /// Single-thread cost of a material's eval and features (Table 1 ratio).
    MaterialCost(material::MaterialCostArgs),
    /// The runtime's cost per shading point: every sampler and the neural material, scalar
    /// and batched, and the dense layers' throughput against the CPU's peak.
    Bench(bench::BenchArgs),
    /// The reparameterization sampler's exact sampling density (its warp inverted) against
    /// its own samples and its pdf network: missed integrand, exact χ², the MIS mismatch.
    ReparamExact(inverse::ReparamExactArgs),
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Materials { json } => list_materials(json),
        Command::Train(a) => train::run(&a),
        Command::Defend(a) => defend::run(&a),
        Command::Inspect { blob, json } => {
            let info = inspect(&blob)?;
            if json {
                print_json(&info)
            } else {
                print!("{}", info.text());
                Ok(())
            }
        }
        Command::MeasuredBlob(a) => measured::run(&a),
        Command::Fixtures(a) => demo::fixtures(&a),
        Command::Demo(a) => neusample_precompute::demo::run(&a.into()),
        Command::Table(a) => neusample_precompute::demo::table::run(&a.into()),
        Command::Scene(a) => neusample_precompute::demo::showcase::run(&a.into()),
        Command::TrainMaterial(a) => material::train_material(&a),
        Command::ImportMaterial(a) => material::import_material(&a),
        Command::MaterialCost(a) => material::material_cost(&a),
        Command::Bench(a) => bench::run(&a),
        Command::ReparamExact(a) => inverse::run(&a),
    }
}

fn list_materials(json: bool) -> Result<()> {
    let names = materials::builtin_names();
    if json {
        print_json(&names)?;
    } else {
        for n in names {
            println!("{n}");
        }
    }
    Ok(())
}
