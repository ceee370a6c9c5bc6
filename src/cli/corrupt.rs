//! `cairn corrupt`: add random false loop closures to a g2o file.

use super::{CliError, bad_input};
use cairn::g2o::ReadOptions;
use cairn::outliers::add_false_loop_closures;
use clap::Args;
use std::path::PathBuf;

/// Options of `cairn corrupt`.
#[derive(Debug, Args)]
pub struct CorruptArgs {
    /// Input g2o file (`-` for stdin).
    file: PathBuf,
    /// Output g2o file (`-` for stdout).
    #[arg(short, long, default_value = "-")]
    output: PathBuf,
    /// False loop closures to add, as a fraction of the file's edges (0 to 10).
    #[arg(long, default_value_t = 0.1)]
    fraction: f64,
    /// Their translations are uniform in ±SPREAD metres per axis (above 0, at
    /// most 10⁶).
    #[arg(long, default_value_t = 10.0)]
    spread: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

pub fn run(a: CorruptArgs) -> Result<(), super::CliError> {
    if !(0.0..=10.0).contains(&a.fraction) {
        return Err(CliError::usage(format!(
            "--fraction must be from 0 to 10, got {}",
            a.fraction
        )));
    }
    if !(a.spread > 0.0 && a.spread <= 1e6) {
        return Err(CliError::usage(format!(
            "--spread must be above 0 and at most 1e6 m, got {:e}",
            a.spread
        )));
    }
    let name = a.file.display().to_string();
    let bytes = super::read_input(&a.file)?;
    let (mut graph, _) =
        cairn::g2o::read_bytes(&bytes, &ReadOptions::default()).map_err(bad_input(&name))?;
    let added = add_false_loop_closures(&mut graph, a.fraction, a.spread, a.seed)
        .map_err(|e| e.to_string())?;
    let text = cairn::g2o::to_string(&graph).map_err(|e| e.to_string())?;
    super::write_output(&a.output, text.as_bytes())?;
    eprintln!(
        "{name}: added {} false loop closures (edges #{}…)",
        added.len(),
        added.first().copied().unwrap_or(0)
    );
    Ok(())
}
