//! How FastSLAM closes its first lap: where place recognition puts the car
//! among the start area's landmarks, and its path and map smoothed there.

mod common;

use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::eval::Report;
use cairn_fs_tools::run::score as score_sim;
use cairn_fs_tools::sim::{SimConfig, Simulation, simulate};
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::estimator::{Estimator, EstimatorKind};
use cairn_slam::filter::fastslam::{FastSlam, ParticleConfig, Version};
use cairn_slam::frontend::association::AssociationMethod;

/// FastSLAM 2.0 with 30 particles, told `configs/standard.toml` (ML), on
/// `sim`, smoothing or not; the run's report.
fn fastslam2(sim: &Simulation, smooth: bool) -> (FastSlam, Report) {
    let config = assumed_config(
        "standard",
        AssociationMethod::MaximumLikelihood,
        EstimatorKind::FastSlam2,
    )
    .unwrap();
    let settings = ParticleConfig {
        particles: 30,
        smooth,
        ..ParticleConfig::new(Version::Two)
    };
    let mut slam = FastSlam::new(config, settings);
    for r in &sim.log {
        slam.process(r);
    }
    Estimator::finish(&mut slam).unwrap();
    let report = score_sim(sim, &slam);
    (slam, report)
}

#[test]
fn fastslam_smooths_the_lap_it_closes() {
    // After a lap every particle descends from one ancestor, so no
    // particle's map has undone the lap's drift; resampling can only choose
    // among them. Smoothing the chosen particle's path and map (its own
    // odometry, sightings and associations, the gyro's bias beside the
    // poses) at the closure and at the end must remove it.
    let (track, course) = random_track(3, &TrackRules::default());
    let sim = simulate(&track, &course, &SimConfig::default());
    let reports = [false, true].map(|smooth| {
        let (slam, report) = fastslam2(&sim, smooth);
        assert_eq!(slam.loop_closures(), 1, "smoothing {smooth}");
        println!("smoothing {smooth}: {report:?}");
        report
    });
    let [drifted, smoothed] = reports;
    assert!(smoothed.map_rmse < 0.15, "{smoothed:?}");
    assert!(smoothed.map_rmse_aligned < 0.06, "{smoothed:?}");
    assert!(
        smoothed.map_rmse < 0.5 * drifted.map_rmse,
        "{} against {} unsmoothed",
        smoothed.map_rmse,
        drifted.map_rmse
    );
    assert_eq!(smoothed.phantom, 0, "{smoothed:?}");
    assert!(smoothed.association_accuracy > 0.98, "{smoothed:?}");
}

#[test]
fn fastslam_closes_its_lap_where_the_start_area_is_not_one_cone_off() {
    // FastSLAM 2.0 on epfl_fsds_competition_1_cones (`standard` seed 0, 30
    // particles) ends its first lap 2.2 m off along the track. Its gates
    // matched four start-area cones one cone off and closed the loop there:
    // 50.9% association, ATE 12 m. Left out of the gates until place
    // recognition finds the start area (scan after scan), it closes right.
    // This is the log the change was made on: a regression guard.
    let Some((track, course)) = common::shared_track("epfl_fsds_competition_1_cones.csv") else {
        return;
    };
    let sim = simulate(&track, &course, &SimConfig::default());
    let (slam, report) = fastslam2(&sim, true);
    assert_eq!(slam.loop_closures(), 1);
    println!("{report:?}");
    assert!(report.association_accuracy > 0.98, "{report:?}");
    assert_eq!(report.phantom, 0, "{report:?}");
    assert!(report.map_rmse_aligned < 0.06, "{report:?}");
    assert!(report.ate < 0.5, "{report:?}");
}
