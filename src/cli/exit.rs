//! A failed command's message and the exit status that tells scripts why
//! (README, "Exit codes").

use std::fmt::Display;
use std::process::ExitCode;

/// Why a command failed; each is a distinct exit status.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exit {
    /// 1: the computation itself failed (a solver error, say) on valid input.
    Failed = 1,
    /// 2: the command line is wrong: an unknown option, a missing value, a
    /// value out of range or options that do not go together (clap's code).
    Usage = 2,
    /// 3: an input file is malformed or holds values out of range.
    Input = 3,
    /// 4: a file could not be read or written.
    Io = 4,
    /// 5: under `--strict`, the solve did not converge (its result was
    /// written, as without `--strict`).
    NotConverged = 5,
}

/// A failed command: what to print and how to exit.
#[derive(Debug)]
pub struct CliError {
    /// The exit status.
    pub exit: Exit,
    /// The message after `error: `.
    pub message: String,
}

impl CliError {
    fn new(exit: Exit, message: impl Into<String>) -> Self {
        Self {
            exit,
            message: message.into(),
        }
    }
    /// A bad command line.
    pub fn usage(message: impl Into<String>) -> Self {
        Self::new(Exit::Usage, message)
    }
    /// A bad input file.
    pub fn input(message: impl Into<String>) -> Self {
        Self::new(Exit::Input, message)
    }
    /// A file that could not be read or written.
    pub fn io(message: impl Into<String>) -> Self {
        Self::new(Exit::Io, message)
    }
    /// A solve that did not converge, under `--strict`.
    pub fn not_converged(message: impl Into<String>) -> Self {
        Self::new(Exit::NotConverged, message)
    }
    /// The process's exit status.
    pub fn code(&self) -> ExitCode {
        ExitCode::from(self.exit as u8)
    }
}

/// `.map_err(bad_input(name))`: an input file's parse error, named.
pub fn bad_input<E: Display>(name: impl Display) -> impl FnOnce(E) -> CliError {
    move |e| CliError::input(format!("{name}: {e}"))
}

/// Any other failure is a failed computation.
impl From<String> for CliError {
    fn from(message: String) -> Self {
        Self::new(Exit::Failed, message)
    }
}

impl From<&str> for CliError {
    fn from(message: &str) -> Self {
        Self::new(Exit::Failed, message)
    }
}
