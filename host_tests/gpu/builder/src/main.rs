//! Builds `../shader` to one SPIR-V module with rust-gpu (spirv-builder 0.11, installed
//! SPIRV-Tools) and copies it to the path given as the first argument. An optional second
//! argument names another shader crate (for experiments).
//!
//! Run through `cargo run` (cargo puts `librustc_codegen_spirv.so` on the library path) with
//! the toolchain pinned in `../rust-toolchain.toml`.

use std::path::PathBuf;
use std::time::Instant;

use spirv_builder::{ModuleResult, SpirvBuilder, SpirvMetadata};

fn main() {
    let out = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("neusample-gpu.spv"));
    let shader = std::env::args_os()
        .nth(2)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shader"));
    let t = Instant::now();
    let result = SpirvBuilder::new(&shader, "spirv-unknown-vulkan1.2")
        .release(true)
        .deny_warnings(false)
        .spirv_metadata(SpirvMetadata::None)
        .build();
    let result = match result {
        Ok(r) => r,
        Err(e) => {
            eprintln!("shader build failed: {e}");
            std::process::exit(1);
        }
    };
    let module = match &result.module {
        ModuleResult::SingleModule(p) => p.clone(),
        ModuleResult::MultiModule(_) => {
            eprintln!("unexpected multi-module output");
            std::process::exit(1);
        }
    };
    if let Err(e) = std::fs::copy(&module, &out) {
        eprintln!("copying {} to {}: {e}", module.display(), out.display());
        std::process::exit(1);
    }
    let size = std::fs::metadata(&out).map(|m| m.len()).unwrap_or(0);
    println!(
        "shader built in {:.1} s: {} ({} bytes), entry points: {}",
        t.elapsed().as_secs_f64(),
        out.display(),
        size,
        result.entry_points.join(", ")
    );
}
