//! The hostile inputs of `shared/reliability/` that reach the front end's
//! readers and the simulator: each ends with a clear error, not a panic,
//! a hang or a wrong result.

mod common;

use cairn_fs_tools::course::Course;
use cairn_fs_tools::track::Track;
use std::path::PathBuf;

fn reliability() -> Option<PathBuf> {
    common::shared::shared_path("reliability")
}

/// Every track that panicked, allocated without bound or hung the
/// simulator is refused when read or when its course is built.
#[test]
fn degenerate_and_far_tracks_are_refused() {
    let Some(dir) = reliability() else { return };
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join("trkfuzz_sim_panics"))
        .expect("the fuzzer's finds")
        .map(|e| e.expect("an entry").path())
        .collect();
    for name in [
        "fssim_track_minimal_6_cones_same_point_PANIC.csv",
        "fssim_track_all_cones_same_point_PANIC.csv",
        "fssim_track_empty_xy_fields_PANIC.csv",
        "fssim_track_coords_1e300_PANIC.csv",
        "fssim_track_yaml_coords_1e300_PANIC.yaml",
        "fssim_eufs_acceleration_plus_cone_x1e300_PANIC_capacity_overflow.csv",
        "fssim_eufs_acceleration_plus_cone_x1e9_OOM_64GB_abort.csv",
        "fssim_eufs_acceleration_plus_cone_x1e6_HANG.csv",
    ] {
        files.push(dir.join(name));
    }
    assert_eq!(files.len(), 40);
    for path in files {
        let refused = match Track::load(&path) {
            Err(e) => e.to_string(),
            Ok(track) => match Course::from_track(&track) {
                Err(e) => e,
                Ok(course) => panic!("{}: a {} m course", path.display(), course.length()),
            },
        };
        assert!(
            [
                "line ",
                "course is",
                "straight is",
                "boundaries",
                "no centre line",
                "no cones"
            ]
            .iter()
            .any(|m| refused.contains(m)),
            "{}: {refused}",
            path.display()
        );
    }
}

/// Numbers past any vehicle's (a speed of 1.8·10³⁰⁸ m/s made the whole
/// trajectory NaN) are refused with the line and the field.
#[test]
fn log_numbers_beyond_a_vehicle_are_refused() {
    use cairn_slam::log::Log;
    let start = "{\"t\": 0.0, \"type\": \"odom\", \"v\": 1.0, \"yaw_rate\": 0.0}\n";
    for (record, field) in [
        (
            "{\"t\": 1.0, \"type\": \"odom\", \"v\": 1.7976931348623157e308, \"yaw_rate\": 0.0}",
            "'v'",
        ),
        (
            "{\"t\": 1.0, \"type\": \"odom\", \"v\": 1.0, \"yaw_rate\": 1e5}",
            "'yaw_rate'",
        ),
        (
            "{\"t\": 1.0, \"type\": \"cones\", \"cones\": [{\"r\": 1e9, \"b\": 0.1}]}",
            "'r'",
        ),
        (
            "{\"t\": 1e300, \"type\": \"odom\", \"v\": 1.0, \"yaw_rate\": 0.0}",
            "'t'",
        ),
        (
            "{\"t\": 1.0, \"type\": \"start\", \"x\": 1e7, \"y\": 0.0}",
            "'x'",
        ),
        (
            "{\"t\": 1.0, \"type\": \"points\", \"points\": [[1e7, 0.0]]}",
            "point 0",
        ),
    ] {
        let err = Log::parse(&format!("{start}{record}\n"), false).unwrap_err();
        assert_eq!(err.line, 2, "{record}");
        assert!(err.message.contains(field), "{record}: {}", err.message);
    }
}

/// A line that is not UTF-8 is a bad line like any other: named, or
/// skipped alone under `--skip-bad`.
#[test]
fn a_line_that_is_not_utf8_is_one_bad_line() {
    use cairn_slam::log::{Log, ScanLimits};
    let mut bytes = b"{\"t\": 0.0, \"type\": \"odom\", \"v\": 1.0, \"yaw_rate\": 0.0}\n".to_vec();
    bytes.extend_from_slice(
        b"{\"t\": 0.5, \"type\": \"odom\", \"v\": 1.0, \xff \"yaw_rate\": 0.0}\n",
    );
    bytes.extend_from_slice(b"{\"t\": 1.0, \"type\": \"odom\", \"v\": 2.0, \"yaw_rate\": 0.0}\r\n");
    let err = Log::parse_bytes(&bytes, false, &ScanLimits::default()).unwrap_err();
    assert_eq!((err.line, err.message.as_str()), (2, "not UTF-8 text"));
    let log = Log::parse_bytes(&bytes, true, &ScanLimits::default()).expect("skips the line");
    assert_eq!(log.records.len(), 2);
    assert_eq!(log.skipped, [(2, "not UTF-8 text".to_string())]);
}

/// A map whose variances are no covariance (negative ones made the
/// localisation 9.6 m off without a word) is refused with its line.
#[test]
fn a_map_with_negative_variances_is_refused() {
    use cairn_slam::map::map_from_csv;
    let err =
        map_from_csv("tag,x,y,direction,x_variance,y_variance,xy_covariance\nblue,1,2,0,-1,-1,0\n")
            .unwrap_err()
            .to_string();
    assert!(
        err.contains("line 2") && err.contains("not a covariance"),
        "{err}"
    );
    let err = map_from_csv("blue,1,2,0,0.01,0.01,0.5\n")
        .unwrap_err()
        .to_string();
    assert!(err.contains("line 1"), "{err}");
    assert_eq!(
        map_from_csv("blue,1,2,0,0.01,0.02,0.001\n")
            .expect("a covariance")
            .len(),
        1
    );
}

/// A scan larger than any sensor's (2,000 cones took EKF-SLAM 123 s, 10⁶
/// points the clustering minutes) is refused by line with its limit, which
/// `fs-slam --max-detections` / `--max-points` raise.
#[test]
fn scans_past_the_limits_are_refused_with_the_flag_that_raises_them() {
    use cairn_slam::log::{Log, ScanLimits};
    let cones: Vec<String> = (0..501)
        .map(|k| format!("{{\"r\": {}, \"b\": 0.1}}", 1.0 + k as f64 * 0.01))
        .collect();
    let scan = format!(
        "{{\"t\": 1.0, \"type\": \"cones\", \"cones\": [{}]}}\n",
        cones.join(",")
    );
    let err = Log::parse(&scan, false).unwrap_err();
    assert_eq!(err.line, 1);
    assert!(
        err.message.contains("501 detections") && err.message.contains("--max-detections"),
        "{}",
        err.message
    );
    let raised = ScanLimits {
        detections: 501,
        ..ScanLimits::default()
    };
    assert_eq!(
        Log::parse_bytes(scan.as_bytes(), false, &raised)
            .expect("within the limit")
            .scans(),
        1
    );
    let points = format!(
        "{{\"t\": 1.0, \"type\": \"points\", \"points\": [{}]}}\n",
        vec!["[1.0, 2.0]"; 50_001].join(",")
    );
    let err = Log::parse(&points, false).unwrap_err();
    assert!(err.message.contains("--max-points"), "{}", err.message);
}

/// A `start` record after the run has begun is ignored by every estimator:
/// the pose does not jump to it.
#[test]
fn a_second_start_record_does_not_move_the_car() {
    use cairn_core::SE2;
    use cairn_slam::Color;
    use cairn_slam::estimator::{EstimatorBuilder, EstimatorKind};
    use cairn_slam::frontend::FrontEndConfig;
    use cairn_slam::log::{Detection, Record};
    use nalgebra::Vector2;
    let cones = [
        (5.0, 2.0, Color::Blue),
        (5.0, -2.0, Color::Yellow),
        (9.0, 2.0, Color::Blue),
    ];
    let mut records = vec![Record::Start {
        t: 0.0,
        pose: SE2::identity(),
    }];
    for k in 0..=20 {
        let t = 0.1 * f64::from(k);
        records.push(Record::Odom {
            t,
            v: 1.0,
            yaw_rate: 0.0,
            steer: None,
            vy: None,
        });
        if k == 10 {
            records.push(Record::Start {
                t,
                pose: SE2::new(100.0, 100.0, 1.0),
            });
        }
        // The cones as seen from x = t (straight ahead at 1 m/s).
        let seen = cones
            .iter()
            .map(|&(x, y, color)| Detection {
                position: Vector2::new(x - t, y),
                range_bearing: None,
                color,
                id: None,
                covariance: None,
            })
            .collect();
        records.push(Record::Cones { t, cones: seen });
    }
    for kind in [
        EstimatorKind::Graph,
        EstimatorKind::Ekf,
        EstimatorKind::FastSlam1,
        EstimatorKind::FastSlam2,
    ] {
        let mut slam = EstimatorBuilder::new(kind, FrontEndConfig::default()).build();
        for record in &records {
            slam.process(record);
        }
        let last = slam.trajectory().last().expect("a trajectory").pose;
        assert!(
            (last.t - Vector2::new(2.0, 0.0)).norm() < 0.5,
            "{kind:?} ends at {last:?}"
        );
    }
}
