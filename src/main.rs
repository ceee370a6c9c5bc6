//! The `cairn` command-line tool.

mod cli;

use clap::Parser;
use std::process::ExitCode;

/// The status of a run ended by SIGINT or SIGTERM (128 + SIGINT, as shells report).
const INTERRUPTED: i32 = 130;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    // An interrupted write leaves its target as it was and no temporary file.
    // (Without the handler the process still ends: only the cleanup is lost.)
    let _ = ctrlc::set_handler(|| {
        cairn::g2o::remove_temporary_files();
        std::process::exit(INTERRUPTED);
    });
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", e.message);
            e.code()
        }
    }
}
