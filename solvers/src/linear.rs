//! Sparse Cholesky of the Hessian: symbolic analysis once, numeric
//! factorisation per iteration into reused buffers. Both kinds of factor
//! are Cairn's block-aware code, analysed on the vertex blocks: simplicial
//! (the `simplicial` module) and supernodal (the `supernodal` module, with
//! faer's dense kernels). Under faer's scalar AMD ordering the factor is
//! faer's own.

use crate::SolveError;
use crate::hessian_layout::HessianLayout;
use crate::selected_inverse::{LowerFactor, SelectedInverse, Supernodes};
use crate::simplicial::{SimplicialCholesky, SimplicialSymbolic};
use crate::supernodal::{SupernodalCholesky, SupernodalSymbolic};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use serde::{Deserialize, Serialize};

/// Multiple of faer's flops-per-non-zero threshold (40) above which
/// [`Factorization::Auto`] goes supernodal, by measurement (BENCHMARKS.md).
/// Flops per factor value on the benchmark files: the 2D files 5–13, the
/// M3500 family 18.8 and simulation-pose-pose 19.7 (Cairn's simplicial
/// factorisation, which forms each block's rows together, solves these
/// faster: the M3500 family by 8–11%); parking-garage 27, intel_slamcourse
/// 31, city10000 42, smallGrid3D 51 and the 3D spheres and torus 130–213
/// (the supernodal one faster: parking-garage by 5%, intel_slamcourse by
/// 12%, city10000 1.8×, the 3D files 3–4×, since session 28's supernodal
/// factorisation; before it the threshold was 36). At 0.6 (24) each file
/// gets its faster kind. Large factors fall out of cache row by row: on the
/// generated Manhattan worlds (above 16 flops per value) simplicial
/// factorises 10⁴ poses (0.46 million values) as fast, 3·10⁴ (3 million)
/// 25% slower and 10⁵ (14 million) 4× slower, so from [`AUTO_LARGE_FACTOR`]
/// values the threshold is [`AUTO_SUPERNODAL_THRESHOLD_LOW`].
const AUTO_SUPERNODAL_THRESHOLD: f64 = 0.6;

/// Factor values from which [`Factorization::Auto`] goes supernodal from 16
/// flops per value instead of 24.
const AUTO_LARGE_FACTOR: usize = 1_000_000;

/// The same (16 flops per value) for factors of [`AUTO_LARGE_FACTOR`] values
/// or more, and under [`Ordering::Amd`], where the simplicial factorisation
/// is faer's, row by row (by measurement, BENCHMARKS.md, session 13).
const AUTO_SUPERNODAL_THRESHOLD_LOW: f64 = 0.4;

/// faer's flops per factor value above which it goes supernodal.
const FAER_SUPERNODAL_RATIO: f64 = 40.0;

/// Whether Cairn's simplicial factorisation beats faer's supernodal one on
/// this factor, by its flops per value and its size (see the thresholds).
fn simplicial_pays(symbolic: &SimplicialSymbolic) -> bool {
    let threshold = if symbolic.len_val() < AUTO_LARGE_FACTOR {
        AUTO_SUPERNODAL_THRESHOLD
    } else {
        AUTO_SUPERNODAL_THRESHOLD_LOW
    };
    symbolic.flops_per_value() <= threshold * FAER_SUPERNODAL_RATIO
}

/// Which Cholesky variant factorises H.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Factorization {
    /// Chosen from the flop count of the symbolic analysis: supernodal when
    /// the factor has dense fronts (from 24 flops per value, 16 for factors of
    /// a million values or more, by measurement).
    #[default]
    Auto,
    /// Column by column (Cairn's, on the vertex blocks; faer's under
    /// [`Ordering::Amd`]); best for very sparse factors.
    Simplicial,
    /// Dense blocks of columns (faer's under [`Ordering::Amd`]); best when
    /// the factor has dense fronts.
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
    /// Every landmark first, then the poses in AMD order of the reduced pose
    /// system: the Cholesky then forms the Schur complement on the landmarks,
    /// as g2o's block solvers do explicitly.
    Schur,
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

/// The block structure of H: one row and column per free vertex.
#[derive(Clone, Copy, Debug)]
pub struct Blocks<'a> {
    /// Pattern of the upper block triangle (`u32` indices, as faer's AMD
    /// takes them: its work arrays then take half the memory).
    pub pattern: SymbolicSparseColMatRef<'a, u32>,
    /// Tangent dimension of each block.
    pub dims: &'a [usize],
    /// Whether each block is a pose (the others are landmarks).
    pub is_pose: &'a [bool],
}

/// faer's parallelism for the dense kernels.
fn par(config: &LinearSolverConfig) -> Par {
    if config.parallel {
        Par::rayon(0)
    } else {
        Par::Seq
    }
}

/// Approximate minimum degree order of the blocks of `pattern`.
fn amd(pattern: SymbolicSparseColMatRef<'_, u32>) -> Result<Vec<usize>, SolveError> {
    let (n, nnz) = (pattern.ncols(), pattern.row_idx().len());
    let (mut perm, mut perm_inv) = (vec![0u32; n], vec![0u32; n]);
    let mut scratch = MemBuffer::try_new(faer::sparse::linalg::amd::order_scratch::<u32>(n, nnz))
        .map_err(|_| SolveError::OutOfMemory)?;
    faer::sparse::linalg::amd::order(
        &mut perm,
        &mut perm_inv,
        pattern,
        Default::default(),
        MemStack::new(&mut scratch),
    )
    .map_err(|e| SolveError::Analysis(format!("{e:?}")))?;
    Ok(perm.into_iter().map(|k| k as usize).collect())
}

/// The landmarks first, then the poses in AMD order of the pattern the
/// landmarks' elimination leaves (the reduced pose system). Landmarks joined to
/// another landmark stay with the poses, so the eliminated block is diagonal.
fn schur_order(blocks: Blocks<'_>) -> Result<Vec<usize>, SolveError> {
    let n = blocks.dims.len();
    let mut neighbours = vec![Vec::new(); n];
    let rows_of = |c: usize| {
        blocks
            .pattern
            .row_idx_of_col_raw(c)
            .iter()
            .map(|&r| r as usize)
    };
    for c in 0..n {
        for r in rows_of(c) {
            if r != c {
                neighbours[r].push(c);
                neighbours[c].push(r);
            }
        }
    }
    let eliminated: Vec<bool> = (0..n)
        .map(|b| !blocks.is_pose[b] && neighbours[b].iter().all(|&o| blocks.is_pose[o]))
        .collect();
    let kept: Vec<usize> = (0..n).filter(|&b| !eliminated[b]).collect();
    let mut index = vec![usize::MAX; n];
    for (k, &b) in kept.iter().enumerate() {
        index[b] = k;
    }
    // Upper triangle of the reduced system: the kept blocks' own couplings plus
    // a clique on the neighbours of each eliminated landmark.
    let mut rows: Vec<Vec<usize>> = (0..kept.len()).map(|k| vec![k]).collect();
    for c in 0..n {
        for r in rows_of(c) {
            if r != c && !eliminated[r] && !eliminated[c] {
                let (a, b) = (index[r].min(index[c]), index[r].max(index[c]));
                rows[b].push(a);
            }
        }
        if eliminated[c] {
            for &p in &neighbours[c] {
                for &q in &neighbours[c] {
                    if index[p] < index[q] {
                        rows[index[q]].push(index[p]);
                    }
                }
            }
        }
    }
    let mut col_ptr = vec![0u32];
    let mut row_idx: Vec<u32> = Vec::new();
    for col in &mut rows {
        col.sort_unstable();
        col.dedup();
        row_idx.extend(col.iter().map(|&r| r as u32));
        let end = u32::try_from(row_idx.len()).map_err(|_| SolveError::TooLarge {
            entries: row_idx.len(),
        })?;
        col_ptr.push(end);
    }
    let reduced = SymbolicSparseColMat::new_checked(kept.len(), kept.len(), col_ptr, None, row_idx);
    let pose_order = amd(reduced.as_ref())?;
    Ok((0..n)
        .filter(|&b| eliminated[b])
        .chain(pose_order.iter().map(|&k| kept[k]))
        .collect())
}

/// The order of the blocks that `ordering` asks for (block `order[k]` goes
/// k-th), or the blocks' own order for the orderings that are not by block.
pub(crate) fn block_order(
    blocks: Blocks<'_>,
    ordering: Ordering,
) -> Result<Vec<usize>, SolveError> {
    match ordering {
        Ordering::BlockAmd => amd(blocks.pattern),
        Ordering::Schur => schur_order(blocks),
        Ordering::Amd | Ordering::Identity => Ok((0..blocks.dims.len()).collect()),
    }
}

/// A solve of H x = b begun by [`SparseCholesky::factorize_and_begin_solve`].
#[must_use]
#[derive(Debug)]
pub struct BegunSolve {
    forwarded: bool,
}

/// A sparse Cholesky solver bound to one sparsity pattern.
#[derive(Debug)]
pub struct SparseCholesky {
    factor: Factor,
    factored: bool,
    /// Entries of H's upper triangle in the analysed layout.
    nnz: usize,
}

/// Cairn's block-aware factors, simplicial or supernodal, or faer's (under
/// faer's own scalar AMD ordering).
#[derive(Debug)]
enum Factor {
    Simplicial(SimplicialCholesky),
    Supernodal(Box<SupernodalCholesky>),
    Faer(FaerCholesky),
}

/// faer's factor with H's scalar pattern, its symbolic analysis and work
/// space.
struct FaerCholesky {
    pattern: SymbolicSparseColMat<usize>,
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    scratch: MemBuffer,
    par: Par,
}

impl std::fmt::Debug for FaerCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FaerCholesky")
            .field("values", &self.values.len())
            .finish()
    }
}

impl FaerCholesky {
    fn factorize(&mut self, values: &[f64]) -> Result<(), NotPositiveDefinite> {
        let h = SparseColMatRef::new(self.pattern.as_ref(), values);
        let regularization = LltRegularization {
            dynamic_regularization_delta: 0.0,
            dynamic_regularization_epsilon: 0.0,
        };
        self.symbolic
            .factorize_numeric_llt(
                &mut self.values,
                h,
                Side::Upper,
                regularization,
                self.par,
                MemStack::new(&mut self.scratch),
                Default::default(),
            )
            .map(|_| ())
            .map_err(|LltError::NonPositivePivot { index }| NotPositiveDefinite { pivot: index })
    }

    fn solve_in_place(&mut self, rhs: &mut [f64]) {
        let llt = LltRef::new(&self.symbolic, &self.values);
        let n = rhs.len();
        let x = MatMut::from_column_major_slice_mut(rhs, n, 1);
        llt.solve_in_place_with_conj(Conj::No, x, self.par, MemStack::new(&mut self.scratch));
    }
}

impl FaerCholesky {
    /// H⁻¹ on the pattern of the factor.
    fn selected_inverse(&self) -> SelectedInverse {
        let position = self.symbolic.perm().map(|p| p.arrays().1.to_vec());
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => {
                let supernodes = Supernodes {
                    begin: s.supernode_begin().to_vec(),
                    end: s.supernode_end().to_vec(),
                    val_ptr: s.col_ptr_for_val().to_vec(),
                    row_ptr: s.col_ptr_for_row_idx().to_vec(),
                    row_idx: s.row_idx().to_vec(),
                    values: self.values.clone(),
                };
                SelectedInverse::from_supernodes(supernodes, position)
            }
            SymbolicCholeskyRaw::Simplicial(s) => {
                let mut columns = LowerFactor {
                    col_ptr: s.col_ptr().to_vec(),
                    row_idx: s.row_idx().to_vec(),
                    values: self.values.clone(),
                };
                columns.sort_columns();
                SelectedInverse::from_columns(columns, position)
            }
        }
    }
}

impl SparseCholesky {
    /// Symbolic analysis of H, laid out by its vertex blocks in `layout`.
    /// Block orderings are the caller's to apply (by numbering the blocks
    /// in `block_order`); only [`Ordering::Amd`] is left to faer, whose
    /// factor it then is; under the others the factor is Cairn's, analysed
    /// on the blocks.
    pub fn analyze(
        layout: &HessianLayout,
        config: &LinearSolverConfig,
    ) -> Result<Self, SolveError> {
        let factor = if config.ordering == Ordering::Amd {
            let threshold = match config.factorization {
                Factorization::Auto => SupernodalThreshold(AUTO_SUPERNODAL_THRESHOLD_LOW),
                Factorization::Simplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
                Factorization::Supernodal => SupernodalThreshold::FORCE_SUPERNODAL,
            };
            Self::faer(layout.scalar_pattern(), threshold, config)?
        } else {
            let blocks = SimplicialSymbolic::analyze(layout)?;
            let simplicial = match config.factorization {
                Factorization::Supernodal => false,
                Factorization::Simplicial => true,
                Factorization::Auto => simplicial_pays(&blocks),
            };
            Self::blockwise(blocks, simplicial, layout, par(config))?
        };
        Ok(Self {
            factor,
            factored: false,
            nnz: layout.nnz(),
        })
    }

    /// Cairn's factor on the block analysis `blocks`: simplicial if asked
    /// and H's dimension fits its `u32` row indices, else supernodal unless
    /// the supernodal plan would outgrow the factor.
    fn blockwise(
        blocks: SimplicialSymbolic,
        simplicial: bool,
        layout: &HessianLayout,
        par: Par,
    ) -> Result<Factor, SolveError> {
        let dim = blocks.dim();
        if !simplicial || u32::try_from(dim).is_err() {
            let symbolic = SupernodalSymbolic::from_blocks(&blocks)?;
            if let Some(factor) = SupernodalCholesky::new(symbolic, layout, par) {
                return Ok(Factor::Supernodal(Box::new(factor)));
            }
        }
        SimplicialCholesky::new(blocks, layout)
            .map(Factor::Simplicial)
            .ok_or(SolveError::TooLarge { entries: dim })
    }

    /// faer's symbolic analysis of H's scalar `pattern` under its scalar
    /// AMD, and work space.
    fn faer(
        pattern: SymbolicSparseColMat<usize>,
        threshold: SupernodalThreshold,
        config: &LinearSolverConfig,
    ) -> Result<Factor, SolveError> {
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: threshold,
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(
            pattern.as_ref(),
            Side::Upper,
            SymmetricOrdering::Amd,
            params,
        )
        .map_err(|e| SolveError::Analysis(format!("{e:?}")))?;
        let par = par(config);
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, par),
        ]);
        let scratch = MemBuffer::try_new(req).map_err(|_| SolveError::OutOfMemory)?;
        Ok(Factor::Faer(FaerCholesky {
            values: vec![0.0; symbolic.len_val()],
            pattern,
            symbolic,
            scratch,
            par,
        }))
    }

    /// Whether the factor is supernodal.
    pub fn is_supernodal(&self) -> bool {
        match &self.factor {
            Factor::Simplicial(_) => false,
            Factor::Supernodal(_) => true,
            Factor::Faer(f) => matches!(f.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)),
        }
    }

    /// Number of stored values of the factor L.
    pub fn factor_nnz(&self) -> usize {
        match &self.factor {
            Factor::Simplicial(s) => s.len_val(),
            Factor::Supernodal(s) => s.len_val(),
            Factor::Faer(f) => f.values.len(),
        }
    }

    /// Numeric factorisation of H given by the `values` of its upper
    /// triangle, in the layout the analysis was given.
    ///
    /// # Panics
    ///
    /// If `values` does not hold one value per entry of that layout.
    pub fn factorize(&mut self, values: &[f64]) -> Result<(), NotPositiveDefinite> {
        self.factorize_with(values, None).map(|_| ())
    }

    /// Factorises H and begins solving H x = `rhs` in place: for supernodal
    /// factors the forward substitution runs inside the factorisation,
    /// while each supernode's values are still in cache (one pass over L
    /// fewer). [`Self::finish_solve`] on the same `rhs` completes it; after
    /// an error `rhs` holds nothing useful.
    ///
    /// # Panics
    ///
    /// As [`Self::factorize`].
    pub fn factorize_and_begin_solve(
        &mut self,
        values: &[f64],
        rhs: &mut [f64],
    ) -> Result<BegunSolve, NotPositiveDefinite> {
        let forwarded = self.factorize_with(values, Some(rhs))?;
        Ok(BegunSolve { forwarded })
    }

    /// Completes the solve that [`Self::factorize_and_begin_solve`] began
    /// on `rhs`.
    pub fn finish_solve(&mut self, begun: BegunSolve, rhs: &mut [f64]) {
        match &mut self.factor {
            Factor::Simplicial(s) => s.solve_in_place(rhs),
            Factor::Supernodal(s) if begun.forwarded => s.backward_solve(rhs),
            Factor::Supernodal(s) => s.solve_in_place(rhs),
            Factor::Faer(f) => f.solve_in_place(rhs),
        }
    }

    fn factorize_with(
        &mut self,
        values: &[f64],
        forward: Option<&mut [f64]>,
    ) -> Result<bool, NotPositiveDefinite> {
        assert_eq!(
            values.len(),
            self.nnz,
            "H's values do not match the layout the factor was analysed for"
        );
        self.factored = false;
        let forwarded = match &mut self.factor {
            Factor::Simplicial(s) => s.factorize(values).map(|()| false)?,
            Factor::Supernodal(s) => {
                let forwarded = forward.is_some();
                s.factorize(values, forward).map(|()| forwarded)?
            }
            Factor::Faer(f) => f.factorize(values).map(|()| false)?,
        };
        self.factored = true;
        Ok(forwarded)
    }

    /// H⁻¹ on the pattern of L, from the last successful factorisation
    /// (`None` if there is none).
    pub(crate) fn selected_inverse(&self) -> Option<SelectedInverse> {
        if !self.factored {
            return None;
        }
        Some(match &self.factor {
            Factor::Simplicial(s) => SelectedInverse::from_columns(s.lower_factor(), None),
            Factor::Supernodal(s) => SelectedInverse::from_supernodes(s.supernodes(), None),
            Factor::Faer(f) => f.selected_inverse(),
        })
    }

    /// Solves H x = rhs in place with the last successful factorisation.
    /// Returns `false` (and leaves `rhs` alone) if there is none.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> bool {
        if !self.factored {
            return false;
        }
        match &mut self.factor {
            Factor::Simplicial(s) => s.solve_in_place(rhs),
            Factor::Supernodal(s) => s.solve_in_place(rhs),
            Factor::Faer(f) => f.solve_in_place(rhs),
        }
        true
    }
}

#[cfg(test)]
mod tests;
