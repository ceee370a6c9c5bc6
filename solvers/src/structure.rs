//! The sparsity pattern of the Hessian H = JᵀΩJ, built once per graph, and the
//! gather maps that assemble H and the gradient from the edges' slots.
//!
//! Each iteration the edges write their blocks into their own slots of one
//! buffer (in parallel, see [`cairn_core::layout`]); every entry of H then sums
//! its sources in a fixed order. No locks, and the same result for any number
//! of threads.

use crate::SolveError;
use crate::linear::Blocks;
use cairn_core::Graph;
use cairn_core::layout;
use faer::sparse::SymbolicSparseColMat;
use rayon::prelude::*;

/// Entries of H (or the gradient) summed per parallel work item.
const GATHER_CHUNK: usize = 4096;

/// A compressed list of source indices for each target entry.
#[derive(Clone, Debug, Default)]
struct Gather {
    start: Vec<u32>,
    source: Vec<u32>,
}

impl Gather {
    /// Groups `(target, source)` pairs by target with a counting sort, which
    /// keeps each target's sources in the order given (the edges' order, so
    /// every entry is summed in the same order whatever the thread count).
    fn from_pairs(targets: usize, pairs: &[(u32, u32)]) -> Self {
        let mut start = vec![0u32; targets + 1];
        for &(t, _) in pairs {
            start[t as usize + 1] += 1;
        }
        for t in 0..targets {
            start[t + 1] += start[t];
        }
        let mut next = start.clone();
        let mut source = vec![0u32; pairs.len()];
        for &(t, s) in pairs {
            source[next[t as usize] as usize] = s;
            next[t as usize] += 1;
        }
        Self { start, source }
    }

    fn apply(&self, buffer: &[f64], out: &mut [f64]) {
        out.par_chunks_mut(GATHER_CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| {
                let base = c * GATHER_CHUNK;
                for (k, v) in chunk.iter_mut().enumerate() {
                    let (a, b) = (
                        self.start[base + k] as usize,
                        self.start[base + k + 1] as usize,
                    );
                    *v = self.source[a..b].iter().map(|&s| buffer[s as usize]).sum();
                }
            });
    }
}

/// The Hessian's fixed structure for one graph and one set of fixed vertices.
#[derive(Debug)]
pub struct HessianStructure {
    /// First column of each vertex in H, `None` for fixed vertices.
    pub column: Vec<Option<usize>>,
    /// Dimension of H.
    pub dim: usize,
    /// Pattern of the upper triangle of H, columns sorted.
    pub pattern: SymbolicSparseColMat<usize>,
    /// Index into the values of each diagonal entry (for LM damping).
    pub diagonal: Vec<usize>,
    /// Pattern of the upper block triangle: one row and column per free vertex,
    /// in column order (for block-level fill-reducing orderings).
    pub block_pattern: SymbolicSparseColMat<usize>,
    /// Tangent dimension of each free vertex, in column order.
    pub block_dims: Vec<usize>,
    /// Whether each free vertex is a pose, in column order.
    pub block_is_pose: Vec<bool>,
    /// Start of each factor group's region in the linearisation buffer.
    pub group_offset: Vec<usize>,
    /// Length of the linearisation buffer.
    pub buffer_len: usize,
    hessian: Gather,
    gradient: Gather,
    chi2_slots: Vec<u32>,
}

impl HessianStructure {
    /// Builds the structure; `fixed[v]` holds vertex index v constant.
    pub fn new(graph: &Graph, fixed: &[bool]) -> Result<Self, SolveError> {
        let n = graph.num_vertices();
        let mut column = vec![None; n];
        let mut dim = 0;
        for v in graph.vertices() {
            if !fixed[v.index] {
                column[v.index] = Some(dim);
                dim += v.kind.dim;
            }
        }
        let vdim: Vec<usize> = graph.vertices().map(|v| v.kind.dim).collect();

        // Block pattern: for each free vertex (a block column), the free vertices
        // sharing an edge with it that come no later (block rows of the upper triangle).
        let mut rows_of: Vec<Vec<usize>> = (0..n)
            .map(|v| if column[v].is_some() { vec![v] } else { vec![] })
            .collect();
        for g in graph.factor_groups() {
            for i in 0..g.len() {
                let vs = g.vertices(i);
                for (p, &a) in vs.iter().enumerate() {
                    for &b in &vs[p + 1..] {
                        if let (Some(ca), Some(cb)) = (column[a], column[b]) {
                            let (r, c) = if ca < cb { (a, b) } else { (b, a) };
                            rows_of[c].push(r);
                        }
                    }
                }
            }
        }
        let mut block_col_ptr = vec![0usize];
        let mut block_row_idx = Vec::new();
        let block_of: Vec<usize> = {
            let mut b = vec![usize::MAX; n];
            let mut order: Vec<usize> = (0..n).filter(|&v| column[v].is_some()).collect();
            order.sort_by_key(|&v| column[v]);
            for (k, &v) in order.iter().enumerate() {
                b[v] = k;
            }
            b
        };
        let mut col_ptr = Vec::with_capacity(dim + 1);
        let mut row_idx = Vec::new();
        // Offset, within each of a block column's scalar columns, of each block row.
        let mut block_pos: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
        col_ptr.push(0usize);
        let mut free: Vec<usize> = (0..n).filter(|&v| column[v].is_some()).collect();
        free.sort_by_key(|&v| column[v]);
        for &b in &free {
            let rows = &mut rows_of[b];
            rows.sort_unstable_by_key(|&r| column[r]);
            rows.dedup();
            let cb = column[b].unwrap_or(0);
            block_row_idx.extend(rows.iter().map(|&r| block_of[r]));
            block_col_ptr.push(block_row_idx.len());
            let mut pos = 0;
            for &r in rows.iter() {
                block_pos[b].push((r, pos));
                pos += vdim[r];
            }
            for j in 0..vdim[b] {
                for &r in rows.iter() {
                    let cr = column[r].unwrap_or(0);
                    let height = if r == b { j + 1 } else { vdim[r] };
                    row_idx.extend(cr..cr + height);
                }
                col_ptr.push(row_idx.len());
                debug_assert_eq!(row_idx.len() - col_ptr[cb + j], pos - vdim[b] + j + 1);
            }
        }
        if row_idx.len() >= u32::MAX as usize {
            return Err(SolveError::TooLarge {
                entries: row_idx.len(),
            });
        }
        // Where block (r, c), r before or equal to c, starts: its first scalar
        // column and its offset within each of that column's entries. Entry
        // (i, j) of the block is then at col_ptr[column + j] + offset + i.
        let block_start = |r: usize, c: usize| -> (usize, usize) {
            // Block rows are sorted by column.
            let offset = block_pos[c]
                .binary_search_by_key(&column[r], |&(v, _)| column[v])
                .map(|k| block_pos[c][k].1)
                .unwrap_or(0);
            (column[c].unwrap_or(0), offset)
        };
        let diagonal: Vec<usize> = free
            .iter()
            .flat_map(|&v| {
                let (cc, offset) = block_start(v, v);
                let col_ptr = &col_ptr;
                (0..vdim[v]).map(move |j| col_ptr[cc + j] + offset + j)
            })
            .collect();

        let mut group_offset = Vec::new();
        let mut buffer_len = 0usize;
        let mut h_pairs: Vec<(u32, u32)> = Vec::new();
        let mut g_pairs: Vec<(u32, u32)> = Vec::new();
        let mut chi2_slots = Vec::new();
        for g in graph.factor_groups() {
            group_offset.push(buffer_len);
            let dims = g.vertex_dims();
            let stride = layout::stride(dims);
            for i in 0..g.len() {
                let slot = buffer_len + i * stride;
                let vs = g.vertices(i);
                for p in 0..vs.len() {
                    for q in p..vs.len() {
                        let (a, b) = (vs[p], vs[q]);
                        let (Some(ca), Some(cb)) = (column[a], column[b]) else {
                            continue;
                        };
                        let off = slot + layout::block_offset(dims, p, q);
                        // The edge's block (p, q) lands transposed when a's
                        // columns come after b's.
                        let transposed = ca > cb;
                        let (cc, offset) = if transposed {
                            block_start(b, a)
                        } else {
                            block_start(a, b)
                        };
                        for j in 0..dims[q] {
                            for i2 in 0..dims[p] {
                                if p == q && i2 > j {
                                    continue;
                                }
                                let src = (off + i2 + j * dims[p]) as u32;
                                let dst = if transposed {
                                    col_ptr[cc + i2] + offset + j
                                } else {
                                    col_ptr[cc + j] + offset + i2
                                };
                                h_pairs.push((dst as u32, src));
                            }
                        }
                    }
                    if let Some(ca) = column[vs[p]] {
                        let off = slot + layout::gradient_offset(dims, p);
                        g_pairs.extend((0..dims[p]).map(|k| ((ca + k) as u32, (off + k) as u32)));
                    }
                }
                chi2_slots.push((slot + stride - 1) as u32);
            }
            buffer_len += g.len() * stride;
            if buffer_len >= u32::MAX as usize {
                return Err(SolveError::TooLarge {
                    entries: buffer_len,
                });
            }
        }
        let nnz = row_idx.len();
        let pattern = SymbolicSparseColMat::new_checked(dim, dim, col_ptr, None, row_idx);
        let blocks = free.len();
        let block_pattern =
            SymbolicSparseColMat::new_checked(blocks, blocks, block_col_ptr, None, block_row_idx);
        let block_dims = free.iter().map(|&v| vdim[v]).collect();
        let block_is_pose = free.iter().map(|&v| graph.vertex(v).kind.is_pose).collect();
        Ok(Self {
            column,
            dim,
            pattern,
            block_pattern,
            block_dims,
            block_is_pose,
            diagonal,
            group_offset,
            buffer_len,
            hessian: Gather::from_pairs(nnz, &h_pairs),
            gradient: Gather::from_pairs(dim, &g_pairs),
            chi2_slots,
        })
    }

    /// The block structure, for the fill-reducing ordering.
    pub fn blocks(&self) -> Blocks<'_> {
        Blocks {
            pattern: self.block_pattern.as_ref(),
            dims: &self.block_dims,
            is_pose: &self.block_is_pose,
        }
    }

    /// Number of stored entries of the upper triangle of H.
    pub fn nnz(&self) -> usize {
        self.pattern.row_idx().len()
    }

    /// Sums the edges' blocks into the values of H.
    pub fn assemble_hessian(&self, buffer: &[f64], values: &mut [f64]) {
        self.hessian.apply(buffer, values);
    }

    /// Sums the edges' JᵀΩe into the gradient.
    pub fn assemble_gradient(&self, buffer: &[f64], gradient: &mut [f64]) {
        self.gradient.apply(buffer, gradient);
    }

    /// `out = H·x` for the symmetric H whose upper triangle is `values`.
    pub fn hessian_times(&self, values: &[f64], x: &[f64], out: &mut [f64]) {
        out.iter_mut().for_each(|o| *o = 0.0);
        let (col_ptr, row_idx) = (self.pattern.col_ptr(), self.pattern.row_idx());
        for j in 0..self.dim {
            for k in col_ptr[j]..col_ptr[j + 1] {
                let (i, v) = (row_idx[k], values[k]);
                out[i] += v * x[j];
                if i != j {
                    out[j] += v * x[i];
                }
            }
        }
    }

    /// Total χ² stored in the buffer by the last linearisation (deterministic order).
    pub fn chi2(&self, buffer: &[f64]) -> f64 {
        cairn_core::factor::deterministic_sum(self.chi2_slots.len(), |k| {
            buffer[self.chi2_slots[k] as usize]
        })
    }
}
