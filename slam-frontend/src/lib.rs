//! Formula Student cone SLAM on Cairn: what a car runs.
//!
//! - [`log`], [`files`], [`map`]: the interchange formats of `shared/fs/FORMAT.md`;
//! - [`frontend`]: the graph-SLAM front end; [`filter`]: EKF-SLAM and
//!   FastSLAM 1.0/2.0 beside it; [`estimator`]: one interface over all;
//! - [`motion`]: odometry integration and its noise;
//! - [`points`]: landmarks from point clouds (clustering, Arun alignment).
//!
//! The simulator, the track files, the evaluation and the importers of real
//! recordings are tools around it, in `cairn-fs-tools`.

pub mod color;
pub mod estimator;
pub mod files;
pub mod filter;
pub mod frontend;
pub mod log;
pub mod map;
pub mod motion;
pub mod points;
pub mod sighting;

pub use color::Color;
pub use map::Cone;
