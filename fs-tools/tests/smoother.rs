//! The batch smoother given the associations, on simulated runs whose truth
//! is known exactly.

use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::eval::evaluate;
use cairn_fs_tools::sim::{Preset, SimConfig, simulate};
use cairn_fs_tools::smoother::{SmoothError, smooth};
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::estimator::EstimatorKind;
use cairn_slam::files::Association;
use cairn_slam::frontend::FrontEndConfig;
use cairn_slam::frontend::association::AssociationMethod;

#[test]
fn the_true_associations_give_the_map_to_centimetres() {
    let (track, course) = random_track(2, &TrackRules::default());
    let preset = Preset::standard();
    let config = assumed_config(
        preset.name,
        AssociationMethod::MaximumLikelihood,
        EstimatorKind::Graph,
    )
    .expect("the preset has a shipped config");
    for seed in [1, 2] {
        let sim = simulate(
            &track,
            &course,
            &SimConfig {
                seed,
                ..SimConfig::default()
            },
        );
        let smoothed = smooth(&sim.log, &sim.truth_associations, &config).expect("solves");
        let report = evaluate(
            &sim.truth_map,
            &smoothed.map,
            &sim.truth,
            &smoothed.trajectory,
            &sim.truth_associations,
            &smoothed.associations,
        );
        // Every detected cone is a landmark, none is a phantom, and the
        // map's shape is right to centimetres (seed 1: 0.032 m aligned). It
        // has no yaw-rate bias state, which the front end estimates, so the
        // simulated gyro bias turns it about the start (0.15 m unaligned).
        assert_eq!(report.phantom, 0, "seed {seed}: {report:?}");
        assert_eq!(report.missed, 0, "seed {seed}: {report:?}");
        assert!(report.map_rmse_aligned < 0.05, "seed {seed}: {report:?}");
        assert!(report.map_rmse < 0.25, "seed {seed}: {report:?}");
        assert!(
            report.association_accuracy > 0.9999,
            "seed {seed}: {report:?}"
        );
        assert!(smoothed.summary.final_chi2 < smoothed.summary.initial_chi2);
    }
}

#[test]
fn an_association_outside_the_log_is_refused() {
    let (track, course) = random_track(2, &TrackRules::default());
    let sim = simulate(
        &track,
        &course,
        &SimConfig {
            laps: 0.2,
            ..SimConfig::default()
        },
    );
    let mut associations = sim.truth_associations.clone();
    associations.push(Association {
        scan: 1_000_000,
        det: 0,
        landmark: Some(0),
    });
    let err = smooth(&sim.log, &associations, &FrontEndConfig::default()).err();
    assert!(
        matches!(
            err,
            Some(SmoothError::NotInLog {
                scan: 1_000_000,
                ..
            })
        ),
        "{err:?}"
    );
    assert!(matches!(
        smooth(&[], &[], &FrontEndConfig::default()),
        Err(SmoothError::NoScan)
    ));
}
