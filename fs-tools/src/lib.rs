//! Tools around Cairn's cone-SLAM front end that a car does not run.
//!
//! - [`track`], [`trackgen`], [`course`]: ground-truth tracks (EUFS, AMZ
//!   fssim, EPFL), random rule-conforming tracks, and the centre line a car
//!   drives;
//! - [`sim`]: a seeded simulator writing the input log and its ground truth;
//!   [`configs`]: what the estimators assume about its presets;
//! - [`eval`], [`matching`], [`placement`], [`run`]: scoring a run against
//!   the truth, the map matched to it one-to-one (after its best rigid
//!   placement, where asked); [`oracle`]: the association a matcher could
//!   reach at best, knowing the true poses, cones and noise;
//! - [`mrclam`]: an importer of the UTIAS Multi-Robot Cooperative
//!   Localization and Mapping dataset (range/bearing landmark detections,
//!   commanded velocities, Vicon ground truth);
//! - [`smoother`]: a batch smoother given the associations ([`batch`]: the
//!   run as one graph), the upper bound of what a front end can map from a log.

pub mod batch;
pub mod configs;
pub mod course;
pub mod eval;
pub mod matching;
pub mod mrclam;
pub mod oracle;
pub mod placement;
pub mod run;
pub mod sim;
pub mod smoother;
pub mod track;
pub mod trackgen;

pub use track::{Track, TrackKind};
