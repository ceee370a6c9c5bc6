//! The `cairn` Python package's native module (`cairn._cairn`): pose graphs
//! read from g2o files or built from numpy arrays, solved by Cairn's
//! optimisers with the GIL released, and the cone-SLAM estimators and
//! simulator. Rust errors become Python exceptions carrying their message:
//! `ValueError` for bad input, `OSError` for files, `RuntimeError` for a
//! solve that fails; nothing panics across the boundary.

use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

mod arrays;
mod graph;
mod slam;

/// A g2o error as the Python exception a user expects: `OSError` when the
/// file could not be read or written, `ValueError` for its content.
fn g2o_error(e: cairn_g2o::G2oError) -> PyErr {
    match e {
        cairn_g2o::G2oError::Io { .. } => PyOSError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// A graph error (unknown or duplicate id, wrong vertex type, bad
/// information) is the caller's input: `ValueError`.
fn graph_error(e: cairn_core::GraphError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A solve that could not be carried out: `RuntimeError`.
fn solve_error(e: cairn_solvers::SolveError) -> PyErr {
    PyRuntimeError::new_err(e.to_string())
}

#[pymodule]
fn _cairn(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<graph::Graph>()?;
    m.add_class::<graph::Summary>()?;
    m.add_function(wrap_pyfunction!(graph::read_g2o, m)?)?;
    m.add_function(wrap_pyfunction!(slam::fs_slam, m)?)?;
    m.add_function(wrap_pyfunction!(slam::fs_sim, m)?)?;
    Ok(())
}
