//! Online odometry calibration from landmark-corrected poses.

use crate::motion::Correction;
use cairn_core::SE2;
use nalgebra::{Matrix3, Vector2};

/// Odometry corrections learnt online from the landmark-corrected poses:
/// a speed scale, a yaw-rate bias and the sideslip; and how fast the bias
/// wanders, learnt from the full optimisations. The presets' 1–3% speed
/// bias and 0.002–0.01 rad/s yaw-rate bias would otherwise bend and stretch
/// the map more than the odometry covariance admits, and a car that slides
/// outward in every left turn drifts as if its gyro were biased.
#[derive(Clone, Copy, Debug)]
pub struct Calibration {
    /// True speed = measured speed × `speed_scale`.
    pub speed_scale: f64,
    /// True yaw rate = measured yaw rate − `yaw_rate_bias` (rad/s).
    pub yaw_rate_bias: f64,
    /// Sideslip per lateral acceleration (rad per m/s²), as [`Correction::sideslip`].
    pub sideslip: f64,
    /// The random walk of the yaw-rate bias (rad/s/√s): the config's, or
    /// more where the loop's headings showed the bias wandering faster.
    pub yaw_rate_bias_walk: f64,
    /// How long after it was measured a scan is stamped (s): the config's
    /// `scan_latency`, or what the end of the run learnt.
    pub scan_latency: f64,
    /// The σ (s) to which the end of the run found the log to pin the
    /// latency, once it has looked (`learn_scan_latency`); the latency is
    /// learnt only where this is small and the log's differs from the
    /// config's by several σ.
    pub scan_latency_sigma: Option<f64>,
    /// Whether the smoothing window has found a sideslip (its estimate
    /// 2.5 σ from none) and estimates it beside the poses; until then the
    /// scans' pose fits learn it, which see only part of it.
    pub sideslip_free: bool,
    /// Σ slip angle × lateral acceleration and Σ lateral acceleration² over
    /// the scans (with the prior): the sideslip is their least-squares ratio.
    slip_moment: f64,
    slip_weight: f64,
}

impl Default for Calibration {
    fn default() -> Self {
        Self {
            speed_scale: 1.0,
            yaw_rate_bias: 0.0,
            sideslip: 0.0,
            yaw_rate_bias_walk: 0.0,
            scan_latency: 0.0,
            scan_latency_sigma: None,
            sideslip_free: false,
            slip_moment: 0.0,
            slip_weight: SIDESLIP_PRIOR,
        }
    }
}

/// How fast the calibration follows each scan's evidence.
const CALIBRATION_GAIN: f64 = 0.02;

/// The prior on no sideslip, in (m/s²/rad)²: as much as eleven scans
/// turning at 3 m/s² whose direction of travel is known to 0.05 rad. A car's
/// sideslip per lateral acceleration is a constant of its tyres, so every
/// scan of the run counts alike. Measured on random tracks 0–2, seeds
/// 100–109 (30 runs each): as strong as 70 such scans, the slide was learnt
/// too late to close 5 `realistic` runs (2 with this prior); as weak as 11
/// scans unweighted, on `hard` logs, which do not slide, the pose fits'
/// scatter made a slide that lost a map (random track 1, seed 6).
const SIDESLIP_PRIOR: f64 = 100.0 / (0.05 * 0.05);

/// The smallest σ of a scan's direction of travel (rad) the weights assume.
const SLIP_FLOOR: f64 = 0.005;

/// A scan whose direction of travel is farther than this (rad) from the
/// predicted one is a poor pose fit, not a slide.
const MAX_SLIP_ANGLE: f64 = 0.2;

/// The largest sideslip learnt (rad per m/s²): 0.5 rad at 10 m/s².
pub(super) const MAX_SIDESLIP: f64 = 0.05;

impl Calibration {
    /// The corrections, as [`Odometry`](crate::motion::Odometry) applies them.
    pub fn correction(&self) -> Correction {
        Correction {
            speed_scale: self.speed_scale,
            yaw_rate_bias: self.yaw_rate_bias,
            sideslip: self.sideslip,
        }
    }

    /// Sets the sideslip to what the smoothing windows learnt, known with
    /// information `info`: the scans' evidence after it adds to that.
    pub(super) fn set_sideslip(&mut self, sideslip: f64, info: f64) {
        self.sideslip = sideslip;
        self.slip_moment = sideslip * info;
        self.slip_weight = info;
    }

    /// Nudges the corrections toward what one scan showed: the odometry
    /// predicted `pred` from `previous`, the landmarks put the car at `pose`.
    /// The yaw-rate bias only `outside_window`: while mapping, the
    /// smoothing window estimates it beside the poses; the sideslip too,
    /// once the window has found one ([`Calibration::sideslip_free`]).
    pub(super) fn learn(
        &mut self,
        previous: &SE2,
        pred: &SE2,
        (pose, pose_cov): (&SE2, &Matrix3<f64>),
        dt: f64,
        outside_window: bool,
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
        // The direction moved, against the one predicted with the sideslip
        // learnt so far, and the step's lateral acceleration v·ω: the slip
        // angle is the sideslip times it.
        let lateral = length * predicted.theta / (dt * dt);
        let turned = predicted
            .t
            .perp(&corrected.t)
            .atan2(predicted.t.dot(&corrected.t));
        if (outside_window || !self.sideslip_free) && turned.abs() < MAX_SLIP_ANGLE {
            let slip = turned + self.sideslip * lateral;
            // Weighed by 1/σ² of the direction between two fits, each placed
            // across the path to the fit's σ.
            let normal = previous.rotation() * Vector2::new(-predicted.t.y, predicted.t.x) / length;
            let across = (normal.transpose() * pose_cov.fixed_view::<2, 2>(0, 0) * normal)[0];
            let variance = (2.0 * across / (length * length)).max(SLIP_FLOOR.powi(2));
            self.slip_moment += slip * lateral / variance;
            self.slip_weight += lateral * lateral / variance;
            self.sideslip =
                (self.slip_moment / self.slip_weight).clamp(-MAX_SIDESLIP, MAX_SIDESLIP);
        }
        if outside_window {
            let residual = cairn_core::se2::normalize_angle(corrected.theta - predicted.theta);
            self.yaw_rate_bias -= CALIBRATION_GAIN * residual / dt;
        }
    }
}

/// What a run of windows learnt about a constant of the car: a Gaussian
/// that each window's estimate joins.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Belief {
    /// Mean and information.
    pub mean: f64,
    pub info: f64,
}

impl Belief {
    /// N(`mean`, `sigma`²).
    pub(super) fn new(mean: f64, sigma: f64) -> Self {
        Self {
            mean,
            info: 1.0 / (sigma * sigma).max(1e-18),
        }
    }

    /// Joins a window's estimate `value` of marginal `variance`, whose
    /// prior this was, then lets the value wander by `walk_variance`.
    /// Each scan's data sit in `windows` consecutive windows, so each adds
    /// a 1/`windows` share of its information.
    pub(super) fn carry(&mut self, value: f64, variance: f64, walk_variance: f64, windows: usize) {
        let windows = windows.max(1) as f64;
        let posterior_info = 1.0 / variance.max(1e-18);
        let share = (posterior_info - self.info).max(0.0) / windows;
        let info = self.info + share;
        // The data's own estimate v_d solves Λ₁ v₁ = Λ₀ v₀ + (Λ₁ − Λ₀) v_d;
        // the share pulls the prior mean toward it by share / info.
        let gain = (posterior_info / (windows * info)).min(1.0);
        self.mean += gain * (value - self.mean);
        self.info = 1.0 / (1.0 / info + walk_variance);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::{Correction, integrate};

    #[test]
    fn a_car_sliding_in_its_turns_has_its_sideslip_learned() {
        // 5 m/s, left and right turns of 4 m/s², a slip of 0.01 rad per m/s²
        // that the odometry does not see; the landmarks find the true pose.
        let (truth, dt) = (0.01, 0.1);
        let mut calibration = Calibration::default();
        let mut pose = SE2::identity();
        // Each fit placed to 2 cm.
        let fit = Matrix3::from_diagonal(&nalgebra::Vector3::new(4e-4, 4e-4, 1e-5));
        for k in 0..400 {
            let omega = if (k / 50) % 2 == 0 { 0.8 } else { -0.8 };
            let step = |slip: f64| {
                let mut s = integrate(&SE2::identity(), 5.0, omega, dt);
                s.t = SE2::new(0.0, 0.0, slip * 5.0 * omega).rotation() * s.t;
                s
            };
            let predicted = pose.compose(&step(calibration.sideslip));
            let actual = pose.compose(&step(truth));
            calibration.learn(&pose, &predicted, (&actual, &fit), dt, true);
            pose = actual;
        }
        let learned = calibration.correction();
        assert!((learned.sideslip - truth).abs() < 0.001, "{learned:?}");
        // The slide shortens the step along the predicted direction by its
        // cosine only: the speed scale hardly moves.
        assert!((learned.speed_scale - 1.0).abs() < 1e-3, "{learned:?}");
        assert_eq!(learned.yaw_rate_bias, Correction::NONE.yaw_rate_bias);
    }
}
