//! Objects that are not cones (EUFS's `inactive_noise`) beside random
//! tracks: the end of the run must take them out of the map.

mod common;

use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::course::Course;
use cairn_fs_tools::run::{run_and_score, run_estimator};
use cairn_fs_tools::sim::Preset;
use cairn_fs_tools::track::Track;
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::estimator::{EstimatorBuilder, EstimatorKind};
use cairn_slam::frontend::FrontEndConfig;
use cairn_slam::frontend::association::AssociationMethod;
use common::simulate_seed;
use nalgebra::Vector2;
use rand::{Rng, SeedableRng, rngs::StdRng};

/// Random track 1 with 60 objects that are not cones (EUFS's
/// `inactive_noise`) at `off` metres from the centre line, clear of every
/// cone and of the track.
fn track_with_clutter(off: std::ops::Range<f64>) -> (Track, Course) {
    let (mut track, course) = random_track(1, &TrackRules::default());
    let mut rng = StdRng::seed_from_u64(5);
    while track.clutter.len() < 60 {
        let s = rng.random_range(0.0..course.length());
        let p = course.point_at(s);
        let tangent = course.point_at(s + 0.5) - p;
        let normal = Vector2::new(-tangent.y, tangent.x).normalize();
        let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        let object = p + normal * side * rng.random_range(off.clone());
        let clear_of_cones = track
            .cones
            .iter()
            .all(|c| (c.position - object).norm() > 1.5);
        if clear_of_cones && course.clearance(&[object]) > 2.5 {
            track.clutter.push(object);
        }
    }
    (track, course)
}

#[test]
fn clutter_seen_only_from_near_the_range_limit_leaves_the_map_too() {
    // Objects 13–14.5 m off the centre line, detected in 30% of the scans
    // with a random colour, only while 13–15 m away. Judged with the
    // mapping's margin (in view within 14 m), most were in view in too few
    // scans for their misses to count: 22 stayed in the map in these 4
    // runs. With the final margin and 6 sightings needed, 3 stay: objects
    // whose detections of one colour were matched to them while the others
    // started landmarks of their own, so that their colours look a cone's.
    let (track, course) = track_with_clutter(13.0..14.5);
    let config = assumed_config(
        "standard",
        AssociationMethod::MaximumLikelihood,
        EstimatorKind::Graph,
    )
    .expect("the preset has a shipped config");
    let mut phantoms = 0;
    for seed in 0..4 {
        let sim = simulate_seed(&track, &course, seed);
        let (slam, report) = run_and_score(&sim, config.clone());
        println!("seed {seed}: {report:?}");
        assert_eq!(slam.loop_closures(), 1, "seed {seed}");
        assert_eq!(report.missed, 0, "seed {seed}");
        phantoms += report.phantom;
    }
    assert!(phantoms <= 4, "{phantoms} phantom landmarks in 4 runs");
}

#[test]
fn clutter_objects_beside_the_track_leave_the_map_at_the_end() {
    // Objects that are not cones (EUFS's `inactive_noise`), detected in 30%
    // of the scans with a random colour, 3–7 m off the centre line and
    // clear of every cone. Many are seen too few times while mapping to be
    // judged; the run's colours and detections together settle them.
    let (track, course) = track_with_clutter(3.0..7.0);
    let preset = Preset::standard();
    let config = assumed_config(
        preset.name,
        AssociationMethod::Tracking,
        EstimatorKind::Graph,
    )
    .expect("the preset has a shipped config");
    // Phantoms and accuracy without and with the matching in hindsight,
    // which also judges clutter again on the colours it matched.
    let mut phantoms = [0, 0];
    let mut accuracy = [0.0, 0.0];
    for seed in 0..3 {
        let sim = simulate_seed(&track, &course, seed);
        for (k, hindsight) in [false, true].into_iter().enumerate() {
            let config = FrontEndConfig {
                hindsight,
                ..config.clone()
            };
            let (slam, report) = run_and_score(&sim, config);
            println!("seed {seed} hindsight {hindsight}: {report:?}");
            assert_eq!(slam.loop_closures(), 1);
            assert_eq!(report.missed, 0, "seed {seed}");
            phantoms[k] += report.phantom;
            accuracy[k] += report.association_accuracy / 3.0;
        }
    }
    println!("phantoms {phantoms:?}, accuracy {accuracy:?}");
    // 60 in the three runs when only the mapping judged clutter; measured
    // 3 without the matching in hindsight, 0 with it.
    assert!(phantoms[0] <= 5, "{phantoms:?} phantom landmarks in 3 runs");
    assert!(
        phantoms[1] <= 1 && phantoms[1] <= phantoms[0],
        "{phantoms:?}"
    );
    assert!(accuracy[0] > 0.995, "association accuracy {accuracy:?}");
    assert!(
        accuracy[1] >= accuracy[0],
        "association accuracy {accuracy:?}"
    );
}

#[test]
fn the_filters_leave_clutter_out_of_their_maps() {
    // The objects 3–7 m off the centre line: EKF-SLAM and FastSLAM judge
    // their maps as the graph does, by the colours and by the scans that
    // had a landmark in view without detecting it, from the poses they
    // estimated as they went.
    let (track, course) = track_with_clutter(3.0..7.0);
    let sim = simulate_seed(&track, &course, 0);
    for kind in [EstimatorKind::Ekf, EstimatorKind::FastSlam2] {
        let config = assumed_config("standard", AssociationMethod::MaximumLikelihood, kind)
            .expect("the preset has a shipped config");
        let mut builder = EstimatorBuilder::new(kind, config);
        builder.particles = 30;
        let (_, report) = run_estimator(&sim, &builder);
        println!("{}: {report:?}", kind.name());
        // Without the judgement EKF-SLAM kept 18 phantoms (97.2% of the
        // detections right), now 2 (98.7%). FastSLAM's best particle keeps
        // its first lap's drift, so most of its phantoms are cones mapped
        // twice, each leaving a true cone missed: the clutter among them
        // went from 9 to none. The bounds guard these measurements.
        let clutter = report.phantom.saturating_sub(report.missed);
        assert!(clutter <= 3, "{}: {report:?}", kind.name());
    }
}
