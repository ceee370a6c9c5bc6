//! Command-line definitions and dispatch.

mod check;
mod corrupt;
mod exit;
mod fs;
mod fs_eval;
mod fs_import;
mod fs_mismatch;
mod fs_report;
mod fs_targets;
mod generate;
mod linearize;
mod plot;
mod progress;
mod shell;
mod solve;
mod solve_output;
mod study;
mod study_sweeps;
mod trajectory;

use clap::{Parser, Subcommand};
pub use exit::{CliError, bad_input};

/// Cairn: fast, g2o-compatible pose-graph and factor-graph optimisation.
#[derive(Debug, Parser)]
#[command(name = "cairn", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Optimise a g2o file and write the result (g2o's `g2o -o OUT FILE`).
    Solve(solve::SolveArgs),
    /// The linear system of a g2o file (H, b, the whitened Jacobian) as Matrix
    /// Market files, and the Cholesky factor's fill under each ordering.
    Linearize(linearize::LinearizeArgs),
    /// Draw a g2o graph from above: poses, odometry, loop closures,
    /// landmarks, and optionally another estimate beneath (SVG or PNG).
    Plot(plot::PlotArgs),
    /// Report on a g2o file: largest χ² edges, χ² histogram, indefinite or badly
    /// scaled information matrices, connected components.
    Check(check::CheckArgs),
    /// Add random false loop closures (seeded) to test robust kernels.
    Corrupt(corrupt::CorruptArgs),
    /// Write a synthetic benchmark graph (Manhattan world or sphere) in g2o format.
    Generate(generate::GenerateArgs),
    /// Simulate a Formula Student run: cone detections and odometry along a track.
    ///
    /// Cones a track file lists closer than 0.2 m apart would overlap; the
    /// detector reports the first of them only (the truth map keeps both).
    FsSim(fs::SimArgs),
    /// Cone SLAM on a log: map, trajectory and associations.
    FsSlam(fs::SlamArgs),
    /// Score a cone-SLAM run against the simulation's truth.
    FsEval(fs_eval::EvalArgs),
    /// Import a real recording as a log and its ground truth (FORMAT.md).
    FsImport(fs_import::ImportArgs),
    /// Smooth a log in one batch given every detection's landmark (the
    /// barcodes of an imported recording): the upper bound of a front end.
    FsSmooth(fs_import::SmoothArgs),
    /// Simulate, map and score every shared and some random tracks into a report.
    FsReport(fs_report::ReportArgs),
    /// Map logs that differ from what the estimator assumes (noise, heavy
    /// tails, a drifting gyro, no start line, the realistic preset) into a report.
    FsMismatch(fs_mismatch::MismatchArgs),
    /// Compare the estimators (graph, EKF-SLAM, FastSLAM 1.0/2.0) on simulated
    /// runs into docs/estimators.md with plots.
    FsStudy(study::StudyArgs),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell).
    Completions(shell::CompletionsArgs),
    /// Write man pages for cairn and each of its commands.
    Man(shell::ManArgs),
}

/// Runs the parsed command.
pub fn run(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Solve(args) => solve::run(args),
        Command::Generate(args) => generate::run(args),
        Command::Check(args) => check::run(args),
        Command::Plot(args) => plot::run(args),
        Command::Linearize(args) => linearize::run(args),
        Command::Corrupt(args) => corrupt::run(args),
        Command::FsSim(args) => fs::run_sim(args),
        Command::FsSlam(args) => fs::run_slam(args),
        Command::FsEval(args) => fs_eval::run_eval(args),
        Command::FsImport(args) => fs_import::run(args),
        Command::FsSmooth(args) => fs_import::run_smooth(args),
        Command::FsReport(args) => fs_report::run(args),
        Command::FsMismatch(args) => fs_mismatch::run(args),
        Command::FsStudy(args) => study::run(args),
        Command::Completions(args) => shell::completions(args),
        Command::Man(args) => shell::man(args),
    }
}

/// The last part of `path` (the whole path if it has none), for titles.
pub fn file_name(path: &std::path::Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// The bytes of `path`, or of stdin for `-`.
pub fn read_input(path: &std::path::Path) -> Result<Vec<u8>, CliError> {
    if path.as_os_str() == "-" {
        use std::io::Read;
        let mut bytes = Vec::new();
        std::io::stdin()
            .read_to_end(&mut bytes)
            .map_err(|e| CliError::io(format!("stdin: {e}")))?;
        return Ok(bytes);
    }
    std::fs::read(path).map_err(|e| CliError::io(format!("{}: {e}", path.display())))
}

/// Fails early, before a long computation, when `path` cannot be written:
/// its folder does not exist.
pub fn check_writable(path: &std::path::Path) -> Result<(), CliError> {
    if path.as_os_str() == "-" {
        return Ok(());
    }
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() && !dir.is_dir() => Err(CliError::io(format!(
            "{}: the folder {} does not exist",
            path.display(),
            dir.display()
        ))),
        _ => Ok(()),
    }
}

/// Writes `bytes` to `path` atomically, or to stdout for `-`.
pub fn write_output(path: &std::path::Path, bytes: &[u8]) -> Result<(), CliError> {
    if path.as_os_str() == "-" {
        use std::io::Write;
        let mut out = std::io::stdout().lock();
        return match out.write_all(bytes).and_then(|_| out.flush()) {
            // The reader has all it wanted (`| head`): not a failure.
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
            result => result.map_err(|e| CliError::io(format!("stdout: {e}"))),
        };
    }
    cairn::g2o::write_atomically(path, bytes).map_err(|e| CliError::io(e.to_string()))
}
