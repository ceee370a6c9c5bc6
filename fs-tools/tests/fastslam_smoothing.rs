//! FastSLAM's smoothing of the lap it closes, against the same filter
//! without it.

use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::run::score as score_sim;
use cairn_fs_tools::sim::{SimConfig, simulate};
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::estimator::{Estimator, EstimatorKind};
use cairn_slam::filter::fastslam::{FastSlam, ParticleConfig, Version};
use cairn_slam::frontend::association::AssociationMethod;

#[test]
fn fastslam_smooths_the_lap_it_closes() {
    // After a lap every particle descends from one ancestor, so no
    // particle's map has undone the lap's drift; resampling can only choose
    // among them. Smoothing the chosen particle's path and map (its own
    // odometry, sightings and associations, the gyro's bias beside the
    // poses) at the closure and at the end must remove it.
    let (track, course) = random_track(3, &TrackRules::default());
    let sim = simulate(&track, &course, &SimConfig::default());
    let config = assumed_config(
        "standard",
        AssociationMethod::MaximumLikelihood,
        EstimatorKind::FastSlam2,
    )
    .unwrap();
    let reports = [false, true].map(|smooth| {
        let settings = ParticleConfig {
            particles: 30,
            smooth,
            ..ParticleConfig::new(Version::Two)
        };
        let mut slam = FastSlam::new(config.clone(), settings);
        for r in &sim.log {
            slam.process(r);
        }
        Estimator::finish(&mut slam).unwrap();
        assert_eq!(slam.loop_closures(), 1, "smoothing {smooth}");
        let report = score_sim(&sim, &slam);
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
