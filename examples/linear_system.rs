//! The linear system of a small pose graph with landmarks: H printed as its
//! sparsity pattern, with the vertex of every column, and the whitened
//! Jacobian's size. `cargo run --example linear_system`
//!
//! `Optimizer::linear_system` gives H (upper triangle), b and the whitened
//! Jacobian J as `sprs` matrices at the graph's current values, over the
//! free vertices in the optimiser's column order (its fill-reducing
//! ordering); `cairn linearize FILE.g2o` writes them as Matrix Market files.

use cairn::core::{EdgeSE2, EdgeSE2XY, Graph, SE2};
use cairn::solvers::{Optimizer, SolverConfig};
use nalgebra::{Matrix2, Matrix3, Vector2};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // Four poses along a line, each seeing one of two landmarks.
    let mut graph = Graph::new();
    for i in 0..4 {
        graph.add_vertex(i, SE2::new(i as f64, 0.0, 0.0))?;
    }
    for i in 0..3 {
        graph.add_edge(
            i,
            i + 1,
            EdgeSE2::new(SE2::new(1.0, 0.0, 0.0)),
            Matrix3::identity(),
        )?;
    }
    graph.add_vertex(10, Vector2::new(1.5, 1.0))?;
    graph.add_vertex(11, Vector2::new(2.5, -1.0))?;
    for (pose, landmark) in [(0, 10), (1, 10), (2, 11), (3, 11)] {
        let z = Vector2::new(1.5 + 1.0 * (landmark - 10) as f64 - pose as f64, 1.0);
        graph.add_edge(pose, landmark, EdgeSE2XY::new(z), Matrix2::identity() * 4.0)?;
    }
    let system = Optimizer::new(&graph, SolverConfig::default())?.linear_system(&graph)?;
    let h = system.hessian_full();
    let n = h.cols();
    println!("H: {n}×{n}, the first pose held as the gauge; columns:");
    for (c, (id, k)) in system.columns.iter().enumerate() {
        print!("{c}:{id}.{k} ");
    }
    println!();
    for r in 0..n {
        let row: String = (0..n)
            .map(|c| if h.get(r, c).is_some() { '#' } else { '.' })
            .collect();
        println!("{row}");
    }
    println!(
        "J: {}×{} with {} entries; b has {} rows; χ² {:.3}",
        system.jacobian.rows(),
        system.jacobian.cols(),
        system.jacobian.nnz(),
        system.rhs.len(),
        system.chi2
    );
    Ok(())
}
