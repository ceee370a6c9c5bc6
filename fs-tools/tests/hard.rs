//! The `hard` preset: 2° bearings, a false positive per scan, odometry
//! biases that drift a lap metres off. Runs on random tracks, so they need
//! nothing from `../shared`.

use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::eval::{Report, association_accuracy, majority_labels};
use cairn_fs_tools::run::run_and_score;
use cairn_fs_tools::sim::{Preset, SimConfig, Simulation, simulate};
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::estimator::EstimatorKind;
use cairn_slam::frontend::association::AssociationMethod;
use cairn_slam::frontend::{FrontEndConfig, GraphSlam};
use cairn_slam::log::Record;

/// A simulated run of random track `track` with the `hard` preset, and the
/// front end's settings for it (tracking association).
fn hard_sim(track: u64, seed: u64) -> (Simulation, FrontEndConfig) {
    hard_sim_on(track, seed, &TrackRules::default())
}

/// [`hard_sim`] on a random track made by `rules`.
fn hard_sim_on(track: u64, seed: u64, rules: &TrackRules) -> (Simulation, FrontEndConfig) {
    let (track, course) = random_track(track, rules);
    let preset = Preset::hard();
    let config = assumed_config(
        preset.name,
        AssociationMethod::Tracking,
        EstimatorKind::Graph,
    )
    .expect("the preset has a shipped config");
    let sim = simulate(
        &track,
        &course,
        &SimConfig {
            seed,
            preset,
            ..SimConfig::default()
        },
    );
    (sim, config)
}

/// Runs random track `track` with `hard` seed `seed`, prints the report and
/// checks that the loop closed once.
fn closed_hard_run(track: u64, seed: u64) -> Report {
    let (sim, config) = hard_sim(track, seed);
    let (slam, report) = run_and_score(&sim, config);
    println!("track {track} seed {seed}: {report:?}");
    assert_eq!(slam.loop_closures(), 1, "track {track} seed {seed}");
    report
}

#[test]
fn a_hard_lap_that_maps_the_start_area_again_still_closes() {
    // Random track 0, `hard` seed 1: the first lap ends 5.5 m along the
    // track and 5° off, about one cone spacing, so the gates map the start
    // area a second time and a single scan puts too few detections on the
    // first lap's landmarks. The landmarks of the lap's last 40 m, aligned
    // to those of its start, close the loop.
    closes_within(0, 1, 1.0, 0.95);
}

#[test]
fn a_long_lap_that_ends_nine_metres_off_still_closes() {
    // Random track 0 (425 m), `hard` seed 4: the heading slips 3° on a
    // sparse stretch and the first lap ends 9 m off, beyond the 8 m place
    // recognition looked for on any lap (it never closed: ATE 10 m,
    // association 89%). 5% of the distance driven is 21 m there.
    closes_within(0, 4, 0.5, 0.99);
}

/// [`closed_hard_run`], with ATE below `ate` and association above `accuracy`.
fn closes_within(track: u64, seed: u64, ate: f64, accuracy: f64) {
    let report = closed_hard_run(track, seed);
    assert!(report.ate < ate, "{}", report.ate);
    let got = report.association_accuracy;
    assert!(got > accuracy, "{got}");
}

#[test]
fn the_smoothing_window_learns_the_yaw_rate_bias_while_mapping() {
    // The `hard` preset's gyro reads 0.01 rad/s high. Estimated in the
    // window beside the poses, the bias is known to about 0.001 rad/s after
    // 40 s of the first lap (the per-scan heading residual it replaced:
    // 0.0019 rad/s rms on 15 tracks × 3 seeds).
    let truth = Preset::hard().odometry.yaw_rate_bias;
    let mut squares = 0.0;
    let mut runs = 0;
    for track_seed in 0..3 {
        for seed in 0..2 {
            let (sim, config) = hard_sim(track_seed, seed);
            let mut slam = GraphSlam::new(config);
            for r in &sim.log {
                if matches!(r, Record::Cones { t, .. } if *t > 40.0) {
                    break;
                }
                slam.process(r);
            }
            let online = slam.calibration().yaw_rate_bias;
            println!("track {track_seed} seed {seed}: {online}");
            assert_eq!(slam.loop_closures(), 0);
            assert!(
                (online - truth).abs() < 0.002,
                "track {track_seed} seed {seed}: {online}"
            );
            squares += (online - truth).powi(2);
            runs += 1;
        }
    }
    let rms = (squares / runs as f64).sqrt();
    assert!(rms < 0.0012, "{rms}");
}

#[test]
fn the_end_of_the_run_matches_what_the_real_time_gates_left_unmatched() {
    // The `hard` preset's 2° bearings leave far detections between the 99%
    // gate and the new-landmark gate in real time; from the optimised poses
    // most of them match.
    for (track, seed) in [(2, 0), (2, 1), (1, 1)] {
        let (sim, config) = hard_sim(track, seed);
        let mut slam = GraphSlam::new(config);
        for r in &sim.log {
            slam.process(r);
        }
        let (real_time, _) = association_accuracy(
            &sim.truth_associations,
            &slam.associations(),
            &majority_labels(&sim.truth_associations, &slam.associations()),
        );
        slam.finish().unwrap();
        let (last, _) = association_accuracy(
            &sim.truth_associations,
            &slam.associations(),
            &majority_labels(&sim.truth_associations, &slam.associations()),
        );
        println!("track {track} seed {seed}: {real_time} → {last}");
        assert_eq!(slam.loop_closures(), 1);
        assert!(last > real_time + 0.008, "{real_time} → {last}");
        assert!(last > 0.97, "{last}");
    }
}

#[test]
fn the_start_area_is_not_missed_while_it_waits_for_the_loop_to_close() {
    // Back near the start, the gates leave the first lap's start-area
    // landmarks out until place recognition closes the loop. Counted as
    // misses meanwhile, they removed the start's cones seen fewer than ten
    // times; with them gone, random track 0 `hard` seeds 0 and 3 never
    // closed (association 72% and 65%).
    for seed in [0, 3] {
        let report = closed_hard_run(0, seed);
        assert!(
            report.association_accuracy > 0.98,
            "seed {seed}: {}",
            report.association_accuracy
        );
    }
}

#[test]
fn a_loop_closure_far_from_the_optimum_iterates_until_it_converges() {
    // Random track 1, `hard` seed 7: the first lap ends 6 m and 2.5° off.
    // One Gauss–Newton step from there left the car 2 m off on the closed
    // map, and the second lap localised on a bent map (association 58%).
    let report = closed_hard_run(1, 7);
    assert!(
        report.association_accuracy > 0.95,
        "{}",
        report.association_accuracy
    );
}

#[test]
fn wrong_sightings_do_not_bend_the_final_map() {
    // Random track 1, `hard` seeds 1, 5 and 6: a few percent of the
    // detections are matched to the wrong cone, some at the start line
    // where the loop joins. Weighed like the rest, they bent the final map
    // (RMSE 0.60, 0.66, 0.79 m; ATE 1.1–1.5 m); under the Cauchy kernel
    // 0.39–0.43 m and 0.39–0.50 m.
    for seed in [1, 5, 6] {
        let report = closed_hard_run(1, seed);
        assert!(report.map_rmse < 0.5, "seed {seed}: {}", report.map_rmse);
        assert!(report.ate < 0.7, "seed {seed}: {}", report.ate);
    }
}

/// Random tracks with cones 1.5–2 m apart, as on the EUFS tracks.
fn tight_rules() -> TrackRules {
    TrackRules {
        length: (150.0, 200.0),
        spacing: (1.5, 2.0),
        ..TrackRules::default()
    }
}

#[test]
fn far_detections_of_the_start_area_do_not_close_the_loop_one_cone_off() {
    // On these tracks a `hard` lap drifts about a cone spacing. The gates
    // used to leave the start area to place recognition only within 12 m
    // of the start; from 12–15 m they matched far detections one cone off
    // and closed the loop there (association 54%, ATE 1.9–2.5 m). Runs of
    // 20 that did: track 0 seed 2, track 1 seed 1, track 3 seed 0.
    for (track, seed) in [(0, 2), (1, 1), (3, 0)] {
        let (sim, config) = hard_sim_on(track, seed, &tight_rules());
        let (slam, report) = run_and_score(&sim, config);
        println!("track {track} seed {seed}: {report:?}");
        assert_eq!(slam.loop_closures(), 1, "track {track} seed {seed}");
        assert!(report.association_accuracy > 0.97, "{report:?}");
        assert!(report.ate < 0.3, "{report:?}");
    }
}

#[test]
fn far_detections_matched_alone_gain_from_hindsight_too() {
    // Without tracker ids each detection is matched again alone, from the
    // final poses and map instead of those of the moment it was seen, with
    // clutter as an alternative to every landmark. Measured 97.4 → 98.4%,
    // 98.1 → 98.7%, 98.4 → 99.1%.
    for (without, with) in hindsight_on_tight_tracks(AssociationMethod::MaximumLikelihood) {
        assert!(with > without + 0.005, "{without} → {with}");
    }
}

/// Association accuracy without and with the matching in hindsight, under
/// `method`, on `hard` runs of tight random tracks 1 (seeds 0 and 2) and 2
/// (seed 2).
fn hindsight_on_tight_tracks(method: AssociationMethod) -> Vec<(f64, f64)> {
    let tight = tight_rules();
    [(1, 0), (1, 2), (2, 2)]
        .into_iter()
        .map(|(track, seed)| {
            let (sim, config) = hard_sim_on(track, seed, &tight);
            let accuracy = |hindsight: bool| {
                let config = FrontEndConfig {
                    hindsight,
                    association: method,
                    ..config.clone()
                };
                let (slam, report) = run_and_score(&sim, config);
                assert_eq!(slam.loop_closures(), 1, "track {track} seed {seed}");
                report.association_accuracy
            };
            let (without, with) = (accuracy(false), accuracy(true));
            println!("track {track} seed {seed}: {without} → {with}");
            (without, with)
        })
        .collect()
}

#[test]
fn tracker_chains_put_the_far_detections_right_in_hindsight() {
    // Cones 1.5–2 m apart along each side, as on the EUFS tracks, are closer
    // than far detections' noise (0.3–0.4 m at 10–15 m): matched alone in
    // real time, about 4% go to a neighbour. At the end of the run the
    // tracker id ties each to the near sightings of the same cone.
    // Measured 97.6 → 98.7%, 98.3 → 99.6%, 97.9 → 99.3%.
    for (without, with) in hindsight_on_tight_tracks(AssociationMethod::Tracking) {
        assert!(with > without + 0.007, "{without} → {with}");
        assert!(with > 0.985, "{with}");
    }
}
