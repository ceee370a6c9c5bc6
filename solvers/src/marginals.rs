//! Marginal covariances: blocks of H⁻¹ at the current estimate, computed from
//! the sparse Cholesky factor, by solving for the requested columns or by
//! selected inversion.

use crate::SolveError;
use crate::config::PhaseTimes;
use crate::optimizer::Optimizer;
use cairn_core::{Graph, VertexId};
use nalgebra::DMatrix;

/// Columns of H⁻¹ up to which the marginals come from triangular solves;
/// beyond, from one selected inversion, which cost about as much as 20–30
/// columns' solves on city10000, M3500a, sphere2500 and torus3D (48, 19,
/// 96 and 228 ms for every vertex, against 58 s, 3.7 s, 37 s and 238 s by
/// solves) and 66 on parking-garage.
const SOLVED_COLUMNS: usize = 24;

impl Optimizer {
    /// The marginal covariance of each vertex in `ids`: the diagonal block of
    /// H⁻¹ (H = JᵀΩJ at the graph's current values, undamped), in the vertex's
    /// tangent coordinates. H⁻¹ is never formed: a few blocks cost a pair of
    /// triangular solves per column, many (more than 24 columns) one
    /// selected inversion, which gives H⁻¹ on the pattern of the Cholesky
    /// factor for about the cost of factorising.
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
        let wanted: usize = columns.iter().map(|&(_, d)| d).sum();
        if wanted > SOLVED_COLUMNS {
            self.marginals_by_selected_inversion(&columns)
        } else {
            Ok(self.marginals_by_solves(&columns))
        }
    }

    /// Each block from solves for its columns of H⁻¹.
    fn marginals_by_solves(&mut self, columns: &[(usize, usize)]) -> Vec<DMatrix<f64>> {
        let dim = self.dimension();
        let mut rhs = vec![0.0; dim];
        let mut out = Vec::with_capacity(columns.len());
        for &(c, d) in columns {
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
        out
    }

    /// Every block from one selected inversion.
    fn marginals_by_selected_inversion(
        &self,
        columns: &[(usize, usize)],
    ) -> Result<Vec<DMatrix<f64>>, SolveError> {
        let z = self.selected_inverse().ok_or(SolveError::NothingToSolve)?;
        let mut out = Vec::with_capacity(columns.len());
        for &(c, d) in columns {
            let mut block = DMatrix::zeros(d, d);
            for i in 0..d {
                for j in 0..d {
                    // A vertex's diagonal block is dense in H, so in L.
                    block[(i, j)] = z.get(c + i, c + j).unwrap_or(f64::NAN);
                }
            }
            out.push(block);
        }
        Ok(out)
    }
}
