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
