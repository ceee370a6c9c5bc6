//! Tools around Cairn's cone-SLAM front end that a car does not run:
//! importers that turn real landmark-SLAM recordings into the log and
//! ground-truth files of `shared/fs/FORMAT.md`.
//!
//! - [`mrclam`]: the UTIAS Multi-Robot Cooperative Localization and Mapping
//!   dataset (range/bearing landmark detections, commanded velocities, Vicon
//!   ground truth).
//! - [`smoother`]: a batch smoother given the associations ([`batch`]: the
//!   run as one graph), the upper bound of what a front end can map from a log.

pub mod batch;
pub mod mrclam;
pub mod smoother;
