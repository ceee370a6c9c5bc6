//! The pending downdates against the textbook EKF update.

use super::{EkfSlam, ROBOT};
use crate::filter::{innovation, predict};
use crate::frontend::FrontEndConfig;
use cairn_core::SE2;
use cairn_core::se2::normalize_angle;
use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use rand::{Rng, SeedableRng, rngs::StdRng};

/// A filter holding `landmarks` landmarks around the pose, with a random
/// correlated covariance.
fn filter(landmarks: usize, rng: &mut StdRng) -> EkfSlam {
    let mut ekf = EkfSlam::new(FrontEndConfig::default());
    for l in 0..landmarks {
        let slot = ekf.push_slot(l);
        let angle = l as f64;
        ekf.x[slot] = 6.0 * angle.cos();
        ekf.x[slot + 1] = 6.0 * angle.sin();
    }
    let n = ekf.dim;
    let a = DMatrix::from_fn(n, n, |_, _| rng.random_range(-0.1..0.1));
    let p = &a * a.transpose() + DMatrix::identity(n, n) * 0.01;
    ekf.p.view_mut((0, 0), (n, n)).copy_from(&p);
    ekf
}

/// The EKF update with H over the whole state: K = P Hᵀ (H P Hᵀ + R)⁻¹,
/// x ← x + K ν, P ← (I − K H) P.
fn textbook(x: &mut DVector<f64>, p: &mut DMatrix<f64>, slot: usize, z: &Vector2<f64>) {
    let n = x.len();
    let pose = SE2::new(x[0], x[1], x[2]);
    let pred = predict(&pose, &Vector2::new(x[slot], x[slot + 1])).unwrap();
    let mut h = DMatrix::zeros(2, n);
    h.view_mut((0, 0), (2, 3)).copy_from(&pred.h_pose);
    h.view_mut((0, slot), (2, 2)).copy_from(&pred.h_landmark);
    let s = &h * &*p * h.transpose() + DMatrix::identity(2, 2) * 0.01;
    let k = &*p * h.transpose() * s.try_inverse().unwrap();
    let nu = innovation(z, &pred.z);
    *x += &k * DVector::from_column_slice(nu.as_slice());
    x[2] = normalize_angle(x[2]);
    *p = (DMatrix::identity(n, n) - &k * &h) * &*p;
}

#[test]
fn pending_downdates_give_the_sequential_updates() {
    let mut rng = StdRng::seed_from_u64(7);
    let mut ekf = filter(12, &mut rng);
    let n = ekf.dim;
    let mut x = ekf.x.rows(0, n).into_owned();
    let mut p = ekf.p.view((0, 0), (n, n)).into_owned();
    // More updates than PENDING holds, so some are applied on the way.
    for k in 0..40 {
        let slot = ROBOT + 2 * (k * 5 % 12);
        let z = Vector2::new(rng.random_range(5.0..7.0), rng.random_range(-3.0..3.0));
        assert!(ekf.update_joint(slot, &z, &Matrix2::identity().scale(0.01)));
        textbook(&mut x, &mut p, slot, &z);
    }
    assert!(ekf.rank > 0, "the last updates are still pending");
    ekf.flush();
    let got = ekf.p.view((0, 0), (n, n));
    let off = (got - &p).abs().max();
    assert!(off < 1e-9, "P is {off} off");
    assert!((ekf.x.rows(0, n) - &x).abs().max() < 1e-9);
    assert_eq!(got, got.transpose(), "P stays exactly symmetric");
}
