//! The sparsity pattern of the Hessian H = JᵀΩJ, built once per graph, and
//! where every edge's blocks add into it.
//!
//! On one thread each edge adds its blocks straight into H, in edge order.
//! On more, the edges write their blocks into their own slots of one buffer
//! (in parallel, see [`cairn_core::layout`]) and every entry of H then sums
//! its sources in the same edge order. No locks, and the same bits for any
//! number of threads.

use crate::SolveError;
use crate::hessian_layout::HessianLayout;
use crate::linear::{Blocks, Ordering, block_order};
use cairn_core::Graph;
use cairn_core::layout::{self, BlockTarget, Scatter};
use faer::sparse::{SymbolicSparseColMat, SymbolicSparseColMatRef};

/// The Hessian's fixed structure for one graph and one set of fixed vertices.
#[derive(Debug)]
pub struct HessianStructure {
    /// First column of each vertex in H, `None` for fixed vertices.
    pub column: Vec<Option<usize>>,
    /// Dimension of H.
    pub dim: usize,
    /// Where H's entries sit among its values, by vertex block: one row and
    /// column per free vertex, in column order.
    pub layout: HessianLayout,
    /// Each vertex's block (its position in column order), `u32::MAX` if fixed.
    pub(crate) block_of: Vec<u32>,
    /// Number of edges.
    edges: usize,
    /// Scalars the edges' blocks fill when linearised into a buffer.
    pub(crate) buffer_len: usize,
    /// Where every edge's blocks and gradient segments add into H and the
    /// gradient (for linearising straight into them on one thread), in
    /// edge order, and where each factor group's start in them.
    block_targets: Vec<BlockTarget>,
    column_targets: Vec<u32>,
    group_targets: Vec<[usize; 3]>,
}

/// Groups `(key, item)` pairs by key with a counting sort, keeping each key's
/// items in the order given: `(start, items)` with key k's at `start[k]..start[k + 1]`.
pub(crate) fn group_by_key<T: Copy + Default>(
    keys: usize,
    pairs: &[(u32, T)],
) -> (Vec<usize>, Vec<T>) {
    let mut start = vec![0usize; keys + 1];
    for &(k, _) in pairs {
        start[k as usize + 1] += 1;
    }
    for k in 0..keys {
        start[k + 1] += start[k];
    }
    let mut next = start.clone();
    let mut items = vec![T::default(); pairs.len()];
    for &(k, item) in pairs {
        items[next[k as usize]] = item;
        next[k as usize] += 1;
    }
    (start, items)
}

/// Each vertex's block index: its position in `free`, `u32::MAX` if fixed.
fn block_indices(vertices: usize, free: &[usize]) -> Vec<u32> {
    let mut block_of = vec![u32::MAX; vertices];
    for (k, &v) in free.iter().enumerate() {
        block_of[v] = k as u32;
    }
    block_of
}

/// Pattern of the upper block triangle (`col_ptr`, `row_idx`): for each block
/// column, the block rows that share an edge with it and come no later, sorted.
fn block_pattern(graph: &Graph, block_of: &[u32]) -> (Vec<usize>, Vec<u32>) {
    let blocks = block_of.iter().filter(|&&b| b != u32::MAX).count();
    let mut couplings: Vec<(u32, u32)> = (0..blocks as u32).map(|b| (b, b)).collect();
    for g in graph.factor_groups() {
        for i in 0..g.len() {
            let vs = g.vertices(i);
            for (p, &a) in vs.iter().enumerate() {
                for &b in &vs[p + 1..] {
                    let (ba, bb) = (block_of[a], block_of[b]);
                    if ba != u32::MAX && bb != u32::MAX {
                        couplings.push((ba.max(bb), ba.min(bb)));
                    }
                }
            }
        }
    }
    let (mut col_ptr, mut row_idx) = group_by_key(blocks, &couplings);
    drop(couplings);
    let mut kept = 0;
    for c in 0..blocks {
        let begin = kept;
        let rows = &mut row_idx[col_ptr[c]..col_ptr[c + 1]];
        rows.sort_unstable();
        let mut last = u32::MAX;
        for k in col_ptr[c]..col_ptr[c + 1] {
            let r = row_idx[k];
            if r != last {
                row_idx[kept] = r;
                kept += 1;
                last = r;
            }
        }
        col_ptr[c] = begin;
    }
    col_ptr[blocks] = kept;
    row_idx.truncate(kept);
    (col_ptr, row_idx)
}

/// The upper block triangle (`col_ptr`, `row_idx`) with its blocks
/// renumbered: block `order[k]` becomes block k.
fn permuted(col_ptr: &[usize], row_idx: &[u32], order: &[usize]) -> (Vec<usize>, Vec<u32>) {
    let mut new_index = vec![0u32; order.len()];
    for (k, &b) in order.iter().enumerate() {
        new_index[b] = k as u32;
    }
    let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(row_idx.len());
    for c in 0..order.len() {
        let b = new_index[c];
        for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
            let a = new_index[r as usize];
            pairs.push((a.max(b), a.min(b)));
        }
    }
    let (col_ptr, mut row_idx) = group_by_key(order.len(), &pairs);
    for c in 0..order.len() {
        row_idx[col_ptr[c]..col_ptr[c + 1]].sort_unstable();
    }
    (col_ptr, row_idx)
}

impl HessianStructure {
    /// Builds the structure; `fixed[v]` holds vertex index v constant. The
    /// free vertices take their columns in the block order `ordering` asks
    /// for (block AMD or Schur; vertex order for the others).
    ///
    /// Works block by block (one row and column per free vertex): H's
    /// entries are addressed through its [`HessianLayout`], without scalar
    /// row indices.
    pub fn new(graph: &Graph, fixed: &[bool], ordering: Ordering) -> Result<Self, SolveError> {
        let n = graph.num_vertices();
        let vdim: Vec<usize> = graph.vertices().map(|v| v.kind.dim).collect();
        // Free vertices in column order: the fill-reducing block order when
        // there is one, so that H is assembled already permuted (faer then
        // factorises it as it is, instead of permuting it every iteration).
        let mut free: Vec<usize> = (0..n).filter(|&v| !fixed[v]).collect();
        let (mut block_col_ptr, mut block_row_idx) = block_pattern(graph, &block_indices(n, &free));
        if matches!(ordering, Ordering::BlockAmd | Ordering::Schur) {
            let col_ptr = block_col_ptr.iter().map(|&p| u32::try_from(p).ok());
            let col_ptr: Vec<u32> = col_ptr.collect::<Option<_>>().ok_or(SolveError::TooLarge {
                entries: block_row_idx.len(),
            })?;
            let nb = free.len();
            let pattern =
                SymbolicSparseColMatRef::new_checked(nb, nb, &col_ptr, None, &block_row_idx);
            let dims: Vec<usize> = free.iter().map(|&v| vdim[v]).collect();
            let is_pose: Vec<bool> = free.iter().map(|&v| graph.vertex(v).kind.is_pose).collect();
            let order = block_order(
                Blocks {
                    pattern,
                    dims: &dims,
                    is_pose: &is_pose,
                },
                ordering,
            )?;
            (block_col_ptr, block_row_idx) = permuted(&block_col_ptr, &block_row_idx, &order);
            free = order.iter().map(|&k| free[k]).collect();
        }
        let block_of = block_indices(n, &free);
        let blocks = free.len();
        let hessian = HessianLayout::new(
            SymbolicSparseColMat::new_checked(
                blocks,
                blocks,
                block_col_ptr,
                None,
                block_row_idx.into_iter().map(|r| r as usize).collect(),
            ),
            free.iter().map(|&v| vdim[v]).collect(),
        )?;
        let (block_col_ptr, block_row_idx) =
            (hessian.blocks().col_ptr(), hessian.blocks().row_idx());
        let (column_of_block, col_ptr) = (hessian.block_column(), hessian.col_ptr());
        let column: Vec<Option<usize>> = (0..n)
            .map(|v| (block_of[v] != u32::MAX).then(|| column_of_block[block_of[v] as usize]))
            .collect();
        // Block (r, c), r ≤ c: the diagonal block comes last in its column.
        let block_index = |r: u32, c: u32| -> usize {
            let range = block_col_ptr[c as usize]..block_col_ptr[c as usize + 1];
            match r == c {
                true => range.end - 1,
                false => {
                    range.start
                        + block_row_idx[range]
                            .binary_search(&(r as usize))
                            .unwrap_or(0)
                }
            }
        };
        // Each block of H's entry (0, 0), and the rows above the diagonal in
        // its block column (the diagonal block's offset: it comes last).
        let row_offset = hessian.row_offset();
        let mut block_first = vec![BlockTarget::NONE; block_row_idx.len()];
        for c in 0..blocks {
            let column = col_ptr[column_of_block[c]] as u32;
            let above = row_offset[block_col_ptr[c + 1] - 1];
            for k in block_col_ptr[c]..block_col_ptr[c + 1] {
                block_first[k] = BlockTarget {
                    first: column + row_offset[k],
                    above,
                    transposed: false,
                };
            }
        }
        // Where every edge's blocks and gradient segments add: each block's
        // target in H (transposed for a block below the diagonal), none if
        // a vertex is fixed.
        let groups = graph.factor_groups();
        let arities = || groups.iter().map(|g| (g.len(), g.vertex_dims().len()));
        let mut block_targets =
            Vec::with_capacity(arities().map(|(n, a)| n * a * (a + 1) / 2).sum());
        let mut column_targets = Vec::with_capacity(arities().map(|(n, a)| n * a).sum());
        let mut group_targets = Vec::with_capacity(groups.len());
        let (mut edges, mut buffer_len) = (0, 0);
        for g in groups {
            group_targets.push([block_targets.len(), column_targets.len(), edges]);
            edges += g.len();
            buffer_len += g.len() * layout::stride(g.vertex_dims());
            for i in 0..g.len() {
                let vs = g.vertices(i);
                for (p, &vp) in vs.iter().enumerate() {
                    let bp = block_of[vp];
                    for &vq in &vs[p..] {
                        let bq = block_of[vq];
                        block_targets.push(match bp == u32::MAX || bq == u32::MAX {
                            true => BlockTarget::NONE,
                            false => BlockTarget {
                                transposed: bp > bq,
                                ..block_first[block_index(bp.min(bq), bp.max(bq))]
                            },
                        });
                    }
                    column_targets.push(match bp {
                        u32::MAX => u32::MAX,
                        b => column_of_block[b as usize] as u32,
                    });
                }
            }
        }
        // The parallel assembly addresses the buffer with u32 offsets.
        if buffer_len >= u32::MAX as usize {
            return Err(SolveError::TooLarge {
                entries: buffer_len,
            });
        }

        Ok(Self {
            column,
            dim: hessian.dim(),
            layout: hessian,
            block_of,
            edges,
            buffer_len,
            block_targets,
            column_targets,
            group_targets,
        })
    }

    /// Number of stored entries of the upper triangle of H.
    pub fn nnz(&self) -> usize {
        self.layout.nnz()
    }

    /// Linearises every edge on the calling thread, adding its blocks
    /// straight into `values` (H) and `gradient`, and returns χ²: the same
    /// bits as [`cairn_core::FactorGroup::linearize`] and
    /// [`crate::assembly::Assembly::assemble`], without the buffer between.
    pub fn linearize_into(
        &self,
        graph: &Graph,
        values: &mut [f64],
        gradient: &mut [f64],
        chi2: &mut [f64],
    ) -> f64 {
        // -0.0: the empty sum, as the buffer's assembly starts its sums.
        values.fill(-0.0);
        gradient.fill(-0.0);
        let groups = graph.factor_groups();
        for (k, group) in groups.iter().enumerate() {
            let [b, c, e] = self.group_targets[k];
            let n = group.len();
            let arity = group.vertex_dims().len();
            group.linearize_into(
                graph.values(),
                Scatter {
                    blocks: &self.block_targets[b..b + n * arity * (arity + 1) / 2],
                    columns: &self.column_targets[c..c + n * arity],
                    hessian: values,
                    gradient,
                    chi2: &mut chi2[e..e + n],
                },
            );
        }
        cairn_core::factor::deterministic_sum(chi2.len(), |k| chi2[k])
    }

    /// Number of edges (χ² terms).
    pub fn num_edges(&self) -> usize {
        self.edges
    }
}

#[cfg(test)]
mod tests;
