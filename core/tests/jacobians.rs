//! Analytic Jacobians of every built-in edge against central differences at
//! 1,000 random states each, and each edge's share of the normal equations
//! against JᵀWJ and JᵀWe.

use cairn_core::edge::{numeric_binary, numeric_unary};
use cairn_core::se3::quaternion_from_vector;
use cairn_core::{
    BinaryEdge, EdgePriorSE2, EdgeSE2, EdgeSE2XY, EdgeSE3, SE2, SE3, Se3Error, UnaryEdge,
};
use nalgebra::{DMatrix, SMatrix, UnitQuaternion, Vector2, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::f64::consts::PI;

const STATES: usize = 1000;

fn se2(rng: &mut StdRng) -> SE2 {
    SE2::new(
        rng.random_range(-20.0..20.0),
        rng.random_range(-20.0..20.0),
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
        rng.random_range(-10.0..10.0),
        rng.random_range(-10.0..10.0),
        rng.random_range(-10.0..10.0),
    );
    SE3::new(
        t,
        UnitQuaternion::from_scaled_axis(axis * rng.random_range(0.0..3.0)),
    )
}

fn assert_close<const R: usize, const C: usize>(
    analytic: &SMatrix<f64, R, C>,
    numeric: &SMatrix<f64, R, C>,
    what: &str,
) {
    let scale = 1.0f64.max(numeric.amax());
    let diff = (analytic - numeric).amax();
    assert!(
        diff <= 1e-6 * scale,
        "{what}: analytic and numeric Jacobians differ by {diff:e}\nanalytic {}\nnumeric {}",
        DMatrix::from_column_slice(R, C, analytic.as_slice()),
        DMatrix::from_column_slice(R, C, numeric.as_slice())
    );
}

/// A random symmetric positive-definite E × E information matrix with
/// entries of either sign off the diagonal.
fn information<const E: usize>(rng: &mut StdRng) -> SMatrix<f64, E, E> {
    let m = SMatrix::<f64, E, E>::from_fn(|_, _| rng.random_range(-2.0..2.0));
    m.transpose() * m + SMatrix::identity() * 0.1
}

fn check_binary<T, const E: usize, const D1: usize, const D2: usize>(
    edge: &T,
    x1: &T::V1,
    x2: &T::V2,
    rng: &mut StdRng,
) where
    T: BinaryEdge<E, D1, D2>,
{
    let (a1, a2) = edge.jacobians(x1, x2);
    let (n1, n2) = numeric_binary(edge, x1, x2);
    assert_close(&a1, &n1, T::NAME);
    assert_close(&a2, &n2, T::NAME);
    // The solver's combined call gives exactly the same numbers.
    let (e, l1, l2) = edge.linearize(x1, x2);
    assert_eq!(e, edge.error(x1, x2), "{}: linearize's error", T::NAME);
    assert_eq!((l1, l2), (a1, a2), "{}: linearize's Jacobians", T::NAME);
    // Its share of the normal equations is JᵀWJ and JᵀWe, however formed.
    let w = information::<E>(rng);
    let b = edge.normal_blocks(&(e, l1, l2), &w);
    let what = format!("{}: normal blocks", T::NAME);
    let close = |ours: &[f64], plain: &[f64]| {
        let scale = plain.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        let diff = ours
            .iter()
            .zip(plain)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(diff <= 1e-12 * scale, "{what}: {diff:e} off");
    };
    close(b.h11.as_slice(), (l1.transpose() * w * l1).as_slice());
    close(b.h12.as_slice(), (l1.transpose() * w * l2).as_slice());
    close(b.h22.as_slice(), (l2.transpose() * w * l2).as_slice());
    close(b.g1.as_slice(), (l1.transpose() * w * e).as_slice());
    close(b.g2.as_slice(), (l2.transpose() * w * e).as_slice());
}

#[test]
fn edge_se2_jacobians() {
    let mut rng = StdRng::seed_from_u64(1);
    for _ in 0..STATES {
        let (edge, xi, xj) = (EdgeSE2::new(se2(&mut rng)), se2(&mut rng), se2(&mut rng));
        check_binary(&edge, &xi, &xj, &mut rng);
        // g2o's definition: t2v(Z⁻¹ · (Xᵢ⁻¹ · Xⱼ)).
        let d = edge.measurement().inverse().compose(&xi.between(&xj));
        let e = edge.error(&xi, &xj);
        assert!(
            (e - Vector3::new(d.t.x, d.t.y, d.theta)).amax() < 1e-12,
            "{e} vs {d:?}"
        );
    }
}

#[test]
fn edge_se2_xy_jacobians() {
    let mut rng = StdRng::seed_from_u64(2);
    for _ in 0..STATES {
        let z = Vector2::new(rng.random_range(-10.0..10.0), rng.random_range(-10.0..10.0));
        let l = Vector2::new(rng.random_range(-30.0..30.0), rng.random_range(-30.0..30.0));
        let x = se2(&mut rng);
        check_binary(&EdgeSE2XY::new(z), &x, &l, &mut rng);
    }
}

#[test]
fn edge_prior_se2_jacobian() {
    let mut rng = StdRng::seed_from_u64(3);
    for _ in 0..STATES {
        let edge = EdgePriorSE2::new(se2(&mut rng));
        let x = se2(&mut rng);
        assert_close(
            &edge.jacobian(&x),
            &numeric_unary(&edge, &x),
            "EDGE_PRIOR_SE2",
        );
    }
}

#[test]
fn edge_se3_jacobians() {
    for kind in Se3Error::ALL {
        let mut rng = StdRng::seed_from_u64(4);
        let mut checked = 0;
        while checked < STATES {
            let z = se3(&mut rng);
            let (edge, xi, xj) = (EdgeSE3::with_error(z, kind), se3(&mut rng), se3(&mut rng));
            // Both errors are discontinuous where q_E's real part changes
            // sign (a rotation of π).
            let e = edge.measurement().inverse().compose(&xi.between(&xj));
            if e.q.quaternion().w.abs() < 1e-3 {
                continue;
            }
            check_binary(&edge, &xi, &xj, &mut rng);
            checked += 1;
        }
    }
}

/// The Logmap error's rotation part is the rotation vector of R_E, and its
/// translation part g2o's.
#[test]
fn the_logmap_error_is_the_rotation_vector() {
    let mut rng = StdRng::seed_from_u64(6);
    for _ in 0..STATES {
        let (z, xi, xj) = (se3(&mut rng), se3(&mut rng), se3(&mut rng));
        let e = z.inverse().compose(&xi.between(&xj));
        let g2o = EdgeSE3::new(z).error(&xi, &xj);
        let log = EdgeSE3::with_error(z, Se3Error::Logmap).error(&xi, &xj);
        let rotation = e.q.scaled_axis();
        let angle = rotation.norm();
        if angle > PI - 1e-6 {
            continue;
        }
        assert!((log.fixed_rows::<3>(3) - rotation).amax() < 1e-9 * angle.max(1.0));
        assert_eq!(log.fixed_rows::<3>(0), g2o.fixed_rows::<3>(0));
        // |q.xyz| = sin(θ/2): g2o's rotation part is the same axis, shorter.
        let half = (angle / 2.0).sin();
        assert!((g2o.fixed_rows::<3>(3).norm() - half).abs() < 1e-9);
    }
}

#[test]
fn edge_se3_jacobians_near_the_optimum() {
    // Small errors are where solvers spend their time.
    let mut rng = StdRng::seed_from_u64(5);
    for _ in 0..STATES {
        let xi = se3(&mut rng);
        let z = se3(&mut rng);
        let noise = SE3::new(
            Vector3::new(1e-3, -2e-3, 5e-4) * rng.random_range(-1.0..1.0),
            quaternion_from_vector(
                &(Vector3::new(1e-3, 2e-3, -1e-3) * rng.random_range(-1.0..1.0)),
            ),
        );
        let xj = xi.compose(&z).compose(&noise);
        for kind in Se3Error::ALL {
            check_binary(&EdgeSE3::with_error(z, kind), &xi, &xj, &mut rng);
        }
    }
}
