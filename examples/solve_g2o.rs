//! Read a g2o file, optimise it with Levenberg-Marquardt and write the result.
//! Without arguments it makes a synthetic Manhattan-world graph first.
//!
//! `cargo run --release --example solve_g2o -- INPUT.g2o OUTPUT.g2o`

use cairn::g2o::{ReadOptions, read_file, write_file};
use cairn::generate::{ManhattanOptions, manhattan};
use cairn::solvers::{Algorithm, SolverConfig, optimize};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = std::env::temp_dir();
    let input = match args.first() {
        Some(path) => PathBuf::from(path),
        None => {
            let path = dir.join("cairn-example-manhattan.g2o");
            write_file(
                &manhattan(&ManhattanOptions {
                    poses: 2000,
                    ..Default::default()
                })?,
                &path,
            )?;
            path
        }
    };
    let output = args
        .get(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| dir.join("cairn-example-solved.g2o"));

    let (mut graph, report) = read_file(&input, &ReadOptions::default())?;
    println!(
        "{}: {} vertices, {} edges, {} unknown lines",
        input.display(),
        graph.num_vertices(),
        graph.num_edges(),
        report.unknown_lines()
    );
    let config = SolverConfig {
        algorithm: Algorithm::LevenbergMarquardt,
        ..Default::default()
    };
    let summary = optimize(&mut graph, config)?;
    println!(
        "{:?} after {} iterations: χ² {:.4} → {:.4} in {:.3} s",
        summary.termination,
        summary.iterations,
        summary.initial_chi2,
        summary.final_chi2,
        summary.solve_time
    );
    write_file(&graph, &output)?;
    println!("wrote {}", output.display());
    Ok(())
}
