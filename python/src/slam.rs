//! `cairn.fs_slam` and `cairn.fs_sim`: the cone-SLAM estimators on a log,
//! and the simulator writing a run.

use crate::arrays::rows;
use cairn_fs_tools::configs::assumed_config;
use cairn_fs_tools::course::Course;
use cairn_fs_tools::run::{LogRun, run_log};
use cairn_fs_tools::sim::{Preset, SimConfig, simulate};
use cairn_fs_tools::track::Track;
use cairn_fs_tools::trackgen::{TrackRules, random_track};
use cairn_slam::estimator::{EstimatorBuilder, EstimatorKind};
use cairn_slam::frontend::FrontEndConfig;
use cairn_slam::frontend::association::AssociationMethod;
use cairn_slam::log::{Log, ScanLimits};
use cairn_slam::map::MapError;
use numpy::IntoPyArray;
use numpy::ndarray::Array2;
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};

fn read(path: &Path) -> PyResult<Vec<u8>> {
    std::fs::read(path).map_err(|e| PyOSError::new_err(format!("{}: {e}", path.display())))
}

/// Runs a cone-SLAM estimator on a log in the FORMAT.md format and returns
/// a dict of numpy arrays: "map" (n, 5: x, y, x_variance, y_variance,
/// xy_covariance), "colors" (the map's colour per row), "trajectory" (m,
/// 4: t, x, y, yaw), "associations" (k, 3 integers: scan, detection, map
/// row or -1) and "warnings". estimator: graph, ekf, fastslam1 or
/// fastslam2; association: ml, scnn, jcbb or tracking; config: a TOML file
/// of the estimators' assumptions (configs/ in the repository), the
/// simulator's `standard` noise without one. Raises OSError for unreadable
/// files and ValueError, naming the line or setting, for bad ones. The GIL
/// is released while it runs.
#[pyfunction]
#[pyo3(signature = (log_path, estimator = "graph", association = "ml", config = None, particles = 100, seed = 0))]
pub fn fs_slam<'py>(
    py: Python<'py>,
    log_path: PathBuf,
    estimator: &str,
    association: &str,
    config: Option<PathBuf>,
    particles: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let kind = EstimatorKind::by_name(estimator).ok_or_else(|| {
        PyValueError::new_err(format!(
            "estimator must be graph, ekf, fastslam1 or fastslam2, got {estimator:?}"
        ))
    })?;
    let method = AssociationMethod::by_name(association).ok_or_else(|| {
        PyValueError::new_err(format!(
            "association must be ml, scnn, jcbb or tracking, got {association:?}"
        ))
    })?;
    if !(1..=100_000).contains(&particles) {
        return Err(PyValueError::new_err(format!(
            "particles must be from 1 to 100000, got {particles}"
        )));
    }
    let mut settings = match &config {
        Some(path) => {
            let text = String::from_utf8(read(path)?).map_err(|e| {
                PyValueError::new_err(format!("{}: not UTF-8 ({e})", path.display()))
            })?;
            FrontEndConfig::from_toml_for(&text, kind)
                .map_err(|e| PyValueError::new_err(format!("{}: {e}", path.display())))?
        }
        None => assumed_config("standard", method, kind)
            .map_err(|e| PyValueError::new_err(e.to_string()))?,
    };
    settings.association = method;
    let bytes = read(&log_path)?;
    let result = py.detach(move || {
        let log = Log::parse_bytes(&bytes, false, &ScanLimits::default())
            .map_err(|e| format!("{}: {e}", log_path.display()))?;
        let mut builder = EstimatorBuilder::new(kind, settings);
        builder.particles = particles;
        builder.seed = seed;
        let LogRun { slam, finished, .. } = run_log(&builder, &log);
        let mut warnings = slam.warnings().to_vec();
        if let Err(e) = finished {
            warnings.push(format!(
                "the final optimisation failed ({e}); kept the estimate"
            ));
        }
        Ok::<_, String>((slam.map(), slam.trajectory(), slam.associations(), warnings))
    });
    let (map, trajectory, associations, warnings) = result.map_err(PyValueError::new_err)?;
    let map_rows: Vec<f64> = map
        .iter()
        .flat_map(|c| {
            let v = c.covariance;
            [c.position.x, c.position.y, v[(0, 0)], v[(1, 1)], v[(0, 1)]]
        })
        .collect();
    let traj_rows: Vec<f64> = trajectory
        .iter()
        .flat_map(|p| [p.t, p.pose.t.x, p.pose.t.y, p.pose.theta])
        .collect();
    let assoc = Array2::from_shape_fn((associations.len(), 3), |(r, c)| {
        let a = &associations[r];
        match c {
            0 => a.scan as i64,
            1 => a.det as i64,
            _ => a.landmark.map_or(-1, |l| l as i64),
        }
    });
    let out = PyDict::new(py);
    out.set_item("map", rows(py, 5, &map_rows))?;
    let colors: Vec<&str> = map.iter().map(|c| c.color.as_str()).collect();
    out.set_item("colors", colors)?;
    out.set_item("trajectory", rows(py, 4, &traj_rows))?;
    out.set_item("associations", assoc.into_pyarray(py))?;
    out.set_item("warnings", warnings)?;
    Ok(out)
}

/// Simulates a car driving a track and writes the run into the folder
/// `out` (created if needed): log.jsonl, and the truth files truth_map.csv,
/// truth_traj.tum and truth_assoc.csv (FORMAT.md). track: a track file
/// (EUFS or AMZ fssim CSV/YAML, shared/tracks/) or None for a random
/// rule-conforming track from `seed`; preset: "standard" or "hard" noise;
/// laps in (0, 1000]; speed in [0.1, 100] m/s. Returns the paths written.
#[pyfunction]
#[pyo3(signature = (out, track = None, seed = 0, laps = 2.0, speed = 5.0, preset = "standard"))]
pub fn fs_sim(
    py: Python<'_>,
    out: PathBuf,
    track: Option<PathBuf>,
    seed: u64,
    laps: f64,
    speed: f64,
    preset: &str,
) -> PyResult<Vec<PathBuf>> {
    let preset = Preset::by_name(preset).ok_or_else(|| {
        PyValueError::new_err(format!(
            "preset must be standard, hard or realistic, got {preset:?}"
        ))
    })?;
    let (track, course) = match &track {
        Some(path) => {
            let track = Track::load(path).map_err(|e| match e {
                MapError::Io { .. } => PyOSError::new_err(e.to_string()),
                _ => PyValueError::new_err(format!("{}: {e}", path.display())),
            })?;
            let course = Course::from_track(&track)
                .map_err(|e| PyValueError::new_err(format!("{}: {e}", path.display())))?;
            (track, course)
        }
        None => random_track(seed, &TrackRules::default()),
    };
    let config = SimConfig {
        preset,
        laps,
        speed,
        seed,
        ..SimConfig::default()
    };
    config
        .check(&course)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let sim = py.detach(|| simulate(&track, &course, &config));
    std::fs::create_dir_all(&out)
        .map_err(|e| PyOSError::new_err(format!("{}: {e}", out.display())))?;
    let mut written = Vec::new();
    for (file, text) in sim.files() {
        let path = out.join(file);
        cairn_g2o::write_atomically(&path, text.as_bytes())
            .map_err(|e| PyOSError::new_err(e.to_string()))?;
        written.push(path);
    }
    Ok(written)
}
