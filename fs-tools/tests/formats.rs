//! The FORMAT.md files: round trips, bad input with line numbers, `--skip-bad`.

use cairn_core::SE2;
use cairn_fs_tools::sim::{SimConfig, simulate};
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::files::{
    Association, StampedPose, associations_from_csv, associations_to_csv, trajectory_from_tum,
    trajectory_to_tum,
};
use cairn_slam::log::{Log, Record, to_jsonl};
use cairn_slam::map::{map_from_csv, map_to_csv};
use cairn_slam::{Color, Cone};

#[test]
fn the_format_md_example_parses() {
    let text = r#"{"t": 0.00, "type": "start", "x": 1.0, "y": 2.0, "yaw": 0.5}
{"t": 0.02, "type": "odom", "v": 4.98, "yaw_rate": 0.012}
{"t": 0.02, "type": "odom", "v": 4.98, "yaw_rate": 0.012, "steer": 0.05}
{"t": 0.10, "type": "cones", "cones": [{"x": 7.9, "y": 1.6, "color": "blue"}, {"r": 9.3, "b": -0.21, "color": "yellow", "id": 17, "cov": [0.01, 0.0, 0.02]}]}
{"t": 0.10, "type": "points", "points": [[1.0, 2.0, 0.1], [3.0, 4.0]]}
{"t": 0.11, "type": "imu", "ax": 1.0}
"#;
    let log = Log::parse(text, false).unwrap();
    assert_eq!(log.records.len(), 5);
    assert_eq!(log.unknown_types.get("imu"), Some(&1));
    assert_eq!(
        log.records[0],
        Record::Start {
            t: 0.0,
            pose: SE2::new(1.0, 2.0, 0.5)
        }
    );
    let Record::Cones { cones, .. } = &log.records[3] else {
        panic!("not a scan")
    };
    assert_eq!(cones[0].color, Color::Blue);
    assert!((cones[1].position.x - 9.3 * (-0.21f64).cos()).abs() < 1e-12);
    assert_eq!(cones[1].id, Some(17));
    assert!((cones[1].covariance.unwrap()[(1, 1)] - 0.02).abs() < 1e-15);
    let Record::Points { points, .. } = &log.records[4] else {
        panic!("not points")
    };
    assert_eq!(points[1], [3.0, 4.0, 0.0]);
}

#[test]
fn bad_lines_name_their_line_or_are_skipped() {
    let cases = [
        ("{\"t\": 0.1, \"type\": \"odom\", \"v\": 1.0}", "yaw_rate"),
        (
            "{\"t\": 0.1, \"type\": \"odom\", \"v\": NaN, \"yaw_rate\": 0}",
            "JSON",
        ),
        (
            "{\"t\": 0.0, \"type\": \"odom\", \"v\": 1.0, \"yaw_rate\": 0}",
            "backwards",
        ),
        ("not json", "JSON"),
        (
            "{\"t\": 0.2, \"type\": \"cones\", \"cones\": [{\"r\": -1, \"b\": 0}]}",
            "range",
        ),
        (
            "{\"t\": 0.2, \"type\": \"cones\", \"cones\": [{\"x\": 1, \"y\": 0, \"color\": \"red\"}]}",
            "colour",
        ),
        (
            "{\"t\": 0.2, \"type\": \"cones\", \"cones\": [{\"x\": 1, \"y\": 0, \"cov\": [1, 2, 1]}]}",
            "positive definite",
        ),
        ("{\"t\": 1e999, \"type\": \"start\"}", "t"),
    ];
    for (bad, words) in cases {
        let text = format!(
            "{{\"t\": 0.05, \"type\": \"start\"}}\n{bad}\n{{\"t\": 0.3, \"type\": \"odom\", \"v\": 1, \"yaw_rate\": 0}}\n"
        );
        let err = Log::parse(&text, false).unwrap_err();
        assert_eq!(err.line, 2, "{bad}");
        assert!(err.message.contains(words), "{bad}: {}", err.message);
        let log = Log::parse(&text, true).unwrap();
        assert_eq!(log.skipped.len(), 1);
        assert_eq!(log.records.len(), 2);
    }
}

#[test]
fn simulated_logs_round_trip_through_json_lines() {
    let (track, course) = random_track(3, &TrackRules::default());
    let sim = simulate(
        &track,
        &course,
        &SimConfig {
            laps: 0.2,
            ..SimConfig::default()
        },
    );
    let text = to_jsonl(&sim.log);
    let back = Log::parse(&text, false).unwrap();
    assert!(back.records == sim.log, "the log changed on a round trip");
}

#[test]
fn maps_trajectories_and_associations_round_trip() {
    let mut cone = Cone::new(1.5, -2.25, Color::BigOrange);
    cone.covariance = nalgebra::Matrix2::new(0.01, 0.002, 0.002, 0.03);
    let cones = vec![cone, Cone::new(0.1, 0.2, Color::Unknown)];
    assert_eq!(map_from_csv(&map_to_csv(&cones)).unwrap(), cones);

    let poses = vec![
        StampedPose {
            t: 0.5,
            pose: SE2::new(1.0, 2.0, 3.0),
        },
        StampedPose {
            t: 0.6,
            pose: SE2::new(-1.0, 0.0, -2.5),
        },
    ];
    let back = trajectory_from_tum(&trajectory_to_tum(&poses)).unwrap();
    for (a, b) in poses.iter().zip(&back) {
        assert!((a.t - b.t).abs() < 1e-6);
        assert_eq!(a.pose.t, b.pose.t);
        assert!((a.pose.theta - b.pose.theta).abs() < 1e-12);
    }

    let assoc = vec![
        Association {
            scan: 0,
            det: 0,
            landmark: Some(4),
        },
        Association {
            scan: 0,
            det: 1,
            landmark: None,
        },
    ];
    let text = associations_to_csv(&assoc);
    assert!(text.contains("0,1,-1"));
    assert_eq!(associations_from_csv(&text).unwrap(), assoc);
    assert_eq!(
        associations_from_csv("scan,det,landmark\n0,1,x\n")
            .unwrap_err()
            .line,
        2
    );
    assert_eq!(trajectory_from_tum("0 1 2\n").unwrap_err().line, 1);
}
