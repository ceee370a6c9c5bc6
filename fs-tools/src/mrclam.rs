//! The UTIAS MRCLAM dataset (Leung, Halpern, Barfoot and Liu, IJRR 2011) as
//! a cone-SLAM log and its ground truth.
//!
//! A dataset folder holds `Barcodes.dat` (`subject barcode`),
//! `Landmark_Groundtruth.dat` (`subject x y σx σy`) and per robot
//! `RobotN_Odometry.dat` (`t v ω`), `RobotN_Measurement.dat`
//! (`t barcode range bearing`) and, where Vicon recorded it,
//! `RobotN_Groundtruth.dat` (`t x y θ`). Subjects 1–5 are the robots, 6–20
//! the landmarks; a barcode in no row of `Barcodes.dat` is a misreading.
//!
//! [`import`] turns one robot's files into:
//! - the log: one `odom` record per odometry line, one `cones` scan per
//!   measurement time stamp with the landmark detections as range/bearing of
//!   colour `unknown` (the barcode becomes the tracker id only when asked),
//!   and, where Vicon saw the robot, a `start` record with its pose when the
//!   odometry begins. Times are seconds since the first odometry record.
//!   Measurements before it (no motion to go with them) and detections of
//!   other robots are left out and counted;
//! - the truth: the landmarks in `Landmark_Groundtruth.dat`'s row order, the
//!   Vicon trajectory over the log's time span, and for every detection the
//!   row of the landmark its barcode names, or none for a misread barcode.

use cairn_core::SE2;
use cairn_core::se2::normalize_angle;
use cairn_slam::Color;
use cairn_slam::Cone;
use cairn_slam::files::{Association, StampedPose};
use cairn_slam::log::{Detection, Record};
use nalgebra::{Matrix2, Vector2};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The robots of a dataset are subjects 1 to this.
pub const ROBOTS: u32 = 5;

/// What to import.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// The robot, 1 to [`ROBOTS`].
    pub robot: u32,
    /// Give each detection its barcode as the tracker id (for the
    /// tracking-assisted association); without it the log says nothing of
    /// which landmark a detection is.
    pub ids: bool,
}

/// An imported recording.
#[derive(Clone, Debug)]
pub struct Import {
    /// The log records in time order.
    pub log: Vec<Record>,
    /// The landmarks, in `Landmark_Groundtruth.dat`'s order, colour
    /// `unknown`, with Vicon's variances.
    pub truth_map: Vec<Cone>,
    /// The robot's Vicon poses over the log's time span, when recorded.
    pub truth_trajectory: Option<Vec<StampedPose>>,
    /// For every detection of the log, the row of its landmark in
    /// `truth_map`, or none for a misread barcode.
    pub truth_associations: Vec<Association>,
    /// What was read and what was left out.
    pub counts: Counts,
}

/// What an import read and left out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Odometry records written.
    pub odometry: usize,
    /// Scans written.
    pub scans: usize,
    /// Detections written (landmarks and misread barcodes).
    pub detections: usize,
    /// Detections whose barcode is in no row of `Barcodes.dat`.
    pub misread: usize,
    /// Detections of other robots, left out.
    pub robots: usize,
    /// Measurements before the first odometry record, left out.
    pub before_odometry: usize,
}

/// Why a folder could not be imported.
#[derive(Debug, thiserror::Error)]
pub enum MrclamError {
    /// A file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// A line is not what the format says.
    #[error("{}: line {line}: {message}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The folder is not an MRCLAM dataset, or lacks what the import needs.
    #[error("{}: not an MRCLAM dataset: {why}", dir.display())]
    NotMrclam {
        /// The folder.
        dir: PathBuf,
        /// What is missing.
        why: String,
    },
    /// The robot number is out of range.
    #[error("the robot must be 1 to {ROBOTS}, got {0}")]
    Robot(u32),
}

/// Reads one robot's recording from a dataset folder.
pub fn import(dir: &Path, options: &Options) -> Result<Import, MrclamError> {
    if !(1..=ROBOTS).contains(&options.robot) {
        return Err(MrclamError::Robot(options.robot));
    }
    let not_mrclam = |why: String| MrclamError::NotMrclam {
        dir: dir.to_path_buf(),
        why,
    };
    for name in ["Barcodes.dat", "Landmark_Groundtruth.dat"] {
        if !dir.join(name).is_file() {
            return Err(not_mrclam(format!("no {name}")));
        }
    }
    let robot = options.robot;
    let odometry_path = dir.join(format!("Robot{robot}_Odometry.dat"));
    let measurement_path = dir.join(format!("Robot{robot}_Measurement.dat"));
    for path in [&odometry_path, &measurement_path] {
        if !path.is_file() {
            return Err(not_mrclam(format!("no {}", file_name(path))));
        }
    }
    let subject_of = read_barcodes(&dir.join("Barcodes.dat"))?;
    let (truth_map, row_of) = read_landmarks(&dir.join("Landmark_Groundtruth.dat"))?;
    let odometry = read_table::<3>(&odometry_path, &[Column::Time, Column::Real, Column::Real])?;
    let measurements = read_table::<4>(
        &measurement_path,
        &[
            Column::Time,
            Column::Integer,
            Column::NonNegative,
            Column::Real,
        ],
    )?;
    let truth_path = dir.join(format!("Robot{robot}_Groundtruth.dat"));
    let truth = if truth_path.is_file() {
        Some(read_table::<4>(
            &truth_path,
            &[Column::Time, Column::Real, Column::Real, Column::Real],
        )?)
    } else {
        None
    };
    let Some(first) = odometry.first() else {
        return Err(not_mrclam(format!(
            "{} is empty",
            file_name(&odometry_path)
        )));
    };
    let t0 = first.0;
    let seconds = |t: i64| (t - t0) as f64 / 1000.0;

    let mut import = Import {
        log: Vec::with_capacity(odometry.len() + measurements.len()),
        truth_map,
        truth_trajectory: None,
        truth_associations: Vec::new(),
        counts: Counts::default(),
    };
    if let Some(pose) = truth.as_deref().and_then(|truth| pose_at(truth, t0)) {
        import.log.push(Record::Start { t: 0.0, pose });
    }
    let scans = group_scans(&measurements);
    let mut odometry = odometry.iter().peekable();
    for scan in scans {
        let t = scan[0].0;
        while let Some(o) = odometry.next_if(|o| o.0 <= t) {
            push_odometry(&mut import, seconds(o.0), &o.1);
        }
        if t < t0 {
            import.counts.before_odometry += scan.len();
            continue;
        }
        let mut cones = Vec::new();
        for &(_, [_, barcode, range, bearing]) in scan {
            let barcode = barcode as u32;
            let subject = subject_of.get(&barcode).copied();
            if subject.is_some_and(|s| (1..=ROBOTS).contains(&s)) {
                import.counts.robots += 1;
                continue;
            }
            let landmark = subject.and_then(|s| row_of.get(&s).copied());
            import.counts.misread += usize::from(landmark.is_none());
            import.truth_associations.push(Association {
                scan: import.counts.scans,
                det: cones.len(),
                landmark,
            });
            cones.push(Detection {
                position: Vector2::new(range * bearing.cos(), range * bearing.sin()),
                range_bearing: Some((range, bearing)),
                color: Color::Unknown,
                id: options.ids.then_some(u64::from(barcode)),
                covariance: None,
            });
        }
        if cones.is_empty() {
            continue;
        }
        import.counts.scans += 1;
        import.counts.detections += cones.len();
        import.log.push(Record::Cones {
            t: seconds(t),
            cones,
        });
    }
    for o in odometry {
        push_odometry(&mut import, seconds(o.0), &o.1);
    }
    let end = import.log.last().map_or(0.0, Record::time);
    import.truth_trajectory = truth.map(|truth| {
        truth
            .iter()
            .map(|(t, v)| StampedPose {
                t: seconds(*t),
                pose: SE2::new(v[1], v[2], v[3]),
            })
            .filter(|p| (0.0..=end).contains(&p.t))
            .collect()
    });
    Ok(import)
}

fn push_odometry(import: &mut Import, t: f64, v: &[f64]) {
    import.log.push(Record::Odom {
        t,
        v: v[1],
        yaw_rate: v[2],
        steer: None,
        vy: None,
    });
    import.counts.odometry += 1;
}

/// Consecutive measurements with one time stamp: one camera frame.
fn group_scans<const N: usize>(rows: &[(i64, [f64; N])]) -> Vec<&[(i64, [f64; N])]> {
    rows.chunk_by(|a, b| a.0 == b.0).collect()
}

/// The Vicon pose at `t` (milliseconds), interpolated between the samples
/// around it; none outside the recording.
fn pose_at(truth: &[(i64, [f64; 4])], t: i64) -> Option<SE2> {
    let i = truth.partition_point(|s| s.0 < t);
    let b = truth.get(i)?;
    if b.0 == t || i == 0 {
        return (b.0 == t).then(|| SE2::new(b.1[1], b.1[2], b.1[3]));
    }
    let a = &truth[i - 1];
    let u = (t - a.0) as f64 / (b.0 - a.0) as f64;
    let lerp = |k: usize| a.1[k] + u * (b.1[k] - a.1[k]);
    let theta = a.1[3] + u * normalize_angle(b.1[3] - a.1[3]);
    Some(SE2::new(lerp(1), lerp(2), theta))
}

/// `Barcodes.dat`: barcode → subject.
fn read_barcodes(path: &Path) -> Result<HashMap<u32, u32>, MrclamError> {
    let rows = read_table::<2>(path, &[Column::Integer, Column::Integer])?;
    let mut subject_of = HashMap::new();
    for (line, (_, [subject, barcode])) in rows.iter().enumerate() {
        if subject_of
            .insert(*barcode as u32, *subject as u32)
            .is_some()
        {
            return Err(MrclamError::Line {
                path: path.to_path_buf(),
                line: line + 1,
                message: format!("barcode {barcode} is listed twice"),
            });
        }
    }
    Ok(subject_of)
}

/// `Landmark_Groundtruth.dat`: the landmarks in row order, and subject → row.
fn read_landmarks(path: &Path) -> Result<(Vec<Cone>, HashMap<u32, usize>), MrclamError> {
    let rows = read_table::<5>(
        path,
        &[
            Column::Integer,
            Column::Real,
            Column::Real,
            Column::NonNegative,
            Column::NonNegative,
        ],
    )?;
    let mut row_of = HashMap::new();
    let mut cones = Vec::new();
    for (_, [subject, x, y, sx, sy]) in rows {
        let subject = subject as u32;
        if subject <= ROBOTS || row_of.insert(subject, cones.len()).is_some() {
            return Err(MrclamError::Line {
                path: path.to_path_buf(),
                line: cones.len() + 1,
                message: format!("subject {subject} is a robot or listed twice"),
            });
        }
        cones.push(Cone {
            position: Vector2::new(x, y),
            color: Color::Unknown,
            covariance: Matrix2::new(sx * sx, 0.0, 0.0, sy * sy),
        });
    }
    Ok((cones, row_of))
}

/// What a column holds.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Column {
    /// Seconds since 1970, kept as whole milliseconds (the files' resolution).
    Time,
    /// A whole number from 0 to 2³¹.
    Integer,
    /// A finite number.
    Real,
    /// A finite number ≥ 0.
    NonNegative,
}

/// The times of the files lie between 1970 and about the year 5000: whole
/// milliseconds fit an `i64` with room to subtract.
const LATEST_TIME: f64 = 1e11;

/// Reads a whitespace-separated table of `N` columns (lines starting with
/// `#` are comments). A `Time` in the first column must not go backwards;
/// it comes back as milliseconds and its entry in the array is left zero, so
/// the other columns keep their positions.
fn read_table<const N: usize>(
    path: &Path,
    columns: &[Column; N],
) -> Result<Vec<(i64, [f64; N])>, MrclamError> {
    let bytes = std::fs::read(path).map_err(|source| MrclamError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let text = String::from_utf8(bytes).map_err(|e| MrclamError::Line {
        path: path.to_path_buf(),
        line: 1 + e.as_bytes()[..e.utf8_error().valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count(),
        message: "not UTF-8 text".into(),
    })?;
    let timed = columns[0] == Column::Time;
    let mut rows = Vec::new();
    let mut last = i64::MIN;
    for (i, raw) in text.lines().enumerate() {
        let raw = raw.trim();
        if raw.is_empty() || raw.starts_with('#') {
            continue;
        }
        let error = |message: String| MrclamError::Line {
            path: path.to_path_buf(),
            line: i + 1,
            message,
        };
        let fields: Vec<&str> = raw.split_whitespace().collect();
        if fields.len() != N {
            return Err(error(format!(
                "expected {N} columns, found {}",
                fields.len()
            )));
        }
        let mut values = [0.0; N];
        let mut time = 0;
        for (k, (field, column)) in fields.iter().zip(columns).enumerate() {
            let x: f64 = field
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| error(format!("column {}: '{field}' is not a number", k + 1)))?;
            match column {
                Column::Time if (0.0..LATEST_TIME).contains(&x) => {
                    time = (x * 1000.0).round() as i64;
                }
                Column::Integer if x.fract() == 0.0 && (0.0..=2f64.powi(31)).contains(&x) => {
                    values[k] = x;
                }
                Column::Real => values[k] = x,
                Column::NonNegative if x >= 0.0 => values[k] = x,
                _ => {
                    let want = match column {
                        Column::Time => "a time in seconds since 1970",
                        Column::Integer => "a whole number from 0 to 2^31",
                        _ => "not negative",
                    };
                    return Err(error(format!("column {}: '{field}' must be {want}", k + 1)));
                }
            }
        }
        if timed {
            if time < last {
                return Err(error("time goes backwards".into()));
            }
            last = time;
            values[0] = 0.0;
        }
        rows.push((time, values));
    }
    Ok(rows)
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}
