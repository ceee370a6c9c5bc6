//! Cone maps: the EUFS CSV map the front end writes and reads back for
//! localisation (FORMAT.md, "Outputs"), which is also the EUFS track format.

use crate::color::Color;
use cairn_core::SE2;
use nalgebra::{Matrix2, Vector2};
use std::fmt::Write as _;

/// Why a map or track file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
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

/// A [`MapError::Parse`] at `line`.
pub fn parse_error(line: usize, message: impl Into<String>) -> MapError {
    MapError::Parse {
        line,
        message: message.into(),
    }
}

/// One cone of a map or track.
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

/// Coordinates farther than this from the origin (m) are refused: a track
/// or map is a few kilometres across, and the course and simulation built on
/// it grow with its size.
pub const MAX_COORDINATE: f64 = 1e5;

/// A coordinate read from a text field: a number within
/// [`MAX_COORDINATE`] of zero; `what` names it in the error.
pub fn number(field: Option<&str>, line: usize, what: &str) -> Result<f64, MapError> {
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

/// A coordinate already read as a number, range-checked as [`number`] does.
pub fn coordinate(value: f64, line: usize, what: &str) -> Result<f64, MapError> {
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

/// The rows of an EUFS CSV file: cones, clutter objects and the car's start.
#[derive(Clone, Debug, Default)]
pub struct EufsFile {
    /// The cones, in row order, without non-cone rows.
    pub cones: Vec<Cone>,
    /// `inactive_noise` rows: objects that are not cones.
    pub clutter: Vec<Vector2<f64>>,
    /// The `car_start` row's pose, if there is one.
    pub start: Option<SE2>,
}

/// EUFS CSV (`tag,x,y,direction,x_variance,y_variance,xy_covariance`), with
/// or without the header row. Also the map format the front end writes.
pub fn parse_eufs_csv(text: &str) -> Result<EufsFile, MapError> {
    let mut track = EufsFile::default();
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
                track.start = Some(SE2::new(x, y, yaw));
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
pub fn map_from_csv(text: &str) -> Result<Vec<Cone>, MapError> {
    Ok(parse_eufs_csv(text)?.cones)
}
