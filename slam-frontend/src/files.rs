//! The trajectory (TUM) and association (CSV) files of FORMAT.md.

use cairn_core::SE2;
use std::fmt::Write as _;

/// The log's file name inside a run's folder.
pub const LOG: &str = "log.jsonl";
/// The true trajectory (TUM).
pub const TRUTH_TRAJ: &str = "truth_traj.tum";
/// The true association of every detection.
pub const TRUTH_ASSOC: &str = "truth_assoc.csv";
/// The true cones; their row order gives the ids in `truth_assoc.csv`.
pub const TRUTH_MAP: &str = "truth_map.csv";

/// A malformed trajectory or association line.
#[derive(Debug, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct FormatError {
    /// 1-based line number.
    pub line: usize,
    /// What is wrong with it.
    pub message: String,
}

/// A pose with its time stamp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StampedPose {
    /// Time (s).
    pub t: f64,
    /// Pose in the world frame.
    pub pose: SE2,
}

/// TUM format: `t x y z qx qy qz qw`, z = 0 and the yaw as a rotation about z.
pub fn trajectory_to_tum(poses: &[StampedPose]) -> String {
    let mut out = String::new();
    for p in poses {
        let (s, c) = (0.5 * p.pose.theta).sin_cos();
        let _ = writeln!(
            out,
            "{:.6} {:?} {:?} 0 0 0 {:?} {:?}",
            p.t, p.pose.t.x, p.pose.t.y, s, c
        );
    }
    out
}

/// Reads a TUM trajectory (lines starting with `#` are comments); the yaw is
/// taken from the full quaternion.
pub fn trajectory_from_tum(text: &str) -> Result<Vec<StampedPose>, FormatError> {
    let mut poses = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let raw = raw.trim();
        if raw.is_empty() || raw.starts_with('#') {
            continue;
        }
        let fields: Result<Vec<f64>, _> = raw.split_whitespace().map(str::parse::<f64>).collect();
        let error = |message: &str| FormatError {
            line: i + 1,
            message: message.to_string(),
        };
        let f = fields.map_err(|_| error("not a number"))?;
        if f.len() != 8 {
            return Err(error("expected 8 fields: t x y z qx qy qz qw"));
        }
        if f.iter().any(|x| !x.is_finite()) {
            return Err(error("not finite"));
        }
        let (qx, qy, qz, qw) = (f[4], f[5], f[6], f[7]);
        let yaw = (2.0 * (qw * qz + qx * qy)).atan2(1.0 - 2.0 * (qy * qy + qz * qz));
        poses.push(StampedPose {
            t: f[0],
            pose: SE2::new(f[1], f[2], yaw),
        });
    }
    Ok(poses)
}

/// The landmark a detection was associated with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Association {
    /// 0-based index of the `cones` record in the log.
    pub scan: usize,
    /// 0-based index of the detection inside it.
    pub det: usize,
    /// Map row (0-based), or `None` when rejected as spurious (`-1`).
    pub landmark: Option<usize>,
}

/// Associations in map rows: `detections` name landmarks by index (of
/// `landmarks` in all), and `map_rows` lists the landmarks of the map in
/// row order; detections of landmarks not in the map become `None`.
pub fn in_map_rows(
    detections: impl Iterator<Item = (usize, usize, Option<usize>)>,
    landmarks: usize,
    map_rows: &[usize],
) -> Vec<Association> {
    let mut row = vec![None; landmarks];
    for (k, &l) in map_rows.iter().enumerate() {
        row[l] = Some(k);
    }
    detections
        .map(|(scan, det, l)| Association {
            scan,
            det,
            landmark: l.and_then(|l| row.get(l).copied().flatten()),
        })
        .collect()
}

/// CSV `scan,det,landmark` with `-1` for rejected detections.
pub fn associations_to_csv(associations: &[Association]) -> String {
    let mut out = String::from("scan,det,landmark\n");
    for a in associations {
        let landmark = a.landmark.map_or(-1, |l| l as i64);
        let _ = writeln!(out, "{},{},{}", a.scan, a.det, landmark);
    }
    out
}

/// Reads an association CSV (the header row is optional).
pub fn associations_from_csv(text: &str) -> Result<Vec<Association>, FormatError> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let raw = raw.trim();
        if raw.is_empty() || (i == 0 && raw.starts_with("scan")) {
            continue;
        }
        let error = |message: &str| FormatError {
            line: i + 1,
            message: message.to_string(),
        };
        let f: Vec<&str> = raw.split(',').map(str::trim).collect();
        if f.len() != 3 {
            return Err(error("expected scan,det,landmark"));
        }
        let scan = f[0].parse().map_err(|_| error("bad scan index"))?;
        let det = f[1].parse().map_err(|_| error("bad detection index"))?;
        let landmark: i64 = f[2].parse().map_err(|_| error("bad landmark id"))?;
        if landmark < -1 {
            return Err(error("landmark id below -1"));
        }
        out.push(Association {
            scan,
            det,
            landmark: usize::try_from(landmark).ok(),
        });
    }
    Ok(out)
}
