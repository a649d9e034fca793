//! `neusample measured-blob`: an RGL measured material as a blob.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use neusample_precompute::jobs::measured::{measured_blob, MeasuredBlobJob};

use crate::output::print_json;

/// Options of `neusample measured-blob`.
#[derive(Args, Clone, Debug)]
pub struct MeasuredBlobArgs {
    /// The RGL `.bsdf` file (Mitsuba's `measured` format, RGB).
    input: PathBuf,
    /// Where to write the blob (default: the input with the extension `.nsb`).
    #[arg(short, long)]
    out: Option<PathBuf>,
    /// The label's `name=` field (default: the input's file stem).
    #[arg(long)]
    name: Option<String>,
    /// Print what was written as JSON.
    #[arg(long)]
    json: bool,
}

impl From<&MeasuredBlobArgs> for MeasuredBlobJob {
    fn from(a: &MeasuredBlobArgs) -> Self {
        MeasuredBlobJob {
            input: a.input.clone(),
            out: a
                .out
                .clone()
                .unwrap_or_else(|| a.input.with_extension("nsb")),
            name: a.name.clone(),
        }
    }
}

pub fn run(a: &MeasuredBlobArgs) -> Result<()> {
    let r = measured_blob(&a.into())?;
    if a.json {
        return print_json(&r);
    }
    println!(
        "{} → {} ({} bytes): measured material, {}×{} incident nodes, jacobian {}",
        r.input,
        r.out,
        r.bytes,
        r.shape[0],
        r.shape[1],
        if r.shape[10] == 1 { "yes" } else { "no" }
    );
    println!("  label: {}", r.label);
    Ok(())
}
