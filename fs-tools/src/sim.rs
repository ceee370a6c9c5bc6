//! The simulator behind `cairn fs-sim`: a kinematic bicycle driven along a
//! track's centre line by pure pursuit, with a cone detector and odometry
//! whose errors follow a named preset.

use crate::course::Course;
use crate::track::Track;
use cairn_core::SE2;
use cairn_slam::Color;
use cairn_slam::Cone;
use cairn_slam::files::{Association, StampedPose};
use cairn_slam::log::{Detection, Record};
use cairn_slam::motion::integrate;
use nalgebra::Vector2;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Poisson, StandardNormal};
use std::collections::HashMap;
use std::f64::consts::PI;

/// The cone detector's error model.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorModel {
    /// Scans per second.
    pub rate: f64,
    /// Full field of view (rad), centred on the heading.
    pub fov: f64,
    /// Largest detection range (m).
    pub max_range: f64,
    /// Probability that a cone in view is detected in a scan.
    pub detection_probability: f64,
    /// Range noise σ = `range_sigma` + `range_sigma_relative` · range (m).
    pub range_sigma: f64,
    /// See `range_sigma`.
    pub range_sigma_relative: f64,
    /// Bearing noise σ (rad).
    pub bearing_sigma: f64,
    /// Probability that a detected colour is wrong (blue↔yellow, orange↔big orange).
    pub wrong_color: f64,
    /// Probability that a detected colour is `unknown`.
    pub unknown_color: f64,
    /// Mean number of false positives per scan (Poisson), uniform in the field of view.
    pub false_positives: f64,
    /// Probability per scan that the tracker swaps the ids of two nearby cones.
    pub id_swap: f64,
    /// Probability that a clutter object in view (EUFS `inactive_noise`) is
    /// detected as a cone, with a random colour: a recurring false positive.
    pub clutter_detection_probability: f64,
}

/// The odometry's error model.
#[derive(Clone, Debug, PartialEq)]
pub struct OdometryModel {
    /// Odometry messages per second.
    pub rate: f64,
    /// Speed noise σ (m/s).
    pub speed_sigma: f64,
    /// Speed scale bias (0.01 = reads 1% fast).
    pub speed_scale_bias: f64,
    /// Yaw-rate noise σ (rad/s).
    pub yaw_rate_sigma: f64,
    /// Constant yaw-rate bias (rad/s).
    pub yaw_rate_bias: f64,
    /// Steering-angle noise σ (rad).
    pub steer_sigma: f64,
}

/// A named pair of error models.
#[derive(Clone, Debug, PartialEq)]
pub struct Preset {
    /// `standard` or `hard`.
    pub name: &'static str,
    /// Detector.
    pub sensor: SensorModel,
    /// Odometry.
    pub odometry: OdometryModel,
}

impl Preset {
    /// 10 Hz scans, 50 Hz odometry, 180° FOV, 15 m range, detection 0.9,
    /// range σ 0.05 m + 1%, bearing σ 0.5°, 2% wrong colour, 5% unknown,
    /// 0.3 false positives per scan; speed σ 0.05 m/s with 1% scale bias,
    /// yaw-rate σ 0.005 rad/s with 0.002 rad/s bias.
    /// Clutter objects are detected with probability 0.3 and a random colour;
    /// tracker ids swap with probability 0.01 per scan.
    pub fn standard() -> Preset {
        Preset {
            name: "standard",
            sensor: SensorModel {
                rate: 10.0,
                fov: PI,
                max_range: 15.0,
                detection_probability: 0.9,
                range_sigma: 0.05,
                range_sigma_relative: 0.01,
                bearing_sigma: 0.5f64.to_radians(),
                wrong_color: 0.02,
                unknown_color: 0.05,
                false_positives: 0.3,
                id_swap: 0.01,
                clutter_detection_probability: 0.3,
            },
            odometry: OdometryModel {
                rate: 50.0,
                speed_sigma: 0.05,
                speed_scale_bias: 0.01,
                yaw_rate_sigma: 0.005,
                yaw_rate_bias: 0.002,
                steer_sigma: 0.005,
            },
        }
    }

    /// `standard` with range σ 0.1 m + 2%, bearing σ 2°, detection 0.8, 5%
    /// wrong colour, 10% unknown, 1 false positive per scan, 3% speed bias,
    /// 0.01 rad/s yaw-rate bias.
    pub fn hard() -> Preset {
        let mut p = Preset::standard();
        p.name = "hard";
        p.sensor.range_sigma = 0.1;
        p.sensor.range_sigma_relative = 0.02;
        p.sensor.bearing_sigma = 2f64.to_radians();
        p.sensor.detection_probability = 0.8;
        p.sensor.wrong_color = 0.05;
        p.sensor.unknown_color = 0.10;
        p.sensor.false_positives = 1.0;
        p.sensor.id_swap = 0.03;
        p.odometry.speed_scale_bias = 0.03;
        p.odometry.yaw_rate_bias = 0.01;
        p
    }

    /// A preset by name.
    pub fn by_name(name: &str) -> Option<Preset> {
        match name {
            "standard" => Some(Preset::standard()),
            "hard" => Some(Preset::hard()),
            _ => None,
        }
    }
}

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

/// Zero-mean Gaussian noise: σ times a standard normal draw (the same draws
/// as `rand_distr::Normal`, which refuses some σ instead).
struct Gaussian {
    sigma: f64,
}

impl Distribution<f64> for Gaussian {
    fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        self.sigma * rng.sample::<f64, _>(StandardNormal)
    }
}

/// Gaussian noise of standard deviation `sigma`, clamped to [1e-300,
/// f64::MAX]: a noise-free sensor (σ = 0) or a configuration error
/// (negative, NaN or infinite σ) still draws finite noise.
fn gaussian(sigma: f64) -> Gaussian {
    let sigma = if sigma.is_nan() {
        1e-300
    } else {
        sigma.clamp(1e-300, f64::MAX)
    };
    Gaussian { sigma }
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

/// Simulates `config.laps` laps of `track` along `course`.
pub fn simulate(track: &Track, course: &Course, config: &SimConfig) -> Simulation {
    let mut rng = StdRng::seed_from_u64(config.seed);
    let hidden = hidden_by_overlap(&track.cones);
    let odo = &config.preset.odometry;
    let dt = 1.0 / odo.rate;
    let scan_every = (odo.rate / config.preset.sensor.rate).round().max(1.0) as usize;
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
    let mut tracker = Tracker::default();
    let mut scan = 0;
    let mut step = 0usize;
    // A hard cap guards against a car that cannot make progress.
    let max_steps = ((distance / config.speed.max(0.1)) * odo.rate * 3.0) as usize + 100;
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
        let v = config.speed;
        let yaw_rate = v * steer.tan() / config.wheelbase;
        truth.push(StampedPose { t, pose });
        log.push(Record::Odom {
            t,
            v: v * (1.0 + odo.speed_scale_bias) + gaussian(odo.speed_sigma).sample(&mut rng),
            yaw_rate: yaw_rate + odo.yaw_rate_bias + gaussian(odo.yaw_rate_sigma).sample(&mut rng),
            steer: Some(steer + gaussian(odo.steer_sigma).sample(&mut rng)),
            vy: None,
        });
        if step.is_multiple_of(scan_every) {
            let (cones, sources) = detect(
                track,
                &hidden,
                &pose,
                &config.preset.sensor,
                &mut tracker,
                &mut rng,
            );
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
        // Integrate the bicycle model exactly over the step (constant v, ω).
        pose = integrate(&pose, v, yaw_rate, dt);
        let s_new = course.project(&pose.t, Some(s), 10.0);
        let mut ds = s_new - s;
        if course.is_closed() {
            let l = course.length();
            ds = (ds + l / 2.0).rem_euclid(l) - l / 2.0;
        }
        travelled += ds;
        s = s_new;
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

/// Tracker identities: an object keeps its id while seen in recent scans.
#[derive(Default)]
struct Tracker {
    ids: HashMap<Source, (u64, usize)>,
    next: u64,
    scan: usize,
}

impl Tracker {
    fn id(&mut self, source: Source) -> u64 {
        let scan = self.scan;
        if source == Source::FalsePositive {
            self.next += 1;
            return self.next;
        }
        match self.ids.get_mut(&source) {
            Some((id, last)) if scan <= *last + 3 => {
                *last = scan;
                *id
            }
            _ => {
                self.next += 1;
                self.ids.insert(source, (self.next, scan));
                self.next
            }
        }
    }
}

/// One scan from `pose`. A cone `hidden` by an overlapping one draws its
/// noise like any other (so that hiding it leaves every other detection's
/// draws as they were) but is not reported.
fn detect(
    track: &Track,
    hidden: &[bool],
    pose: &SE2,
    sensor: &SensorModel,
    tracker: &mut Tracker,
    rng: &mut StdRng,
) -> (Vec<Detection>, Vec<Source>) {
    let inverse = pose.inverse();
    let bearing_noise = gaussian(sensor.bearing_sigma);
    let mut found: Vec<(Source, Vector2<f64>, Color)> = Vec::new();
    let objects = track
        .cones
        .iter()
        .enumerate()
        .map(|(i, c)| (Source::Cone(i), c.position, c.color))
        .chain(
            track
                .clutter
                .iter()
                .enumerate()
                .map(|(i, p)| (Source::Clutter(i), *p, Color::Unknown)),
        );
    for (source, world, color) in objects {
        let local = inverse.transform_point(&world);
        let (r, b) = (local.norm(), local.y.atan2(local.x));
        if r > sensor.max_range || r < 0.5 || b.abs() > sensor.fov / 2.0 {
            continue;
        }
        let (probability, color) = match source {
            Source::Clutter(_) => (
                sensor.clutter_detection_probability,
                [Color::Blue, Color::Yellow, Color::Unknown][rng.random_range(0..3)],
            ),
            _ => (sensor.detection_probability, color),
        };
        if rng.random::<f64>() < probability {
            found.push((source, local, color));
        }
    }
    let fp = Poisson::new(sensor.false_positives.max(1e-12))
        .map(|p| p.sample(rng) as usize)
        .unwrap_or(0);
    for _ in 0..fp {
        let r = rng.random_range(1.0..sensor.max_range);
        let b = rng.random_range(-sensor.fov / 2.0..sensor.fov / 2.0);
        let color = [Color::Blue, Color::Yellow, Color::Unknown][rng.random_range(0..3)];
        found.push((
            Source::FalsePositive,
            Vector2::new(r * b.cos(), r * b.sin()),
            color,
        ));
    }
    found.shuffle(rng);
    tracker.scan += 1;
    let mut ids: Vec<u64> = found.iter().map(|(s, _, _)| tracker.id(*s)).collect();
    if found.len() >= 2 && rng.random::<f64>() < sensor.id_swap {
        // Swap the ids of two tracked objects less than 3 m apart.
        let i = rng.random_range(0..found.len());
        let near = (0..found.len()).find(|&j| {
            j != i
                && found[j].0 != Source::FalsePositive
                && found[i].0 != Source::FalsePositive
                && (found[j].1 - found[i].1).norm() < 3.0
        });
        if let Some(j) = near {
            ids.swap(i, j);
            for k in [i, j] {
                if let Some(entry) = tracker.ids.get_mut(&found[k].0) {
                    entry.0 = ids[k];
                }
            }
        }
    }
    let mut detections = Vec::with_capacity(found.len());
    let mut sources = Vec::with_capacity(found.len());
    for ((source, local, color), id) in found.into_iter().zip(ids) {
        let r = local.norm();
        let range_noise = gaussian(sensor.range_sigma + sensor.range_sigma_relative * r);
        let r = (r + range_noise.sample(rng)).max(0.0);
        let b = local.y.atan2(local.x) + bearing_noise.sample(rng);
        let u: f64 = rng.random();
        let color = if u < sensor.unknown_color {
            Color::Unknown
        } else if u < sensor.unknown_color + sensor.wrong_color {
            match color {
                Color::Blue => Color::Yellow,
                Color::Yellow => Color::Blue,
                Color::Orange => Color::BigOrange,
                Color::BigOrange => Color::Orange,
                Color::Unknown => Color::Unknown,
            }
        } else {
            color
        };
        if matches!(source, Source::Cone(i) if hidden[i]) {
            continue;
        }
        detections.push(Detection {
            position: Vector2::new(r * b.cos(), r * b.sin()),
            range_bearing: Some((r, b)),
            color,
            id: Some(id),
            covariance: None,
        });
        sources.push(source);
    }
    (detections, sources)
}

mod scanner;
pub use scanner::point_clouds;

#[cfg(test)]
mod tests;
