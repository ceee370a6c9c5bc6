//! Cairn solvers: Gauss-Newton and Levenberg-Marquardt with g2o's semantics
//! over a sparse Cholesky from faer.
//!
//! The Hessian's block pattern and the symbolic factorisation are computed once
//! per graph ([`Optimizer::new`]); every iteration linearises the edges in
//! parallel into preallocated slots, sums them into the fixed pattern and
//! refactorises numerically into reused buffers. A failed factorisation raises
//! λ in LM and ends GN with [`Termination::NotPositiveDefinite`].
//!
//! ```
//! use cairn_core::{EdgePriorSE2, EdgeSE2, Graph, SE2};
//! use cairn_solvers::{optimize, SolverConfig, Termination};
//! use nalgebra::Matrix3;
//!
//! let mut graph = Graph::new();
//! graph.add_vertex(0, SE2::new(0.3, -0.2, 0.1))?;
//! graph.add_vertex(1, SE2::new(0.0, 0.0, 0.0))?;
//! graph.add_unary_edge(0, EdgePriorSE2::new(SE2::identity()), Matrix3::identity() * 100.0)?;
//! graph.add_edge(0, 1, EdgeSE2::new(SE2::new(2.0, 0.0, 0.0)), Matrix3::identity())?;
//! let summary = optimize(&mut graph, SolverConfig::default())?;
//! assert!(summary.termination.converged());
//! assert!(summary.gauge.is_empty()); // the prior already fixes the gauge
//! let x1: SE2 = graph.value(1)?;
//! assert!((x1.t.x - 2.0).abs() < 1e-6);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod assembly;
pub mod chordal;
pub mod config;
pub mod hessian_layout;
pub mod initialization;
pub mod linear;
pub mod linear_system;
pub mod marginals;
pub mod optimizer;
mod selected_inverse;
mod simplicial;
pub mod structure;
mod supernodal;
#[cfg(test)]
mod test_matrices;

pub use chordal::{ChordalReport, ChordalWeights, chordal_initialize, chordal_initialize_with};
pub use config::{
    AUTO_TRUSTED_ITERATIONS, Algorithm, Damping, DoglegConfig, Gauge, Initialization,
    IterationStats, LevenbergMarquardtConfig, PhaseTimes, SolverConfig, Summary, Termination,
};
pub use hessian_layout::HessianLayout;
pub use initialization::{optimize, spanning_tree_initialize};
pub use linear::{
    Factorization, LinearSolverConfig, NotPositiveDefinite, Ordering, SparseCholesky,
};
pub use linear_system::LinearSystem;
pub use optimizer::Optimizer;
pub use structure::HessianStructure;

/// Why an optimisation could not run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// Vertices or edges were added after the optimizer was built.
    #[error("the graph changed since the optimizer was built; build a new one")]
    GraphChanged,
    /// χ² is NaN or infinite at the initial estimate.
    #[error(
        "χ² is not finite at the initial estimate: {name} edge #{edge} on vertices {vertices:?}"
    )]
    NonFiniteChi2 {
        /// Edge number (insertion order).
        edge: usize,
        /// Edge type.
        name: &'static str,
        /// Its vertex ids.
        vertices: Vec<i64>,
    },
    /// faer's symbolic analysis failed.
    #[error("symbolic analysis of the Hessian failed: {0}")]
    Analysis(String),
    /// No memory for the factorisation's workspace.
    #[error("not enough memory for the factorisation")]
    OutOfMemory,
    /// An id that names no vertex.
    #[error("vertex {0} is not in the graph")]
    UnknownVertex(i64),
    /// A marginal was asked of a fixed vertex (a FIX vertex or the gauge).
    #[error("vertex {0} is fixed, so it has no marginal covariance")]
    FixedVertex(i64),
    /// H is not positive definite at the current estimate.
    #[error("the Hessian is not positive definite at the current estimate (pivot {0})")]
    NotPositiveDefinite(usize),
    /// Every vertex is fixed.
    #[error("every vertex is fixed: there is no system to solve")]
    NothingToSolve,
    /// More entries than 32-bit indices address.
    #[error("the problem is too large: {entries} entries exceed the 32-bit index range")]
    TooLarge {
        /// Entries needed.
        entries: usize,
    },
}
