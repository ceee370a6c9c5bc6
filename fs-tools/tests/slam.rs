//! The simulator, data association, evaluation and the whole pipeline.

mod common;

use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::eval::{
    aligned_rms, association_accuracy, association_labels, evaluate, majority_labels, map_labels,
    rigid_alignment,
};
use cairn_fs_tools::run::run_and_score;
use cairn_fs_tools::sim::{Preset, SimConfig, simulate};
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::estimator::EstimatorKind;
use cairn_slam::files::Association;
use cairn_slam::frontend::association::AssociationMethod;
use cairn_slam::frontend::{FrontEndConfig, GraphSlam, Mode};
use cairn_slam::log::Record;
use cairn_slam::{Color, Cone};
use common::simulate_seed;
use nalgebra::{Rotation2, Vector2};

#[test]
fn simulation_is_seeded_and_drives_the_laps() {
    let (track, course) = random_track(1, &TrackRules::default());
    let config = SimConfig {
        laps: 1.0,
        ..SimConfig::default()
    };
    let a = simulate(&track, &course, &config);
    let b = simulate(&track, &course, &config);
    assert_eq!(a.log, b.log);
    let c = simulate(
        &track,
        &course,
        &SimConfig {
            seed: 2,
            ..config.clone()
        },
    );
    assert_ne!(a.log, c.log);
    // One lap at 5 m/s takes length / 5 seconds.
    let duration = a.truth.last().unwrap().t;
    assert!((duration - course.length() / 5.0).abs() < 1.0, "{duration}");
    // The car ends where it started, and every true label names a cone.
    assert!(a.truth.last().unwrap().pose.t.norm() < 2.0);
    assert!(
        a.truth_associations
            .iter()
            .all(|x| x.landmark.is_none_or(|l| l < track.cones.len()))
    );
    let false_positives = a
        .truth_associations
        .iter()
        .filter(|x| x.landmark.is_none())
        .count();
    let scans = a
        .log
        .iter()
        .filter(|r| matches!(r, Record::Cones { .. }))
        .count();
    let rate = false_positives as f64 / scans as f64;
    assert!(
        (0.15..0.5).contains(&rate),
        "false positives per scan {rate}"
    );
}

#[test]
fn rigid_alignment_recovers_a_transform_and_refuses_reflections() {
    let a: Vec<Vector2<f64>> = (0..10)
        .map(|i| Vector2::new(i as f64, (i * i) as f64 * 0.1))
        .collect();
    let r = Rotation2::new(0.7);
    let t = Vector2::new(3.0, -1.0);
    let b: Vec<_> = a.iter().map(|p| r * p + t).collect();
    let (rr, tt) = rigid_alignment(&a, &b);
    assert!((rr - r.matrix()).norm() < 1e-12 && (tt - t).norm() < 1e-12);
    assert!(aligned_rms(&a, &b) < 1e-12);
    // A mirror image cannot be matched by a rotation.
    let mirrored: Vec<_> = a.iter().map(|p| Vector2::new(p.x, -p.y)).collect();
    let (rm, _) = rigid_alignment(&a, &mirrored);
    assert!((rm.determinant() - 1.0).abs() < 1e-12);
}

#[test]
fn association_accuracy_by_majority_and_one_to_one() {
    let truth = [Some(7), Some(7), Some(7), None, Some(8)];
    let est = [Some(0), Some(0), Some(1), None, Some(0)];
    let t: Vec<_> = truth
        .iter()
        .enumerate()
        .map(|(i, &l)| Association {
            scan: 0,
            det: i,
            landmark: l,
        })
        .collect();
    let e: Vec<_> = est
        .iter()
        .enumerate()
        .map(|(i, &l)| Association {
            scan: 0,
            det: i,
            landmark: l,
        })
        .collect();
    // Landmark 0 stands for cone 7 (2 of 3), landmark 1 for cone 7: 4 of 5 right.
    let (acc, n) = association_accuracy(&t, &e, &majority_labels(&t, &e));
    assert_eq!(n, 5);
    assert!((acc - 0.8).abs() < 1e-12);
    // One-to-one, cone 7 stands for one landmark alone: either landmark 0
    // (2 right) with landmark 1 a duplicate, or landmark 0 for cone 8 and 1
    // for cone 7 (1 + 1 right); 3 of 5 either way.
    let labels = association_labels(&t, &e);
    assert!(
        labels == [Some(7), None] || labels == [Some(8), Some(7)],
        "{labels:?}"
    );
    let (acc, _) = association_accuracy(&t, &e, &labels);
    assert!((acc - 0.6).abs() < 1e-12, "{acc}");
    // On the map, landmark 1 is a phantom beside cone 7.
    let mut truth_map = vec![Cone::new(50.0, 50.0, Color::Blue); 9];
    truth_map[7] = Cone::new(0.0, 0.0, Color::Blue);
    truth_map[8] = Cone::new(5.0, 0.0, Color::Yellow);
    let map = [
        Cone::new(0.1, 0.0, Color::Blue),
        Cone::new(0.3, 0.0, Color::Blue),
    ];
    assert_eq!(map_labels(&truth_map, &map), [Some(7), None]);
    let report = evaluate(&truth_map, &map, &[], &[], &t, &e);
    assert_eq!((report.phantom, report.landmarks), (1, 2));
    assert!((report.association_accuracy - 0.6).abs() < 1e-12);
    assert!((report.association_accuracy_majority - 0.8).abs() < 1e-12);
    assert_eq!(report.missed, 1, "cone 8 was seen and has no landmark");
    assert!((report.map_rmse - 0.1).abs() < 1e-12);
}

fn score(method: AssociationMethod, seed: u64) -> (GraphSlam, cairn_fs_tools::eval::Report) {
    let (track, course) = random_track(1, &TrackRules::default());
    let sim = simulate_seed(&track, &course, seed);
    let config = FrontEndConfig {
        association: method,
        ..FrontEndConfig::default()
    };
    run_and_score(&sim, config)
}

#[test]
fn every_association_method_maps_a_random_track_and_closes_the_loop() {
    for method in AssociationMethod::ALL {
        // Seed 1 drifts more than half a cone spacing; see
        // `a_lap_drifting_more_than_half_a_cone_spacing_still_closes_correctly`.
        let (slam, report) = score(method, 2);
        println!("{method:?}: {report:?}");
        assert_eq!(slam.loop_closures(), 1, "{method:?}");
        assert_eq!(slam.mode(), Mode::Localising);
        assert_eq!(report.phantom, 0, "{method:?}");
        assert_eq!(report.missed, 0, "{method:?}");
        assert!(
            report.association_accuracy > 0.97,
            "{method:?}: {}",
            report.association_accuracy
        );
        assert!(
            report.map_rmse_aligned < 0.3,
            "{method:?}: {}",
            report.map_rmse_aligned
        );
    }
}

/// On random track 1 with simulator seed 1 the first lap drifts 2.4 m along
/// the track (EKF-SLAM drifts as much), more than half the 3.4 m cone
/// spacing, so a fit one spacing off is nearer the estimate than the truth.
/// Place recognition must wait for the start line's orange cones.
#[test]
fn a_lap_drifting_more_than_half_a_cone_spacing_still_closes_correctly() {
    for method in AssociationMethod::ALL {
        let (slam, report) = score(method, 1);
        assert_eq!(slam.loop_closures(), 1, "{method:?}");
        assert!(report.association_accuracy > 0.97, "{method:?}: {report:?}");
        assert_eq!(report.phantom, 0, "{method:?}: {report:?}");
    }
}

#[test]
fn the_loop_closure_learns_the_yaw_rate_bias() {
    // The `standard` preset's gyro reads 0.002 rad/s high. The smoothing
    // window estimates it online from 2.5 s at a time; the full
    // optimisation fits it to the whole lap, closer still.
    let (track, course) = random_track(2, &TrackRules::default());
    let (mut online_error, mut fitted_error) = (0.0, 0.0);
    for seed in 1..=6 {
        let config = SimConfig {
            seed,
            ..SimConfig::default()
        };
        let truth = config.preset.odometry.yaw_rate_bias;
        let sim = simulate(&track, &course, &config);
        let mut slam = GraphSlam::new(FrontEndConfig::default());
        let mut online = 0.0;
        for r in &sim.log {
            if slam.loop_closures() == 0 {
                online = slam.calibration().yaw_rate_bias;
            }
            slam.process(r);
            if slam.loop_closures() == 1 {
                break;
            }
        }
        let fitted = slam.calibration().yaw_rate_bias;
        println!("seed {seed}: online {online}, fitted {fitted}");
        assert_eq!(slam.loop_closures(), 1, "seed {seed}");
        assert!((fitted - truth).abs() < 3e-4, "seed {seed}: {fitted}");
        online_error += (online - truth).abs();
        fitted_error += (fitted - truth).abs();
    }
    assert!(
        fitted_error < online_error,
        "fitted {fitted_error}, online {online_error}"
    );
}

#[test]
fn the_final_optimisation_refines_the_map_with_the_laps_on_the_fixed_map() {
    // The second lap is driven on the fixed map; its sightings, with gyro
    // noise independent of the first lap's, straighten the map at the end.
    // The shape (aligned RMSE) gains on every seed; the unaligned RMSE is
    // dominated by how the map turns about the start, which the extra lap
    // pins only on average.
    let (track, course) = random_track(0, &TrackRules::default());
    let (mut before, mut after) = (0.0, 0.0);
    for seed in 1..=8 {
        let sim = simulate_seed(&track, &course, seed);
        let mut slam = GraphSlam::new(FrontEndConfig::default());
        for r in &sim.log {
            slam.process(r);
        }
        assert_eq!(slam.mode(), Mode::Localising, "seed {seed}");
        let scans = slam.trajectory().len();
        let rmse = |slam: &GraphSlam| {
            let r = cairn_fs_tools::eval::evaluate(
                &sim.truth_map,
                &slam.map(),
                &sim.truth,
                slam.trajectory(),
                &sim.truth_associations,
                &slam.associations(),
            );
            (r.map_rmse, r.map_rmse_aligned)
        };
        let first = rmse(&slam);
        slam.finish().expect("final optimisation");
        let last = rmse(&slam);
        println!("seed {seed}: map RMSE, aligned {first:?} -> {last:?} m");
        assert!(slam.timing().final_optimisation.is_some());
        assert_eq!(slam.trajectory().len(), scans, "seed {seed}");
        assert!(
            last.1 < first.1,
            "seed {seed}: aligned {first:?} -> {last:?}"
        );
        before += first.0;
        after += last.0;
    }
    assert!(after < 0.8 * before, "{before} -> {after}");
}

#[test]
fn detections_near_the_start_before_the_loop_closes_are_matched_after_it() {
    // At the lap's end the gates leave the start area's landmarks to place
    // recognition; once the loop closes, the scans before the one it
    // recognised are matched again from their optimised poses.
    let (track, course) = random_track(2, &TrackRules::default());
    let mut total = 0.0;
    for seed in 1..=3 {
        let sim = simulate_seed(&track, &course, seed);
        let mut slam = GraphSlam::new(FrontEndConfig::default());
        let (mut scan, mut closed_at) = (0, None);
        for r in &sim.log {
            slam.process(r);
            if let Record::Cones { .. } = r {
                scan += 1;
                if closed_at.is_none() && slam.loop_closures() == 1 {
                    closed_at = Some(scan - 1);
                }
            }
        }
        let closed_at = closed_at.expect("the loop closes");
        // The scans of the lap's last 12 m, the closing one left out.
        let start = sim.truth[0].pose.t;
        let scan_pose: Vec<Vector2<f64>> = sim
            .log
            .iter()
            .filter_map(|r| match r {
                Record::Cones { t, .. } => sim.truth.iter().find(|p| p.t == *t).map(|p| p.pose.t),
                _ => None,
            })
            .collect();
        let lap_end: Vec<usize> = (closed_at / 2..closed_at)
            .filter(|&k| (scan_pose[k] - start).norm() < 12.0)
            .collect();
        assert!(lap_end.len() >= 5, "seed {seed}: {lap_end:?}");
        let keep = |a: &&Association| lap_end.contains(&a.scan);
        let truth: Vec<Association> = sim
            .truth_associations
            .iter()
            .filter(keep)
            .cloned()
            .collect();
        let estimate: Vec<Association> = slam.associations().iter().filter(keep).cloned().collect();
        let (accuracy, n) =
            association_accuracy(&truth, &estimate, &majority_labels(&truth, &estimate));
        println!(
            "seed {seed}: {} scans, {n} detections, {accuracy}",
            lap_end.len()
        );
        total += accuracy;
    }
    // Measured 0.97, 0.94, 0.84 (without matching again: 0.74, 0.80, 0.61).
    // What is left is mostly a cone 2 m from the start, seen twice as the
    // lap began: too few sightings to confirm, so it is never mapped.
    assert!(total / 3.0 > 0.88, "{total}");
}

/// Runs random track 2 with the start's big orange cones moved into pairs
/// `gap` apart and checks that the map holds each of the four once, within
/// `tolerance`.
fn big_orange_pairs_stay_two(gap: f64, preset: Preset, seed: u64, tolerance: f64) {
    let (mut track, course) = random_track(2, &TrackRules::default());
    let orange: Vec<usize> = (0..track.cones.len())
        .filter(|&i| track.cones[i].color == cairn_slam::color::Color::BigOrange)
        .collect();
    assert_eq!(orange.len(), 4);
    for &i in &orange {
        // Each cone's partner on its side of the track is the nearest one.
        let p = track.cones[i].position;
        let &j = orange
            .iter()
            .filter(|&&j| j != i)
            .min_by(|&&a, &&b| {
                let da = (track.cones[a].position - p).norm();
                let db = (track.cones[b].position - p).norm();
                da.total_cmp(&db)
            })
            .unwrap();
        if i < j {
            let q = track.cones[j].position;
            track.cones[j].position = p + gap * (q - p).normalize();
        }
    }
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
    let (slam, report) = run_and_score(&sim, config);
    assert_eq!(slam.loop_closures(), 1);
    let map = slam.map();
    let mapped: Vec<_> = map
        .iter()
        .filter(|m| m.color == cairn_slam::color::Color::BigOrange)
        .collect();
    // Each cone's nearest big orange landmark is its own and near it.
    let mut nearest: Vec<usize> = orange
        .iter()
        .map(|&i| {
            let c = &track.cones[i];
            let (k, m) = mapped
                .iter()
                .enumerate()
                .min_by(|a, b| {
                    let da = (a.1.position - c.position).norm();
                    let db = (b.1.position - c.position).norm();
                    da.total_cmp(&db)
                })
                .expect("big orange landmarks mapped");
            assert!(
                (m.position - c.position).norm() < tolerance,
                "{c:?} not mapped: {mapped:?}: {report:?}"
            );
            k
        })
        .collect();
    nearest.sort_unstable();
    nearest.dedup();
    assert_eq!(nearest.len(), 4, "two cones share a landmark: {mapped:?}");
}

#[test]
fn cones_closer_than_the_merge_radius_stay_two_after_the_loop_closes() {
    // Pairs inside the merge radius: one scan sees both, so the full
    // optimisation must not merge them as one cone mapped twice.
    big_orange_pairs_stay_two(0.5, Preset::standard(), 2, 0.2);
}

#[test]
fn a_chain_of_merges_does_not_join_a_close_pair() {
    // The EUFS tracks' pairs are 0.28 m apart, inside the `hard` preset's
    // far noise: a landmark a later lap starts beside a pair is merged into
    // one of its cones, and then the pair's other cone, which it was never
    // seen together with, into the same one. Merged, half of every pair's detections
    // went wrong (eufs_boa_constrictor, 5 seeds: association 95.9 →
    // 96.5%). Seeds 0–11 here: 6 kept both pairs before, 11 now.
    big_orange_pairs_stay_two(0.28, Preset::hard(), 4, 0.25);
}

#[test]
fn a_saved_map_localises_a_new_run_from_an_unknown_start() {
    let (track, course) = random_track(1, &TrackRules::default());
    let sim = simulate(
        &track,
        &course,
        &SimConfig {
            laps: 0.3,
            seed: 9,
            preset: Preset::standard(),
            ..SimConfig::default()
        },
    );
    // Drop the start record: the front end must find the pose on the map.
    let log: Vec<Record> = sim
        .log
        .iter()
        .filter(|r| !matches!(r, Record::Start { .. }))
        .cloned()
        .collect();
    let mut slam = GraphSlam::with_map(FrontEndConfig::default(), &sim.truth_map);
    let shifted = cairn_core::SE2::new(5.0, -3.0, 0.4);
    slam.process(&Record::Start {
        t: 0.0,
        pose: shifted,
    });
    for r in &log {
        slam.process(r);
    }
    let last = slam.trajectory().last().unwrap();
    let truth = sim
        .truth
        .iter()
        .find(|p| (p.t - last.t).abs() < 1e-9)
        .unwrap();
    let error = (last.pose.t - truth.pose.t).norm();
    assert!(error < 0.2, "final pose off by {error} m");
    assert!(
        slam.trajectory().len() > 50,
        "localised from the first scans on"
    );
    assert_eq!(slam.map().len(), sim.truth_map.len());
}

#[test]
fn mapping_can_go_on_after_the_loop_closes() {
    // The scans near the start are matched again once the loop closes,
    // which adds sightings of earlier poses; the smoothing window that keeps
    // running must still find them in pose order (it read out of bounds).
    for seed in 1..=3 {
        let (track, course) = random_track(1, &TrackRules::default());
        let sim = simulate_seed(&track, &course, seed);
        let config = FrontEndConfig {
            localise_after_loop: false,
            ..FrontEndConfig::default()
        };
        let (slam, report) = run_and_score(&sim, config);
        println!("seed {seed}: {report:?}");
        assert!(slam.loop_closures() >= 1, "seed {seed}");
        assert_eq!(slam.mode(), Mode::Mapping);
        assert!(
            report.association_accuracy > 0.97,
            "seed {seed}: {report:?}"
        );
        assert!(report.map_rmse < 0.3, "seed {seed}: {report:?}");
    }
}

#[test]
fn the_map_covariances_are_the_final_graphs_marginals_and_fit_its_errors() {
    // The EKF's covariances are relative to the poses that saw each cone:
    // on epfl_fsds_competition_1 they put the map's errors at NEES ≈ 250.
    // The marginals carry the heading's drift since the start.
    let (track, course) = random_track(1, &TrackRules::default());
    let (mut nees, mut error2, mut predicted2) = (0.0, 0.0, 0.0);
    let seeds = 1..=4;
    for seed in seeds.clone() {
        let sim = simulate_seed(&track, &course, seed);
        let (slam, report) = run_and_score(&sim, FrontEndConfig::default());
        assert!(slam.loop_closures() >= 1, "seed {seed}");
        let (Some(n), Some(p)) = (report.map_nees, report.map_rmse_predicted) else {
            panic!("seed {seed}: no covariances: {report:?}");
        };
        println!("seed {seed}: NEES {n:.2}, predicted {p:.3} m, {report:?}");
        nees += n;
        error2 += report.map_rmse.powi(2);
        predicted2 += p * p;
        // Far from the start (where the first pose is given) a cone is
        // less certain than near it.
        let trace = |near: bool| {
            let traces: Vec<f64> = slam
                .map()
                .iter()
                .filter(|c| (c.position.norm() < 20.0) == near)
                .map(|c| c.covariance.trace())
                .collect();
            traces.iter().sum::<f64>() / traces.len() as f64
        };
        assert!(trace(false) > 2.0 * trace(true), "seed {seed}");
    }
    let runs = seeds.count() as f64;
    let nees = nees / runs;
    let ratio = (error2 / predicted2).sqrt();
    assert!((0.5..8.0).contains(&nees), "mean NEES {nees}");
    assert!((0.5..2.0).contains(&ratio), "RMSE / predicted {ratio}");
}

#[test]
fn the_map_scores_its_covariances_when_every_landmark_has_one() {
    use cairn_fs_tools::eval::evaluate;
    use cairn_slam::color::Color;
    use nalgebra::Matrix2;
    let truth = vec![
        Cone::new(0.0, 0.0, Color::Blue),
        Cone::new(10.0, 0.0, Color::Yellow),
    ];
    // Errors of 0.1 m along x and 0.2 m along y, with σ 0.1 m in both.
    let mut map = vec![
        Cone::new(0.1, 0.0, Color::Blue),
        Cone::new(10.0, 0.2, Color::Yellow),
    ];
    for c in &mut map {
        c.covariance = Matrix2::identity() * 0.01;
    }
    let r = evaluate(&truth, &map, &[], &[], &[], &[]);
    assert!((r.map_rmse_predicted.unwrap_or(0.0) - 0.02_f64.sqrt()).abs() < 1e-12);
    assert!((r.map_nees.unwrap_or(0.0) - (1.0 + 4.0) / 2.0).abs() < 1e-12);
    // Ground truth and maps without covariances are not scored.
    map[1].covariance = Matrix2::zeros();
    let r = evaluate(&truth, &map, &[], &[], &[], &[]);
    assert_eq!((r.map_rmse_predicted, r.map_nees), (None, None));
}
