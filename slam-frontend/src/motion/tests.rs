//! Tests of the odometry integration and its noise models.

use super::*;
use nalgebra::Vector3;
use proptest::prelude::*;

fn numeric(x: Vector3<f64>, f: impl Fn(Vector3<f64>) -> Vector3<f64>) -> Matrix3<f64> {
    let h = 1e-6;
    Matrix3::from_fn(|i, j| {
        let (mut a, mut b) = (x, x);
        a[j] += h;
        b[j] -= h;
        let d = f(a) - f(b);
        let d = if i == 2 {
            cairn_core::se2::normalize_angle(d[i])
        } else {
            d[i]
        };
        d / (2.0 * h)
    })
}

proptest! {
    #[test]
    fn composition_jacobians_match_differences(
        p in prop::array::uniform3(-3.0..3.0f64), d in prop::array::uniform3(-2.0..2.0f64),
    ) {
        let (pose, delta) = (SE2::new(p[0], p[1], p[2]), SE2::new(d[0], d[1], d[2]));
        let (j_pose, j_delta) = compose_jacobians(&pose, &delta);
        let by_pose = numeric(pose.to_vector(), |x| SE2::from_vector(&x).compose(&delta).to_vector());
        let by_delta = numeric(delta.to_vector(), |x| pose.compose(&SE2::from_vector(&x)).to_vector());
        prop_assert!((j_pose - by_pose).abs().max() < 1e-6);
        prop_assert!((j_delta - by_delta).abs().max() < 1e-6);
    }

    #[test]
    fn rot_trans_rot_round_trips_and_its_jacobian_matches(
        rot1 in -1.5..1.5f64, trans in 0.05..2.0f64, rot2 in -1.5..1.5f64,
    ) {
        let pose_of = |u: Vector3<f64>| {
            let (s, c) = u[0].sin_cos();
            SE2::new(u[1] * c, u[1] * s, u[0] + u[2])
        };
        let u = Vector3::new(rot1, trans, rot2);
        let (a, b, c) = rot_trans_rot(&pose_of(u));
        prop_assert!((Vector3::new(a, b, c) - u).norm() < 1e-9);
        let by_u = numeric(u, |u| pose_of(u).to_vector());
        prop_assert!((rot_trans_rot_jacobian(rot1, trans) - by_u).abs().max() < 1e-6);
    }
}

#[test]
fn odometry_integrates_a_circle_and_grows_its_covariance() {
    for noise in [
        MotionNoise::Velocity {
            speed_sigma: 0.1,
            speed_sigma_relative: 0.01,
            yaw_rate_sigma: 0.02,
            turn_sigma: 0.05,
            sideslip_sigma: 0.01,
        },
        MotionNoise::RotTransRot {
            alpha: DEFAULT_ALPHA,
        },
    ] {
        let mut odometry = Odometry::new(MotionModel::Unicycle, noise);
        // A quarter circle of radius 10 m at 5 m/s.
        let omega = 0.5;
        let seconds = std::f64::consts::FRAC_PI_2 / omega;
        let steps = 1000;
        for k in 0..=steps {
            odometry.record(
                k as f64 * seconds / steps as f64,
                (5.0, None),
                omega,
                None,
                Correction::NONE,
            );
        }
        let (delta, cov) = odometry.take();
        assert!(
            (delta.t - nalgebra::Vector2::new(10.0, 10.0)).norm() < 1e-6,
            "{noise:?}: {delta:?}"
        );
        assert!((delta.theta - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        assert!((odometry.distance() - 5.0 * seconds).abs() < 1e-9);
        // Positive definite, and reset by take.
        assert!(cov.cholesky().is_some(), "{noise:?}: {cov}");
        assert_eq!(odometry.take().1, Matrix3::zeros());
    }
}

/// Heading variance after spinning on the spot by `turn` rad at 1 rad/s
/// in `steps` steps, then driving 2 m straight, with the turn noise
/// alone; and what `turn_variance` said before the take.
fn spin_then_drive(turn: f64, steps: usize) -> (f64, f64) {
    let noise = MotionNoise::Velocity {
        speed_sigma: 1e-9,
        speed_sigma_relative: 0.0,
        yaw_rate_sigma: 1e-9,
        turn_sigma: 0.1,
        sideslip_sigma: 0.0,
    };
    let mut odometry = Odometry::new(MotionModel::Unicycle, noise);
    let dt = turn / steps as f64;
    for k in 0..steps {
        odometry.record(k as f64 * dt, (0.0, None), 1.0, None, Correction::NONE);
    }
    odometry.record(turn, (2.0, None), 0.0, None, Correction::NONE);
    odometry.record(turn + 1.0, (2.0, None), 0.0, None, Correction::NONE);
    let said = odometry.turn_variance();
    let (_, cov) = odometry.take();
    assert_eq!(odometry.turn_variance(), 0.0, "reset by take");
    (cov[(2, 2)], said)
}

#[test]
fn a_turn_adds_heading_variance_in_proportion_to_the_angle_turned() {
    // σ² = 0.1² per rad turned, whatever the steps; driving straight
    // adds none.
    for (turn, steps) in [(1.0, 50), (1.0, 500), (3.0, 150)] {
        let (variance, said) = spin_then_drive(turn, steps);
        assert!(
            (variance - 0.01 * turn).abs() < 1e-9,
            "{turn} {steps}: {variance}"
        );
        assert!((said - variance).abs() < 1e-9);
    }
}

fn constant_turn(latency: f64) -> Odometry {
    let noise = MotionNoise::Velocity {
        speed_sigma: 0.1,
        speed_sigma_relative: 0.0,
        yaw_rate_sigma: 0.01,
        turn_sigma: 0.0,
        sideslip_sigma: 0.0,
    };
    Odometry::new(MotionModel::Unicycle, noise).with_scan_latency(latency)
}

#[test]
fn a_late_scan_gets_the_pose_it_was_measured_from() {
    // 2 m/s, turning 0.5 rad/s, records every 20 ms, a scan stamped at
    // 1 s that is 50 ms old; the speed doubles from the record at 0.98 s,
    // after the scan was measured.
    let mut late = constant_turn(0.05);
    for k in 0..=50 {
        let t = k as f64 * 0.02;
        let v = if t < 0.97 { 2.0 } else { 4.0 };
        late.record(t, (v, None), 0.5, None, Correction::NONE);
    }
    let measured = late.advance_to_scan(1.0, Correction::NONE);
    assert!((measured - 0.95).abs() < 1e-12);
    let (delta, _) = late.take();
    let expected = integrate(&SE2::identity(), 2.0, 0.5, 0.95);
    assert!(
        (delta.to_vector() - expected.to_vector()).norm() < 1e-12,
        "{delta:?}"
    );
    // The records after 0.95 s count toward the next scan, measured at
    // 1.05 s: 2 m/s until 0.98 s, then 4 m/s.
    late.advance_to_scan(1.1, Correction::NONE);
    let (next, _) = late.take();
    let from = integrate(&SE2::identity(), 2.0, 0.5, 0.03);
    let expected = from.compose(&integrate(&SE2::identity(), 4.0, 0.5, 0.07));
    assert!(
        (next.to_vector() - expected.to_vector()).norm() < 1e-12,
        "{next:?}"
    );
    // Without latency the same records reach the stamp.
    let mut prompt = constant_turn(0.0);
    for k in 0..=50 {
        prompt.record(k as f64 * 0.02, (2.0, None), 0.5, None, Correction::NONE);
    }
    assert_eq!(prompt.advance_to_scan(1.0, Correction::NONE), 1.0);
    let expected = integrate(&SE2::identity(), 2.0, 0.5, 1.0);
    assert!((prompt.take().0.to_vector() - expected.to_vector()).norm() < 1e-12);
}

#[test]
fn sideslip_turns_the_path_not_the_heading() {
    let slide = Correction {
        sideslip: 0.01,
        ..Correction::NONE
    };
    let (mut straight, mut sliding) = (constant_turn(0.0), constant_turn(0.0));
    for k in 0..=100 {
        let t = k as f64 * 0.01;
        straight.record(t, (5.0, None), 0.8, None, Correction::NONE);
        sliding.record(t, (5.0, None), 0.8, None, slide);
    }
    let (a, _) = straight.take();
    let (b, _) = sliding.take();
    assert!((a.theta - b.theta).abs() < 1e-12);
    // Each step moves 0.01 × 4 m/s² = 0.04 rad to the left of its arc.
    let turned = a.t.perp(&b.t).atan2(a.t.dot(&b.t));
    assert!((turned - 0.04).abs() < 1e-9, "{turned}");
    assert!((a.t.norm() - b.t.norm()).abs() < 1e-9);
    // A measured lateral speed of the same slide moves the car alike,
    // whatever sideslip the correction says.
    let mut measured = constant_turn(0.0);
    let vy = 5.0 * (0.04f64).sin();
    let speed = 5.0 * (0.04f64).cos();
    for k in 0..=100 {
        measured.record(k as f64 * 0.01, (speed, Some(vy)), 0.8, None, slide);
    }
    let (c, _) = measured.take();
    assert!(
        (c.to_vector() - b.to_vector()).norm() < 1e-9,
        "{c:?} vs {b:?}"
    );
    assert_eq!(measured.slip_jacobian(), Vector2::zeros());
}

#[test]
fn the_slip_jacobian_is_the_motions_derivative() {
    // Turning left, then right, at varying speed.
    let drive = |sideslip: f64| {
        let mut odometry = constant_turn(0.0);
        let correction = Correction {
            sideslip,
            ..Correction::NONE
        };
        for k in 0..=60 {
            let t = k as f64 * 0.02;
            let omega = if k < 30 { 0.9 } else { -0.6 };
            odometry.record(t, (4.0 + 0.05 * k as f64, None), omega, None, correction);
        }
        let jacobian = odometry.slip_jacobian();
        (odometry.take().0, jacobian)
    };
    let (at, jacobian) = drive(0.01);
    let h = 1e-6;
    let numeric = (drive(0.01 + h).0.t - drive(0.01 - h).0.t) / (2.0 * h);
    assert!(
        (jacobian - numeric).norm() < 1e-6,
        "{jacobian} vs {numeric}"
    );
    // Not a vanishing derivative.
    assert!(jacobian.norm() > 1.0, "{jacobian} at {at:?}");
}
