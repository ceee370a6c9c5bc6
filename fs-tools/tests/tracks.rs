//! Track readers and centre lines on the shared tracks, and runs on them.

mod common;

use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::course::Course;
use cairn_fs_tools::eval::Report;
use cairn_fs_tools::run::{run_and_score, run_estimator};
use cairn_fs_tools::sim::{Preset, SimConfig, simulate};
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_fs_tools::{Track, TrackKind};
use cairn_slam::Color;
use cairn_slam::estimator::{EstimatorBuilder, EstimatorKind};
use cairn_slam::frontend::GraphSlam;
use cairn_slam::frontend::association::AssociationMethod;
use nalgebra::Vector2;
use std::path::PathBuf;

fn tracks_dir() -> Option<PathBuf> {
    common::shared::shared_path("tracks")
}

/// (file, blue, yellow, orange, big orange, approximate lap length) from the
/// MANIFEST, less the cones fssim repeats at the same place (it closes each
/// boundary with its first cone).
const TRACKS: &[(&str, usize, usize, usize, usize, f64)] = &[
    ("amz_fssim_FSG.yaml", 94, 88, 0, 4, 309.0),
    ("amz_fssim_FSI.yaml", 80, 74, 0, 4, 218.0),
    ("amz_fssim_acceleration.yaml", 14, 14, 41, 8, 0.0),
    ("amz_fssim_skidpad.yaml", 29, 29, 11, 4, 0.0),
    ("eufs_small_track.csv", 35, 38, 0, 4, 150.0),
    ("eufs_peanut.csv", 54, 64, 0, 4, 106.0),
    ("eufs_acceleration.csv", 14, 14, 12, 6, 0.0),
    ("eufs_skidpad.csv", 30, 30, 20, 4, 0.0),
    ("eufs_comp_2021.csv", 156, 156, 0, 4, 264.0),
    (
        "eufs_hairpins_increasing_difficulty.csv",
        490,
        490,
        0,
        4,
        831.0,
    ),
    ("eufs_garden_light.csv", 101, 99, 0, 4, 204.0),
    ("eufs_boa_constrictor.csv", 44, 51, 0, 4, 93.0),
    ("eufs_rand.csv", 99, 109, 0, 4, 405.0),
    ("epfl_fsds_competition_1_cones.csv", 85, 85, 0, 4, 339.0),
    ("epfl_fsds_competition_2_cones.csv", 115, 115, 0, 4, 458.0),
    ("epfl_fsds_competition_3_cones.csv", 90, 90, 0, 4, 329.0),
    ("epfl_track_3_cones.csv", 147, 141, 0, 4, 429.0),
];

#[test]
fn every_shared_track_reads_with_the_manifest_counts() {
    let Some(dir) = tracks_dir() else { return };
    for &(file, blue, yellow, orange, big, _) in TRACKS {
        let track = Track::load(&dir.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        let count = |c| track.of_color(c).len();
        assert_eq!(
            (
                count(Color::Blue),
                count(Color::Yellow),
                count(Color::Orange),
                count(Color::BigOrange)
            ),
            (blue, yellow, orange, big),
            "{file}"
        );
    }
    let rand = Track::load(&dir.join("eufs_rand.csv")).unwrap();
    assert_eq!(rand.clutter.len(), 134);
    let epfl = Track::load(&dir.join("epfl_track_3_cones.csv")).unwrap();
    assert!((epfl.start.theta - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
}

#[test]
fn loop_centre_lines_stay_between_the_cones() {
    let Some(dir) = tracks_dir() else { return };
    for &(file, _, _, _, _, length) in TRACKS {
        let track = Track::load(&dir.join(file)).unwrap();
        if track.kind != TrackKind::Loop {
            continue;
        }
        let course = Course::from_track(&track);
        if file == "eufs_garden_light.csv" {
            // Known limitation: its boundaries interleave too closely for
            // the nearest-cone walk; the simulator refuses it with a message.
            assert!(course.is_err());
            continue;
        }
        let course = course.unwrap_or_else(|e| panic!("{file}: {e}"));
        let cones: Vec<_> = track.cones.iter().map(|c| c.position).collect();
        let clearance = course.clearance(&cones);
        println!(
            "{file}: length {:.1} (manifest ≈{length}), clearance {clearance:.2}",
            course.length()
        );
        assert!(clearance >= 0.7, "{file}: clearance {clearance}");
        assert!(
            (course.length() / length - 1.0).abs() < 0.2,
            "{file}: length {}",
            course.length()
        );
    }
}

#[test]
fn random_tracks_follow_the_rules() {
    for seed in 0..10 {
        let (track, course) = random_track(seed, &TrackRules::default());
        assert!((200.0..=500.0).contains(&course.length()), "seed {seed}");
        let cones: Vec<_> = track.cones.iter().map(|c| c.position).collect();
        assert!(course.clearance(&cones) >= 1.5, "seed {seed}: width ≥ 3 m");
        for color in [Color::Blue, Color::Yellow] {
            let side = track.of_color(color);
            for &i in &side {
                let p = track.cones[i].position;
                let gap = side
                    .iter()
                    .filter(|&&j| j != i)
                    .map(|&j| (track.cones[j].position - p).norm())
                    .fold(f64::INFINITY, f64::min);
                assert!(gap <= 5.0 + 1e-9, "seed {seed}: gap {gap}");
            }
        }
    }
}

/// A run of shared track `file` with `preset` noise `seed` under
/// `method`: the track, the front end after it, and its score. None (after
/// a note) without `../shared`.
fn shared_run(
    file: &str,
    preset: Preset,
    seed: u64,
    method: AssociationMethod,
) -> Option<(Track, GraphSlam, Report)> {
    let track = Track::load(&tracks_dir()?.join(file)).unwrap();
    let course = Course::from_track(&track).unwrap();
    let config = SimConfig {
        preset: preset.clone(),
        seed,
        ..SimConfig::default()
    };
    let sim = simulate(&track, &course, &config);
    let frontend = assumed_config(preset.name, method, EstimatorKind::Graph)
        .expect("the preset has a shipped config");
    let (slam, report) = run_and_score(&sim, frontend);
    println!("{file} seed {seed}: {report:?}");
    Some((track, slam, report))
}

/// [`shared_run`] with the `hard` preset and maximum likelihood.
fn hard_ml_run(file: &str, seed: u64) -> Option<(Track, GraphSlam, Report)> {
    shared_run(
        file,
        Preset::hard(),
        seed,
        AssociationMethod::MaximumLikelihood,
    )
}

/// The distance from `p` to the nearest of `points`.
fn nearest(p: &Vector2<f64>, points: impl IntoIterator<Item = Vector2<f64>>) -> f64 {
    points
        .into_iter()
        .map(|q| (q - p).norm())
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn a_lap_that_ends_one_cone_off_among_clutter_closes_on_the_start_line() {
    // eufs_rand, `hard` seed 29, tracking association: the first lap ends
    // 3.7 m off, about one cone spacing. Clutter and the drift prior made a
    // fit one spacing off the best, while a fit near the truth put two big
    // orange detections on the start line's cones; the loop closed 3.8 m
    // off and the run ended 22 m off (60.8% of detections matched right).
    let Some((_, slam, report)) = shared_run(
        "eufs_rand.csv",
        Preset::hard(),
        29,
        AssociationMethod::Tracking,
    ) else {
        return;
    };
    assert_eq!(slam.loop_closures(), 1);
    assert!(report.ate < 0.5, "{report:?}");
    assert!(report.association_accuracy > 0.98, "{report:?}");
}

#[test]
fn a_landmark_a_later_lap_starts_beside_a_big_orange_pair_leaves_the_map() {
    // eufs_boa_constrictor, `hard` seed 0, maximum likelihood: the start's
    // big orange cones stand in pairs 0.28 m apart. The second lap started
    // a landmark beside each pair, which scans then matched with either
    // cone, so it never merged; the map held 6 big orange cones for 4 (map
    // RMSE 0.107 m, big orange 0.21 m; 97.48% of detections matched right).
    let Some((track, slam, report)) = hard_ml_run("eufs_boa_constrictor.csv", 0) else {
        return;
    };
    let truth: Vec<_> = track
        .cones
        .iter()
        .filter(|c| c.color == Color::BigOrange)
        .map(|c| c.position)
        .collect();
    let mapped: Vec<_> = slam
        .map()
        .into_iter()
        .filter(|c| c.color == Color::BigOrange)
        .map(|c| c.position)
        .collect();
    assert_eq!(mapped.len(), truth.len(), "{mapped:?}");
    for p in &mapped {
        let d = nearest(p, truth.iter().copied());
        assert!(d < 0.1, "{p} is {d} m from a big orange cone");
    }
    assert!(report.map_rmse < 0.09, "{report:?}");
    assert!(report.association_accuracy > 0.975, "{report:?}");
}

#[test]
fn a_cone_whose_detections_went_to_its_neighbours_gets_a_landmark_at_the_end() {
    // eufs_boa_constrictor, `hard` seed 1, maximum likelihood: the landmark
    // begun for yellow cone 30, between two others 1.3 and 1.6 m away,
    // drifted onto one of them while mapping, and matched again in
    // hindsight the cone's 41 detections went to clutter (32) and to its
    // neighbours: the cone was missed (96.81% of detections right). Its
    // unmatched detections gather on one spot and now found its landmark.
    let Some((track, slam, report)) = hard_ml_run("eufs_boa_constrictor.csv", 1) else {
        return;
    };
    assert_eq!(report.missed, 0, "{report:?}");
    let d = nearest(
        &track.cones[30].position,
        slam.map().iter().map(|c| c.position),
    );
    assert!(d < 0.2, "cone 30's nearest landmark is {d} m off");
    // By majority: the run keeps four duplicate or clutter landmarks, whose
    // detections count as wrong one-to-one (measured 96.2% against 97.3%).
    assert!(report.association_accuracy_majority > 0.97, "{report:?}");
}

#[test]
fn objects_beside_the_track_do_not_become_landmarks_at_the_end() {
    // eufs_rand, `hard` seed 0, maximum likelihood: its clutter objects,
    // which the detector takes for cones now and then, stand 8–15 m from
    // the path. Two of them gathered 6 and 20 unmatched detections, and
    // mapped as cones they were phantoms (3 instead of 1). Counted here are
    // the landmarks over a metre from every cone: a duplicate of a start
    // line cone is a phantom too, but not an object beside the track.
    let Some((track, slam, report)) = hard_ml_run("eufs_rand.csv", 0) else {
        return;
    };
    let beside = slam
        .map()
        .iter()
        .filter(|l| nearest(&l.position, track.cones.iter().map(|c| c.position)) > 1.0)
        .count();
    assert!(
        beside <= 1,
        "{beside} landmarks beside the track: {report:?}"
    );
    assert!(report.phantom <= 2, "{report:?}");
}

#[test]
fn each_scan_is_matched_again_as_a_whole() {
    // eufs_boa_constrictor, `standard` seed 1, maximum likelihood. Matched
    // again at the end of the run claim by claim, the cheaper claim first,
    // the big orange pairs (0.28 m apart, range noise 0.15 m at 10 m) were
    // often taken the wrong way round: 99.54% of detections right. The
    // scan's most likely assignment weighs both detections of a pair.
    let Some((_, _, report)) = shared_run(
        "eufs_boa_constrictor.csv",
        Preset::standard(),
        1,
        AssociationMethod::MaximumLikelihood,
    ) else {
        return;
    };
    assert!(report.association_accuracy > 0.997, "{report:?}");
}

/// fssim files in any YAML layout read alike: block lists, flow lists, a
/// flow mapping, comments, keys the reader does not use.
#[test]
fn fssim_yaml_reads_in_block_and_flow_style() {
    let block = "# an fssim track\ncones_left:\n- - 0.0\n  - 2.0\n- - 5.0\n  - 2.0\n\
                 cones_right:\n- - 0.0\n  - -2.0\n- [5.0, -2.0]\ncones_orange_big: []\n\
                 starting_pose_front_wing: [-1.0, 0.0, 0.1]\ntk_device_distance: 3.0\n";
    let flow = "{cones_left: [[0, 2], [5, 2]], cones_right: [[0, -2], [5.0, -2.0]],\n \
                starting_pose_front_wing: [-1, 0, 0.1]}\n";
    let a = Track::parse("block", block, true).unwrap();
    let b = Track::parse("flow", flow, true).unwrap();
    assert_eq!(a.cones.len(), 4);
    assert_eq!(a.cones, b.cones);
    assert_eq!(a.start, b.start);
    assert_eq!(a.start.theta, 0.1);
    // Errors name the line.
    let bad = "cones_left:\n- [0.0, 2.0]\n- [1.0, oops]\n";
    let err = Track::parse("bad", bad, true).unwrap_err().to_string();
    assert!(err.starts_with("line 3:"), "{err}");
    let short = "cones_left: [[0.0, 2.0]]\ncones_right:\n- [1.0]\n";
    let err = Track::parse("short", short, true).unwrap_err().to_string();
    assert_eq!(err, "line 2: a point under 'cones_right' needs x and y");
}

#[test]
fn fastslam_closes_its_loop_where_the_start_straight_repeats_itself() {
    // epfl_track_3 seed 12: the best particle comes back 1.3 m off, and a
    // fit of the start area's regular rows one cone spacing (3.3 m) along
    // scored better. Taken without the start line's confirmation, the
    // particles localised 3.3 m off and matched almost nothing on the
    // second lap (50.1% of the detections right); it now takes 1.4 m.
    let Some(dir) = tracks_dir() else { return };
    let track = Track::load(&dir.join("epfl_track_3_cones.csv")).unwrap();
    let course = Course::from_track(&track).unwrap();
    let sim = common::simulate_seed(&track, &course, 12);
    let config = assumed_config(
        "standard",
        AssociationMethod::MaximumLikelihood,
        EstimatorKind::FastSlam2,
    )
    .expect("the preset has a shipped config");
    // FastSLAM samples, so one sampler seed is one draw: with 30 particles
    // the loop closed with 7 of sampler seeds 0–7 (not seed 0). Four draws
    // must close at least three times. The bounds on the runs that close
    // are regression guards (seeds 1–3: 95.8–96.0%, ATE 1.18–1.63 m;
    // before FastSLAM 2.0 sampled its whole proposal, seed 0 closed with
    // 95.5% and 0.49 m).
    let mut closed = 0;
    for seed in 0..4 {
        let mut builder = EstimatorBuilder::new(EstimatorKind::FastSlam2, config.clone());
        builder.particles = 30;
        builder.seed = seed;
        let (slam, report) = run_estimator(&sim, &builder);
        println!("seed {seed}: {report:?}");
        if slam.loop_closures() == 1 {
            closed += 1;
            assert!(report.association_accuracy > 0.9, "{report:?}");
            assert!(report.ate < 2.0, "{report:?}");
        }
    }
    assert!(closed >= 3, "the loop closed in {closed} of 4 draws");
}
