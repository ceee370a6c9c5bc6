//! Sparse Cholesky of the Hessian with faer: symbolic analysis once, numeric
//! factorisation per iteration into reused buffers.

use crate::SolveError;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use serde::{Deserialize, Serialize};

/// Multiple of faer's flops-per-non-zero threshold above which
/// [`Factorization::Auto`] goes supernodal. faer's own (1.0) keeps
/// parking-garage and intel_slamcourse simplicial, where supernodal measured
/// 1.7× and 1.2× faster; at 0.5 they switch and nothing else does (lower values
/// switch files where neither wins clearly). See BENCHMARKS.md.
const AUTO_SUPERNODAL_THRESHOLD: f64 = 0.5;

/// Which Cholesky variant faer uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Factorization {
    /// Chosen from the flop count of the symbolic analysis: supernodal when
    /// the factor has dense fronts (half faer's own threshold, by measurement).
    #[default]
    Auto,
    /// Column by column; best for very sparse factors.
    Simplicial,
    /// Dense blocks of columns; best when the factor has dense fronts.
    Supernodal,
}

/// Fill-reducing ordering.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Ordering {
    /// Approximate minimum degree on the scalar pattern.
    Amd,
    /// Approximate minimum degree on the vertex (block) graph, each vertex's
    /// columns kept together. The default: the same fill as [`Ordering::Amd`]
    /// on every benchmark file (or a little less), and cheaper to find on the
    /// large ones (city10000's setup: 46 ms instead of 108 ms).
    #[default]
    BlockAmd,
    /// The vertex order as it is.
    Identity,
}

/// Options of the linear solver.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LinearSolverConfig {
    /// Simplicial or supernodal factorisation.
    pub factorization: Factorization,
    /// Fill-reducing ordering.
    pub ordering: Ordering,
    /// Let faer use the rayon thread pool.
    pub parallel: bool,
}

/// The numeric factorisation found a non-positive pivot: the (damped) Hessian is
/// not positive definite.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the Hessian is not positive definite (pivot {pivot})")]
pub struct NotPositiveDefinite {
    /// The pivot (in the permuted order) where factorisation stopped.
    pub pivot: usize,
}

/// AMD on the block graph, expanded to a scalar permutation (forward, inverse).
fn block_amd(
    blocks: SymbolicSparseColMatRef<'_, usize>,
    dims: &[usize],
) -> Result<(Vec<usize>, Vec<usize>), SolveError> {
    let n = dims.len();
    let (mut perm, mut perm_inv) = (vec![0usize; n], vec![0usize; n]);
    let nnz = blocks.row_idx().len();
    let mut scratch = MemBuffer::try_new(faer::sparse::linalg::amd::order_scratch::<usize>(n, nnz))
        .map_err(|_| SolveError::OutOfMemory)?;
    faer::sparse::linalg::amd::order(
        &mut perm,
        &mut perm_inv,
        blocks,
        Default::default(),
        MemStack::new(&mut scratch),
    )
    .map_err(|e| SolveError::Analysis(format!("{e:?}")))?;
    let mut start = Vec::with_capacity(n);
    let mut total = 0;
    for &d in dims {
        start.push(total);
        total += d;
    }
    let forward: Vec<usize> = perm
        .iter()
        .flat_map(|&b| start[b]..start[b] + dims[b])
        .collect();
    let mut inverse = vec![0usize; total];
    for (i, &f) in forward.iter().enumerate() {
        inverse[f] = i;
    }
    Ok((forward, inverse))
}

/// A sparse Cholesky solver bound to one sparsity pattern.
pub struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    factor: Vec<f64>,
    scratch: MemBuffer,
    par: Par,
    factored: bool,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("factor_len", &self.factor.len())
            .finish()
    }
}

impl SparseCholesky {
    /// Symbolic analysis (ordering and elimination structure) of the upper
    /// triangle `pattern`, whose block structure is `blocks` (the pattern of one
    /// row and column per vertex, and each vertex's dimension).
    pub fn analyze(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        blocks: (SymbolicSparseColMatRef<'_, usize>, &[usize]),
        config: &LinearSolverConfig,
    ) -> Result<Self, SolveError> {
        let threshold = match config.factorization {
            Factorization::Auto => SupernodalThreshold(AUTO_SUPERNODAL_THRESHOLD),
            Factorization::Simplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
            Factorization::Supernodal => SupernodalThreshold::FORCE_SUPERNODAL,
        };
        let block_perm = match config.ordering {
            Ordering::BlockAmd => Some(block_amd(blocks.0, blocks.1)?),
            _ => None,
        };
        let ordering = match (config.ordering, &block_perm) {
            (Ordering::BlockAmd, Some((fwd, inv))) => {
                SymmetricOrdering::Custom(faer::perm::PermRef::new_checked(fwd, inv, fwd.len()))
            }
            (Ordering::Identity, _) => SymmetricOrdering::Identity,
            _ => SymmetricOrdering::Amd,
        };
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: threshold,
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(pattern, Side::Upper, ordering, params)
            .map_err(|e| SolveError::Analysis(format!("{e:?}")))?;
        let par = if config.parallel {
            Par::rayon(0)
        } else {
            Par::Seq
        };
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, par),
        ]);
        let scratch = MemBuffer::try_new(req).map_err(|_| SolveError::OutOfMemory)?;
        let factor = vec![0.0; symbolic.len_val()];
        Ok(Self {
            symbolic,
            factor,
            scratch,
            par,
            factored: false,
        })
    }

    /// Whether the factor is supernodal.
    pub fn is_supernodal(&self) -> bool {
        matches!(
            self.symbolic.raw(),
            faer::sparse::linalg::cholesky::SymbolicCholeskyRaw::Supernodal(_)
        )
    }

    /// Number of stored values of the factor L.
    pub fn factor_nnz(&self) -> usize {
        self.factor.len()
    }

    /// Numeric factorisation of H given by `pattern` and `values`.
    pub fn factorize(
        &mut self,
        pattern: SymbolicSparseColMatRef<'_, usize>,
        values: &[f64],
    ) -> Result<(), NotPositiveDefinite> {
        self.factored = false;
        let h = SparseColMatRef::new(pattern, values);
        let stack = MemStack::new(&mut self.scratch);
        let regularization = LltRegularization {
            dynamic_regularization_delta: 0.0,
            dynamic_regularization_epsilon: 0.0,
        };
        match self.symbolic.factorize_numeric_llt(
            &mut self.factor,
            h,
            Side::Upper,
            regularization,
            self.par,
            stack,
            Default::default(),
        ) {
            Ok(_) => {
                self.factored = true;
                Ok(())
            }
            Err(LltError::NonPositivePivot { index }) => Err(NotPositiveDefinite { pivot: index }),
        }
    }

    /// Solves H x = rhs in place with the last successful factorisation.
    /// Returns `false` (and leaves `rhs` alone) if there is none.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> bool {
        if !self.factored {
            return false;
        }
        let llt = LltRef::new(&self.symbolic, &self.factor);
        let stack = MemStack::new(&mut self.scratch);
        let n = rhs.len();
        let x = MatMut::from_column_major_slice_mut(rhs, n, 1);
        llt.solve_in_place_with_conj(Conj::No, x, self.par, stack);
        true
    }
}
