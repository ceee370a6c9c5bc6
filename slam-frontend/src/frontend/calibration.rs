//! Online odometry calibration from landmark-corrected poses.

use cairn_core::SE2;

/// Odometry corrections learnt online from the landmark-corrected poses:
/// a speed scale and a yaw-rate bias. The presets' 1–3% speed bias and
/// 0.002–0.01 rad/s yaw-rate bias would otherwise bend and stretch the map
/// more than the odometry covariance admits.
#[derive(Clone, Copy, Debug)]
pub struct Calibration {
    /// True speed = measured speed × `speed_scale`.
    pub speed_scale: f64,
    /// True yaw rate = measured yaw rate − `yaw_rate_bias` (rad/s).
    pub yaw_rate_bias: f64,
}

impl Default for Calibration {
    fn default() -> Self {
        Self {
            speed_scale: 1.0,
            yaw_rate_bias: 0.0,
        }
    }
}

/// How fast the calibration follows each scan's evidence.
const CALIBRATION_GAIN: f64 = 0.02;

impl Calibration {
    /// (speed scale, yaw-rate bias), as [`Odometry`](crate::motion::Odometry) applies them.
    pub fn correction(&self) -> (f64, f64) {
        (self.speed_scale, self.yaw_rate_bias)
    }

    /// Nudges the corrections toward what one scan showed: the odometry
    /// predicted `pred` from `previous`, the landmarks put the car at `pose`.
    /// The yaw-rate bias only with `learn_bias`: while mapping, the
    /// smoothing window estimates it beside the poses instead.
    pub(super) fn learn(
        &mut self,
        previous: &SE2,
        pred: &SE2,
        pose: &SE2,
        dt: f64,
        learn_bias: bool,
    ) {
        let predicted = previous.between(pred);
        let corrected = previous.between(pose);
        let length = predicted.t.norm();
        if length < 0.1 || dt <= 0.0 {
            return;
        }
        let along = corrected.t.dot(&predicted.t) / length;
        let ratio = (along / length).clamp(0.8, 1.2);
        self.speed_scale *= 1.0 + CALIBRATION_GAIN * (ratio - 1.0);
        if learn_bias {
            let residual = cairn_core::se2::normalize_angle(corrected.theta - predicted.theta);
            self.yaw_rate_bias -= CALIBRATION_GAIN * residual / dt;
        }
    }
}
