//! `cairn completions` and `cairn man`: shell completions and man pages,
//! generated from the command-line definitions.

use super::{Cli, CliError};
use clap::{Args, CommandFactory};
use clap_complete::Shell;
use std::path::PathBuf;

/// Options of `cairn completions`.
#[derive(Debug, Args)]
pub struct CompletionsArgs {
    /// The shell to complete for.
    #[arg(value_enum)]
    shell: Shell,
}

/// Options of `cairn man`.
#[derive(Debug, Args)]
pub struct ManArgs {
    /// The folder to write `cairn.1` and a page per command
    /// (`cairn-solve.1`, …) into; it is created if missing.
    #[arg(short, long, default_value = "man")]
    out: PathBuf,
}

/// Prints the completion script on stdout.
pub fn completions(a: CompletionsArgs) -> Result<(), CliError> {
    let mut command = Cli::command();
    let mut script = Vec::new();
    clap_complete::generate(a.shell, &mut command, "cairn", &mut script);
    super::write_output(std::path::Path::new("-"), &script)
}

/// Writes the man pages.
pub fn man(a: ManArgs) -> Result<(), CliError> {
    std::fs::create_dir_all(&a.out)
        .map_err(|e| CliError::io(format!("{}: {e}", a.out.display())))?;
    let command = Cli::command();
    let mut pages = vec![("cairn".to_string(), command.clone())];
    for sub in command.get_subcommands() {
        let name = format!("cairn-{}", sub.get_name());
        pages.push((name.clone(), sub.clone().name(name)));
    }
    for (name, page) in pages {
        let mut text = Vec::new();
        clap_mangen::Man::new(page)
            .render(&mut text)
            .map_err(|e| CliError::io(e.to_string()))?;
        super::write_output(&a.out.join(format!("{name}.1")), &text)?;
    }
    eprintln!("wrote the man pages to {}", a.out.display());
    Ok(())
}
