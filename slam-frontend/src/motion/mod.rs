//! Motion models shared by every estimator: odometry records are integrated
//! into the relative motion since the last scan and its covariance.

use cairn_core::SE2;
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2, Vector3};
use std::collections::VecDeque;

/// How odometry turns into a yaw rate.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionModel {
    /// Speed and the measured yaw rate.
    Unicycle,
    /// Speed and the steering angle: ω = v·tan(δ)/L (falls back to the yaw
    /// rate when the log has no `steer`).
    Bicycle {
        /// Wheelbase L (m).
        wheelbase: f64,
    },
}

/// How the uncertainty of one odometry step is modelled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MotionNoise {
    /// Velocity model: independent errors on speed (σ plus a fraction of
    /// the speed) and on the yaw rate, and a heading error that grows with
    /// the turn itself.
    Velocity {
        /// Speed σ (m/s).
        speed_sigma: f64,
        /// Speed σ per m/s of speed (covers a scale bias).
        speed_sigma_relative: f64,
        /// Yaw-rate σ (rad/s).
        yaw_rate_sigma: f64,
        /// Heading σ per √rad turned (rad/√rad): the variance grows by
        /// `turn_sigma² · |turn|`, independent from one turn to the next,
        /// as when a robot's commanded spins are overstated or understated.
        /// 0 for a gyro, whose error is its bias (`yaw_rate_sigma`).
        turn_sigma: f64,
        /// Slip angle σ per m/s² of lateral acceleration (rad per m/s²):
        /// in a turn the car moves sideways, which wheel speed and gyro
        /// odometry do not see.
        sideslip_sigma: f64,
    },
    /// The odometry model of Thrun et al. (Probabilistic Robotics, 5.4): the
    /// step as a rotation δrot1, a translation δtrans and a rotation δrot2,
    /// with variances α₁δrot² + α₂δtrans² for the rotations and
    /// α₃δtrans² + α₄(δrot1² + δrot2²) for the translation.
    RotTransRot {
        /// α₁ … α₄.
        alpha: [f64; 4],
    },
}

impl MotionNoise {
    /// The command-line name.
    pub fn name(&self) -> &'static str {
        match self {
            MotionNoise::Velocity { .. } => "velocity",
            MotionNoise::RotTransRot { .. } => "rot-trans-rot",
        }
    }
}

/// What the odometry is corrected by before it is integrated: its speed
/// scale, its yaw-rate bias and the car's sideslip.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correction {
    /// True speed = measured speed × `speed_scale`.
    pub speed_scale: f64,
    /// True yaw rate = measured yaw rate − `yaw_rate_bias` (rad/s).
    pub yaw_rate_bias: f64,
    /// The car moves `sideslip` × its lateral acceleration (rad per m/s²)
    /// to the left of its heading: a linear tyre's slip angle, which wheel
    /// speeds and a gyro do not see.
    pub sideslip: f64,
}

impl Correction {
    /// The odometry as measured.
    pub const NONE: Correction = Correction {
        speed_scale: 1.0,
        yaw_rate_bias: 0.0,
        sideslip: 0.0,
    };
}

/// α₁…α₄ of the rot-trans-rot model matching the default velocity model
/// at 5 m/s and 50 Hz odometry: a 0.1 m step has σ 5 mm along the path
/// (α₃) and 0.4 mrad in heading (α₂); α₁ and α₄ cover turning.
pub const DEFAULT_ALPHA: [f64; 4] = [1e-3, 1.6e-5, 2.5e-3, 1e-4];

/// An odometry record, as held or waiting for the scan measured after it.
#[derive(Clone, Copy, Debug)]
struct Reading {
    t: f64,
    speeds: (f64, Option<f64>),
    yaw_rate: f64,
    steer: Option<f64>,
}

/// Odometry errors are mostly bias, so they add up over a scan interval
/// rather than average out; the step covariance is scaled as for this many
/// correlated steps.
const CORRELATED_STEPS: f64 = 10.0;

/// Integrates odometry records into the motion since the last
/// [`Odometry::take`], with its covariance (in the frame of the pose it
/// started from).
#[derive(Clone, Debug)]
pub struct Odometry {
    model: MotionModel,
    noise: MotionNoise,
    /// (speed, yaw rate, lateral speed) held until the next record.
    held: Option<(f64, f64, Option<f64>)>,
    time: Option<f64>,
    delta: SE2,
    delta_cov: Matrix3<f64>,
    /// Σ dt² over the steps since the last take: white noise of σ per
    /// step integrates to a heading variance of σ² Σ dt².
    step_time2: f64,
    /// Heading variance from the turns since the last take (the
    /// velocity model's `turn_sigma`).
    turn_variance: f64,
    /// ∂ of the motion's translation with respect to the sideslip (m per
    /// rad per m/s²), over the steps since the last take.
    slip_jacobian: Vector2<f64>,
    distance: f64,
    /// How long after it was measured a scan is stamped (s).
    scan_latency: f64,
    /// Records newer than the latest scan's moment of measurement could
    /// be: integrated once a later scan needs them.
    delayed: VecDeque<Reading>,
}

impl Odometry {
    /// An integrator with no motion yet.
    pub fn new(model: MotionModel, noise: MotionNoise) -> Self {
        Self {
            model,
            noise,
            held: None,
            time: None,
            delta: SE2::identity(),
            delta_cov: Matrix3::zeros(),
            step_time2: 0.0,
            turn_variance: 0.0,
            slip_jacobian: Vector2::zeros(),
            distance: 0.0,
            scan_latency: 0.0,
            delayed: VecDeque::new(),
        }
    }

    /// Scans are stamped `latency` seconds after they were measured: the
    /// odometry is integrated up to that moment ([`Odometry::advance_to_scan`]),
    /// and records in between wait for the next scan.
    pub fn with_scan_latency(mut self, latency: f64) -> Self {
        self.scan_latency = latency.max(0.0);
        self
    }

    /// Takes in the record at `t`: integrates up to `t` with the held
    /// record, then holds this one (with a scan latency, once a scan
    /// measured after `t` arrives). A measured lateral speed `vy` moves
    /// the car sideways instead of the sideslip of `correction`.
    pub fn record(
        &mut self,
        t: f64,
        (v, vy): (f64, Option<f64>),
        yaw_rate: f64,
        steer: Option<f64>,
        correction: Correction,
    ) {
        let reading = Reading {
            t,
            speeds: (v, vy),
            yaw_rate,
            steer,
        };
        if self.scan_latency > 0.0 {
            self.release(t - self.scan_latency, correction);
            self.delayed.push_back(reading);
        } else {
            self.hold(reading, correction);
        }
    }

    /// Integrates up to the moment a scan stamped `t` was measured (`t`
    /// less the scan latency) and returns that moment, the time the scan's
    /// pose belongs to.
    pub fn advance_to_scan(&mut self, t: f64, correction: Correction) -> f64 {
        let measured = t - self.scan_latency;
        self.release(measured, correction);
        self.advance(measured, correction);
        measured
    }

    /// Holds the delayed records up to time `until`.
    fn release(&mut self, until: f64, correction: Correction) {
        while let Some(&d) = self.delayed.front() {
            if d.t > until {
                break;
            }
            self.delayed.pop_front();
            self.hold(d, correction);
        }
    }

    /// Integrates up to the reading's time, then holds it.
    fn hold(&mut self, reading: Reading, correction: Correction) {
        self.advance(reading.t, correction);
        let (v, vy) = reading.speeds;
        let omega = match (self.model, reading.steer) {
            (MotionModel::Bicycle { wheelbase }, Some(s)) => v * s.tan() / wheelbase,
            _ => reading.yaw_rate,
        };
        self.held = Some((v, omega, vy));
        self.time = Some(reading.t);
    }

    /// Integrates the held record up to time `t`, corrected by `correction`.
    pub fn advance(&mut self, t: f64, correction: Correction) {
        let (Some((v, omega, vy)), Some(t0)) = (self.held, self.time) else {
            return;
        };
        let dt = t - t0;
        if dt <= 0.0 || !dt.is_finite() {
            return;
        }
        let omega = omega - correction.yaw_rate_bias;
        // The velocity's angle off the heading: measured, or the sideslip of
        // the lateral acceleration.
        // The lateral acceleration the sideslip multiplies (none where the
        // lateral speed is measured).
        let (v, slip, lateral) = match vy {
            Some(vy) => (v.hypot(vy) * correction.speed_scale, vy.atan2(v), 0.0),
            None => {
                let v = v * correction.speed_scale;
                (v, correction.sideslip * v * omega, v * omega)
            }
        };
        let mut step = integrate(&SE2::identity(), v, omega, dt);
        if slip != 0.0 {
            step.t = SE2::new(0.0, 0.0, slip).rotation() * step.t;
        }
        // A little more sideslip turns the step's translation further.
        let turned = Vector2::new(-step.t.y, step.t.x);
        self.slip_jacobian += self.delta.rotation() * turned * lateral;
        // Covariance of delta ∘ step: F with respect to delta, and the
        // step's own covariance rotated into delta's frame.
        let r = self.delta.rotation();
        let mut f = Matrix3::identity();
        f.fixed_view_mut::<2, 1>(0, 2)
            .copy_from(&(skew() * r * step.t));
        let mut rot = Matrix3::identity();
        rot.fixed_view_mut::<2, 2>(0, 0).copy_from(&r);
        let step_cov = self.step_cov(v, dt, &step);
        self.delta_cov = f * self.delta_cov * f.transpose()
            + rot * step_cov * rot.transpose() * CORRELATED_STEPS;
        // The turn's own error adds to the heading alone (rotating the
        // step into delta's frame leaves the heading as it is), and is not
        // a bias: it does not scale as correlated steps.
        if let MotionNoise::Velocity { turn_sigma, .. } = self.noise {
            let turned = turn_sigma * turn_sigma * step.theta.abs();
            self.delta_cov[(2, 2)] += turned;
            self.turn_variance += turned;
        }
        self.delta = self.delta.compose(&step);
        self.step_time2 += dt * dt;
        self.distance += (v * dt).abs();
        self.time = Some(t);
    }

    /// Covariance of one step (in the frame it starts from).
    fn step_cov(&self, v: f64, dt: f64, step: &SE2) -> Matrix3<f64> {
        match self.noise {
            MotionNoise::Velocity {
                speed_sigma,
                speed_sigma_relative,
                yaw_rate_sigma,
                sideslip_sigma,
                ..
            } => {
                // First order in dt: the step moves v·dt ahead and turns ω·dt.
                let mut g = SMatrix::<f64, 3, 2>::zeros();
                g[(0, 0)] = dt;
                g[(2, 1)] = dt;
                let sv = speed_sigma + speed_sigma_relative * v.abs();
                let q = Matrix2::new(sv * sv, 0.0, 0.0, yaw_rate_sigma.powi(2));
                let mut cov = g * q * g.transpose();
                // Sideways by the slip angle of the lateral acceleration v·ω.
                let omega = step.theta / dt;
                let lateral = v * dt * sideslip_sigma * (v * omega).abs();
                cov[(1, 1)] += lateral * lateral;
                cov
            }
            MotionNoise::RotTransRot { alpha } => {
                let (rot1, trans, rot2) = rot_trans_rot(step);
                let var = nalgebra::Vector3::new(
                    alpha[0] * rot1 * rot1 + alpha[1] * trans * trans,
                    alpha[2] * trans * trans + alpha[3] * (rot1 * rot1 + rot2 * rot2),
                    alpha[0] * rot2 * rot2 + alpha[1] * trans * trans,
                );
                let j = rot_trans_rot_jacobian(rot1, trans);
                j * Matrix3::from_diagonal(&var) * j.transpose()
            }
        }
    }

    /// The motion since the last call, with its covariance; starts anew.
    pub fn take(&mut self) -> (SE2, Matrix3<f64>) {
        let out = (self.delta, self.delta_cov);
        self.delta = SE2::identity();
        self.delta_cov = Matrix3::zeros();
        self.step_time2 = 0.0;
        self.turn_variance = 0.0;
        self.slip_jacobian = Vector2::zeros();
        out
    }

    /// ∂ of the translation of the motion since the last [`Odometry::take`]
    /// with respect to the correction's sideslip (read it before taking).
    pub fn slip_jacobian(&self) -> Vector2<f64> {
        self.slip_jacobian
    }

    /// Σ dt² of the integration steps since the last [`Odometry::take`]
    /// (read it before taking).
    pub fn step_time2(&self) -> f64 {
        self.step_time2
    }

    /// Variance of the heading change since the last [`Odometry::take`]
    /// from a yaw rate's white noise of `yaw_rate_noise` (rad/s) and the
    /// turns' own error, without the bias (read it before taking).
    pub fn white_heading_variance(&self, yaw_rate_noise: f64) -> f64 {
        yaw_rate_noise * yaw_rate_noise * self.step_time2 + self.turn_variance
    }

    /// Heading variance from the turns since the last [`Odometry::take`]
    /// (the velocity model's `turn_sigma`; read it before taking): an error
    /// of each turn, not of a bias the full optimisation estimates.
    pub fn turn_variance(&self) -> f64 {
        self.turn_variance
    }

    /// The motion since the last [`Odometry::take`], without resetting it.
    pub fn pending(&self) -> SE2 {
        self.delta
    }

    /// Distance driven so far (m).
    pub fn distance(&self) -> f64 {
        self.distance
    }
}

/// A relative pose as (δrot1, δtrans, δrot2).
pub fn rot_trans_rot(step: &SE2) -> (f64, f64, f64) {
    let trans = step.t.norm();
    let rot1 = if trans > 1e-12 {
        step.t.y.atan2(step.t.x)
    } else {
        0.0
    };
    let rot2 = cairn_core::se2::normalize_angle(step.theta - rot1);
    (rot1, trans, rot2)
}

/// ∂(x, y, θ)/∂(δrot1, δtrans, δrot2) of the pose reached from the origin.
pub fn rot_trans_rot_jacobian(rot1: f64, trans: f64) -> Matrix3<f64> {
    let (s, c) = rot1.sin_cos();
    Matrix3::new(-trans * s, c, 0.0, trans * c, s, 0.0, 1.0, 0.0, 1.0)
}

/// The pose `pose ∘ delta` and its covariance, first order, from the
/// covariances of `pose` (world frame) and `delta` (in `pose`'s frame).
pub fn compose_with_cov(
    pose: &SE2,
    pose_cov: &Matrix3<f64>,
    delta: &SE2,
    delta_cov: &Matrix3<f64>,
) -> (SE2, Matrix3<f64>) {
    let (j_pose, j_delta) = compose_jacobians(pose, delta);
    (
        pose.compose(delta),
        j_pose * pose_cov * j_pose.transpose() + j_delta * delta_cov * j_delta.transpose(),
    )
}

/// Jacobians of `pose ∘ delta` (as x, y, θ) with respect to `pose` and to `delta`.
pub fn compose_jacobians(pose: &SE2, delta: &SE2) -> (Matrix3<f64>, Matrix3<f64>) {
    let r = pose.rotation();
    let mut j_pose = Matrix3::identity();
    j_pose
        .fixed_view_mut::<2, 1>(0, 2)
        .copy_from(&(skew() * r * delta.t));
    let mut j_delta = Matrix3::identity();
    j_delta.fixed_view_mut::<2, 2>(0, 0).copy_from(&r);
    (j_pose, j_delta)
}

/// The 90° rotation: d R(θ)/dθ = skew · R(θ).
/// The motion `delta` of `dt` seconds with a yaw-rate bias of `bias`
/// (rad/s) taken out of its turn, and its derivative with respect to the
/// bias in `delta`'s frame: the turn less `bias·dt`, the chord turned by
/// half that.
pub fn without_bias(delta: &SE2, bias: f64, dt: f64) -> (SE2, Vector3<f64>) {
    let chord = SE2::new(0.0, 0.0, -0.5 * bias * dt).rotation() * delta.t;
    let corrected = SE2::new(chord.x, chord.y, delta.theta - bias * dt);
    let by_bias = Vector3::new(0.5 * dt * chord.y, -0.5 * dt * chord.x, -dt);
    (corrected, by_bias)
}

/// `cov` of a motion with its heading variance replaced by `heading`
/// and the position–heading covariance scaled to match (never widened):
/// where an estimator carries the yaw-rate bias as a state, the
/// integrated heading is weighed by the yaw rate's white noise alone,
/// not by a σ (and the correlated steps' inflation) that covers the bias.
pub fn with_heading_variance(cov: &Matrix3<f64>, heading: f64) -> Matrix3<f64> {
    let heading = heading.max(1e-12);
    let scale = (heading / cov[(2, 2)].max(1e-12)).min(1.0).sqrt();
    let mut out = *cov;
    for i in 0..2 {
        out[(i, 2)] *= scale;
        out[(2, i)] *= scale;
    }
    out[(2, 2)] = heading;
    out
}

fn skew() -> Matrix2<f64> {
    Matrix2::new(0.0, -1.0, 1.0, 0.0)
}

/// Exact integration of a unicycle with constant speed and yaw rate.
pub fn integrate(pose: &SE2, v: f64, yaw_rate: f64, dt: f64) -> SE2 {
    let dth = yaw_rate * dt;
    let local = if dth.abs() < 1e-9 {
        Vector2::new(v * dt, 0.0)
    } else {
        let r = v / yaw_rate;
        Vector2::new(r * dth.sin(), r * (1.0 - dth.cos()))
    };
    pose.compose(&SE2::new(local.x, local.y, dth))
}

#[cfg(test)]
mod tests;
