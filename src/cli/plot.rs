//! `cairn plot`: a picture of a g2o graph from above.

use super::fs_eval::check_plot_format;
use super::{CliError, bad_input, file_name};
use cairn::graph_plot::{draw_graph, picture};
use clap::Args;
use std::path::{Path, PathBuf};

/// Options of `cairn plot`.
#[derive(Debug, Args)]
pub struct PlotArgs {
    /// The g2o file to draw (`-` for stdin).
    file: PathBuf,
    /// A second estimate of the same graph (the file before solving, say),
    /// drawn in grey beneath it.
    #[arg(long, value_name = "OTHER.g2o")]
    compare: Option<PathBuf>,
    /// The picture: FILE.svg or FILE.png.
    #[arg(short, long)]
    out: PathBuf,
    /// The title (default: the file's name).
    #[arg(long)]
    title: Option<String>,
}

fn read(path: &Path) -> Result<cairn::core::Graph, CliError> {
    let bytes = super::read_input(path)?;
    let (graph, _) =
        cairn::g2o::read_bytes(&bytes, &Default::default()).map_err(bad_input(path.display()))?;
    Ok(graph)
}

/// Draws the graph.
pub fn run(a: PlotArgs) -> Result<(), CliError> {
    check_plot_format(&a.out)?;
    super::check_writable(&a.out)?;
    let main = picture(&read(&a.file)?);
    let beneath = match &a.compare {
        Some(path) => Some((picture(&read(path)?), file_name(path))),
        None => None,
    };
    let title = a.title.clone().unwrap_or_else(|| file_name(&a.file));
    // Drawn beside the target, then moved over it, as every output.
    let tmp = a.out.with_file_name(format!(
        ".{}.{}.plot.{}",
        a.out
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        std::process::id(),
        a.out.extension().and_then(|e| e.to_str()).unwrap_or("svg")
    ));
    let drawn = draw_graph(
        &title,
        &main,
        beneath.as_ref().map(|(p, l)| (p, l.as_str())),
        &tmp,
    );
    let result = drawn.map_err(CliError::io).and_then(|()| {
        let bytes =
            std::fs::read(&tmp).map_err(|e| CliError::io(format!("{}: {e}", tmp.display())))?;
        super::write_output(&a.out, &bytes)
    });
    let _ = std::fs::remove_file(&tmp);
    result
}
