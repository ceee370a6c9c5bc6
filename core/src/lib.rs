//! Cairn core: the Lie groups SE(2) and SE(3), variables, edges with g2o's
//! error conventions, and the factor graph that holds them.
//!
//! Conventions follow g2o so results can be compared with it: χ² = Σ eᵀΩe,
//! information matrices in the order of the error vector, SE2 updates additive
//! on (x, y, θ), SE3 updates right-multiplied by (t, qx, qy, qz).
//!
//! ```
//! use cairn_core::{EdgeSE2, Graph, SE2};
//! use nalgebra::Matrix3;
//!
//! let mut graph = Graph::new();
//! for (id, x) in [(0, 0.0), (1, 1.2), (2, 1.9)] {
//!     graph.add_vertex(id, SE2::new(x, 0.0, 0.0))?;
//! }
//! let step = EdgeSE2::new(SE2::new(1.0, 0.0, 0.0));
//! graph.add_edge(0, 1, step.clone(), Matrix3::identity())?;
//! graph.add_edge(1, 2, step, Matrix3::identity())?;
//! assert!((graph.chi2() - (0.04 + 0.09)).abs() < 1e-12); // errors 0.2 and −0.3
//! assert_eq!(graph.gauge_vertices(), vec![0]); // the lowest-id pose's id
//! # Ok::<(), cairn_core::GraphError>(())
//! ```

pub mod diagnostics;
pub mod disjoint;
pub mod edge;
pub mod edges;
pub mod factor;
pub mod graph;
pub mod information;
pub mod kernel;
pub mod layout;
pub mod se2;
pub mod se3;
pub mod topology;
pub mod values;
pub mod variable;

pub use disjoint::DisjointSets;
pub use edge::{
    BinaryEdge, Linearized, NormalBlocks, NumericBinaryEdge, NumericUnaryEdge, UnaryEdge,
};
pub use edges::{EdgePriorSE2, EdgeSE2, EdgeSE2XY, EdgeSE3, Se3Error};
pub use factor::FactorGroup;
pub use graph::{EdgeView, Graph, GraphError, VariableKind, VertexId, VertexView};
pub use information::{InformationIssue, PositiveDefinite};
pub use kernel::RobustKernel;
pub use nalgebra;
pub use se2::SE2;
pub use se3::SE3;
pub use topology::{Components, SpanningTreeReport};
pub use values::Values;
pub use variable::Variable;
