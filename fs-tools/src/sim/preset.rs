//! The simulator's error models: the cone detector's and the odometry's,
//! and the named presets that pair them (`standard`, `hard`, `realistic`).

use super::{SimConfigError, SpeedProfile, TrackerModel};
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
    /// Student-t degrees of freedom (above 2) of the range and bearing
    /// noise, at the same σ: heavy tails. `None`: Gaussian.
    pub noise_dof: Option<f64>,
    /// Detection probability at `max_range`, falling linearly from
    /// `detection_probability` at the vehicle. `None`: the same everywhere.
    pub far_detection_probability: Option<f64>,
    /// Nearer cones hide those whose centre is behind them.
    pub occlusion: bool,
    /// Age of a scan when it is stamped (s): the detections are measured
    /// from where the car was this long before the scan's time.
    pub latency: f64,
    /// Where the detections' tracker ids come from.
    pub tracker: TrackerModel,
}

impl SensorModel {
    /// Multiplies the range σ (both parts) and the bearing σ by `k`: a
    /// detector `k` times as noisy.
    pub fn scale_noise(&mut self, k: f64) {
        self.range_sigma *= k;
        self.range_sigma_relative *= k;
        self.bearing_sigma *= k;
    }
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
    /// Random walk of the yaw-rate bias (rad/s/√s): after t seconds it has
    /// drifted by this·√t (one σ).
    pub yaw_rate_bias_walk: f64,
    /// Sideslip per lateral acceleration (rad per m/s²): the car moves this
    /// far off its heading, outwards in a turn, which neither the speed nor
    /// the yaw rate measures.
    pub sideslip: f64,
}

/// A named pair of error models.
#[derive(Clone, Debug, PartialEq)]
pub struct Preset {
    /// `standard`, `hard` or `realistic`.
    pub name: &'static str,
    /// Detector.
    pub sensor: SensorModel,
    /// Odometry.
    pub odometry: OdometryModel,
    /// How fast the car drives, up to [`SimConfig::speed`](super::SimConfig::speed).
    pub speed: SpeedProfile,
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
                noise_dof: None,
                far_detection_probability: None,
                occlusion: false,
                latency: 0.0,
                tracker: TrackerModel::Oracle,
            },
            odometry: OdometryModel {
                rate: 50.0,
                speed_sigma: 0.05,
                speed_scale_bias: 0.01,
                yaw_rate_sigma: 0.005,
                yaw_rate_bias: 0.002,
                steer_sigma: 0.005,
                yaw_rate_bias_walk: 0.0,
                sideslip: 0.0,
            },
            speed: SpeedProfile::Constant,
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

    /// `standard`'s noise levels with what real cars and their perception
    /// add: Student-t noise with 3 degrees of freedom, detection falling to
    /// 0.6 at the range limit, occlusion by nearer cones, scans 50 ms old
    /// when stamped, tracker ids from gated nearest neighbour (0.5 m, 2
    /// misses), a yaw-rate bias random-walking at 5·10⁻⁴ rad/s/√s,
    /// sideslip of 0.01 rad per m/s², and a speed that slows to 4 m/s² of
    /// lateral acceleration in corners (accelerating and braking at 3 m/s²).
    pub fn realistic() -> Preset {
        let mut p = Preset::standard();
        p.name = "realistic";
        p.sensor.noise_dof = Some(3.0);
        p.sensor.far_detection_probability = Some(0.6);
        p.sensor.occlusion = true;
        p.sensor.latency = 0.05;
        p.sensor.tracker = TrackerModel::NearestNeighbour {
            gate: 0.5,
            max_misses: 2,
        };
        p.odometry.yaw_rate_bias_walk = 5e-4;
        p.odometry.sideslip = 0.01;
        p.speed = SpeedProfile::Corners {
            lateral_acceleration: 4.0,
            longitudinal_acceleration: 3.0,
        };
        p
    }

    /// The presets' names, as [`Preset::by_name`] takes them.
    pub const NAMES: [&'static str; 3] = ["standard", "hard", "realistic"];

    /// A preset by name.
    pub fn by_name(name: &str) -> Option<Preset> {
        match name {
            "standard" => Some(Preset::standard()),
            "hard" => Some(Preset::hard()),
            "realistic" => Some(Preset::realistic()),
            _ => None,
        }
    }
}

impl Preset {
    /// Checks the settings that a preset's effects rely on.
    pub fn check(&self) -> Result<(), SimConfigError> {
        let (s, o) = (&self.sensor, &self.odometry);
        let probability = |p: f64| (0.0..=1.0).contains(&p);
        let mut checks: Vec<(&'static str, f64, bool, &'static str)> = vec![
            (
                "latency",
                s.latency,
                (0.0..=1.0).contains(&s.latency),
                "from 0 to 1 s",
            ),
            (
                "yaw_rate_bias_walk",
                o.yaw_rate_bias_walk,
                (0.0..=1.0).contains(&o.yaw_rate_bias_walk),
                "from 0 to 1 rad/s/√s",
            ),
            (
                "sideslip",
                o.sideslip,
                (-0.5..=0.5).contains(&o.sideslip),
                "from -0.5 to 0.5 rad per m/s²",
            ),
        ];
        if let Some(dof) = s.noise_dof {
            checks.push((
                "noise_dof",
                dof,
                dof > 2.0 && dof.is_finite(),
                "finite and above 2",
            ));
        }
        if let Some(p) = s.far_detection_probability {
            checks.push((
                "far_detection_probability",
                p,
                probability(p),
                "from 0 to 1",
            ));
        }
        if let TrackerModel::NearestNeighbour { gate, .. } = s.tracker {
            checks.push((
                "tracker gate",
                gate,
                gate > 0.0 && gate <= 10.0,
                "above 0 and at most 10 m",
            ));
        }
        if let SpeedProfile::Corners {
            lateral_acceleration: a,
            longitudinal_acceleration: b,
        } = self.speed
        {
            checks.push((
                "lateral_acceleration",
                a,
                a > 0.0 && a <= 50.0,
                "above 0 and at most 50 m/s²",
            ));
            checks.push((
                "longitudinal_acceleration",
                b,
                b > 0.0 && b <= 50.0,
                "above 0 and at most 50 m/s²",
            ));
        }
        match checks.into_iter().find(|c| !c.2) {
            Some((field, value, _, rule)) => Err(SimConfigError::Model { field, rule, value }),
            None => Ok(()),
        }
    }
}
