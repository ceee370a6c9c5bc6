//! numpy arrays (or anything array-like) in and out, shapes and values checked.

use nalgebra::{SMatrix, SVector};
use numpy::ndarray::Array2;
use numpy::{AllowTypeChange, IntoPyArray, PyArray2, PyArrayLike1, PyArrayLike2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// An array-like of floats of one dimension, cast to float64 as numpy's
/// `asarray` would.
pub type Vector<'py> = PyArrayLike1<'py, f64, AllowTypeChange>;
/// An array-like of floats of two dimensions.
pub type Matrix<'py> = PyArrayLike2<'py, f64, AllowTypeChange>;

/// `what` as a vector of exactly `N` finite numbers.
pub fn vector<const N: usize>(a: &Vector<'_>, what: &str) -> PyResult<SVector<f64, N>> {
    let view = a.as_array();
    if view.len() != N {
        return Err(PyValueError::new_err(format!(
            "{what} must have {N} numbers, got {}",
            view.len()
        )));
    }
    let v = SVector::<f64, N>::from_iterator(view.iter().copied());
    finite(v.as_slice(), what)?;
    Ok(v)
}

/// `what` as an `N`×`N` matrix of finite numbers.
pub fn matrix<const N: usize>(a: &Matrix<'_>, what: &str) -> PyResult<SMatrix<f64, N, N>> {
    let view = a.as_array();
    if view.shape() != [N, N] {
        return Err(PyValueError::new_err(format!(
            "{what} must be {N}×{N}, got {:?}",
            view.shape()
        )));
    }
    let m = SMatrix::<f64, N, N>::from_fn(|r, c| view[[r, c]]);
    finite(m.as_slice(), what)?;
    Ok(m)
}

/// Refuses NaN and infinite values, naming `what`.
pub fn finite(values: &[f64], what: &str) -> PyResult<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(PyValueError::new_err(format!(
            "{what} has a NaN or infinite value"
        )))
    }
}

/// Rows of `width` numbers as an (n, width) numpy array.
pub fn rows<'py>(py: Python<'py>, width: usize, data: &[f64]) -> Bound<'py, PyArray2<f64>> {
    let n = data.len() / width.max(1);
    Array2::from_shape_fn((n, width), |(r, c)| data[r * width + c]).into_pyarray(py)
}

/// A nalgebra matrix as a numpy array.
pub fn dense<'py>(py: Python<'py>, m: &nalgebra::DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn(m.shape(), |(r, c)| m[(r, c)]).into_pyarray(py)
}
