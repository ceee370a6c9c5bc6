//! `fs-sim`'s options for the effects a preset may add: each on its own,
//! on top of `--preset`.

use super::CliError;
use cairn::fs_tools::sim::{Preset, SimConfigError, SpeedProfile, TrackerModel};
use clap::Args;

/// Effects of `fs-sim` beyond the preset's (each overrides it).
#[derive(Debug, Args)]
pub struct SimEffects {
    /// Multiply the preset's range and bearing noise σ by this (e.g. 2 for a
    /// detector noisier than an estimator assumes), above 0 and at most 100.
    #[arg(long)]
    noise_scale: Option<f64>,
    /// Student-t range and bearing noise with this many degrees of freedom
    /// (above 2), at the same σ: heavy tails.
    #[arg(long)]
    noise_dof: Option<f64>,
    /// Detection probability at the range limit, falling linearly from the
    /// preset's near the car.
    #[arg(long)]
    far_detection_probability: Option<f64>,
    /// Nearer cones hide the cones behind them: true or false.
    #[arg(long)]
    occlusion: Option<bool>,
    /// Scans are this old when stamped (s, at most 1): the detections are
    /// measured from where the car was then.
    #[arg(long)]
    latency: Option<f64>,
    /// Tracker ids: `oracle` (keyed on the true cone) or `nn` (gated nearest
    /// neighbour on the noisy detections: ids switch, fragment and return).
    #[arg(long, value_parser = ["oracle", "nn"])]
    tracker: Option<String>,
    /// The `nn` tracker's gate (m).
    #[arg(long, default_value_t = 0.5)]
    tracker_gate: f64,
    /// Random walk of the gyro's yaw-rate bias (rad/s/√s).
    #[arg(long)]
    yaw_rate_bias_walk: Option<f64>,
    /// Sideslip per lateral acceleration (rad per m/s²): the car slides off
    /// its heading in turns, which the odometry does not see.
    #[arg(long)]
    sideslip: Option<f64>,
    /// Speed: `constant` (`--speed` throughout) or `corners` (`--speed` on
    /// straights, slowing to 4 m/s² of lateral acceleration in corners).
    #[arg(long, value_parser = ["constant", "corners"])]
    speed_profile: Option<String>,
}

impl SimEffects {
    /// `preset` with these options applied.
    pub fn apply(&self, mut preset: Preset) -> Result<Preset, CliError> {
        let (sensor, odometry) = (&mut preset.sensor, &mut preset.odometry);
        if let Some(scale) = self.noise_scale {
            if !(scale > 0.0 && scale <= 100.0) {
                return Err(CliError::usage(format!(
                    "--noise-scale must be above 0 and at most 100, got {scale}"
                )));
            }
            sensor.scale_noise(scale);
        }
        if self.noise_dof.is_some() {
            sensor.noise_dof = self.noise_dof;
        }
        if self.far_detection_probability.is_some() {
            sensor.far_detection_probability = self.far_detection_probability;
        }
        if let Some(occlusion) = self.occlusion {
            sensor.occlusion = occlusion;
        }
        if let Some(latency) = self.latency {
            sensor.latency = latency;
        }
        match self.tracker.as_deref() {
            Some("oracle") => sensor.tracker = TrackerModel::Oracle,
            Some(_) => {
                sensor.tracker = TrackerModel::NearestNeighbour {
                    gate: self.tracker_gate,
                    max_misses: 2,
                }
            }
            None => {}
        }
        if let Some(walk) = self.yaw_rate_bias_walk {
            odometry.yaw_rate_bias_walk = walk;
        }
        if let Some(sideslip) = self.sideslip {
            odometry.sideslip = sideslip;
        }
        match self.speed_profile.as_deref() {
            Some("constant") => preset.speed = SpeedProfile::Constant,
            Some(_) => {
                preset.speed = SpeedProfile::Corners {
                    lateral_acceleration: 4.0,
                    longitudinal_acceleration: 3.0,
                }
            }
            None => {}
        }
        preset.check().map_err(flag_error)?;
        Ok(preset)
    }
}

/// A preset setting out of range, named by its flag.
pub fn flag_error(e: SimConfigError) -> CliError {
    match e {
        SimConfigError::Model { field, rule, value } => CliError::usage(format!(
            "--{} must be {rule}, got {value}",
            field.replace(['_', ' '], "-")
        )),
        other => CliError::usage(other.to_string()),
    }
}
