//! Build a small 2D pose graph in code — a robot driving a square twice with
//! drifting odometry and one loop closure — and optimise it.
//!
//! `cargo run --release --example pose_graph_2d`

use cairn::core::{EdgeSE2, Graph, SE2};
use cairn::solvers::{Optimizer, SolverConfig};
use nalgebra::{Matrix3, Vector3};
use std::f64::consts::FRAC_PI_2;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut graph = Graph::new();
    // Odometry: 1 m forward, then a quarter turn at each corner of a 4 m square.
    let straight = SE2::new(1.0, 0.0, 0.0);
    let corner = SE2::new(1.0, 0.0, FRAC_PI_2);
    let information = Matrix3::from_diagonal(&Vector3::new(100.0, 100.0, 400.0));

    // Dead reckoning with a small heading bias gives the initial estimate.
    let bias = SE2::new(0.0, 0.0, 0.02);
    let mut pose = SE2::identity();
    graph.add_vertex(0, pose)?;
    for i in 1..=32 {
        let step = if i % 4 == 0 { corner } else { straight };
        pose = pose.compose(&step).compose(&bias);
        graph.add_vertex(i, pose)?;
        graph.add_edge(i - 1, i, EdgeSE2::new(step), information)?;
    }
    // After two laps the robot recognises its start: pose 32 coincides with pose 16 and 0.
    graph.add_edge(0, 16, EdgeSE2::new(SE2::identity()), information)?;
    graph.add_edge(16, 32, EdgeSE2::new(SE2::identity()), information)?;

    let mut optimizer = Optimizer::new(&graph, SolverConfig::default())?;
    let summary = optimizer.optimize_with(&mut graph, &mut |s| {
        println!("iteration {:2}: χ² = {:.6}", s.iteration, s.chi2);
    })?;
    let end: SE2 = graph.value(32)?;
    println!(
        "{:?}: χ² {:.3} → {:.3e}; pose 32 at ({:.4}, {:.4}, {:.4})",
        summary.termination, summary.initial_chi2, summary.final_chi2, end.t.x, end.t.y, end.theta
    );
    Ok(())
}
