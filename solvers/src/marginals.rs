//! Marginal covariances: blocks of H⁻¹ at the current estimate, computed from
//! the sparse Cholesky factor by solving for the requested columns only.

use crate::SolveError;
use crate::config::PhaseTimes;
use crate::optimizer::Optimizer;
use cairn_core::{Graph, VertexId};
use nalgebra::DMatrix;

impl Optimizer {
    /// The marginal covariance of each vertex in `ids`: the diagonal block of
    /// H⁻¹ (H = JᵀΩJ at the graph's current values, undamped), in the vertex's
    /// tangent coordinates. Each block costs `dim` triangular solve pairs with
    /// the existing factorisation pattern; H⁻¹ is never formed.
    ///
    /// Fixed vertices (including the automatic gauge) have no marginal.
    pub fn marginals(
        &mut self,
        graph: &Graph,
        ids: &[VertexId],
    ) -> Result<Vec<DMatrix<f64>>, SolveError> {
        if (graph.num_vertices(), graph.num_edges()) != self.shape() {
            return Err(SolveError::GraphChanged);
        }
        let mut columns = Vec::with_capacity(ids.len());
        for &id in ids {
            let v = graph
                .vertex_index(id)
                .ok_or(SolveError::UnknownVertex(id))?;
            let c = self.column(v).ok_or(SolveError::FixedVertex(id))?;
            columns.push((c, graph.vertex(v).kind.dim));
        }
        let mut phases = PhaseTimes::default();
        self.relinearize(graph, &mut phases);
        self.factorize_undamped()?;
        let dim = self.dimension();
        let mut rhs = vec![0.0; dim];
        let mut out = Vec::with_capacity(ids.len());
        for (c, d) in columns {
            let mut block = DMatrix::zeros(d, d);
            for j in 0..d {
                rhs.iter_mut().for_each(|x| *x = 0.0);
                rhs[c + j] = 1.0;
                self.solve_factorized(&mut rhs);
                for i in 0..d {
                    block[(i, j)] = rhs[c + i];
                }
            }
            // Symmetrise away rounding.
            out.push((&block + block.transpose()) * 0.5);
        }
        Ok(out)
    }
}
