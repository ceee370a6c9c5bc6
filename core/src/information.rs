//! Checks and repairs of information matrices.

use nalgebra::{DMatrix, SMatrix};

/// Why an information matrix cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum InformationIssue {
    /// A NaN or infinite entry.
    #[error("has a non-finite entry")]
    NonFinite,
    /// Ω ≠ Ωᵀ beyond rounding.
    #[error("is not symmetric")]
    Asymmetric,
    /// Not positive definite: χ² = eᵀΩe would not be bounded below or would
    /// ignore a direction.
    #[error(
        "is not positive definite (smallest eigenvalue {min_eigenvalue:e}, largest {max_eigenvalue:e})"
    )]
    NotPositiveDefinite {
        /// Smallest eigenvalue.
        min_eigenvalue: f64,
        /// Largest eigenvalue.
        max_eigenvalue: f64,
    },
}

/// Checks that `m` is finite, symmetric and positive definite.
pub fn check_information<const E: usize>(m: &SMatrix<f64, E, E>) -> Result<(), InformationIssue> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(InformationIssue::NonFinite);
    }
    let scale = m.amax();
    if (m - m.transpose()).amax() > 1e-9 * scale {
        return Err(InformationIssue::Asymmetric);
    }
    if clearly_positive_definite(m) {
        return Ok(());
    }
    let eig = DMatrix::from_column_slice(E, E, m.as_slice()).symmetric_eigenvalues();
    let (min, max) = (eig.min(), eig.max());
    if min > 0.0 {
        Ok(())
    } else {
        Err(InformationIssue::NotPositiveDefinite {
            min_eigenvalue: min,
            max_eigenvalue: max,
        })
    }
}

/// An information matrix that [`check_information`] accepted: finite,
/// symmetric and positive definite. Lets a caller that checks matrices
/// itself (the g2o reader, to repair or refuse them by line) hand them to
/// [`Graph::add_checked_edge`](crate::Graph::add_checked_edge) without a
/// second check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositiveDefinite<const E: usize>(SMatrix<f64, E, E>);

impl<const E: usize> PositiveDefinite<E> {
    /// `m`, if [`check_information`] accepts it.
    pub fn new(m: SMatrix<f64, E, E>) -> Result<Self, InformationIssue> {
        check_information(&m).map(|()| Self(m))
    }

    /// The matrix.
    pub fn matrix(&self) -> &SMatrix<f64, E, E> {
        &self.0
    }
}

/// Whether a Cholesky factorisation proves the symmetric `m` positive
/// definite with room to spare: its smallest eigenvalue is at least
/// det / traceᴱ⁻¹ (the other eigenvalues are at most the trace), and that
/// bound is over 1e-8 × trace, far above the eigenvalue solver's rounding.
/// Much cheaper than the eigenvalues, which are left for the doubtful cases
/// (and for the error message); loading a file checks every edge's matrix.
fn clearly_positive_definite<const E: usize>(m: &SMatrix<f64, E, E>) -> bool {
    let Some(cholesky) = nalgebra::Cholesky::new(*m) else {
        return false;
    };
    let determinant = cholesky
        .l_dirty()
        .diagonal()
        .iter()
        .map(|d| d * d)
        .product::<f64>();
    let trace = m.trace();
    let bound = determinant / trace.powi(E as i32 - 1);
    bound.is_finite() && bound > 1e-8 * trace
}

/// Relative floor of the eigenvalues after [`nearest_positive_definite`].
pub const EIGENVALUE_FLOOR: f64 = 1e-9;

/// The symmetric positive-definite matrix nearest to `m` (Frobenius norm): the
/// symmetric part with its eigenvalues raised to at least
/// [`EIGENVALUE_FLOOR`] × the largest absolute eigenvalue (Higham 1988).
pub fn nearest_positive_definite<const E: usize>(m: &SMatrix<f64, E, E>) -> SMatrix<f64, E, E> {
    let sym = (m + m.transpose()) * 0.5;
    let eig = DMatrix::from_column_slice(E, E, sym.as_slice()).symmetric_eigen();
    let largest = eig.eigenvalues.amax();
    let floor = if largest > 0.0 {
        EIGENVALUE_FLOOR * largest
    } else {
        1.0
    };
    let clamped = eig.eigenvalues.map(|l| l.max(floor));
    let fixed = &eig.eigenvectors * DMatrix::from_diagonal(&clamped) * eig.eigenvectors.transpose();
    let fixed = (&fixed + fixed.transpose()) * 0.5;
    SMatrix::from_column_slice(fixed.as_slice())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Matrix6};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// A random symmetric matrix with eigenvalues `values` in random directions.
    fn with_eigenvalues<const E: usize>(rng: &mut StdRng, values: [f64; E]) -> SMatrix<f64, E, E> {
        let a = DMatrix::<f64>::from_fn(E, E, |_, _| rng.random_range(-1.0..1.0));
        let q = SMatrix::<f64, E, E>::from_column_slice(a.qr().q().as_slice());
        let m = q * SMatrix::<f64, E, E>::from_diagonal(&values.into()) * q.transpose();
        (m + m.transpose()) * 0.5
    }

    /// The Cholesky shortcut only ever accepts what the eigenvalues accept, and
    /// takes the common well-conditioned matrices.
    #[test]
    fn the_shortcut_agrees_with_the_eigenvalues() {
        let mut rng = StdRng::seed_from_u64(5);
        let mut accepted = 0;
        for _ in 0..2000 {
            let scale = 10f64.powf(rng.random_range(-6.0..8.0));
            let mut values = [0.0; 6];
            for v in &mut values {
                // Mostly positive and spread over up to 12 decades, some tiny,
                // zero or negative.
                *v = match rng.random_range(0..10) {
                    0 => -scale * rng.random::<f64>(),
                    1 => 0.0,
                    2 => scale * 1e-17,
                    _ => scale * 10f64.powf(rng.random_range(-12.0..0.0)),
                };
            }
            let m6: Matrix6<f64> = with_eigenvalues(&mut rng, values);
            let m3: Matrix3<f64> = with_eigenvalues(&mut rng, [values[0], values[1], values[2]]);
            for (fast, eig) in [
                (
                    clearly_positive_definite(&m6),
                    DMatrix::from_column_slice(6, 6, m6.as_slice())
                        .symmetric_eigenvalues()
                        .min(),
                ),
                (
                    clearly_positive_definite(&m3),
                    DMatrix::from_column_slice(3, 3, m3.as_slice())
                        .symmetric_eigenvalues()
                        .min(),
                ),
            ] {
                assert!(
                    !fast || eig > 0.0,
                    "accepted with smallest eigenvalue {eig:e}"
                );
                accepted += usize::from(fast);
            }
        }
        assert!(accepted > 100, "{accepted} accepted");
        // Typical g2o information matrices take the shortcut.
        let odometry = Matrix3::from_diagonal(&nalgebra::Vector3::new(100.0, 100.0, 1000.0));
        assert!(clearly_positive_definite(&odometry));
        let se3 = Matrix6::from_diagonal(&nalgebra::Vector6::new(1e4, 1e4, 1e4, 4e4, 4e4, 4e4));
        assert!(clearly_positive_definite(&se3));
        assert!(!clearly_positive_definite(&-odometry));
        assert!(!clearly_positive_definite(&Matrix3::zeros()));
    }
}
