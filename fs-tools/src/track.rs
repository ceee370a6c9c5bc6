//! Ground-truth cone tracks: the EUFS CSV, AMZ fssim YAML and EPFL CSV
//! formats of `shared/tracks`.

use cairn_core::SE2;
use cairn_slam::Color;
use cairn_slam::map::{Cone, MapError, coordinate, number, parse_error, parse_eufs_csv};
use nalgebra::Vector2;
use std::f64::consts::FRAC_PI_2;
use std::path::Path;

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
    pub fn load(path: &Path) -> Result<Track, MapError> {
        let text = std::fs::read_to_string(path).map_err(|source| MapError::Io {
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
    pub fn parse(name: &str, text: &str, yaml: bool) -> Result<Track, MapError> {
        let mut track = if yaml {
            parse_fssim_yaml(text)?
        } else if text.trim_start().starts_with("cone_type") {
            parse_epfl_csv(text)?
        } else {
            let file = parse_eufs_csv(text)?;
            Track {
                name: String::new(),
                cones: file.cones,
                clutter: file.clutter,
                start: file.start.unwrap_or_else(SE2::identity),
                kind: TrackKind::Loop,
            }
        };
        if track.cones.is_empty() {
            return Err(MapError::Empty);
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

/// EPFL track_database CSV (`cone_type,X,Y,Z,...`): the car starts at the
/// origin facing +y.
fn parse_epfl_csv(text: &str) -> Result<Track, MapError> {
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
fn parse_fssim_yaml(text: &str) -> Result<Track, MapError> {
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
