//! Variables (g2o "vertices"): values on a manifold with a D-dimensional update.

use crate::se2::SE2;
use crate::se3::SE3;
use nalgebra::{Quaternion, SVector, UnitQuaternion, Vector3};

/// A variable whose tangent space has `D` dimensions.
///
/// The value is stored in the graph as `PARAMS` plain numbers (g2o's "estimate
/// data"), which keeps all variables in one flat buffer and lets the g2o reader
/// and writer handle any variable type by its parameters.
///
/// ```
/// use cairn_core::{SE2, Variable};
/// use nalgebra::Vector3;
/// let x = SE2::new(1.0, 2.0, 0.5).oplus(&Vector3::new(0.1, 0.0, 0.0));
/// assert_eq!(x.t.x, 1.1); // SE2 updates are additive, as in g2o
/// ```
pub trait Variable<const D: usize>:
    Clone + Default + std::fmt::Debug + Send + Sync + 'static
{
    /// Number of stored parameters.
    const PARAMS: usize;
    /// Name for messages (g2o tag style, e.g. `"SE2"`).
    const NAME: &'static str;
    /// Whether this is a pose; the automatic gauge fixes the lowest-id pose of
    /// each connected component.
    const IS_POSE: bool = false;

    /// Builds the value from `PARAMS` parameters. It may normalise them (unit
    /// quaternions, wrapped angles).
    fn from_params(p: &[f64]) -> Self;
    /// Writes the `PARAMS` parameters into `out`.
    fn write_params(&self, out: &mut [f64]);
    /// The update `x ⊞ δ` (g2o `oplusImpl`).
    fn oplus(&self, delta: &SVector<f64, D>) -> Self;
}

impl Variable<3> for SE2 {
    const PARAMS: usize = 3;
    const NAME: &'static str = "SE2";
    const IS_POSE: bool = true;

    fn from_params(p: &[f64]) -> Self {
        SE2::new(p[0], p[1], p[2])
    }
    fn write_params(&self, out: &mut [f64]) {
        out[..3].copy_from_slice(&[self.t.x, self.t.y, self.theta]);
    }
    /// Additive on (x, y, θ) with the angle wrapped, like g2o's `VertexSE2`.
    fn oplus(&self, d: &Vector3<f64>) -> Self {
        SE2::new(self.t.x + d.x, self.t.y + d.y, self.theta + d.z)
    }
}

macro_rules! vector_variable {
    ($($n:literal => $name:literal),*) => {$(
        /// A plain vector with additive updates.
        impl Variable<$n> for SVector<f64, $n> {
            const PARAMS: usize = $n;
            const NAME: &'static str = $name;

            fn from_params(p: &[f64]) -> Self {
                SVector::from_column_slice(&p[..$n])
            }
            fn write_params(&self, out: &mut [f64]) {
                out[..$n].copy_from_slice(self.as_slice());
            }
            fn oplus(&self, d: &SVector<f64, $n>) -> Self {
                self + d
            }
        }
    )*};
}

// 2D points (g2o `VERTEX_XY`), 3D points, and the vectors of chordal
// initialisation (a 3×3 rotation relaxed to 9 numbers).
vector_variable!(1 => "VECTOR1", 2 => "XY", 3 => "XYZ", 4 => "VECTOR4", 6 => "VECTOR6", 9 => "VECTOR9");

/// `q` normalised, robust to components that would overflow or underflow when
/// squared. Already-unit quaternions are kept bit for bit, so that reading what
/// was written is exact. A zero or non-finite quaternion gives the identity.
fn unit_quaternion(q: Quaternion<f64>) -> UnitQuaternion<f64> {
    if (q.norm_squared() - 1.0).abs() <= 4.0 * f64::EPSILON {
        return UnitQuaternion::new_unchecked(q);
    }
    let scale = q.coords.amax();
    if scale > 0.0 && scale.is_finite() {
        UnitQuaternion::new_normalize(q / scale)
    } else {
        UnitQuaternion::identity()
    }
}

impl Variable<6> for SE3 {
    /// x y z qx qy qz qw, the order of g2o's `VERTEX_SE3:QUAT` lines.
    const PARAMS: usize = 7;
    const NAME: &'static str = "SE3";
    const IS_POSE: bool = true;

    fn from_params(p: &[f64]) -> Self {
        SE3::new(
            Vector3::new(p[0], p[1], p[2]),
            unit_quaternion(Quaternion::new(p[6], p[3], p[4], p[5])),
        )
    }
    fn write_params(&self, out: &mut [f64]) {
        let q = self.q.quaternion();
        out[..7].copy_from_slice(&[self.t.x, self.t.y, self.t.z, q.i, q.j, q.k, q.w]);
    }
    /// Right-multiplies by the increment (t, qx, qy, qz), as g2o's
    /// `VertexSE3::oplusImpl` does, but takes the increment as the screw
    /// exp(t, 2·(qx, qy, qz)) ([`SE3::exp`]) where g2o takes translation t and
    /// rotation (√(1−|q|²), q). The two differ only in second-order terms,
    /// so the Jacobians and covariances are g2o's, and near a minimum the steps.
    /// Far from one they are not: g2o's rotation is undefined for |q| > 1 and
    /// g2o drops it. From a poor start Gauss-Newton proposes thousands of such
    /// steps (torus3D: 10950 in a run); with them dropped it stalls at χ² 45561
    /// and with the exponential it reaches 19974 (BENCHMARKS.md).
    fn oplus(&self, d: &SVector<f64, 6>) -> Self {
        let inc = SE3::exp(
            &Vector3::new(d[0], d[1], d[2]),
            &(Vector3::new(d[3], d[4], d[5]) * 2.0),
        );
        let mut x = self.compose(&inc);
        x.q.renormalize_fast();
        x
    }
}
