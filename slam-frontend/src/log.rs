//! The input log (FORMAT.md): JSON Lines of `start`, `odom`, `cones` and
//! `points` records, ordered by time.

use crate::color::Color;
use cairn_core::SE2;
use nalgebra::{Matrix2, Vector2};
use serde_json::{Map, Value, json};
use std::collections::BTreeMap;

/// A malformed log line.
#[derive(Debug, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct LogError {
    /// 1-based line number.
    pub line: usize,
    /// What is wrong with it.
    pub message: String,
}

/// One cone detection in the vehicle frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Detection {
    /// Position in the vehicle frame (x forward, y left).
    pub position: Vector2<f64>,
    /// Range and bearing when the log gave the cone that way.
    pub range_bearing: Option<(f64, f64)>,
    /// Detected colour.
    pub color: Color,
    /// The tracker's identity, if any.
    pub id: Option<u64>,
    /// Covariance in the vehicle frame, if the log gives one.
    pub covariance: Option<Matrix2<f64>>,
}

/// One record of the log.
#[derive(Clone, Debug, PartialEq)]
pub enum Record {
    /// The initial pose.
    Start {
        /// Time (s).
        t: f64,
        /// The pose in the world frame.
        pose: SE2,
    },
    /// Odometry held until the next `odom`.
    Odom {
        /// Time (s).
        t: f64,
        /// Forward speed (m/s).
        v: f64,
        /// Yaw rate (rad/s).
        yaw_rate: f64,
        /// Steering angle (rad), for the bicycle model.
        steer: Option<f64>,
        /// Lateral speed (m/s).
        vy: Option<f64>,
    },
    /// A detection scan.
    Cones {
        /// Time (s).
        t: f64,
        /// The detections in scan order.
        cones: Vec<Detection>,
    },
    /// A raw point cloud in the vehicle frame (z = 0 when omitted).
    Points {
        /// Time (s).
        t: f64,
        /// The points.
        points: Vec<[f64; 3]>,
    },
}

impl Record {
    /// The record's time.
    pub fn time(&self) -> f64 {
        match self {
            Record::Start { t, .. }
            | Record::Odom { t, .. }
            | Record::Cones { t, .. }
            | Record::Points { t, .. } => *t,
        }
    }
}

/// A parsed log and what was set aside while reading it.
#[derive(Clone, Debug, Default)]
pub struct Log {
    /// The records in file order.
    pub records: Vec<Record>,
    /// Records of unknown `type`, by type.
    pub unknown_types: BTreeMap<String, usize>,
    /// Bad lines skipped under `skip_bad`: (line, message).
    pub skipped: Vec<(usize, String)>,
}

/// The largest scans a log may hold: the estimators' cost grows with a
/// scan's size (EKF-SLAM took 123 s over one scan of 2,000 new cones, the
/// clustering minutes over 10⁶ points), and real sensors give far less.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScanLimits {
    /// Detections in one `cones` record.
    pub detections: usize,
    /// Points in one `points` record.
    pub points: usize,
}

impl Default for ScanLimits {
    /// 500 detections (a scan of a track sees under 100 cones) and 50,000
    /// points (a lidar scan after ground removal holds a few thousand).
    fn default() -> Self {
        Self {
            detections: 500,
            points: 50_000,
        }
    }
}

impl Log {
    /// Parses a log. With `skip_bad`, malformed lines (bad JSON, missing or
    /// non-finite numbers, time going backwards, scans past the default
    /// [`ScanLimits`]) are skipped and listed in [`Log::skipped`]; without
    /// it the first one is an error.
    pub fn parse(text: &str, skip_bad: bool) -> Result<Log, LogError> {
        Self::parse_bytes(text.as_bytes(), skip_bad, &ScanLimits::default())
    }

    /// [`Log::parse`] on the bytes of a file, with these scan limits: a
    /// line that is not UTF-8 is a bad line like any other (skipped under
    /// `skip_bad`).
    pub fn parse_bytes(bytes: &[u8], skip_bad: bool, limits: &ScanLimits) -> Result<Log, LogError> {
        let mut log = Log::default();
        let mut last_t = f64::NEG_INFINITY;
        for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
            let line = i + 1;
            let parsed = std::str::from_utf8(raw)
                .map_err(|_| "not UTF-8 text".to_string())
                .and_then(|raw| {
                    let raw = raw.strip_suffix('\r').unwrap_or(raw);
                    if raw.trim().is_empty() {
                        return Ok(None);
                    }
                    parse_line(raw, last_t, limits).map(|r| Some((raw, r)))
                });
            match parsed {
                Ok(None) => {}
                Ok(Some((_, Some(record)))) => {
                    last_t = record.time();
                    log.records.push(record);
                }
                Ok(Some((raw, None))) => {
                    let kind = serde_json::from_str::<Value>(raw)
                        .ok()
                        .and_then(|v| v.get("type").and_then(Value::as_str).map(str::to_string))
                        .unwrap_or_default();
                    *log.unknown_types.entry(kind).or_default() += 1;
                }
                Err(message) if skip_bad => log.skipped.push((line, message)),
                Err(message) => return Err(LogError { line, message }),
            }
        }
        Ok(log)
    }

    /// The number of scans: `cones` and `points` records.
    pub fn scans(&self) -> usize {
        self.records
            .iter()
            .filter(|r| matches!(r, Record::Cones { .. } | Record::Points { .. }))
            .count()
    }
}

fn finite(obj: &Map<String, Value>, key: &str) -> Result<Option<f64>, String> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => {
            let x = v
                .as_f64()
                .ok_or_else(|| format!("'{key}' is not a number"))?;
            if x.is_finite() {
                bounded(key, x).map(Some)
            } else {
                Err(format!("'{key}' is not finite"))
            }
        }
    }
}

fn required(obj: &Map<String, Value>, key: &str) -> Result<f64, String> {
    finite(obj, key)?.ok_or_else(|| format!("missing '{key}'"))
}

/// The largest magnitude each field may have: past these a record is no
/// vehicle's and integrating it overflows (a speed of 10³⁰⁸ m/s makes the
/// trajectory NaN).
const LIMITS: [(&str, f64); 11] = [
    ("t", 1e11),
    ("x", 1e5),
    ("y", 1e5),
    ("yaw", 1e3),
    ("v", 1e3),
    ("yaw_rate", 1e2),
    ("steer", 10.0),
    ("vy", 1e3),
    ("r", 1e4),
    ("b", 1e3),
    ("cov", 1e6),
];

/// `value` of field `key`, refused beyond its [`LIMITS`].
fn bounded(key: &str, value: f64) -> Result<f64, String> {
    match LIMITS.iter().find(|(k, _)| *k == key) {
        Some((_, limit)) if value.abs() > *limit => {
            Err(format!("'{key}' is {value:e}, beyond ±{limit:e}"))
        }
        _ => Ok(value),
    }
}

/// Parses one line: `Ok(None)` for an unknown type.
fn parse_line(raw: &str, last_t: f64, limits: &ScanLimits) -> Result<Option<Record>, String> {
    // serde_json refuses NaN and Infinity literals, which is what FORMAT.md asks.
    let value: Value = serde_json::from_str(raw).map_err(|e| format!("bad JSON: {e}"))?;
    let obj = value.as_object().ok_or("a record must be a JSON object")?;
    let t = required(obj, "t")?;
    if t < last_t {
        return Err(format!("time goes backwards ({t} after {last_t})"));
    }
    let kind = obj
        .get("type")
        .and_then(Value::as_str)
        .ok_or("missing 'type'")?;
    Ok(Some(match kind {
        "start" => Record::Start {
            t,
            pose: SE2::new(
                finite(obj, "x")?.unwrap_or(0.0),
                finite(obj, "y")?.unwrap_or(0.0),
                finite(obj, "yaw")?.unwrap_or(0.0),
            ),
        },
        "odom" => Record::Odom {
            t,
            v: required(obj, "v")?,
            yaw_rate: required(obj, "yaw_rate")?,
            steer: finite(obj, "steer")?,
            vy: finite(obj, "vy")?,
        },
        "cones" => {
            let list = obj
                .get("cones")
                .and_then(Value::as_array)
                .ok_or("'cones' must be a list")?;
            if list.len() > limits.detections {
                return Err(format!(
                    "{} detections in one scan, more than the limit of {} (--max-detections)",
                    list.len(),
                    limits.detections
                ));
            }
            let cones = list
                .iter()
                .enumerate()
                .map(|(k, c)| parse_detection(c).map_err(|m| format!("cone {k}: {m}")))
                .collect::<Result<Vec<_>, _>>()?;
            Record::Cones { t, cones }
        }
        "points" => {
            let list = obj
                .get("points")
                .and_then(Value::as_array)
                .ok_or("'points' must be a list")?;
            if list.len() > limits.points {
                return Err(format!(
                    "{} points in one scan, more than the limit of {} (--max-points)",
                    list.len(),
                    limits.points
                ));
            }
            let mut points = Vec::with_capacity(list.len());
            for (k, p) in list.iter().enumerate() {
                let coords = p
                    .as_array()
                    .filter(|a| a.len() == 2 || a.len() == 3)
                    .ok_or_else(|| format!("point {k} must be [x, y] or [x, y, z]"))?;
                let mut xyz = [0.0; 3];
                for (j, c) in coords.iter().enumerate() {
                    xyz[j] = c
                        .as_f64()
                        .filter(|x| x.is_finite() && x.abs() <= 1e4)
                        .ok_or_else(|| {
                            format!(
                                "point {k} has a bad coordinate (not a number, or beyond ±1e4 m)"
                            )
                        })?;
                }
                points.push(xyz);
            }
            Record::Points { t, points }
        }
        _ => return Ok(None),
    }))
}

fn parse_detection(value: &Value) -> Result<Detection, String> {
    let obj = value.as_object().ok_or("must be an object")?;
    let color = match obj.get("color").and_then(Value::as_str) {
        Some(name) => name.parse::<Color>()?,
        None => Color::Unknown,
    };
    let (position, range_bearing) = match (finite(obj, "x")?, finite(obj, "y")?) {
        (Some(x), Some(y)) => (Vector2::new(x, y), None),
        _ => {
            let r = required(obj, "r")?;
            let b = required(obj, "b")?;
            if r < 0.0 {
                return Err("negative range".into());
            }
            (Vector2::new(r * b.cos(), r * b.sin()), Some((r, b)))
        }
    };
    let id = match obj.get("id") {
        None | Some(Value::Null) => None,
        Some(v) => Some(v.as_u64().ok_or("'id' must be a non-negative integer")?),
    };
    let covariance = match obj.get("cov") {
        None | Some(Value::Null) => None,
        Some(v) => {
            let c = v
                .as_array()
                .filter(|a| a.len() == 3)
                .ok_or("'cov' must be [sxx, sxy, syy]")?;
            let mut s = [0.0; 3];
            for (k, x) in c.iter().enumerate() {
                s[k] = x
                    .as_f64()
                    .filter(|x| x.is_finite())
                    .ok_or("'cov' has a bad number")
                    .and_then(|x| {
                        bounded("cov", x).map_err(|_| "'cov' has a number beyond ±1e6")
                    })?;
            }
            let m = Matrix2::new(s[0], s[1], s[1], s[2]);
            if s[0] <= 0.0 || m.determinant() <= 0.0 {
                return Err("'cov' is not positive definite".into());
            }
            Some(m)
        }
    };
    Ok(Detection {
        position,
        range_bearing,
        color,
        id,
        covariance,
    })
}

/// Writes records as JSON Lines.
pub fn to_jsonl(records: &[Record]) -> String {
    let mut out = String::new();
    for r in records {
        let value = match r {
            Record::Start { t, pose } => {
                json!({"t": t, "type": "start", "x": pose.t.x, "y": pose.t.y, "yaw": pose.theta})
            }
            Record::Odom {
                t,
                v,
                yaw_rate,
                steer,
                vy,
            } => {
                let mut o = json!({"t": t, "type": "odom", "v": v, "yaw_rate": yaw_rate});
                if let Some(s) = steer {
                    o["steer"] = json!(s);
                }
                if let Some(vy) = vy {
                    o["vy"] = json!(vy);
                }
                o
            }
            Record::Cones { t, cones } => {
                let list: Vec<Value> = cones.iter().map(detection_json).collect();
                json!({"t": t, "type": "cones", "cones": list})
            }
            Record::Points { t, points } => {
                json!({"t": t, "type": "points", "points": points})
            }
        };
        out.push_str(&value.to_string());
        out.push('\n');
    }
    out
}

fn detection_json(d: &Detection) -> Value {
    let mut o = match d.range_bearing {
        Some((r, b)) => json!({"r": r, "b": b}),
        None => json!({"x": d.position.x, "y": d.position.y}),
    };
    o["color"] = json!(d.color.as_str());
    if let Some(id) = d.id {
        o["id"] = json!(id);
    }
    if let Some(c) = d.covariance {
        o["cov"] = json!([c[(0, 0)], c[(0, 1)], c[(1, 1)]]);
    }
    o
}
