//! The simulator behind `cairn fs-sim`: a kinematic bicycle driven along a
//! track's centre line by pure pursuit, with a cone detector and odometry
//! whose errors follow a named preset.

use crate::course::Course;
use crate::track::Track;
use cairn_core::SE2;
use cairn_slam::Color;
use cairn_slam::Cone;
use cairn_slam::files::{Association, StampedPose};
use cairn_slam::log::Record;
use cairn_slam::motion::integrate;
use detector::detect;
pub(crate) use detector::read_probability;
use effects::{Noise, integrate_with_sideslip};
use nalgebra::Vector2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::Distribution;
use std::collections::VecDeque;
use tracker::Tracker;

pub use effects::SpeedProfile;
pub use preset::{OdometryModel, Preset, SensorModel};
pub use tracker::TrackerModel;

/// What to simulate.
#[derive(Clone, Debug)]
pub struct SimConfig {
    /// Error models.
    pub preset: Preset,
    /// Laps of a loop track (an acceleration run is driven once).
    pub laps: f64,
    /// Target speed (m/s).
    pub speed: f64,
    /// Random seed.
    pub seed: u64,
    /// Wheelbase of the bicycle model (m).
    pub wheelbase: f64,
    /// Pure-pursuit look-ahead distance (m).
    pub lookahead: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            preset: Preset::standard(),
            laps: 2.0,
            speed: 5.0,
            seed: 0,
            wheelbase: 1.55,
            lookahead: 3.0,
        }
    }
}

/// Most laps a simulation drives.
pub const MAX_LAPS: f64 = 1000.0;

/// The speeds it drives at (m/s).
pub const SPEEDS: std::ops::RangeInclusive<f64> = 0.1..=100.0;

/// The longest run it simulates (s).
pub const MAX_DURATION: f64 = 86_400.0;

/// A [`SimConfig`] setting out of range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SimConfigError {
    /// Laps not in (0, [`MAX_LAPS`]].
    #[error("laps must be above 0 and at most {MAX_LAPS}, got {0}")]
    Laps(f64),
    /// A preset setting out of its range.
    #[error("the preset's {field} must be {rule}, got {value}")]
    Model {
        /// The setting.
        field: &'static str,
        /// What it must be.
        rule: &'static str,
        /// What it was.
        value: f64,
    },
    /// A speed outside [`SPEEDS`].
    #[error("speed must be from {min} to {max} m/s, got {0}", min = SPEEDS.start(), max = SPEEDS.end())]
    Speed(f64),
    /// A run longer than [`MAX_DURATION`].
    #[error(
        "{laps} laps of {length:.0} m at {speed} m/s last {seconds:.0} s; the simulator runs at most {MAX_DURATION} s (a day)"
    )]
    TooLong {
        /// Laps driven.
        laps: f64,
        /// The course's length (m).
        length: f64,
        /// Speed (m/s).
        speed: f64,
        /// The run's duration (s).
        seconds: f64,
    },
}

impl SimConfig {
    /// Checks the laps and speed, and that the run on `course` lasts at
    /// most [`MAX_DURATION`] (an open course is driven once).
    pub fn check(&self, course: &Course) -> Result<(), SimConfigError> {
        if !(self.laps > 0.0 && self.laps <= MAX_LAPS) {
            return Err(SimConfigError::Laps(self.laps));
        }
        if !SPEEDS.contains(&self.speed) {
            return Err(SimConfigError::Speed(self.speed));
        }
        self.preset.check()?;
        let laps = if course.is_closed() { self.laps } else { 1.0 };
        let seconds = laps * course.length() / self.speed;
        if seconds > MAX_DURATION {
            return Err(SimConfigError::TooLong {
                laps,
                length: course.length(),
                speed: self.speed,
                seconds,
            });
        }
        Ok(())
    }
}

/// A simulated run: the input log and its ground truth.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// The log the front end reads.
    pub log: Vec<Record>,
    /// The true pose at every odometry time.
    pub truth: Vec<StampedPose>,
    /// For each detection, the index of the true cone (`None`: a false positive).
    pub truth_associations: Vec<Association>,
    /// The true cones; their order gives the indices above.
    pub truth_map: Vec<Cone>,
    /// Sightings no detection stands for: in a point-cloud run, a cone whose
    /// points the clustering merged into another cone's cluster or left
    /// out. Scoring counts each as a wrong association.
    pub lost_sightings: usize,
}

impl Simulation {
    /// The run as the files of FORMAT.md: (file name, contents) of the log
    /// and its truth, in the layout `fs-eval --truth` reads.
    pub fn files(&self) -> [(&'static str, String); 4] {
        use cairn_slam::files::{TRUTH_ASSOC, TRUTH_MAP, TRUTH_TRAJ};
        [
            (cairn_slam::files::LOG, cairn_slam::log::to_jsonl(&self.log)),
            (
                TRUTH_TRAJ,
                cairn_slam::files::trajectory_to_tum(&self.truth),
            ),
            (
                TRUTH_ASSOC,
                cairn_slam::files::associations_to_csv(&self.truth_associations),
            ),
            (TRUTH_MAP, cairn_slam::map::map_to_csv(&self.truth_map)),
        ]
    }
}

/// Which physical object a detection came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Source {
    Cone(usize),
    Clutter(usize),
    FalsePositive,
}

/// Cone centres closer than this (m) overlap: a small cone's base is
/// 0.228 m across, so two such cones cannot both stand, and a detector sees
/// one object there. Some track files list a cone twice, 0.10–0.11 m apart
/// (eufs_rand three times); the big orange pairs stand 0.28 m apart.
pub const OVERLAP: f64 = 0.2;

/// For every cone, whether an earlier cone in the file overlaps it (see
/// [`OVERLAP`]): the detector reports only the first of such cones.
pub fn hidden_by_overlap(cones: &[Cone]) -> Vec<bool> {
    (0..cones.len())
        .map(|i| {
            cones[..i]
                .iter()
                .any(|c| (c.position - cones[i].position).norm() < OVERLAP)
        })
        .collect()
}

/// Simulates the default run (two laps at 5 m/s) of `preset` with noise
/// `seed`: [`simulate`] with the rest of [`SimConfig::default`].
pub fn simulate_preset(track: &Track, course: &Course, preset: Preset, seed: u64) -> Simulation {
    let config = SimConfig {
        preset,
        seed,
        ..SimConfig::default()
    };
    simulate(track, course, &config)
}

/// Simulates `config.laps` laps of `track` along `course`.
pub fn simulate(track: &Track, course: &Course, config: &SimConfig) -> Simulation {
    let mut rng = StdRng::seed_from_u64(config.seed);
    let hidden = hidden_by_overlap(&track.cones);
    let (odo, sensor) = (&config.preset.odometry, &config.preset.sensor);
    let dt = 1.0 / odo.rate;
    let scan_every = (odo.rate / sensor.rate).round().max(1.0) as usize;
    let distance = if course.is_closed() {
        config.laps * course.length()
    } else {
        course.length()
    };

    let mut pose = track.start;
    let mut s = course.project(&pose.t, None, 0.0);
    let mut travelled = 0.0;
    let mut log = vec![Record::Start { t: 0.0, pose }];
    let mut truth = Vec::new();
    let mut truth_associations = Vec::new();
    let mut tracker = Tracker::new(sensor.tracker);
    // The poses of the last `latency` seconds and one step more, newest
    // last: a scan sees from between the two oldest.
    let age = sensor.latency * odo.rate;
    let delay = age.ceil() as usize;
    let mut recent: VecDeque<SE2> = VecDeque::with_capacity(delay + 1);
    let mut bias = odo.yaw_rate_bias;
    let mut speed = config.speed;
    // The motion the odometry measured since the last scan, for the tracker.
    let mut measured = SE2::identity();
    let mut scan = 0;
    let mut step = 0usize;
    // A hard cap guards against a car that cannot make progress.
    let slowest = match config.preset.speed {
        SpeedProfile::Constant => config.speed,
        SpeedProfile::Corners { .. } => config.speed.min(2.0),
    };
    let max_steps = ((distance / slowest.max(0.1)) * odo.rate * 3.0) as usize + 100;
    while travelled < distance && step < max_steps {
        let t = step as f64 * dt;
        // Pure pursuit toward the centre line `lookahead` metres ahead.
        let target = pose
            .inverse()
            .transform_point(&course.point_at(s + config.lookahead));
        let alpha = target.y.atan2(target.x);
        let steer = (2.0 * config.wheelbase * alpha.sin() / target.norm().max(0.5))
            .atan()
            .clamp(-0.6, 0.6);
        let curvature = 2.0 * alpha.sin() / target.norm().max(0.5);
        let v = speed;
        let yaw_rate = v * steer.tan() / config.wheelbase;
        truth.push(StampedPose { t, pose });
        let odom = (
            v * (1.0 + odo.speed_scale_bias) + Noise::gaussian(odo.speed_sigma).sample(&mut rng),
            yaw_rate + bias + Noise::gaussian(odo.yaw_rate_sigma).sample(&mut rng),
        );
        log.push(Record::Odom {
            t,
            v: odom.0,
            yaw_rate: odom.1,
            steer: Some(steer + Noise::gaussian(odo.steer_sigma).sample(&mut rng)),
            vy: None,
        });
        if recent.len() > delay {
            recent.pop_front();
        }
        recent.push_back(pose);
        if step.is_multiple_of(scan_every) {
            let seen_from = pose_ago(&recent, age);
            let (cones, sources) = detect(
                track,
                &hidden,
                &seen_from,
                sensor,
                (&mut tracker, &measured),
                &mut rng,
            );
            measured = SE2::identity();
            for (det, source) in sources.iter().enumerate() {
                truth_associations.push(Association {
                    scan,
                    det,
                    landmark: match source {
                        Source::Cone(i) => Some(*i),
                        _ => None,
                    },
                });
            }
            log.push(Record::Cones { t, cones });
            scan += 1;
        }
        measured = integrate(&measured, odom.0, odom.1, dt);
        if odo.yaw_rate_bias_walk > 0.0 {
            bias += Noise::gaussian(odo.yaw_rate_bias_walk * dt.sqrt()).sample(&mut rng);
        }
        // Integrate the bicycle model exactly over the step (constant v, ω),
        // the velocity turned by the sideslip of the lateral acceleration.
        let sideslip = odo.sideslip * v * yaw_rate;
        pose = integrate_with_sideslip(&pose, v, yaw_rate, sideslip, dt);
        let s_new = course.project(&pose.t, Some(s), 10.0);
        let mut ds = s_new - s;
        if course.is_closed() {
            let l = course.length();
            ds = (ds + l / 2.0).rem_euclid(l) - l / 2.0;
        }
        travelled += ds;
        s = s_new;
        speed = config.preset.speed.next(speed, config.speed, curvature, dt);
        step += 1;
    }
    Simulation {
        log,
        truth,
        truth_associations,
        truth_map: track.cones.clone(),
        lost_sightings: 0,
    }
}

mod detector;
mod effects;
mod preset;
mod scanner;
mod tracker;
pub use scanner::point_clouds;

#[cfg(test)]
mod tests;

/// The pose `age` odometry steps before the newest of `recent` (whose
/// poses are one step apart, newest last), interpolated between steps;
/// the oldest there is before the log began.
fn pose_ago(recent: &VecDeque<SE2>, age: f64) -> SE2 {
    let newest = recent.len() - 1;
    let steps = age.ceil() as usize;
    if steps > newest {
        return recent[0];
    }
    let (older, newer) = (
        recent[newest - steps],
        recent[newest - steps.saturating_sub(1)],
    );
    let toward_newer = steps as f64 - age;
    let turn = cairn_core::se2::normalize_angle(newer.theta - older.theta);
    SE2::new(
        older.t.x + toward_newer * (newer.t.x - older.t.x),
        older.t.y + toward_newer * (newer.t.y - older.t.y),
        older.theta + toward_newer * turn,
    )
}
