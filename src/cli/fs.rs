//! The Formula Student commands `fs-sim` and `fs-slam` (`fs-eval` is in `fs_eval.rs`).

mod settings;
mod sim_effects;

use super::fs_eval::describe_sigma;

use super::{CliError, bad_input, write_output};
use cairn::fs_tools::Track;
use cairn::fs_tools::course::{Course, start_on_line};
use cairn::fs_tools::eval::latency_ms;
use cairn::fs_tools::run::{LogRun, run_log};
use cairn::fs_tools::sim::{Preset, SimConfig, SimConfigError, point_clouds, simulate};
use cairn::fs_tools::trackgen::{TrackRules, random_track};
use cairn::slam::estimator::{EstimatorBuilder, EstimatorKind};
use cairn::slam::files;
use cairn::slam::log::{Log, Record, ScanLimits};
use cairn::slam::map::MapError;
use cairn::slam::map::{map_from_csv, map_to_csv};
use cairn::slam::points::PointCloudConfig;
use clap::Args;
use settings::{rejection_warning, slam_config};
use std::path::{Path, PathBuf};

pub use cairn::slam::files::{LOG, TRUTH_ASSOC, TRUTH_MAP, TRUTH_TRAJ};

/// Options of `cairn fs-sim`.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// Track file (EUFS CSV, AMZ fssim YAML, EPFL CSV); without it a random
    /// rule-conforming track is generated from `--seed`.
    #[arg(long)]
    track: Option<PathBuf>,
    /// Sensor and odometry errors: `standard`, `hard` or `realistic`
    /// (`standard`'s noise levels with heavy tails, occlusion, detection
    /// falling with range, latency, a nearest-neighbour tracker, a drifting
    /// gyro bias, sideslip and slowing for corners).
    #[arg(long, default_value = "standard", value_parser = ["standard", "hard", "realistic"])]
    preset: String,
    #[command(flatten)]
    effects: sim_effects::SimEffects,
    /// Laps to drive, above 0 and at most 1000 (acceleration runs are driven once).
    #[arg(long, default_value_t = 2.0)]
    laps: f64,
    /// Speed, 0.1 to 100 m/s. The run may last at most a day.
    #[arg(long, default_value_t = 5.0)]
    speed: f64,
    /// Random seed (track generation and noise).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Seed of the random track when it should differ from `--seed`
    /// (`fs-report`'s `random-N` is `--track-seed N`).
    #[arg(long)]
    track_seed: Option<u64>,
    /// Cone spacing along each boundary of the random track (m): `MIN,MAX`
    /// to draw it from that range, or one value. The rules allow up to 5 m;
    /// the default 3,5 is how the report's random tracks are made, 1.5,2 is
    /// as tight as the EUFS tracks.
    #[arg(long, value_name = "MIN[,MAX]", value_delimiter = ',', num_args = 1..=2)]
    cone_spacing: Option<Vec<f64>>,
    /// Start on the start line (between the big orange cones) instead of
    /// where the track file puts the car.
    #[arg(long)]
    start_on_line: bool,
    /// Output directory: log.jsonl, truth_traj.tum, truth_assoc.csv, truth_map.csv.
    #[arg(short, long)]
    out: PathBuf,
    /// Write point clouds (`points` records) instead of cone detections;
    /// truth_assoc.csv then labels the clusters `fs-slam` extracts.
    #[arg(long)]
    points: bool,
}

/// Where `fs-slam` and `fs-smooth` write their estimate.
#[derive(Debug, Args)]
pub struct EstimateOutputs {
    /// Write the map (EUFS CSV).
    #[arg(long)]
    pub map_out: Option<PathBuf>,
    /// Write the trajectory (TUM).
    #[arg(long)]
    pub traj_out: Option<PathBuf>,
    /// Write the associations (CSV scan,det,landmark), in the map's rows.
    #[arg(long)]
    pub assoc_out: Option<PathBuf>,
}

impl EstimateOutputs {
    /// Fails, before the run, when an output's folder does not exist.
    pub fn check(&self) -> Result<(), CliError> {
        [&self.map_out, &self.traj_out, &self.assoc_out]
            .into_iter()
            .flatten()
            .try_for_each(|path| super::check_writable(path))
    }
}

/// Options of `cairn fs-slam`.
#[derive(Debug, Args)]
pub struct SlamArgs {
    /// Input log (JSON Lines, FORMAT.md).
    log: PathBuf,
    #[command(flatten)]
    out: EstimateOutputs,
    /// Write update and loop-closure timings (JSON).
    #[arg(long)]
    timing_out: Option<PathBuf>,
    /// Localise on this map (EUFS CSV) from the start, finding the initial alignment.
    #[arg(long)]
    map_in: Option<PathBuf>,
    /// Everything the estimators assume about the detector, the odometry and
    /// the run, from a TOML file (`configs/` holds documented examples:
    /// standard.toml, hard.toml, realistic.toml, mrclam.toml). A file
    /// without `gate` gets the estimator's χ² gate. The options below
    /// override single values; without it the settings follow `--noise`.
    #[arg(long, value_name = "FILE.toml")]
    config: Option<PathBuf>,
    /// Data association: ml, scnn, jcbb or tracking (default: the config's,
    /// tracking without one).
    #[arg(long, value_parser = ["ml", "scnn", "jcbb", "tracking"])]
    association: Option<String>,
    /// Motion model: unicycle (speed + yaw rate) or bicycle (speed + steering)
    /// (default: the config's, unicycle without one).
    #[arg(long, value_parser = ["unicycle", "bicycle"])]
    motion: Option<String>,
    /// Wheelbase for the bicycle model (m).
    #[arg(long, default_value_t = 1.55)]
    wheelbase: f64,
    /// Keep mapping after the loop closes instead of localising on the map.
    #[arg(long)]
    keep_mapping: bool,
    /// Do not match detections again at the end of the run (the graph: every
    /// detection, along its tracker id's chain with tracking association,
    /// alone with the other methods, about half of the end-of-run time;
    /// EKF-SLAM: those left unmatched, against its final map); the
    /// associations written are then those made in real time.
    #[arg(long)]
    no_hindsight: bool,
    /// Learn the detector's noise from the matches while driving (graph
    /// estimator), for a detector whose σ is not known well: prints what it
    /// learned. Off unless given here or in the config.
    #[arg(long)]
    learn_noise: bool,
    /// Write the associations as they stood before the end-of-run pass (the
    /// real-time ones; landmark ids of the map as it stood then), for
    /// `fs-eval --assoc-real-time`.
    #[arg(long)]
    assoc_real_time_out: Option<PathBuf>,
    /// Skip and count malformed log lines instead of stopping at the first.
    #[arg(long)]
    skip_bad: bool,
    /// Refuse scans of more detections than this (the estimators' time
    /// grows with a scan's size).
    #[arg(long, default_value_t = ScanLimits::default().detections)]
    max_detections: usize,
    /// Refuse point clouds of more points than this.
    #[arg(long, default_value_t = ScanLimits::default().points)]
    max_points: usize,
    /// Assumed sensor preset (`standard`, `hard` or `realistic`, the
    /// simulator's presets, as configs/<preset>.toml); the options below
    /// override its parts. Not with `--config`.
    #[arg(long, conflicts_with = "config", value_parser = ["standard", "hard", "realistic"])]
    noise: Option<String>,
    /// Assumed range noise σ (m), the part that does not grow with range.
    #[arg(long)]
    range_sigma: Option<f64>,
    /// Assumed range noise growing with range: σ_r = range_sigma + this × r.
    #[arg(long)]
    range_sigma_relative: Option<f64>,
    /// Assumed bearing noise σ (degrees).
    #[arg(long)]
    bearing_sigma_deg: Option<f64>,
    /// Assumed chance that the detector sees a cone in its view, per scan.
    #[arg(long)]
    detection_probability: Option<f64>,
    /// Assumed false positives per scan.
    #[arg(long)]
    false_positives: Option<f64>,
    /// Estimator: graph (pose graph + per-landmark EKFs), ekf (EKF-SLAM),
    /// fastslam1 or fastslam2.
    #[arg(long, default_value = "graph", value_parser = ["graph", "ekf", "fastslam1", "fastslam2"])]
    estimator: String,
    /// Odometry noise model: velocity (speed and yaw-rate σ) or
    /// rot-trans-rot (Thrun's δrot1, δtrans, δrot2 with α₁…α₄) (default: the
    /// config's, velocity without one).
    #[arg(long, value_parser = ["velocity", "rot-trans-rot"])]
    odometry_noise: Option<String>,
    /// α₁,α₂,α₃,α₄ of the rot-trans-rot model, comma-separated.
    #[arg(long, value_delimiter = ',', value_name = "A1,A2,A3,A4")]
    alpha: Option<Vec<f64>>,
    /// FastSLAM particles, 1 to 100,000.
    #[arg(long, default_value_t = 100, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100000))]
    particles: usize,
    /// FastSLAM sampler seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Known correspondences (a truth_assoc.csv from `fs-sim`) instead of
    /// data association; ekf, fastslam1 and fastslam2 only.
    #[arg(long)]
    known_assoc: Option<PathBuf>,
}

pub(super) fn read_text(path: &Path) -> Result<String, CliError> {
    std::fs::read_to_string(path).map_err(|e| CliError::io(format!("{}: {e}", path.display())))
}

/// A track file's error: unreadable, or malformed.
fn track_error(path: &Path) -> impl FnOnce(MapError) -> CliError + '_ {
    move |e| match e {
        MapError::Io { .. } => CliError::io(e.to_string()),
        _ => CliError::input(format!("{}: {e}", path.display())),
    }
}

/// The rules of `fs-sim`'s random track.
fn track_rules(a: &SimArgs) -> Result<TrackRules, CliError> {
    let mut rules = TrackRules::default();
    if let Some(spacing) = &a.cone_spacing {
        if a.track.is_some() {
            return Err(CliError::usage(
                "--cone-spacing applies to random tracks only, not to --track",
            ));
        }
        let (min, max) = (spacing[0], *spacing.last().unwrap_or(&spacing[0]));
        if !(min > 0.0 && min <= max && max <= 5.0) {
            return Err(CliError::usage(format!(
                "--cone-spacing must be MIN,MAX with 0 < MIN <= MAX <= 5 m (the rules' largest), got {min},{max}"
            )));
        }
        rules.spacing = (min, max);
    }
    Ok(rules)
}

pub fn run_sim(a: SimArgs) -> Result<(), super::CliError> {
    let preset = Preset::by_name(&a.preset)
        .ok_or_else(|| CliError::usage("--preset must be standard, hard or realistic"))?;
    let preset = a.effects.apply(preset)?;
    let rules = track_rules(&a)?;
    let (track, course) = match &a.track {
        Some(path) => {
            let track = Track::load(path).map_err(track_error(path))?;
            let course = Course::from_track(&track).map_err(bad_input(path.display()))?;
            (track, course)
        }
        None => random_track(a.track_seed.unwrap_or(a.seed), &rules),
    };
    let mut track = track;
    if a.start_on_line {
        track.start = start_on_line(&track, &course).ok_or_else(|| {
            CliError::usage("--start-on-line needs a track with big orange cones")
        })?;
    }
    let config = SimConfig {
        preset,
        laps: a.laps,
        speed: a.speed,
        seed: a.seed,
        ..SimConfig::default()
    };
    config.check(&course).map_err(|e| {
        CliError::usage(match e {
            // The library names the setting; the command line, its flag.
            SimConfigError::Laps(_) | SimConfigError::Speed(_) => format!("--{e}"),
            SimConfigError::TooLong { .. } | SimConfigError::Model { .. } => e.to_string(),
        })
    })?;
    let mut sim = simulate(&track, &course, &config);
    if a.points {
        sim = point_clouds(&sim, &PointCloudConfig::default(), a.seed);
    }
    std::fs::create_dir_all(&a.out)
        .map_err(|e| CliError::io(format!("{}: {e}", a.out.display())))?;
    for (file, text) in sim.files() {
        write_output(&a.out.join(file), text.as_bytes())?;
    }
    eprintln!(
        "{}: {:.0} m course, {} scans, {} detections → {}",
        track.name,
        course.length(),
        sim.log
            .iter()
            .filter(|r| matches!(
                r,
                cairn::slam::log::Record::Cones { .. } | cairn::slam::log::Record::Points { .. }
            ))
            .count(),
        sim.truth_associations.len(),
        a.out.display()
    );
    if sim.lost_sightings > 0 {
        // FORMAT.md's association file has a row per detection only.
        eprintln!(
            "{} cone sightings have no cluster of their own (merged into another cone's or too \
             sparse); truth_assoc.csv cannot list them, so fs-eval does not count them",
            sim.lost_sightings
        );
    }
    if a.preset == "hard" {
        // The log does not say how noisy its detector is (FORMAT.md).
        eprintln!("run fs-slam on it with `--noise hard`: its gates assume the detector's noise");
    }
    Ok(())
}

pub fn run_slam(a: SlamArgs) -> Result<(), super::CliError> {
    let name = a.log.display().to_string();
    // The options first: a wrong one fails before the log is read.
    a.out.check()?;
    for path in [&a.timing_out, &a.assoc_real_time_out]
        .into_iter()
        .flatten()
    {
        super::check_writable(path)?;
    }
    let kind = EstimatorKind::by_name(&a.estimator)
        .ok_or_else(|| CliError::usage("--estimator must be graph, ekf, fastslam1 or fastslam2"))?;
    let config = slam_config(&a, kind)?;
    let assumed_latency = config.scan_latency;
    let limits = ScanLimits {
        detections: a.max_detections,
        points: a.max_points,
    };
    let log = Log::parse_bytes(&super::read_input(&a.log)?, a.skip_bad, &limits)
        .map_err(bad_input(&name))?;
    for (line, message) in &log.skipped {
        eprintln!("{name}: skipped line {line}: {message}");
    }
    for (kind, n) in &log.unknown_types {
        eprintln!("{name}: {n} records of unknown type '{kind}' ignored");
    }
    let map = match &a.map_in {
        Some(path) => {
            let map = map_from_csv(&read_text(path)?).map_err(bad_input(path.display()))?;
            if map.is_empty() {
                return Err(CliError::input(format!(
                    "{}: the map has no cones to localise on",
                    path.display()
                )));
            }
            Some(map)
        }
        None => None,
    };
    let known = match &a.known_assoc {
        Some(_) if kind == EstimatorKind::Graph => {
            return Err(CliError::usage(
                "--known-assoc works with ekf, fastslam1 and fastslam2",
            ));
        }
        Some(path) => Some(
            files::associations_from_csv(&read_text(path)?).map_err(bad_input(path.display()))?,
        ),
        None => None,
    };
    let mut builder = EstimatorBuilder::new(kind, config.clone());
    builder.particles = a.particles;
    builder.seed = a.seed;
    builder.map = map.as_deref();
    builder.known = known.as_deref();
    let LogRun {
        slam,
        finished,
        real_time,
    } = run_log(&builder, &log);
    if let Err(e) = finished {
        eprintln!("warning: the final optimisation failed ({e}); writing the estimate as it was");
    }
    for warning in slam.warnings() {
        eprintln!("warning: {warning}");
    }
    let associations = slam.associations();
    let rejected = associations.iter().filter(|a| a.landmark.is_none()).count();
    let scans = (log.records.iter())
        .filter(|r| matches!(r, Record::Cones { .. } | Record::Points { .. }))
        .count();
    if let Some(warning) = rejection_warning(rejected, associations.len(), scans, &config) {
        eprintln!("warning: {warning}");
        if let Some(path) = &a.map_in {
            eprintln!(
                "warning: or {} is not the map of this run's track: most detections match none of its cones",
                path.display()
            );
        }
    }
    // Everything is computed before anything is written, so a failure leaves no partial output.
    let (cones, poses) = (slam.map(), slam.trajectory());
    let finite = cones.iter().all(|c| {
        c.position
            .iter()
            .chain(c.covariance.iter())
            .all(|x| x.is_finite())
    }) && poses
        .iter()
        .all(|p| p.pose.t.iter().all(|x| x.is_finite()) && p.pose.theta.is_finite());
    if !finite {
        return Err(format!(
            "{name}: the estimate is not finite (NaN or infinite); nothing written"
        )
        .into());
    }
    let map = map_to_csv(&cones);
    let traj = files::trajectory_to_tum(&poses);
    let assoc = files::associations_to_csv(&associations);
    let timing = serde_json::json!({
        "updates_s": slam.timing().updates,
        "loop_closures_s": slam.timing().loop_closures,
        "final_s": slam.timing().final_optimisation,
        "detector_sigma": slam.detector_noise().map(|n| {
            serde_json::json!({"assumed": n.assumed, "estimated": n.estimated})
        }),
        "odometry_calibration": slam.calibration().map(|c| {
            serde_json::json!({
                "speed_scale": c.speed_scale,
                "yaw_rate_bias": c.yaw_rate_bias,
                "sideslip": c.sideslip,
                "yaw_rate_bias_walk": c.yaw_rate_bias_walk,
                "scan_latency": c.scan_latency,
                "scan_latency_sigma": c.scan_latency_sigma,
            })
        }),
    })
    .to_string();
    let real_time = files::associations_to_csv(&real_time);
    for (path, text) in [
        (&a.out.map_out, &map),
        (&a.out.traj_out, &traj),
        (&a.out.assoc_out, &assoc),
        (&a.assoc_real_time_out, &real_time),
        (&a.timing_out, &timing),
    ] {
        if let Some(path) = path {
            write_output(path, text.as_bytes())?;
        }
    }
    let timing = slam.timing();
    let lat = latency_ms(&timing.updates).unwrap_or_default();
    let mut optimisations = String::new();
    if let Some(longest) = timing.loop_closures.iter().copied().reduce(f64::max) {
        optimisations += &format!("; loop closure {:.1} ms", 1e3 * longest);
    }
    if let Some(last) = timing.final_optimisation {
        optimisations += &format!("; final optimisation {:.0} ms", 1e3 * last);
    }
    eprintln!(
        "{name}: {} scans, {} landmarks, {} loop closure(s), {} relocalisation(s), mode {:?}; update p50 {:.3} ms, p99 {:.3} ms, p99.9 {:.3} ms, max {:.3} ms{optimisations}",
        log.scans(),
        slam.map().len(),
        slam.loop_closures(),
        slam.relocalisations(),
        slam.mode(),
        lat[0],
        lat[1],
        lat[2],
        lat[3]
    );
    if let Some(noise) = slam.detector_noise() {
        eprintln!("detector noise {}", describe_noise(&noise));
    }
    if let Some(c) = slam.calibration() {
        eprintln!(
            "odometry learnt: speed ×{:.4}, sideslip {:.4} rad per m/s² of lateral acceleration, gyro bias walk {:.1e} rad/s/√s",
            c.speed_scale, c.sideslip, c.yaw_rate_bias_walk
        );
        if let Some(sigma) = c.scan_latency_sigma {
            eprintln!(
                "scan latency {:.1} ms (the log pins it to σ {:.1} ms; learnt where σ ≤ 15 ms and 3σ from the config's {:.1} ms)",
                1e3 * c.scan_latency,
                1e3 * sigma,
                1e3 * assumed_latency
            );
        }
    }
    Ok(())
}

/// The detector's σ as assumed and as learned, in the units people read.
fn describe_noise(noise: &cairn::slam::frontend::DetectorNoise) -> String {
    format!(
        "assumed {}; learned {} (variance ×{:.2})",
        describe_sigma(noise.assumed),
        describe_sigma(noise.estimated),
        noise.variance_scale
    )
}
