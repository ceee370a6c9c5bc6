//! Helpers shared by the front end's integration tests.
#![allow(dead_code)]

pub mod shared;

use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::course::Course;
use cairn_fs_tools::sim::{SimConfig, Simulation, simulate};
use cairn_fs_tools::track::Track;
use cairn_slam::estimator::EstimatorKind;
use cairn_slam::frontend::FrontEndConfig;
use cairn_slam::frontend::association::AssociationMethod;

/// A run of the default simulation (two laps, `standard`) of `track` with
/// noise `seed`.
pub fn simulate_seed(track: &Track, course: &Course, seed: u64) -> Simulation {
    simulate(
        track,
        course,
        &SimConfig {
            seed,
            ..SimConfig::default()
        },
    )
}

/// The shared track file `file` (under `../shared/tracks`) and its course;
/// `None` (the test skips) without `../shared`.
pub fn shared_track(file: &str) -> Option<(Track, Course)> {
    let path = shared::shared_path(&format!("tracks/{file}"))?;
    let track = Track::load(&path).expect("the shared track reads");
    let course = Course::from_track(&track).expect("a closed course");
    Some((track, course))
}

/// What the graph front end is told of a `standard` log: the shipped
/// `configs/standard.toml`, maximum-likelihood association.
pub fn standard_graph_config() -> FrontEndConfig {
    assumed_config(
        "standard",
        AssociationMethod::MaximumLikelihood,
        EstimatorKind::Graph,
    )
    .expect("the preset has a shipped config")
}
