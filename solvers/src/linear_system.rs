//! The linearised system at the graph's current values, for studying a
//! problem (conditioning, sparsity, orderings) or handing it to another
//! solver: H, b and the whitened Jacobian as `sprs` matrices.

use crate::optimizer::Optimizer;
use crate::{PhaseTimes, SolveError};
use cairn_core::{Graph, VertexId};
use nalgebra::{DMatrix, SymmetricEigen};
use sprs::{CsMat, TriMat};

/// The Gauss-Newton system H δ = b at the graph's current values, over the
/// free vertices: fixed vertices and the automatic gauge (the vertex each
/// component without a fixed vertex or a prior holds) are left out, as in
/// the solve. With W = ρ′(eᵀΩe)·Ω each edge's weighted information (Ω
/// alone without a robust kernel) and U its square root (UᵀU = W):
/// H = JᵀWJ, b = −JᵀWe, and the whitened Jacobian is UJ, so that
/// H = (UJ)ᵀ(UJ) and b = −(UJ)ᵀ(Ue).
#[derive(Clone, Debug)]
pub struct LinearSystem {
    /// H's upper triangle (diagonal included), compressed by column, in
    /// the column order of [`LinearSystem::columns`]. [`LinearSystem::hessian_full`]
    /// gives both triangles.
    pub hessian: CsMat<f64>,
    /// b = −JᵀWe: the Gauss-Newton step solves H δ = b.
    pub rhs: Vec<f64>,
    /// The whitened Jacobian UJ, compressed by row: one row per error
    /// component of every edge, columns as H's.
    pub jacobian: CsMat<f64>,
    /// The whitened error Ue, one entry per row of the Jacobian.
    pub error: Vec<f64>,
    /// Per column: the vertex's id and the tangent coordinate (0-based).
    pub columns: Vec<(VertexId, usize)>,
    /// Per row of the Jacobian: the edge (its index in insertion order, as
    /// [`Graph::edge`] takes it) and the error component.
    pub rows: Vec<(usize, usize)>,
    /// χ² at the linearisation point (robust where a kernel is set).
    pub chi2: f64,
}

impl LinearSystem {
    /// H with both triangles, compressed by column.
    pub fn hessian_full(&self) -> CsMat<f64> {
        let n = self.hessian.cols();
        let mut full = TriMat::with_capacity((n, n), 2 * self.hessian.nnz());
        for (&value, (row, col)) in self.hessian.iter() {
            full.add_triplet(row, col, value);
            if row != col {
                full.add_triplet(col, row, value);
            }
        }
        full.to_csc()
    }
}

impl Optimizer {
    /// Linearises `graph` at its current values and returns H, b and the
    /// whitened Jacobian ([`LinearSystem`]). Costs one linearisation and a
    /// pass over the edges; the optimiser's own buffers are reused, so call
    /// it between solves as often as wanted.
    pub fn linear_system(&mut self, graph: &Graph) -> Result<LinearSystem, SolveError> {
        if (graph.num_vertices(), graph.num_edges()) != self.shape() {
            return Err(SolveError::GraphChanged);
        }
        let mut phases = PhaseTimes::default();
        let chi2 = self.relinearize(graph, &mut phases);
        let layout = &self.structure().layout;
        let n = layout.dim();
        let pattern = layout.scalar_pattern();
        let hessian = CsMat::new_csc(
            (n, n),
            pattern.col_ptr().to_vec(),
            pattern.row_idx().to_vec(),
            self.hessian_values().to_vec(),
        );
        let rhs: Vec<f64> = self.gradient_values().iter().map(|g| -g).collect();
        let mut columns = vec![(0, 0); n];
        for v in 0..graph.num_vertices() {
            if let Some(c) = self.column(v) {
                let vertex = graph.vertex(v);
                for k in 0..vertex.kind.dim {
                    columns[c + k] = (vertex.id, k);
                }
            }
        }
        let (jacobian, error, rows) = self.whitened_jacobian(graph, n);
        Ok(LinearSystem {
            hessian,
            rhs,
            jacobian,
            error,
            columns,
            rows,
            chi2,
        })
    }

    /// UJ (by row), Ue and each row's (edge, component).
    fn whitened_jacobian(
        &self,
        graph: &Graph,
        n: usize,
    ) -> (CsMat<f64>, Vec<f64>, Vec<(usize, usize)>) {
        let values = graph.values();
        let rows_total: usize = graph.edges().map(|e| e.error_dim()).sum();
        let mut jacobian = TriMat::new((rows_total, n));
        let mut error = Vec::with_capacity(rows_total);
        let mut rows = Vec::with_capacity(rows_total);
        let (mut e, mut j) = (Vec::new(), Vec::new());
        for (k, edge) in graph.edges().enumerate() {
            let dim = edge.error_dim();
            let dims = edge.vertex_dims();
            e.resize(dim, 0.0);
            j.resize(dim * dims.iter().sum::<usize>(), 0.0);
            edge.jacobians(values, &mut e, &mut j);
            let e_vec = nalgebra::DVector::from_column_slice(&e);
            let omega = DMatrix::from_column_slice(dim, dim, edge.information());
            let weight = edge.kernel().map_or(1.0, |kernel| {
                let s = e_vec.dot(&(&omega * &e_vec));
                kernel.robustify(s)[1]
            });
            let u = square_root(&(omega * weight));
            let first = rows.len();
            for (r, value) in (&u * &e_vec).iter().enumerate() {
                error.push(*value);
                rows.push((k, r));
            }
            let mut at = 0;
            for (&vertex, &d) in edge.vertices().iter().zip(dims) {
                let block = DMatrix::from_column_slice(dim, d, &j[at..at + dim * d]);
                at += dim * d;
                let Some(column) = self.column(vertex) else {
                    continue;
                };
                let whitened = &u * block;
                for ((r, c), &value) in whitened
                    .iter()
                    .enumerate()
                    .map(|(i, v)| ((i % dim, i / dim), v))
                {
                    if value != 0.0 {
                        jacobian.add_triplet(first + r, column + c, value);
                    }
                }
            }
        }
        (jacobian.to_csr(), error, rows)
    }
}

/// U with UᵀU = W for a symmetric positive semi-definite W: Λ^½Vᵀ from
/// W = VΛVᵀ (negative rounding in Λ taken as zero).
fn square_root(w: &DMatrix<f64>) -> DMatrix<f64> {
    let eigen = SymmetricEigen::new(0.5 * (w + w.transpose()));
    let root = eigen.eigenvalues.map(|l| l.max(0.0).sqrt());
    DMatrix::from_diagonal(&root) * eigen.eigenvectors.transpose()
}
