//! The rigid-body group SE(3) as translation plus unit quaternion, with g2o's
//! "MQT" minimal vector (t, qx, qy, qz with qw ≥ 0).

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3, Vector6};

/// A 3D pose: rotation `q` then translation `t` (x ↦ q·x + t).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SE3 {
    /// Translation.
    pub t: Vector3<f64>,
    /// Rotation.
    pub q: UnitQuaternion<f64>,
}

impl Default for SE3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl SE3 {
    /// A pose from a translation and a rotation.
    pub fn new(t: Vector3<f64>, q: UnitQuaternion<f64>) -> Self {
        Self { t, q }
    }

    /// The identity pose.
    pub fn identity() -> Self {
        Self {
            t: Vector3::zeros(),
            q: UnitQuaternion::identity(),
        }
    }

    /// Group composition `self · other`.
    pub fn compose(&self, other: &SE3) -> SE3 {
        SE3 {
            t: self.t + self.q * other.t,
            q: self.q * other.q,
        }
    }

    /// Group inverse.
    pub fn inverse(&self) -> SE3 {
        let qi = self.q.inverse();
        SE3 {
            t: -(qi * self.t),
            q: qi,
        }
    }

    /// `self⁻¹ · other`.
    pub fn between(&self, other: &SE3) -> SE3 {
        let qi = self.q.inverse();
        SE3 {
            t: qi * (other.t - self.t),
            q: qi * other.q,
        }
    }

    /// Rotation matrix.
    pub fn rotation(&self) -> Matrix3<f64> {
        self.q.to_rotation_matrix().into_inner()
    }

    /// Applies the pose to a point.
    pub fn transform_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.t + self.q * p
    }

    /// The exponential map of the Lie algebra se(3): the pose reached by moving
    /// along the screw (ρ, ω) for unit time, with ω a rotation vector. The
    /// rotation is exp(ω) and the translation V(ω)·ρ, where
    /// V = I + (1 − cos θ)/θ²·\[ω\]× + (θ − sin θ)/θ³·\[ω\]×², θ = |ω|.
    pub fn exp(rho: &Vector3<f64>, omega: &Vector3<f64>) -> SE3 {
        let theta2 = omega.norm_squared();
        // Taylor series below θ = 1e-4, where the closed forms lose digits.
        let (a, b) = if theta2 < 1e-8 {
            (0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0)
        } else {
            let theta = theta2.sqrt();
            (
                (1.0 - theta.cos()) / theta2,
                (theta - theta.sin()) / (theta2 * theta),
            )
        };
        let w = skew(omega);
        let v = Matrix3::identity() + w * a + w * w * b;
        SE3 {
            t: v * rho,
            q: UnitQuaternion::from_scaled_axis(*omega),
        }
    }

    /// g2o's `toVectorMQT`: (t, qx, qy, qz) with the quaternion's sign chosen so
    /// that qw ≥ 0. The rotation part is ≈ θ/2 · axis, not the log map.
    pub fn to_mqt(&self) -> Vector6<f64> {
        let q = canonical(&self.q);
        Vector6::new(self.t.x, self.t.y, self.t.z, q.i, q.j, q.k)
    }

    /// g2o's `fromVectorMQT`: the inverse of [`SE3::to_mqt`] (see
    /// [`quaternion_from_vector`] for vector parts of norm above one).
    pub fn from_mqt(v: &Vector6<f64>) -> SE3 {
        SE3 {
            t: Vector3::new(v[0], v[1], v[2]),
            q: quaternion_from_vector(&Vector3::new(v[3], v[4], v[5])),
        }
    }
}

/// The quaternion's coefficients with the sign chosen so that w ≥ 0.
pub fn canonical(q: &UnitQuaternion<f64>) -> Quaternion<f64> {
    let q = *q.quaternion();
    if q.w < 0.0 { -q } else { q }
}

/// The unit quaternion (√(1−|v|²), v). A vector of norm above one names no
/// rotation; like g2o's `fromCompactQuaternion` it then gives the identity.
pub fn quaternion_from_vector(v: &Vector3<f64>) -> UnitQuaternion<f64> {
    let w2 = 1.0 - v.norm_squared();
    if w2 < 0.0 {
        UnitQuaternion::identity()
    } else {
        UnitQuaternion::new_unchecked(Quaternion::new(w2.sqrt(), v.x, v.y, v.z))
    }
}

/// The rotation vector (axis times angle in (−π, π]) of a unit quaternion
/// with w ≥ 0: SO(3)'s log map.
pub fn rotation_log(q: &Quaternion<f64>) -> Vector3<f64> {
    let v = Vector3::new(q.i, q.j, q.k);
    let n = v.norm();
    // θ/n = 2·atan2(n, w)/n, by its series where n is tiny.
    let scale = if n < 1e-8 {
        2.0 / q.w
    } else {
        2.0 * n.atan2(q.w) / n
    };
    v * scale
}

/// The inverse of SO(3)'s right Jacobian at the rotation vector `phi`:
/// Log(Exp(φ)·Exp(δ)) ≈ φ + J_r⁻¹(φ)·δ for a small δ.
pub fn right_jacobian_inverse(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = phi.norm_squared();
    // (1/θ² − (1 + cos θ)/(2θ·sin θ)), by its series below θ = 1e-3.
    let c = if theta2 < 1e-6 {
        1.0 / 12.0 + theta2 / 720.0
    } else {
        let theta = theta2.sqrt();
        1.0 / theta2 - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    let w = skew(phi);
    Matrix3::identity() + w * 0.5 + w * w * c
}

/// The skew-symmetric matrix with `skew(a) · b = a × b`.
pub fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

impl std::ops::Mul for SE3 {
    type Output = SE3;
    fn mul(self, rhs: SE3) -> SE3 {
        self.compose(&rhs)
    }
}
