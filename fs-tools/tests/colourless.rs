//! Colour is optional: a log whose every detection is `unknown` (a lidar
//! or a barcode camera gives no colour) maps like its coloured twin, with
//! every estimator.

mod common;

use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::eval::Report;
use cairn_fs_tools::run::run_estimator;
use cairn_fs_tools::sim::Simulation;
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::Color;
use cairn_slam::estimator::{EstimatorBuilder, EstimatorKind};
use cairn_slam::frontend::association::AssociationMethod;
use cairn_slam::log::Record;
use common::simulate_seed;

/// The log with every detection's colour `unknown`.
fn colourless(sim: &Simulation) -> Simulation {
    let mut sim = sim.clone();
    for record in &mut sim.log {
        if let Record::Cones { cones, .. } = record {
            for d in cones {
                d.color = Color::Unknown;
            }
        }
    }
    sim
}

/// The particle filters run 30 particles, as docs/estimators.md's do.
fn run(sim: &Simulation, kind: EstimatorKind) -> Report {
    let config = assumed_config("standard", AssociationMethod::MaximumLikelihood, kind)
        .expect("the preset has a shipped config");
    let mut builder = EstimatorBuilder::new(kind, config);
    builder.particles = 30;
    run_estimator(sim, &builder).1
}

#[test]
fn an_all_unknown_log_maps_like_its_coloured_twin() {
    for (track_seed, seed) in [(3, 11), (4, 12)] {
        let (track, course) = random_track(track_seed, &TrackRules::default());
        let sim = simulate_seed(&track, &course, seed);
        let plain = colourless(&sim);
        // FastSLAM 2.0 once closed random-4 seed 12's loop without colour
        // with 6 of 8 sampler seeds; since its first-lap closure is
        // confirmed over several scans, with 8 of 8 (30 particles).
        for kind in [
            EstimatorKind::Graph,
            EstimatorKind::Ekf,
            EstimatorKind::FastSlam1,
            EstimatorKind::FastSlam2,
        ] {
            let coloured = run(&sim, kind);
            let unknown = run(&plain, kind);
            let what = format!("random-{track_seed} seed {seed} {}", kind.name());
            eprintln!(
                "{what}: coloured {} landmarks, {:.3} m, {:.2}%, {} phantom; unknown {} landmarks, {:.3} m, {:.2}%, {} phantom",
                coloured.landmarks,
                coloured.map_rmse,
                100.0 * coloured.association_accuracy,
                coloured.phantom,
                unknown.landmarks,
                unknown.map_rmse,
                100.0 * unknown.association_accuracy,
                unknown.phantom,
            );
            assert!(unknown.missed <= coloured.missed, "{what}: {unknown:?}");
            assert!(
                unknown.phantom <= coloured.phantom + 1,
                "{what}: {unknown:?}"
            );
            assert!(
                unknown.landmarks >= coloured.landmarks.saturating_sub(2),
                "{what}: {unknown:?}"
            );
            assert!(
                unknown.map_rmse <= coloured.map_rmse * 1.25 + 0.01,
                "{what}: {unknown:?} vs {coloured:?}"
            );
            // Colour is evidence, but these match as well without it.
            let loss = 0.01;
            assert!(
                unknown.association_accuracy >= coloured.association_accuracy - loss,
                "{what}: {unknown:?} vs {coloured:?}"
            );
        }
    }
}
