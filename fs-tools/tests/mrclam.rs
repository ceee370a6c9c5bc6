//! The MRCLAM importer on slices of Dataset 6 and on broken folders. The
//! golden values were read by hand from the dataset's files.

#[path = "common/shared.rs"]
mod shared;

use cairn_fs_tools::mrclam::{Counts, MrclamError, Options, import};
use cairn_slam::Color;
use cairn_slam::log::Record;
use std::path::{Path, PathBuf};

fn dataset6() -> Option<PathBuf> {
    shared::shared_path("real/mrclam/MRCLAM_Dataset6")
}

/// A fresh folder under the system's temporary directory.
fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cairn-mrclam-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    dir
}

/// The first `lines` lines of a file of `from`, written into `to`.
fn head(from: &Path, to: &Path, name: &str, lines: usize) {
    let text = std::fs::read_to_string(from.join(name)).expect("the dataset's file reads");
    let slice: Vec<&str> = text.lines().take(lines).collect();
    std::fs::write(to.join(name), slice.join("\n") + "\n").expect("the slice writes");
}

fn scans(log: &[Record]) -> Vec<(f64, Vec<(f64, f64)>)> {
    log.iter()
        .filter_map(|r| match r {
            Record::Cones { t, cones } => Some((
                *t,
                cones
                    .iter()
                    .map(|d| d.range_bearing.expect("range/bearing"))
                    .collect(),
            )),
            _ => None,
        })
        .collect()
}

/// Robot 1's first 12 measurements (4 comment lines, then from
/// 1248444189.599) and 4 odometry records (from 1248444187.156).
#[test]
fn a_slice_of_robot_1_imports_as_read_by_hand() {
    let Some(dataset) = dataset6() else { return };
    let dir = folder("slice");
    for name in ["Barcodes.dat", "Landmark_Groundtruth.dat"] {
        head(&dataset, &dir, name, usize::MAX);
    }
    head(&dataset, &dir, "Robot1_Measurement.dat", 16);
    head(&dataset, &dir, "Robot1_Odometry.dat", 8);
    head(&dataset, &dir, "Robot1_Groundtruth.dat", 700);
    let import = import(
        &dir,
        &Options {
            robot: 1,
            ids: false,
        },
    )
    .expect("the slice imports");

    // Barcode 14 is robot 2 (5 lines; the frames that saw only it, 190.289,
    // 190.981 and 191.131, make no scan).
    // Barcode 90 is subject 15, landmark row 9; barcode 61 subject 14, row 8.
    assert_eq!(
        import.counts,
        Counts {
            odometry: 4,
            scans: 5,
            detections: 7,
            misread: 0,
            robots: 5,
            before_odometry: 0,
        }
    );
    let got = scans(&import.log);
    let want = vec![
        (2.443, vec![(6.758, -0.005)]),
        (2.672, vec![(6.6, -0.022), (6.626, 0.002)]),
        (2.903, vec![(6.561, -0.019)]),
        (3.363, vec![(6.448, -0.011), (6.6, 0.019)]),
        (3.826, vec![(6.652, 0.017)]),
    ];
    assert_eq!(got, want);
    let rows: Vec<(usize, usize, Option<usize>)> = import
        .truth_associations
        .iter()
        .map(|a| (a.scan, a.det, a.landmark))
        .collect();
    assert_eq!(
        rows,
        [
            (0, 0, Some(9)),
            (1, 0, Some(8)),
            (1, 1, Some(9)),
            (2, 0, Some(8)),
            (3, 0, Some(8)),
            (3, 1, Some(9)),
            (4, 0, Some(9)),
        ]
    );
    // Every detection is colourless and carries no id without --ids.
    for record in &import.log {
        if let Record::Cones { cones, .. } = record {
            assert!(
                cones
                    .iter()
                    .all(|d| d.color == Color::Unknown && d.id.is_none())
            );
        }
    }
    // The start: Vicon at 187.156, between 187.146 (1.41269620, -3.89080560,
    // 2.2720) and 187.157 (1.41271360, -3.89081880, 2.2720), 10/11 of the way.
    let Record::Start { t, pose } = &import.log[0] else {
        panic!("the log starts with a start record: {:?}", import.log[0]);
    };
    assert_eq!(*t, 0.0);
    assert!((pose.t.x - (1.4126962 + 0.0000174 * 10.0 / 11.0)).abs() < 1e-9);
    assert!((pose.t.y - (-3.8908056 - 0.0000132 * 10.0 / 11.0)).abs() < 1e-9);
    assert!((pose.theta - 2.272).abs() < 1e-12);
    // Odometry: 0.086 m/s, -0.398 rad/s from t = 0 in steps of 30, 11, 10 ms.
    let odometry: Vec<(f64, f64, f64)> = import
        .log
        .iter()
        .filter_map(|r| match r {
            Record::Odom { t, v, yaw_rate, .. } => Some((*t, *v, *yaw_rate)),
            _ => None,
        })
        .collect();
    assert_eq!(
        odometry,
        [
            (0.0, 0.086, -0.398),
            (0.03, 0.086, -0.398),
            (0.041, 0.086, -0.398),
            (0.051, 0.086, -0.398)
        ]
    );
    // The truth trajectory spans the log only, on its clock.
    let truth = import.truth_trajectory.expect("Vicon poses");
    assert!(truth.first().is_some_and(|p| p.t >= 0.0));
    assert!(truth.last().is_some_and(|p| p.t <= 3.826));
    assert_eq!(import.truth_map.len(), 15);
    // Row 9 is subject 15 (barcode 90).
    assert!(
        (import.truth_map[9].position - nalgebra::Vector2::new(1.54725918, 2.76939627)).norm()
            < 1e-12
    );

    // With --ids, the barcodes are the tracker ids.
    let with_ids = cairn_fs_tools::mrclam::import(
        &dir,
        &Options {
            robot: 1,
            ids: true,
        },
    )
    .expect("the slice imports");
    let ids: Vec<u64> = with_ids
        .log
        .iter()
        .filter_map(|r| match r {
            Record::Cones { cones, .. } => Some(cones.iter().filter_map(|d| d.id)),
            _ => None,
        })
        .flatten()
        .take(3)
        .collect();
    assert_eq!(ids, [90, 61, 90]);
    let _ = std::fs::remove_dir_all(&dir);
}

fn write(dir: &Path, name: &str, text: &str) {
    std::fs::write(dir.join(name), text).expect("the fixture writes");
}

/// A hand-made dataset: a misread barcode, a measurement before the
/// odometry, a robot seen, and no Vicon trajectory (as Dataset 1).
fn tiny(dir: &Path) {
    write(
        dir,
        "Barcodes.dat",
        "# subject barcode\n1 5\n2 14\n6 63\n7 81\n",
    );
    write(
        dir,
        "Landmark_Groundtruth.dat",
        "6 1.0 2.0 0.001 0.002\n7 -1.0 0.5 0 0\n",
    );
    write(
        dir,
        "Robot1_Odometry.dat",
        "100.000 0.1 0.0\n100.500 0.1 0.2\n",
    );
    write(
        dir,
        "Robot1_Measurement.dat",
        "99.000 63 2.0 0.1\n100.250 81 1.5 -0.2\n100.250 14 3.0 0.0\n100.250 99 2.5 0.3\n101.000 63 1.9 0.1\n",
    );
}

#[test]
fn misreads_robots_and_early_measurements_are_sorted_out() {
    let dir = folder("tiny");
    tiny(&dir);
    let import = import(
        &dir,
        &Options {
            robot: 1,
            ids: false,
        },
    )
    .expect("imports");
    assert_eq!(
        import.counts,
        Counts {
            odometry: 2,
            scans: 2,
            detections: 3,
            misread: 1,
            robots: 1,
            before_odometry: 1,
        }
    );
    assert!(import.truth_trajectory.is_none());
    assert!(
        !matches!(import.log[0], Record::Start { .. }),
        "no Vicon, no start"
    );
    let truth: Vec<Option<usize>> = import
        .truth_associations
        .iter()
        .map(|a| a.landmark)
        .collect();
    assert_eq!(truth, [Some(1), None, Some(0)]);
    assert_eq!(
        scans(&import.log),
        [
            (0.25, vec![(1.5, -0.2), (2.5, 0.3)]),
            (1.0, vec![(1.9, 0.1)])
        ]
    );
    // The odometry of 100.5 comes between the two scans.
    assert!(matches!(import.log[2], Record::Odom { t, .. } if t == 0.5));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn broken_folders_get_errors_that_name_the_file_and_line() {
    let dir = folder("broken");
    let err = import(
        &dir,
        &Options {
            robot: 1,
            ids: false,
        },
    )
    .unwrap_err();
    assert!(matches!(err, MrclamError::NotMrclam { .. }), "{err}");
    assert!(err.to_string().contains("no Barcodes.dat"), "{err}");
    tiny(&dir);
    assert!(matches!(
        import(
            &dir,
            &Options {
                robot: 6,
                ids: false
            }
        ),
        Err(MrclamError::Robot(6))
    ));
    let err = import(
        &dir,
        &Options {
            robot: 2,
            ids: false,
        },
    )
    .unwrap_err();
    assert!(err.to_string().contains("no Robot2_Odometry.dat"), "{err}");
    for (name, text, message) in [
        (
            "Robot1_Odometry.dat",
            "100.0 0.1\n",
            "line 1: expected 3 columns, found 2",
        ),
        (
            "Robot1_Odometry.dat",
            "100.0 0.1 0\n99.0 0.1 0\n",
            "line 2: time goes backwards",
        ),
        (
            "Robot1_Odometry.dat",
            "100.0 NaN 0\n",
            "line 1: column 2: 'NaN' is not a number",
        ),
        (
            "Robot1_Odometry.dat",
            "1e300 0.1 0\n",
            "line 1: column 1: '1e300' must be a time",
        ),
        (
            "Robot1_Measurement.dat",
            "100.0 63 -2.0 0.1\n",
            "line 1: column 3: '-2.0' must be not negative",
        ),
        (
            "Robot1_Measurement.dat",
            "100.0 6.5 2.0 0.1\n",
            "line 1: column 2: '6.5' must be a whole number",
        ),
        (
            "Barcodes.dat",
            "6 63\n7 63\n",
            "line 2: barcode 63 is listed twice",
        ),
        ("Robot1_Odometry.dat", "", "Robot1_Odometry.dat is empty"),
    ] {
        tiny(&dir);
        write(&dir, name, text);
        let err = import(
            &dir,
            &Options {
                robot: 1,
                ids: false,
            },
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains(message), "{name} {text:?}: {err}");
        assert!(err.contains(name), "{err}");
    }
    tiny(&dir);
    std::fs::write(dir.join("Robot1_Odometry.dat"), b"100.0 0.1 0\n\xff\n").expect("writes");
    let err = import(
        &dir,
        &Options {
            robot: 1,
            ids: false,
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("line 2: not UTF-8"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
