//! Formula Student cone SLAM on Cairn.
//!
//! - [`track`], [`trackgen`], [`course`]: ground-truth tracks (EUFS, AMZ fssim,
//!   EPFL), random rule-conforming tracks, and the centre line a car drives;
//! - [`sim`]: a seeded simulator writing the input log and its ground truth;
//! - [`log`], [`files`]: the interchange formats of `shared/fs/FORMAT.md`;
//! - [`frontend`]: the graph-SLAM front end; [`filter`]: EKF-SLAM and
//!   FastSLAM 1.0/2.0 beside it; [`estimator`]: one interface over all;
//! - [`points`]: landmarks from point clouds (clustering, Arun alignment).

pub mod color;
pub mod course;
pub mod estimator;
pub mod eval;
pub mod files;
pub mod filter;
pub mod frontend;
pub mod log;
pub mod motion;
pub mod points;
pub mod run;
pub mod sighting;
pub mod sim;
pub mod track;
pub mod trackgen;

pub use color::Color;
pub use track::{Cone, Track, TrackKind};
