//! Logs whose sensors differ from what the estimator assumes: the graph
//! front end learns the detector's noise from its matches and the car's
//! sideslip from its pose fits and a gyro's wandering bias from the loop's
//! headings, a detector's latency where the car's speed changes, and the
//! tail of a heavy-tailed detector's noise; a lap that ends far off still
//! closes.

use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::eval::Report;
use cairn_fs_tools::run::run_and_score;
use cairn_fs_tools::sim::{Preset, simulate_preset};
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::estimator::EstimatorKind;
use cairn_slam::frontend::association::AssociationMethod;
use cairn_slam::frontend::{FrontEndConfig, GraphSlam};

/// A `standard` log of random track 11, seed 11, changed by `change`,
/// mapped by the graph told `configs/standard.toml` and then `tell`.
fn mismatched(
    change: impl FnOnce(&mut Preset),
    tell: impl FnOnce(&mut FrontEndConfig),
) -> (GraphSlam, Report) {
    mismatched_on((11, 11), AssociationMethod::MaximumLikelihood, change, tell)
}

/// [`mismatched`] on random track `track`, seed `seed`, matched by `method`.
fn mismatched_on(
    (track, seed): (u64, u64),
    method: AssociationMethod,
    change: impl FnOnce(&mut Preset),
    tell: impl FnOnce(&mut FrontEndConfig),
) -> (GraphSlam, Report) {
    let (track, course) = random_track(track, &TrackRules::default());
    let mut preset = Preset::standard();
    change(&mut preset);
    let sim = simulate_preset(&track, &course, preset, seed);
    let mut config = assumed_config("standard", method, EstimatorKind::Graph)
        .expect("the preset has a shipped config");
    tell(&mut config);
    run_and_score(&sim, config)
}

/// [`mismatched`] with the detector's noise `scale` times the preset's,
/// learning it or not.
fn noisier(scale: f64, learn: bool) -> (GraphSlam, Report) {
    mismatched(
        |p| p.sensor.scale_noise(scale),
        |c| c.learn_detector_noise = learn,
    )
}

/// JCBB's joint test sums a hypothesis's χ², four times what it assumes
/// when the detector is twice as noisy: it kept only the pairs that
/// happened to fit, the rest were dropped, and the map drifted from the
/// first second (random track 0, seed 101: association 41.8%, the loop
/// never closed, before the test was widened by the innovations' spread).
/// A regression guard on a log that failed, not a measurement on fresh ones.
#[test]
fn jcbb_matches_a_detector_twice_as_noisy_as_assumed() {
    let (slam, report) = mismatched_on(
        (0, 101),
        AssociationMethod::Jcbb,
        |p| p.sensor.scale_noise(2.0),
        |_| {},
    );
    println!("{report:?}");
    // Measured: 99.63%, one phantom.
    assert!(report.association_accuracy > 0.99, "{report:?}");
    assert!(report.phantom <= 2, "{report:?}");
    assert_eq!(slam.loop_closures(), 1);
}

/// The `realistic` preset's gyro bias random-walks while the estimator,
/// told `configs/standard.toml`, assumes a steady one: random track 0's
/// 425 m lap ended 13 m off (seed 101), beyond the 3% of the distance that
/// place recognition searched, and with JCBB the loop never closed
/// (association 54.8%, 280 phantoms). A regression guard on a log that
/// failed, not a measurement on fresh ones.
#[test]
fn a_lap_that_ends_far_off_still_closes() {
    let (slam, report) = mismatched_on(
        (0, 101),
        AssociationMethod::Jcbb,
        |p| *p = Preset::realistic(),
        |_| {},
    );
    println!("{report:?}");
    // Measured: 99.87%.
    assert_eq!(slam.loop_closures(), 1);
    assert!(report.association_accuracy > 0.99, "{report:?}");
    assert!(report.phantom <= 2, "{report:?}");
}

/// Student-t noise (3 degrees of freedom) at the assumed σ puts a few
/// detections in every hundred far beyond the Gaussian's gate; matched in
/// hindsight by a likelihood with the tail it learns, they stay with their
/// cones instead of going to clutter.
#[test]
fn heavy_tailed_noise_is_matched_by_the_tail_learnt_in_hindsight() {
    let (slam, report) = mismatched(|p| p.sensor.noise_dof = Some(3.0), |_| {});
    println!("{report:?}");
    // Measured: 99.86% (99.03% before the tail); 98.6% in real time, where
    // the Gaussian's gate still holds.
    assert!(report.association_accuracy > 0.995, "{report:?}");
    let real_time = report.association_accuracy_real_time.expect("scored");
    assert!(real_time < 0.992, "{report:?}");
    assert!(
        slam.warnings().iter().any(|w| w.contains("heavy-tailed")),
        "{:?}",
        slam.warnings()
    );
}

/// Clutter beside the cones of a Gaussian detector is not a heavy tail:
/// the `hard` preset's random track 0, seed 0, learnt a tail of 0.6% and
/// was warned of one before the warning waited for 1% (Student-t noise
/// learns 1.5–1.9%). A regression guard on the one log of docs/fs-slam.md
/// that warned.
#[test]
fn clutter_beside_the_cones_is_not_reported_as_a_heavy_tail() {
    let (track, course) = random_track(0, &TrackRules::default());
    let sim = simulate_preset(&track, &course, Preset::hard(), 0);
    let config = assumed_config(
        "hard",
        AssociationMethod::MaximumLikelihood,
        EstimatorKind::Graph,
    )
    .expect("the preset has a shipped config");
    let (slam, report) = run_and_score(&sim, config);
    assert!(report.association_accuracy > 0.95, "{report:?}");
    assert!(
        !slam.warnings().iter().any(|w| w.contains("heavy-tailed")),
        "{:?}",
        slam.warnings()
    );
}

#[test]
fn a_detector_twice_as_noisy_as_assumed_keeps_its_matches() {
    let (slam, report) = noisier(2.0, true);
    let noise = slam.detector_noise().expect("learning");
    println!("learned {noise:?}: {report:?}");
    // Measured: 99.88% of detections right, σ learned ×2.56: what makes the
    // residuals consistent includes the landmarks' own over-confidence.
    assert!(report.association_accuracy > 0.995, "{report:?}");
    let ratio = noise.estimated[2] / noise.assumed[2];
    assert!((1.6..3.0).contains(&ratio), "{ratio}");
    assert_eq!(slam.loop_closures(), 1);
    // Without learning, far detections fall outside the gates while
    // driving (91.9% before the end-of-run matching could widen them); the
    // end of the run matches them again at the noise the map shows.
    let (slam, fixed) = noisier(2.0, false);
    println!("not learned: {fixed:?}");
    let real_time = fixed.association_accuracy_real_time.expect("scored");
    assert!(real_time < 0.95, "{fixed:?}");
    assert!(fixed.association_accuracy > 0.99, "{fixed:?}");
    assert!(
        slam.warnings().iter().any(|w| w.contains("times as noisy")),
        "{:?}",
        slam.warnings()
    );
}

#[test]
fn a_detector_as_noisy_as_assumed_is_matched_at_its_noise_to_the_end() {
    let (slam, report) = noisier(1.0, false);
    assert!(report.association_accuracy > 0.999, "{report:?}");
    assert!(
        !slam.warnings().iter().any(|w| w.contains("times as noisy")),
        "{:?}",
        slam.warnings()
    );
}

#[test]
fn a_detector_half_as_noisy_as_assumed_narrows_the_gates() {
    let (slam, report) = noisier(0.5, true);
    let noise = slam.detector_noise().expect("learning");
    println!("learned {noise:?}: {report:?}");
    let ratio = noise.estimated[0] / noise.assumed[0];
    assert!((0.35..0.8).contains(&ratio), "{ratio}");
    assert!(report.association_accuracy > 0.999, "{report:?}");
}

#[test]
fn a_gyro_whose_bias_wanders_has_its_walk_learned() {
    let walking = |p: &mut Preset| p.odometry.yaw_rate_bias_walk = 5e-4;
    let (slam, learned) = mismatched(walking, |_| {});
    let walk = slam.calibration().yaw_rate_bias_walk;
    let (_, told) = mismatched(walking, |c| c.yaw_rate_bias_walk = 5e-4);
    println!(
        "walk learned {walk:.2e} rad/s/√s, map RMSE {:.3} m; told 5e-4, {:.3} m",
        learned.map_rmse, told.map_rmse
    );
    // Measured: 3.97e-4 learned, 0.075 m against 0.068 m told; the steady
    // bias assumed before the walk was learned turned the map, 0.606 m.
    assert!((2e-4..1e-3).contains(&walk), "{walk}");
    assert!(
        learned.map_rmse < 1.5 * told.map_rmse,
        "{learned:?} vs {told:?}"
    );
    assert!(learned.association_accuracy > 0.999, "{learned:?}");
    // A steady bias is not taken for a wandering one.
    let (steady, _) = mismatched(|_| {}, |_| {});
    let assumed = FrontEndConfig::default().yaw_rate_bias_walk;
    assert_eq!(steady.calibration().yaw_rate_bias_walk, assumed);
}

#[test]
fn a_car_that_slides_in_corners_has_its_sideslip_learned() {
    let sliding = |p: &mut Preset| p.odometry.sideslip = 0.01;
    let (slam, report) = mismatched(sliding, |_| {});
    let learned = slam.calibration().sideslip;
    println!("sideslip learned {learned:.4} rad per m/s²: {report:?}");
    // Measured 0.0095 of the 0.01 simulated (map RMSE 0.099 m) with the
    // smoothing window solving for it; 0.0071 when only the scans' pose
    // fits learnt it, whose landmarks mapped in the same corner slide with
    // the car and hide part of it.
    assert!((0.006..0.014).contains(&learned), "{learned}");
    assert!(slam.calibration().sideslip_free);
    // A car that does not slide is not given a slide.
    let (steady, _) = mismatched(|_| {}, |_| {});
    assert!(
        !steady.calibration().sideslip_free,
        "{:?}",
        steady.calibration()
    );
    assert!(report.association_accuracy > 0.999, "{report:?}");
    // The bound for a mismatched log.
    assert!(report.map_rmse < 0.15, "{report:?}");
}

#[test]
fn a_detector_latency_in_the_config_is_taken_out() {
    let late = |p: &mut Preset| p.sensor.latency = 0.05;
    let (unknown, assumed) = mismatched(late, |c| c.learn_scan_latency = false);
    let (slam, told) = mismatched(late, |c| c.scan_latency = 0.05);
    println!(
        "aligned map RMSE with the latency unknown {:.3} m, told {:.3} m",
        assumed.map_rmse_aligned, told.map_rmse_aligned
    );
    // The map is pushed 0.25 m along the direction of travel unless the
    // scans are placed where they were measured.
    assert!(
        told.map_rmse_aligned < 0.5 * assumed.map_rmse_aligned,
        "{told:?} vs {assumed:?}"
    );
    assert!(told.association_accuracy > 0.999, "{told:?}");
    // The trajectory's poses carry the moment of measurement.
    let shift = unknown.trajectory()[0].t - slam.trajectory()[0].t;
    assert!((shift - 0.05).abs() < 1e-9, "{shift}");
}

#[test]
fn a_detector_latency_is_learned_where_the_car_changes_speed() {
    // Slowing for corners: a cone seen braking and accelerating from poses
    // 50 ms off lands in different places.
    let late = |p: &mut Preset| {
        p.sensor.latency = 0.05;
        p.speed = Preset::realistic().speed;
    };
    let (slam, learned) = mismatched(late, |_| {});
    let (_, unlearned) = mismatched(late, |c| c.learn_scan_latency = false);
    let (_, told) = mismatched(late, |c| c.scan_latency = 0.05);
    let c = slam.calibration();
    let sigma = c.scan_latency_sigma.expect("the last optimisation looked");
    println!(
        "latency learned {:.4} s (σ {sigma:.4} s); map RMSE {:.3} m (aligned {:.3} m), not learned {:.3} m ({:.3} m), told {:.3} m ({:.3} m)",
        c.scan_latency,
        learned.map_rmse,
        learned.map_rmse_aligned,
        unlearned.map_rmse,
        unlearned.map_rmse_aligned,
        told.map_rmse,
        told.map_rmse_aligned
    );
    // Measured 0.0499 s (σ 0.0043 s); map RMSE 0.131 m (aligned 0.038 m),
    // not learned 0.441 m (0.088 m), told 0.103 m (0.037 m).
    assert!((c.scan_latency - 0.05).abs() < 3.0 * sigma, "{c:?}");
    assert!(
        learned.map_rmse_aligned < 0.6 * unlearned.map_rmse_aligned,
        "{learned:?} vs {unlearned:?}"
    );
    // Placed at the start, not a latency's travel behind it.
    assert!(
        learned.map_rmse < 1.5 * told.map_rmse,
        "{learned:?} vs {told:?}"
    );
    assert!(learned.association_accuracy > 0.999, "{learned:?}");
    // Where the log has no latency the config's stands.
    let (prompt, _) = mismatched(|p| p.speed = Preset::realistic().speed, |_| {});
    assert_eq!(prompt.calibration().scan_latency, 0.0);
    assert!(prompt.calibration().scan_latency_sigma.is_some());
}
