//! Lie-group axioms for SE(2) and SE(3), checked by one generic function, and
//! the g2o conventions of the vector forms.

use cairn_core::se2::normalize_angle;
use cairn_core::{SE2, SE3, Variable};
use nalgebra::{UnitQuaternion, Vector3, Vector6};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::f64::consts::PI;

trait Group: Copy {
    fn compose(&self, o: &Self) -> Self;
    fn inverse(&self) -> Self;
    fn between(&self, o: &Self) -> Self;
    fn identity() -> Self;
    fn distance(&self, o: &Self) -> f64;
}

impl Group for SE2 {
    fn compose(&self, o: &Self) -> Self {
        SE2::compose(self, o)
    }
    fn inverse(&self) -> Self {
        SE2::inverse(self)
    }
    fn between(&self, o: &Self) -> Self {
        SE2::between(self, o)
    }
    fn identity() -> Self {
        SE2::identity()
    }
    fn distance(&self, o: &Self) -> f64 {
        (self.t - o.t)
            .amax()
            .max(normalize_angle(self.theta - o.theta).abs())
    }
}

impl Group for SE3 {
    fn compose(&self, o: &Self) -> Self {
        SE3::compose(self, o)
    }
    fn inverse(&self) -> Self {
        SE3::inverse(self)
    }
    fn between(&self, o: &Self) -> Self {
        SE3::between(self, o)
    }
    fn identity() -> Self {
        SE3::identity()
    }
    fn distance(&self, o: &Self) -> f64 {
        (self.t - o.t).amax().max(self.q.angle_to(&o.q))
    }
}

fn check_axioms<G: Group>(a: G, b: G, c: G) {
    let tol = 1e-9;
    assert!(
        a.compose(&b)
            .compose(&c)
            .distance(&a.compose(&b.compose(&c)))
            < tol,
        "associativity"
    );
    assert!(
        a.compose(&G::identity()).distance(&a) < tol,
        "right identity"
    );
    assert!(
        G::identity().compose(&a).distance(&a) < tol,
        "left identity"
    );
    assert!(
        a.compose(&a.inverse()).distance(&G::identity()) < tol,
        "inverse"
    );
    assert!(a.inverse().inverse().distance(&a) < tol, "double inverse");
    assert!(
        a.between(&b).distance(&a.inverse().compose(&b)) < tol,
        "between"
    );
    assert!(
        a.compose(&b)
            .inverse()
            .distance(&b.inverse().compose(&a.inverse()))
            < tol,
        "inverse of product"
    );
}

fn se2(rng: &mut StdRng) -> SE2 {
    SE2::new(
        rng.random_range(-50.0..50.0),
        rng.random_range(-50.0..50.0),
        rng.random_range(-PI..PI),
    )
}

fn se3(rng: &mut StdRng) -> SE3 {
    let axis = Vector3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    let t = Vector3::new(
        rng.random_range(-50.0..50.0),
        rng.random_range(-50.0..50.0),
        rng.random_range(-50.0..50.0),
    );
    SE3::new(
        t,
        UnitQuaternion::from_scaled_axis(axis * rng.random_range(0.0..3.1)),
    )
}

#[test]
fn se2_axioms() {
    let mut rng = StdRng::seed_from_u64(11);
    for _ in 0..1000 {
        check_axioms(se2(&mut rng), se2(&mut rng), se2(&mut rng));
    }
}

#[test]
fn se3_axioms() {
    let mut rng = StdRng::seed_from_u64(12);
    for _ in 0..1000 {
        check_axioms(se3(&mut rng), se3(&mut rng), se3(&mut rng));
    }
}

#[test]
fn angles_wrap_to_minus_pi_exclusive_pi_inclusive() {
    assert_eq!(normalize_angle(PI), PI);
    assert!((normalize_angle(-PI) - PI).abs() < 1e-15);
    assert!((normalize_angle(3.0 * PI) - PI).abs() < 1e-12);
    assert!((normalize_angle(2.0 * PI + 0.5) - 0.5).abs() < 1e-12);
    assert!((normalize_angle(-2.0 * PI - 0.5) + 0.5).abs() < 1e-12);
    let mut rng = StdRng::seed_from_u64(13);
    for _ in 0..1000 {
        let a = rng.random_range(-100.0..100.0);
        let w = normalize_angle(a);
        assert!(w > -PI && w <= PI);
        assert!(((a - w) / (2.0 * PI) - ((a - w) / (2.0 * PI)).round()).abs() < 1e-9);
    }
}

#[test]
fn se2_oplus_is_additive_and_wraps() {
    let x = SE2::new(1.0, 2.0, 3.0).oplus(&Vector3::new(0.5, -0.5, 0.5));
    assert_eq!((x.t.x, x.t.y), (1.5, 1.5));
    assert!((x.theta - (3.5 - 2.0 * PI)).abs() < 1e-12);
}

#[test]
fn se3_mqt_round_trip_and_canonical_sign() {
    let mut rng = StdRng::seed_from_u64(14);
    for _ in 0..1000 {
        let x = se3(&mut rng);
        let back = SE3::from_mqt(&x.to_mqt());
        assert!(back.distance(&x) < 1e-9);
    }
    // q and −q are the same rotation; the vector form picks w ≥ 0.
    let q = UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, 2.5));
    let minus = UnitQuaternion::new_unchecked(-*q.quaternion());
    let v = SE3::new(Vector3::zeros(), minus).to_mqt();
    assert!(v[5] > 0.0 && (v[5] - (1.25f64).sin()).abs() < 1e-12);
}

#[test]
fn se3_oplus_right_multiplies_and_differs_from_g2o_only_at_second_order() {
    let mut rng = StdRng::seed_from_u64(15);
    for _ in 0..200 {
        let x = se3(&mut rng);
        let d = Vector6::from_fn(|_, _| rng.random_range(-1.0..1.0));
        for s in [1e-2, 1e-3, 1e-4] {
            let ds = d * s;
            // The increment acts on the right: x ⊕ d = x · (ε ⊕ d).
            let inc = SE3::identity().oplus(&ds);
            assert!(x.oplus(&ds).distance(&x.compose(&inc)) < 1e-9);
            // g2o's increment (t, (√(1−|q|²), q)) differs by at most
            // |q|·|t| ≤ |d|²/2 in translation and O(|q|³) in rotation.
            let g2o = x.compose(&SE3::from_mqt(&ds));
            assert!(x.oplus(&ds).distance(&g2o) <= 0.5 * ds.norm_squared() + 1e-12);
        }
    }
}

#[test]
fn se3_oplus_turns_a_compact_quaternion_above_unit_norm_into_a_rotation() {
    // g2o's form names no rotation here and drops it; the exponential turns
    // by twice the vector's norm about its axis.
    let v = Vector3::new(0.9, 0.9, 0.0);
    let x = SE3::identity().oplus(&Vector6::new(1.0, 0.0, 0.0, v.x, v.y, v.z));
    assert!((x.q.angle() - 2.0 * v.norm()).abs() < 1e-12);
    let axis = x.q.axis().map(|a| a.into_inner()).unwrap_or_default();
    assert!((axis - v.normalize()).norm() < 1e-12);
}

#[test]
fn se3_exp_is_a_one_parameter_subgroup() {
    let mut rng = StdRng::seed_from_u64(17);
    let mut xi = || Vector6::from_fn(|_, _| rng.random_range(-1.0..1.0));
    // Random screws, and tiny ones whose doubled angle crosses the Taylor
    // series' threshold (θ = 1e-4), so the two branches must agree.
    let screws: Vec<Vector6<f64>> = (0..200)
        .map(|i| {
            let v = xi();
            if i % 2 == 0 {
                v
            } else {
                v.normalize() * 0.7e-4
            }
        })
        .collect();
    let exp =
        |v: &Vector6<f64>| SE3::exp(&v.fixed_rows::<3>(0).into(), &v.fixed_rows::<3>(3).into());
    for v in &screws {
        for (s, t) in [(1.0, 1.0), (0.3, -1.2), (2.0, 0.5)] {
            let product = exp(&(v * s)).compose(&exp(&(v * t)));
            assert!(product.distance(&exp(&(v * (s + t)))) < 1e-12);
        }
        // Pure translations and pure rotations.
        let (rho, omega) = (
            v.fixed_rows::<3>(0).into_owned(),
            v.fixed_rows::<3>(3).into_owned(),
        );
        let shift = SE3::exp(&rho, &Vector3::zeros());
        assert!(shift.distance(&SE3::new(rho, UnitQuaternion::identity())) < 1e-15);
        let turn = SE3::exp(&Vector3::zeros(), &omega);
        assert!(
            turn.distance(&SE3::new(
                Vector3::zeros(),
                UnitQuaternion::from_scaled_axis(omega)
            )) < 1e-15
        );
        // A screw moves along its own axis: the rotation axis is fixed by it.
        let along = SE3::exp(&omega, &omega);
        assert!((along.t - omega).norm() < 1e-12);
    }
}

#[test]
fn se3_params_round_trip_is_exact() {
    let mut rng = StdRng::seed_from_u64(16);
    for _ in 0..1000 {
        let x = se3(&mut rng);
        let mut p = [0.0; 7];
        x.write_params(&mut p);
        let y = SE3::from_params(&p);
        let mut q = [0.0; 7];
        y.write_params(&mut q);
        assert_eq!(p, q);
    }
}
