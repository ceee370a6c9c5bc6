//! Simulates two laps of a random track (or a track file) and prints the
//! scores; the front end assumes the simulated preset's noise.
//!
//! `cargo run --release -p cairn-slam --example fs_quick -- [SEED] [METHOD] [TRACK_FILE] [PRESET]`

use cairn_fs_tools::Track;
use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::course::Course;
use cairn_fs_tools::sim::{SimConfig, simulate};
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::estimator::EstimatorKind;
use cairn_slam::frontend::association::AssociationMethod;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seed = args.first().and_then(|s| s.parse().ok()).unwrap_or(1);
    let method = args
        .get(1)
        .and_then(|m| AssociationMethod::by_name(m))
        .unwrap_or(AssociationMethod::Tracking);
    let (track, course) = match args.get(2) {
        Some(file) => {
            let track = Track::load(std::path::Path::new(file))?;
            let course = Course::from_track(&track)?;
            (track, course)
        }
        None => random_track(seed, &TrackRules::default()),
    };
    let preset = args
        .get(3)
        .and_then(|p| cairn_fs_tools::sim::Preset::by_name(p))
        .unwrap_or_else(cairn_fs_tools::sim::Preset::standard);
    let sim = simulate(
        &track,
        &course,
        &SimConfig {
            seed,
            preset: preset.clone(),
            ..SimConfig::default()
        },
    );
    let config = assumed_config(preset.name, method, EstimatorKind::Graph)?;
    let (slam, report) = cairn_fs_tools::run::run_and_score(&sim, config);
    println!(
        "{} ({:.0} m): closures {} mode {:?}\n{}",
        track.name,
        course.length(),
        slam.loop_closures(),
        slam.mode(),
        serde_json::to_string_pretty(&report)?
    );
    Ok(())
}
