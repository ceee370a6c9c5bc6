//! Ground-truth cone tracks: the EUFS CSV, AMZ fssim YAML and EPFL CSV
//! formats of `shared/tracks`, plus the EUFS CSV map that the front end
//! writes (FORMAT.md, "Outputs").

use crate::color::Color;
use cairn_core::SE2;
use nalgebra::{Matrix2, Vector2};
use std::f64::consts::FRAC_PI_2;
use std::fmt::Write as _;
use std::path::Path;

/// Why a track or map file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum TrackError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A line that does not parse.
    #[error("line {line}: {message}")]
    Parse {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The file has no cones.
    #[error("no cones in the file")]
    Empty,
}

fn parse_error(line: usize, message: impl Into<String>) -> TrackError {
    TrackError::Parse {
        line,
        message: message.into(),
    }
}

/// One cone of a track or map.
#[derive(Clone, Debug, PartialEq)]
pub struct Cone {
    /// World position in metres.
    pub position: Vector2<f64>,
    /// Colour class.
    pub color: Color,
    /// Position covariance (the map file's variance columns; zero in ground truth).
    pub covariance: Matrix2<f64>,
}

impl Cone {
    /// The covariance to start a landmark from when localising on a map:
    /// the file's, or 1 cm² when it gives none (ground truth has zeros).
    pub fn prior_covariance(&self) -> Matrix2<f64> {
        if self.covariance.determinant() > 0.0 {
            self.covariance
        } else {
            Matrix2::identity() * 1e-4
        }
    }

    /// A cone with zero covariance.
    pub fn new(x: f64, y: f64, color: Color) -> Self {
        Self {
            position: Vector2::new(x, y),
            color,
            covariance: Matrix2::zeros(),
        }
    }
}

/// What a car does on the track.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrackKind {
    /// A closed loop driven lap after lap (trackdrive, autocross).
    Loop,
    /// A straight run (acceleration event).
    Acceleration,
    /// The figure of eight (skidpad event).
    Skidpad,
}

/// A track: its cones in file order (their indices are the ground-truth
/// landmark ids), clutter objects, and the car's start pose.
#[derive(Clone, Debug)]
pub struct Track {
    /// A short name (the file stem, or `random-<seed>`).
    pub name: String,
    /// The cones, in file order, without non-cone rows.
    pub cones: Vec<Cone>,
    /// Objects that are not cones but can be detected as one (EUFS `inactive_noise`).
    pub clutter: Vec<Vector2<f64>>,
    /// The car's start pose in the world frame.
    pub start: SE2,
    /// Loop, acceleration or skidpad.
    pub kind: TrackKind,
}

impl Track {
    /// Reads a track file, choosing the format by its extension and header:
    /// `.yaml`/`.yml` → AMZ fssim; a `cone_type,` header → EPFL; otherwise EUFS CSV.
    pub fn load(path: &Path) -> Result<Track, TrackError> {
        let text = std::fs::read_to_string(path).map_err(|source| TrackError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        Track::parse(
            &name,
            &text,
            ext.eq_ignore_ascii_case("yaml") || ext.eq_ignore_ascii_case("yml"),
        )
    }

    /// Parses a track from text; `yaml` selects the AMZ fssim format.
    pub fn parse(name: &str, text: &str, yaml: bool) -> Result<Track, TrackError> {
        let mut track = if yaml {
            parse_fssim_yaml(text)?
        } else if text.trim_start().starts_with("cone_type") {
            parse_epfl_csv(text)?
        } else {
            parse_eufs_csv(text)?
        };
        if track.cones.is_empty() {
            return Err(TrackError::Empty);
        }
        track.name = name.to_string();
        let lower = name.to_ascii_lowercase();
        track.kind = if lower.contains("acceleration") {
            TrackKind::Acceleration
        } else if lower.contains("skidpad") {
            TrackKind::Skidpad
        } else {
            TrackKind::Loop
        };
        Ok(track)
    }

    /// The indices of the cones of one colour.
    pub fn of_color(&self, color: Color) -> Vec<usize> {
        (0..self.cones.len())
            .filter(|&i| self.cones[i].color == color)
            .collect()
    }
}

/// Coordinates farther than this from the origin (m) are refused: a track
/// or map is a few kilometres across, and the course and simulation built on
/// it grow with its size.
pub const MAX_COORDINATE: f64 = 1e5;

/// A coordinate: a number within [`MAX_COORDINATE`] of zero.
fn number(field: Option<&str>, line: usize, what: &str) -> Result<f64, TrackError> {
    let field = field.ok_or_else(|| parse_error(line, format!("missing {what}")))?;
    let field = field.trim();
    if field.is_empty() {
        return Err(parse_error(line, format!("{what} is empty")));
    }
    let value: f64 = field
        .parse()
        .map_err(|_| parse_error(line, format!("{what} '{field}' is not a number")))?;
    coordinate(value, line, what)
}

fn coordinate(value: f64, line: usize, what: &str) -> Result<f64, TrackError> {
    if !value.is_finite() {
        return Err(parse_error(line, format!("{what} is not finite")));
    }
    if value.abs() > MAX_COORDINATE {
        return Err(parse_error(
            line,
            format!("{what} {value:e} is more than {MAX_COORDINATE:e} m from the origin"),
        ));
    }
    Ok(value)
}

/// EUFS CSV (`tag,x,y,direction,x_variance,y_variance,xy_covariance`), with
/// or without the header row. Also the map format the front end writes.
fn parse_eufs_csv(text: &str) -> Result<Track, TrackError> {
    let mut track = Track {
        name: String::new(),
        cones: Vec::new(),
        clutter: Vec::new(),
        start: SE2::identity(),
        kind: TrackKind::Loop,
    };
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let raw = raw.trim();
        if raw.is_empty() || raw.starts_with('#') || (i == 0 && raw.starts_with("tag")) {
            continue;
        }
        let mut fields = raw.split(',');
        let tag = fields.next().unwrap_or("").trim();
        let x = number(fields.next(), line, "x")?;
        let y = number(fields.next(), line, "y")?;
        let direction = fields.next();
        match tag {
            "car_start" => {
                let yaw = match direction.map(str::trim) {
                    None | Some("") => 0.0,
                    Some(_) => number(direction, line, "direction")?,
                };
                track.start = SE2::new(x, y, yaw);
            }
            "inactive_noise" => track.clutter.push(Vector2::new(x, y)),
            "midpoint" => {}
            _ => {
                let color: Color = tag.parse().map_err(|m: String| parse_error(line, m))?;
                let mut cone = Cone::new(x, y, color);
                // Variances are informational; real files have typos there
                // (boa_constrictor: `0.0s`), so an unreadable one counts as 0.
                let mut variance = [0.0; 3];
                for v in variance.iter_mut() {
                    let field = fields.next().unwrap_or("").trim();
                    *v = field
                        .parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .unwrap_or(0.0);
                }
                cone.covariance = Matrix2::new(variance[0], variance[2], variance[2], variance[1]);
                let [sxx, syy, sxy] = variance;
                if sxx < 0.0 || syy < 0.0 || sxy * sxy > sxx * syy {
                    return Err(parse_error(
                        line,
                        "the variances are not a covariance (negative, or |xy| > √(xx·yy))",
                    ));
                }
                track.cones.push(cone);
            }
        }
    }
    Ok(track)
}

/// EPFL track_database CSV (`cone_type,X,Y,Z,...`): the car starts at the
/// origin facing +y.
fn parse_epfl_csv(text: &str) -> Result<Track, TrackError> {
    let mut track = Track {
        name: String::new(),
        cones: Vec::new(),
        clutter: Vec::new(),
        start: SE2::new(0.0, 0.0, FRAC_PI_2),
        kind: TrackKind::Loop,
    };
    for (i, raw) in text.lines().enumerate().skip(1) {
        let line = i + 1;
        let raw = raw.trim();
        if raw.is_empty() {
            continue;
        }
        let mut fields = raw.split(',');
        let tag = fields.next().unwrap_or("").trim();
        let color: Color = tag.parse().map_err(|m: String| parse_error(line, m))?;
        let x = number(fields.next(), line, "X")?;
        let y = number(fields.next(), line, "Y")?;
        track.cones.push(Cone::new(x, y, color));
    }
    Ok(track)
}

/// AMZ fssim YAML: lists of `[x, y]` under `cones_left`, `cones_right`,
/// `cones_orange`, `cones_orange_big`, and `starting_pose_front_wing: [x, y, yaw]`,
/// in any YAML layout (block or flow); other keys are ignored. A cone
/// repeated at the same place (fssim closes each boundary with its first
/// cone) is kept once.
fn parse_fssim_yaml(text: &str) -> Result<Track, TrackError> {
    #[derive(serde::Deserialize, Default)]
    #[serde(default)]
    struct Fssim {
        cones_left: Option<Vec<Vec<f64>>>,
        cones_right: Option<Vec<Vec<f64>>>,
        cones_orange: Option<Vec<Vec<f64>>>,
        cones_orange_big: Option<Vec<Vec<f64>>>,
        starting_pose_front_wing: Option<Vec<f64>>,
    }
    let doc: Fssim = serde_saphyr::from_str(text).map_err(|e| {
        let line = e.location().map_or(1, |l| l.line() as usize);
        parse_error(line, e.without_snippet().to_string())
    })?;
    let mut track = Track {
        name: String::new(),
        cones: Vec::new(),
        clutter: Vec::new(),
        start: SE2::identity(),
        kind: TrackKind::Loop,
    };
    if let Some(pose) = doc.starting_pose_front_wing {
        let line = key_line(text, "starting_pose_front_wing");
        if pose.len() < 2 {
            return Err(parse_error(line, "starting pose needs x and y"));
        }
        let x = coordinate(pose[0], line, "the starting x")?;
        let y = coordinate(pose[1], line, "the starting y")?;
        let yaw = pose.get(2).copied().unwrap_or(0.0);
        if !yaw.is_finite() {
            return Err(parse_error(line, "the starting yaw is not finite"));
        }
        track.start = SE2::new(x, y, yaw);
    }
    let lists = [
        ("cones_left", doc.cones_left, Color::Blue),
        ("cones_right", doc.cones_right, Color::Yellow),
        ("cones_orange", doc.cones_orange, Color::Orange),
        ("cones_orange_big", doc.cones_orange_big, Color::BigOrange),
    ];
    for (key, points, color) in lists {
        let line = key_line(text, key);
        for p in points.unwrap_or_default() {
            if p.len() < 2 {
                return Err(parse_error(
                    line,
                    format!("a point under '{key}' needs x and y"),
                ));
            }
            let x = coordinate(p[0], line, &format!("x under '{key}'"))?;
            let y = coordinate(p[1], line, &format!("y under '{key}'"))?;
            let cone = Cone::new(x, y, color);
            let duplicate = track
                .cones
                .iter()
                .any(|c| c.color == color && (c.position - cone.position).norm() < 0.05);
            if !duplicate {
                track.cones.push(cone);
            }
        }
    }
    Ok(track)
}

/// The line where `key` starts a mapping entry at the left margin (1 if
/// the layout has none, as a flow mapping on one line).
fn key_line(text: &str, key: &str) -> usize {
    text.lines()
        .position(|l| {
            l.strip_prefix(key)
                .is_some_and(|r| r.trim_start().starts_with(':'))
        })
        .map_or(1, |i| i + 1)
}

/// Writes cones as the EUFS CSV map (FORMAT.md): one row per cone in order,
/// with its position variances.
pub fn map_to_csv(cones: &[Cone]) -> String {
    let mut out = String::from("tag,x,y,direction,x_variance,y_variance,xy_covariance\n");
    for c in cones {
        let _ = writeln!(
            out,
            "{},{:?},{:?},0.0,{:?},{:?},{:?}",
            c.color,
            c.position.x,
            c.position.y,
            c.covariance[(0, 0)],
            c.covariance[(1, 1)],
            c.covariance[(0, 1)]
        );
    }
    out
}

/// Reads a map written by [`map_to_csv`] (or any EUFS CSV): the cones in row order.
pub fn map_from_csv(text: &str) -> Result<Vec<Cone>, TrackError> {
    Ok(parse_eufs_csv(text)?.cones)
}
