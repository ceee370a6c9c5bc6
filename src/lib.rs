//! Cairn: fast, g2o-compatible factor-graph optimisation in pure Rust.
//!
//! This facade re-exports the workspace's crates:
//! - [`core`]: SE2/SE3, variables, edges and the factor graph;
//! - [`solvers`]: Gauss-Newton and Levenberg-Marquardt over faer's sparse Cholesky;
//! - [`g2o`]: the g2o file format;
//! - [`slam`]: the cone-SLAM front end; [`fs_tools`]: importers of real recordings;
//! - [`generate`]: synthetic benchmark graphs.
//!
//! Features: `cli` (the default) builds the `cairn` command line and turns
//! on `plot` (pictures of tracks, maps and graphs: [`plot`], [`graph_plot`]),
//! which turns on `slam` ([`slam`] and [`fs_tools`]). A library that needs
//! only the solvers depends on `cairn` with `default-features = false`.
//!
//! ```
//! use cairn::g2o::{read_bytes, ReadOptions};
//! use cairn::solvers::{optimize, SolverConfig};
//!
//! let text = cairn::g2o::to_string(&cairn::generate::manhattan(&Default::default())?)?;
//! let (mut graph, _) = read_bytes(text.as_bytes(), &ReadOptions::default())?;
//! let summary = optimize(&mut graph, SolverConfig::default())?;
//! assert!(summary.final_chi2 < summary.initial_chi2);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub use cairn_core as core;
#[cfg(feature = "slam")]
pub use cairn_fs_tools as fs_tools;
pub use cairn_g2o as g2o;
#[cfg(feature = "slam")]
pub use cairn_slam as slam;
pub use cairn_solvers as solvers;

pub mod generate;
#[cfg(feature = "plot")]
pub mod graph_plot;
pub mod outliers;
#[cfg(feature = "plot")]
pub mod plot;
