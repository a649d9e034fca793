//! What the subcommands print.

use anyhow::Result;
use serde::Serialize;

/// `value` as pretty JSON on stdout.
pub fn print_json(value: &impl Serialize) -> Result<()> {
    println!("{}", serde_json::to_string_pretty(value)?);
    Ok(())
}
