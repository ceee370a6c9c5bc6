//! `cairn.Graph` and `cairn.Summary`.

use crate::arrays::{Matrix, Vector, dense, finite, matrix, rows, vector};
use crate::{g2o_error, graph_error, solve_error};
use cairn_core::nalgebra::{Quaternion, UnitQuaternion, Vector2, Vector3};
use cairn_core::{
    EdgePriorSE2, EdgeSE2, EdgeSE2XY, EdgeSE3, RobustKernel, SE2, SE3, Se3Error, VertexId,
};
use cairn_g2o::ReadOptions;
use cairn_solvers::{Algorithm, Initialization, IterationStats, Optimizer, SolverConfig, optimize};
use numpy::PyArray2;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::any::TypeId;
use std::path::PathBuf;

/// The most iterations a solve may be asked for.
const MAX_ITERATIONS: usize = 1_000_000;

/// Reads a g2o file (every vertex and edge type Cairn knows, FIX lines
/// included) into a Graph. `repair_information` replaces information
/// matrices that are not positive definite by the nearest ones instead of
/// refusing the file. `se3_error` is the error of its EDGE_SE3:QUAT edges:
/// "g2o" (translation and the quaternion's vector part) or "logmap"
/// (translation and the rotation vector, the objective of GTSAM to first
/// order). Raises OSError if the file cannot be read and ValueError, naming
/// the line, if its content is bad.
#[pyfunction]
#[pyo3(signature = (path, repair_information = false, se3_error = "g2o"))]
pub fn read_g2o(
    py: Python<'_>,
    path: PathBuf,
    repair_information: bool,
    se3_error: &str,
) -> PyResult<Graph> {
    let se3_error = Se3Error::ALL
        .into_iter()
        .find(|k| k.name() == se3_error)
        .ok_or_else(|| {
            PyValueError::new_err(format!(
                "se3_error must be g2o or logmap, got {se3_error:?}"
            ))
        })?;
    let options = ReadOptions {
        repair_information,
        se3_error,
        ..Default::default()
    };
    let (graph, _) = py
        .detach(|| cairn_g2o::read_file(&path, &options))
        .map_err(g2o_error)?;
    Ok(Graph { inner: graph })
}

/// A factor graph: SE2 and SE3 poses, XY landmarks and the edges between
/// them, with g2o's conventions (χ² = Σ eᵀΩe, information in g2o's order).
#[pyclass(module = "cairn")]
#[derive(Clone)]
pub struct Graph {
    inner: cairn_core::Graph,
}

#[pymethods]
impl Graph {
    /// An empty graph.
    #[new]
    fn new() -> Self {
        Self {
            inner: cairn_core::Graph::new(),
        }
    }

    fn __repr__(&self) -> String {
        format!(
            "Graph({} vertices, {} edges, chi2 {:.6e})",
            self.inner.num_vertices(),
            self.inner.num_edges(),
            self.inner.chi2()
        )
    }

    /// Number of vertices.
    #[getter]
    fn num_vertices(&self) -> usize {
        self.inner.num_vertices()
    }

    /// Number of edges.
    #[getter]
    fn num_edges(&self) -> usize {
        self.inner.num_edges()
    }

    /// A deep copy.
    fn copy(&self) -> Self {
        self.clone()
    }

    /// Adds an SE2 pose (x, y in metres, theta in radians).
    fn add_se2(&mut self, id: VertexId, x: f64, y: f64, theta: f64) -> PyResult<()> {
        self.inner
            .add_vertex(id, SE2::new(x, y, theta))
            .map_err(graph_error)?;
        Ok(())
    }

    /// Adds a 2D point (a landmark).
    fn add_xy(&mut self, id: VertexId, x: f64, y: f64) -> PyResult<()> {
        self.inner
            .add_vertex(id, Vector2::new(x, y))
            .map_err(graph_error)?;
        Ok(())
    }

    /// Adds an SE3 pose: translation t (3) and unit quaternion q as
    /// (qx, qy, qz, qw), g2o's order; q is normalised.
    fn add_se3(&mut self, id: VertexId, t: Vector<'_>, q: Vector<'_>) -> PyResult<()> {
        let pose = se3(&vector::<3>(&t, "t")?, &vector::<4>(&q, "q")?)?;
        self.inner.add_vertex(id, pose).map_err(graph_error)?;
        Ok(())
    }

    /// Adds a relative SE2 measurement from pose i to pose j: measurement
    /// (x, y, theta), information 3×3 in that order (g2o's EDGE_SE2).
    /// Returns the edge's number.
    fn add_edge_se2(
        &mut self,
        i: VertexId,
        j: VertexId,
        measurement: Vector<'_>,
        information: Matrix<'_>,
    ) -> PyResult<usize> {
        let m = vector::<3>(&measurement, "measurement")?;
        let edge = EdgeSE2::new(SE2::new(m[0], m[1], m[2]));
        let info = matrix::<3>(&information, "information")?;
        self.inner.add_edge(i, j, edge, info).map_err(graph_error)
    }

    /// Adds a landmark j seen from pose i: measurement (x, y) in pose i's
    /// frame, information 2×2 (g2o's EDGE_SE2_XY). Returns the edge's number.
    fn add_edge_se2_xy(
        &mut self,
        i: VertexId,
        j: VertexId,
        measurement: Vector<'_>,
        information: Matrix<'_>,
    ) -> PyResult<usize> {
        let edge = EdgeSE2XY::new(vector::<2>(&measurement, "measurement")?);
        let info = matrix::<2>(&information, "information")?;
        self.inner.add_edge(i, j, edge, info).map_err(graph_error)
    }

    /// Adds a prior on SE2 pose i: measurement (x, y, theta), information
    /// 3×3 (g2o's EDGE_SE2_PRIOR). Returns the edge's number.
    fn add_prior_se2(
        &mut self,
        i: VertexId,
        measurement: Vector<'_>,
        information: Matrix<'_>,
    ) -> PyResult<usize> {
        let m = vector::<3>(&measurement, "measurement")?;
        let edge = EdgePriorSE2::new(SE2::new(m[0], m[1], m[2]));
        let info = matrix::<3>(&information, "information")?;
        self.inner
            .add_unary_edge(i, edge, info)
            .map_err(graph_error)
    }

    /// Adds a relative SE3 measurement from pose i to pose j: measurement
    /// (x, y, z, qx, qy, qz, qw), information 6×6 with translation first
    /// (g2o's EDGE_SE3:QUAT). Returns the edge's number.
    fn add_edge_se3(
        &mut self,
        i: VertexId,
        j: VertexId,
        measurement: Vector<'_>,
        information: Matrix<'_>,
    ) -> PyResult<usize> {
        let m = vector::<7>(&measurement, "measurement")?;
        let t = Vector3::new(m[0], m[1], m[2]);
        let q = cairn_core::nalgebra::Vector4::new(m[3], m[4], m[5], m[6]);
        let edge = EdgeSE3::new(se3(&t, &q)?);
        let info = matrix::<6>(&information, "information")?;
        self.inner.add_edge(i, j, edge, info).map_err(graph_error)
    }

    /// Holds the vertices `ids` constant (or frees them with fixed=False).
    #[pyo3(signature = (ids, fixed = true))]
    fn fix(&mut self, ids: Vec<VertexId>, fixed: bool) -> PyResult<()> {
        // Every id is checked before any is changed.
        if let Some(&id) = ids
            .iter()
            .find(|&&id| self.inner.vertex_index(id).is_none())
        {
            return Err(graph_error(cairn_core::GraphError::UnknownVertex(id)));
        }
        for id in ids {
            self.inner.set_fixed(id, fixed).map_err(graph_error)?;
        }
        Ok(())
    }

    /// χ² = Σ eᵀΩe over all edges at the current values.
    fn chi2(&self) -> f64 {
        self.inner.chi2()
    }

    /// Writes the graph as a g2o file, atomically (a temporary file renamed
    /// over the target). Raises OSError if it cannot be written.
    fn write_g2o(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| cairn_g2o::write_file(&self.inner, &path))
            .map_err(g2o_error)
    }

    /// Optimises the graph in place and returns a Summary. solver: "gn"
    /// (Gauss-Newton), "lm" (Levenberg-Marquardt) or "dogleg". init:
    /// "auto" (the current values and two chordal starts, the lowest χ²
    /// kept: what `cairn solve` does), "file" (the current values),
    /// "chordal", "chordal-isotropic" or "spanning-tree". robust_kernel:
    /// None or huber, pseudo-huber, cauchy, geman-mcclure, welsch, fair,
    /// tukey, saturated, dcs, of width robust_kernel_width, on every edge
    /// for this solve. A solve that ends above the χ² it started from
    /// leaves the values as they were (Summary.kept_start). The GIL is
    /// released while it runs.
    #[pyo3(signature = (solver = "gn", init = "auto", max_iterations = 100, robust_kernel = None, robust_kernel_width = 1.0))]
    fn optimize(
        &mut self,
        py: Python<'_>,
        solver: &str,
        init: &str,
        max_iterations: usize,
        robust_kernel: Option<&str>,
        robust_kernel_width: f64,
    ) -> PyResult<Summary> {
        let algorithm = Algorithm::by_short_name(solver).ok_or_else(|| {
            PyValueError::new_err(format!(
                "solver must be \"gn\", \"lm\" or \"dogleg\", got {solver:?}"
            ))
        })?;
        let start = initialization(init)?;
        if !(1..=MAX_ITERATIONS).contains(&max_iterations) {
            return Err(PyValueError::new_err(format!(
                "max_iterations must be from 1 to {MAX_ITERATIONS}, got {max_iterations}"
            )));
        }
        let kernel = match robust_kernel {
            None => None,
            Some(name) => Some(kernel(name, robust_kernel_width)?),
        };
        let config = SolverConfig {
            algorithm,
            max_iterations,
            init: start,
            ..SolverConfig::default()
        };
        let graph = &mut self.inner;
        let solved = py.detach(|| {
            // The edges' own kernels (from a g2o file, say), put back after.
            let own: Option<Vec<Option<RobustKernel>>> =
                kernel.map(|_| graph.edges().map(|e| e.kernel()).collect());
            if kernel.is_some() {
                for k in 0..graph.num_edges() {
                    graph.set_robust_kernel(k, kernel);
                }
            }
            let solved = optimize(graph, config);
            for (k, old) in own.into_iter().flatten().enumerate() {
                graph.set_robust_kernel(k, old);
            }
            solved
        });
        let summary = solved.map_err(solve_error)?;
        Ok(Summary {
            chi2_initial: summary.initial_chi2,
            chi2: summary.final_chi2,
            iterations: summary.iterations,
            termination: snake_case(&format!("{:?}", summary.termination)),
            converged: summary.termination.converged(),
            init: summary.init.name().to_string(),
            kept_start: summary.kept_start,
            time: summary.solve_time,
            trace: summary.trace,
        })
    }

    /// Every SE2 pose as an (n, 4) array of rows (id, x, y, theta), in the
    /// order the vertices were added.
    fn se2_array<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.rows_of::<SE2>(py, 3)
    }

    /// Every 2D point as an (n, 3) array of rows (id, x, y).
    fn xy_array<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.rows_of::<Vector2<f64>>(py, 2)
    }

    /// Every SE3 pose as an (n, 8) array of rows (id, x, y, z, qx, qy, qz, qw).
    fn se3_array<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.rows_of::<SE3>(py, 7)
    }

    /// The marginal covariance of each vertex in `ids` at the current values
    /// (the diagonal blocks of H⁻¹; SE2: x, y, theta; SE3: translation,
    /// then rotation), as a dict from id to array. Fixed vertices, the
    /// automatic gauge (each connected component's lowest-id pose, unless a
    /// prior or fixed vertex anchors it) included, have none: ValueError.
    fn marginals<'py>(&self, py: Python<'py>, ids: Vec<VertexId>) -> PyResult<Bound<'py, PyDict>> {
        let graph = &self.inner;
        let blocks = py
            .detach(|| {
                Optimizer::new(graph, SolverConfig::default())
                    .and_then(|mut optimizer| optimizer.marginals(graph, &ids))
            })
            .map_err(|e| match e {
                cairn_solvers::SolveError::UnknownVertex(_)
                | cairn_solvers::SolveError::FixedVertex(_) => PyValueError::new_err(e.to_string()),
                e => solve_error(e),
            })?;
        let out = PyDict::new(py);
        for (id, block) in ids.iter().zip(&blocks) {
            out.set_item(id, dense(py, block))?;
        }
        Ok(out)
    }
}

impl Graph {
    /// Rows (id, parameters…) of every vertex of type `V`.
    fn rows_of<'py, V: 'static>(
        &self,
        py: Python<'py>,
        params: usize,
    ) -> Bound<'py, PyArray2<f64>> {
        let mut data = Vec::new();
        for v in self.inner.vertices() {
            if v.kind.type_id == TypeId::of::<V>() {
                data.push(v.id as f64);
                data.extend_from_slice(&v.params[..params]);
            }
        }
        rows(py, params + 1, &data)
    }
}

/// The result of [`Graph::optimize`].
#[pyclass(module = "cairn")]
pub struct Summary {
    /// χ² before the solve (at the first start tried).
    #[pyo3(get)]
    chi2_initial: f64,
    /// χ² of the estimate the solve returned.
    #[pyo3(get)]
    chi2: f64,
    /// Iterations of the run whose estimate was kept.
    #[pyo3(get)]
    iterations: usize,
    /// Why it stopped: relative_decrease, gradient_norm, step_size,
    /// max_iterations, no_improvement, not_positive_definite, non_finite,
    /// error_increased or nothing_to_optimize.
    #[pyo3(get)]
    termination: String,
    /// Whether the termination counts as convergence.
    #[pyo3(get)]
    converged: bool,
    /// The start whose estimate was kept: file, chordal, chordal-isotropic
    /// or spanning-tree.
    #[pyo3(get)]
    init: String,
    /// Whether the solve ended above its start, so the values were kept.
    #[pyo3(get)]
    kept_start: bool,
    /// Seconds the kept run took.
    #[pyo3(get)]
    time: f64,
    trace: Vec<IterationStats>,
}

#[pymethods]
impl Summary {
    /// One dict per iteration: iteration, chi2, lambda, radius, trials,
    /// gradient_max, step_max, time, cumulative_time.
    #[getter]
    fn trace<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.trace.iter().map(|s| stats(py, s)).collect()
    }

    fn __repr__(&self) -> String {
        format!(
            "Summary(chi2_initial={:.6e}, chi2={:.6e}, iterations={}, termination={:?}, init={:?})",
            self.chi2_initial, self.chi2, self.iterations, self.termination, self.init
        )
    }
}

/// One iteration's statistics as a dict.
fn stats<'py>(py: Python<'py>, s: &IterationStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let items: [(&str, Option<f64>); 7] = [
        ("chi2", Some(s.chi2)),
        ("lambda", s.lambda),
        ("radius", s.radius),
        ("gradient_max", Some(s.gradient_max)),
        ("step_max", Some(s.step_max)),
        ("time", Some(s.time)),
        ("cumulative_time", Some(s.cumulative_time)),
    ];
    d.set_item("trials", s.trials)?;
    d.set_item("iteration", s.iteration)?;
    for (k, v) in items {
        d.set_item(k, v)?;
    }
    Ok(d)
}

/// `RustName` as `rust_name`.
fn snake_case(name: &str) -> String {
    let mut out = String::new();
    for (i, c) in name.chars().enumerate() {
        if c.is_ascii_uppercase() && i > 0 {
            out.push('_');
        }
        out.push(c.to_ascii_lowercase());
    }
    out
}

fn initialization(name: &str) -> PyResult<Initialization> {
    Initialization::by_name(name).ok_or_else(|| {
        let names: Vec<&str> = Initialization::ALL.iter().map(|i| i.name()).collect();
        PyValueError::new_err(format!(
            "init must be one of {}, got {name:?}",
            names.join(", ")
        ))
    })
}

fn kernel(name: &str, width: f64) -> PyResult<RobustKernel> {
    if !(width.is_finite() && width > 0.0) {
        return Err(PyValueError::new_err(format!(
            "robust_kernel_width must be finite and positive, got {width}"
        )));
    }
    RobustKernel::from_name(name, width).ok_or_else(|| {
        PyValueError::new_err(format!(
            "unknown robust kernel {name:?}; choose one of huber, pseudo-huber, cauchy, \
             geman-mcclure, welsch, fair, tukey, saturated, dcs"
        ))
    })
}

/// A pose from translation t and quaternion (qx, qy, qz, qw).
fn se3(t: &Vector3<f64>, q: &cairn_core::nalgebra::Vector4<f64>) -> PyResult<SE3> {
    finite(q.as_slice(), "q")?;
    let q = Quaternion::new(q[3], q[0], q[1], q[2]);
    if q.norm() < 1e-12 {
        return Err(PyValueError::new_err("q must not be zero"));
    }
    Ok(SE3::new(*t, UnitQuaternion::from_quaternion(q)))
}
