//! The planar rigid-body group SE(2), stored as (x, y, θ) like g2o's `SE2`.

use nalgebra::{Matrix2, Vector2, Vector3};
use std::f64::consts::PI;

/// Wraps an angle to (−π, π], g2o's `normalize_theta` convention.
pub fn normalize_angle(theta: f64) -> f64 {
    if theta > -PI && theta <= PI {
        return theta;
    }
    let wrapped = (theta + PI).rem_euclid(2.0 * PI) - PI;
    // rem_euclid maps onto [−π, π); move the lower end to the upper one.
    if wrapped <= -PI {
        wrapped + 2.0 * PI
    } else {
        wrapped
    }
}

/// Rotation matrix of angle `theta`.
pub fn rotation2(theta: f64) -> Matrix2<f64> {
    let (s, c) = theta.sin_cos();
    Matrix2::new(c, -s, s, c)
}

/// A planar pose: translation (x, y) and heading θ in (−π, π].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SE2 {
    /// Translation.
    pub t: Vector2<f64>,
    /// Heading in radians.
    pub theta: f64,
}

impl SE2 {
    /// A pose from its coordinates; the angle is wrapped to (−π, π].
    pub fn new(x: f64, y: f64, theta: f64) -> Self {
        Self {
            t: Vector2::new(x, y),
            theta: normalize_angle(theta),
        }
    }

    /// The identity pose.
    pub fn identity() -> Self {
        Self::default()
    }

    /// From the vector (x, y, θ) (g2o `v2t`).
    pub fn from_vector(v: &Vector3<f64>) -> Self {
        Self::new(v.x, v.y, v.z)
    }

    /// To the vector (x, y, θ) (g2o `t2v`).
    pub fn to_vector(&self) -> Vector3<f64> {
        Vector3::new(self.t.x, self.t.y, self.theta)
    }

    /// The rotation matrix of the heading.
    pub fn rotation(&self) -> Matrix2<f64> {
        rotation2(self.theta)
    }

    /// Group composition `self · other`.
    pub fn compose(&self, other: &SE2) -> SE2 {
        SE2 {
            t: self.t + self.rotation() * other.t,
            theta: normalize_angle(self.theta + other.theta),
        }
    }

    /// Group inverse.
    pub fn inverse(&self) -> SE2 {
        SE2 {
            t: -(self.rotation().transpose() * self.t),
            theta: normalize_angle(-self.theta),
        }
    }

    /// `self⁻¹ · other`, computed without forming the inverse.
    pub fn between(&self, other: &SE2) -> SE2 {
        let rt = self.rotation().transpose();
        SE2 {
            t: rt * (other.t - self.t),
            theta: normalize_angle(other.theta - self.theta),
        }
    }

    /// Applies the pose to a point.
    pub fn transform_point(&self, p: &Vector2<f64>) -> Vector2<f64> {
        self.t + self.rotation() * p
    }
}

impl std::ops::Mul for SE2 {
    type Output = SE2;
    fn mul(self, rhs: SE2) -> SE2 {
        self.compose(&rhs)
    }
}
