//! Helpers shared by the front end's integration tests.
#![allow(dead_code)]

pub mod shared;

use cairn_fs_tools::course::Course;
use cairn_fs_tools::sim::{SimConfig, Simulation, simulate};
use cairn_fs_tools::track::Track;

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
