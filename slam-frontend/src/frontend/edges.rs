//! The front end's measurements as graph edges: the odometry between
//! keyframes, and the information matrices of covariances.

use crate::motion::compose_with_cov;
use cairn_core::SE2;
use nalgebra::{Matrix3, SMatrix, Vector2};

/// The odometry between consecutive keyframes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OdometryEdge {
    /// Motion integrated from the odometry, with the calibration of the time.
    pub(crate) delta: SE2,
    /// Its information, bias included (for the smoother).
    pub(crate) information: Matrix3<f64>,
    /// Time between the keyframes (s).
    pub(crate) dt: f64,
    /// The yaw-rate bias the integration took out (rad/s).
    pub(crate) yaw_rate_bias: f64,
    /// ∂ of the motion's translation with respect to the sideslip (m per
    /// rad per m/s²), and the part of it the sideslip assumed in the
    /// integration made (that ∂ times it, summed over chained edges).
    pub(crate) slip_jacobian: Vector2<f64>,
    pub(crate) slip_made: Vector2<f64>,
    /// Variance of the integrated heading from the yaw rate's white noise
    /// alone (rad²).
    pub(crate) heading_variance: f64,
}

impl OdometryEdge {
    /// The odometry across consecutive edges, as one edge. The bias taken
    /// out is their time-weighted mean, so the turn corrected for a bias
    /// b is the same, Σ (Δθᵢ + (usedᵢ − b)·dtᵢ).
    pub(crate) fn chain(edges: &[OdometryEdge]) -> OdometryEdge {
        if let [edge] = edges {
            return *edge;
        }
        let (mut delta, mut cov) = (SE2::identity(), Matrix3::zeros());
        let (mut dt, mut bias_time, mut heading_variance) = (0.0, 0.0, 0.0);
        let (mut slip_jacobian, mut slip_made) = (Vector2::zeros(), Vector2::zeros());
        for e in edges {
            slip_jacobian += delta.rotation() * e.slip_jacobian;
            slip_made += delta.rotation() * e.slip_made;
            let e_cov = e.information.try_inverse().unwrap_or_else(Matrix3::zeros);
            (delta, cov) = compose_with_cov(&delta, &cov, &e.delta, &e_cov);
            dt += e.dt;
            bias_time += e.yaw_rate_bias * e.dt;
            heading_variance += e.heading_variance;
        }
        OdometryEdge {
            delta,
            information: nearest_information(&cov),
            dt,
            yaw_rate_bias: if dt > 0.0 {
                bias_time / dt
            } else {
                edges.first().map_or(0.0, |e| e.yaw_rate_bias)
            },
            heading_variance,
            slip_jacobian,
            slip_made,
        }
    }

    /// The motion as if integrated with `sideslip` (first order in the
    /// change of sideslip).
    pub(crate) fn with_sideslip(&self, sideslip: f64) -> SE2 {
        let t = self.delta.t + self.slip_jacobian * sideslip - self.slip_made;
        SE2::new(t.x, t.y, self.delta.theta)
    }
}

/// Least position σ of an odometry edge (m). The integrated covariance
/// has next to no lateral term (the model cannot slide sideways), and
/// edges that claim the lateral motion to a few µm bend the path in the
/// smoother; 1 mm keeps them honest. (Floors growing with the distance
/// driven, 0.5–2 cm per metre, measured worse: the lateral constraint is
/// what carries the heading from scan to scan.)
const ODOMETRY_FLOOR: f64 = 1e-3;

/// Information of an odometry edge: the integrated covariance with [`ODOMETRY_FLOOR`].
pub(crate) fn odometry_information(cov: &Matrix3<f64>) -> Matrix3<f64> {
    let floor = ODOMETRY_FLOOR * ODOMETRY_FLOOR;
    nearest_information(&(cov + Matrix3::from_diagonal(&nalgebra::Vector3::new(floor, floor, 0.0))))
}

/// The information of a covariance: its inverse after a 1e-9 ridge (a
/// singular covariance gets 1e9), symmetrised.
pub fn nearest_information<const N: usize>(cov: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    let reg = cov + SMatrix::<f64, N, N>::identity() * 1e-9;
    let inv = reg
        .try_inverse()
        .unwrap_or_else(|| SMatrix::<f64, N, N>::identity() * 1e9);
    0.5 * (inv + inv.transpose())
}
