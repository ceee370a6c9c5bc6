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

/// One edge's contribution to a block of H: where its block starts in the
/// linearisation buffer, and whether it lands transposed (its first vertex's
/// columns come after its second's).
#[derive(Clone, Copy, Debug, Default)]
struct BlockSource {
    offset: u32,
    transposed: bool,
}

/// Groups `(key, item)` pairs by key with a counting sort, keeping each key's
/// items in the order given: `(start, items)` with key k's at `start[k]..start[k + 1]`.
fn group_by_key<T: Copy + Default>(keys: usize, pairs: &[(u32, T)]) -> (Vec<usize>, Vec<T>) {
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

impl HessianStructure {
    /// Builds the structure; `fixed[v]` holds vertex index v constant.
    ///
    /// Works block by block (one row and column per free vertex) and expands
    /// to scalars only at the end, writing the scalar pattern and gather maps
    /// in their final order.
    pub fn new(graph: &Graph, fixed: &[bool]) -> Result<Self, SolveError> {
        let n = graph.num_vertices();
        let vdim: Vec<usize> = graph.vertices().map(|v| v.kind.dim).collect();
        // Free vertices in column order (vertex order), and each one's block index.
        let free: Vec<usize> = (0..n).filter(|&v| !fixed[v]).collect();
        let mut block_of = vec![u32::MAX; n];
        let mut column_of_block = Vec::with_capacity(free.len() + 1);
        let mut dim = 0;
        for (k, &v) in free.iter().enumerate() {
            block_of[v] = k as u32;
            column_of_block.push(dim);
            dim += vdim[v];
        }
        column_of_block.push(dim);
        let column: Vec<Option<usize>> = (0..n)
            .map(|v| (block_of[v] != u32::MAX).then(|| column_of_block[block_of[v] as usize]))
            .collect();
        let blocks = free.len();

        // Block pattern of the upper triangle: for each block column, the block
        // rows that share an edge with it and come no later, sorted.
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
        let (mut block_col_ptr, mut block_row_idx) = group_by_key(blocks, &couplings);
        drop(couplings);
        let mut kept = 0;
        for c in 0..blocks {
            let rows = &mut block_row_idx[block_col_ptr[c]..block_col_ptr[c + 1]];
            rows.sort_unstable();
            let mut last = u32::MAX;
            let begin = kept;
            for k in block_col_ptr[c]..block_col_ptr[c + 1] {
                let r = block_row_idx[k];
                if r != last {
                    block_row_idx[kept] = r;
                    kept += 1;
                    last = r;
                }
            }
            block_col_ptr[c] = begin;
        }
        block_col_ptr[blocks] = kept;
        block_row_idx.truncate(kept);
        let block_index = |r: u32, c: u32| -> usize {
            let range = block_col_ptr[c as usize]..block_col_ptr[c as usize + 1];
            range.start + block_row_idx[range].binary_search(&r).unwrap_or(0)
        };

        // Every edge's blocks and gradient segments, grouped by the block of H
        // (or the vertex) they add to, in edge order.
        let mut group_offset = Vec::new();
        let mut buffer_len = 0usize;
        let mut h_sources: Vec<(u32, BlockSource)> = Vec::new();
        let mut g_sources: Vec<(u32, u32)> = Vec::new();
        let mut chi2_slots = Vec::new();
        for g in graph.factor_groups() {
            group_offset.push(buffer_len);
            let dims = g.vertex_dims();
            let stride = layout::stride(dims);
            if buffer_len + g.len() * stride >= u32::MAX as usize {
                return Err(SolveError::TooLarge {
                    entries: buffer_len + g.len() * stride,
                });
            }
            for i in 0..g.len() {
                let slot = buffer_len + i * stride;
                let vs = g.vertices(i);
                for p in 0..vs.len() {
                    let bp = block_of[vs[p]];
                    if bp == u32::MAX {
                        continue;
                    }
                    for q in p..vs.len() {
                        let bq = block_of[vs[q]];
                        if bq == u32::MAX {
                            continue;
                        }
                        let source = BlockSource {
                            offset: (slot + layout::block_offset(dims, p, q)) as u32,
                            transposed: bp > bq,
                        };
                        h_sources.push((block_index(bp.min(bq), bp.max(bq)) as u32, source));
                    }
                    g_sources.push((bp, (slot + layout::gradient_offset(dims, p)) as u32));
                }
                chi2_slots.push((slot + stride - 1) as u32);
            }
            buffer_len += g.len() * stride;
        }
        let (h_start, h_sources) = group_by_key(block_row_idx.len(), &h_sources);
        let (g_start, g_sources) = group_by_key(blocks, &g_sources);

        // Expand to scalars. H's values are stored column by column; within a
        // scalar column, block row by block row (upper triangle only in the
        // diagonal block). Each entry's sources are listed in that same order.
        let entries = |c: usize, k: usize| -> usize {
            let (r, d) = (block_row_idx[k] as usize, vdim[free[c]]);
            if r == c {
                d * (d + 1) / 2
            } else {
                vdim[free[r]] * d
            }
        };
        let nnz: usize = (0..blocks)
            .flat_map(|c| (block_col_ptr[c]..block_col_ptr[c + 1]).map(move |k| (c, k)))
            .map(|(c, k)| entries(c, k))
            .sum();
        if nnz >= u32::MAX as usize {
            return Err(SolveError::TooLarge { entries: nnz });
        }
        let sourced: usize = (0..blocks)
            .flat_map(|c| (block_col_ptr[c]..block_col_ptr[c + 1]).map(move |k| (c, k)))
            .map(|(c, k)| entries(c, k) * (h_start[k + 1] - h_start[k]))
            .sum();
        let mut col_ptr = Vec::with_capacity(dim + 1);
        let mut row_idx = Vec::with_capacity(nnz);
        let mut hessian = Gather {
            start: Vec::with_capacity(nnz + 1),
            source: Vec::with_capacity(sourced),
        };
        let mut diagonal = Vec::with_capacity(dim);
        col_ptr.push(0usize);
        hessian.start.push(0);
        for c in 0..blocks {
            let (cc, dc) = (column_of_block[c], vdim[free[c]]);
            for j in 0..dc {
                for k in block_col_ptr[c]..block_col_ptr[c + 1] {
                    let r = block_row_idx[k] as usize;
                    let (cr, dr) = (column_of_block[r], vdim[free[r]]);
                    let height = if r == c { j + 1 } else { dr };
                    if r == c {
                        diagonal.push(row_idx.len() + j);
                    }
                    row_idx.extend(cr..cr + height);
                    let sources = &h_sources[h_start[k]..h_start[k + 1]];
                    for i in 0..height {
                        // A transposed source is stored dc × dr, column-major.
                        hessian.source.extend(sources.iter().map(|s| {
                            s.offset
                                + if s.transposed {
                                    (j + i * dc) as u32
                                } else {
                                    (i + j * dr) as u32
                                }
                        }));
                        hessian.start.push(hessian.source.len() as u32);
                    }
                }
                col_ptr.push(row_idx.len());
            }
            debug_assert_eq!(col_ptr.len(), cc + dc + 1);
        }
        let mut gradient = Gather {
            start: Vec::with_capacity(dim + 1),
            source: Vec::with_capacity(g_sources.len() * 6),
        };
        gradient.start.push(0);
        for c in 0..blocks {
            for i in 0..vdim[free[c]] {
                let sources = &g_sources[g_start[c]..g_start[c + 1]];
                gradient
                    .source
                    .extend(sources.iter().map(|&o| o + i as u32));
                gradient.start.push(gradient.source.len() as u32);
            }
        }

        let pattern = SymbolicSparseColMat::new_checked(dim, dim, col_ptr, None, row_idx);
        let block_pattern = SymbolicSparseColMat::new_checked(
            blocks,
            blocks,
            block_col_ptr,
            None,
            block_row_idx.into_iter().map(|r| r as usize).collect(),
        );
        Ok(Self {
            column,
            dim,
            pattern,
            block_pattern,
            block_dims: free.iter().map(|&v| vdim[v]).collect(),
            block_is_pose: free.iter().map(|&v| graph.vertex(v).kind.is_pose).collect(),
            diagonal,
            group_offset,
            buffer_len,
            hessian,
            gradient,
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

#[cfg(test)]
mod tests {
    use super::*;
    use cairn_core::{EdgePriorSE2, EdgeSE2, EdgeSE2XY, SE2};
    use nalgebra::{DMatrix, Matrix2, Matrix3, Vector2};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// A random graph of poses and landmarks, some fixed, with odometry,
    /// loop closures, sightings and priors added in a shuffled vertex order.
    fn random_graph(rng: &mut StdRng) -> (Graph, Vec<bool>) {
        let mut g = Graph::new();
        let (poses, landmarks) = (rng.random_range(2..12), rng.random_range(0..8));
        // Ids interleave poses and landmarks so block order differs from edge order.
        let mut ids: Vec<i64> = (0..poses + landmarks).collect();
        for i in (1..ids.len()).rev() {
            ids.swap(i, rng.random_range(0..=i));
        }
        let (pose_ids, landmark_ids) = ids.split_at(poses as usize);
        for &p in pose_ids {
            g.add_vertex(p, SE2::new(rng.random(), rng.random(), 0.1))
                .unwrap();
        }
        for &l in landmark_ids {
            g.add_vertex(l, Vector2::new(rng.random(), rng.random()))
                .unwrap();
        }
        for _ in 0..rng.random_range(1..30) {
            let a = pose_ids[rng.random_range(0..pose_ids.len())];
            match rng.random_range(0..3) {
                0 => {
                    let b = pose_ids[rng.random_range(0..pose_ids.len())];
                    if a != b {
                        let edge = EdgeSE2::new(SE2::new(1.0, 0.0, 0.0));
                        g.add_edge(a, b, edge, Matrix3::identity()).unwrap();
                    }
                }
                1 if !landmark_ids.is_empty() => {
                    let l = landmark_ids[rng.random_range(0..landmark_ids.len())];
                    let edge = EdgeSE2XY::new(Vector2::new(1.0, 0.0));
                    g.add_edge(a, l, edge, Matrix2::identity()).unwrap();
                }
                _ => {
                    let edge = EdgePriorSE2::new(SE2::identity());
                    g.add_unary_edge(a, edge, Matrix3::identity()).unwrap();
                }
            }
        }
        let fixed = (0..g.num_vertices())
            .map(|_| rng.random_bool(0.2))
            .collect();
        (g, fixed)
    }

    /// H and the gradient assembled from a buffer of random blocks equal the
    /// dense sums of every edge's blocks at its vertices' columns.
    #[test]
    fn assembly_matches_a_dense_sum_of_the_edges_blocks() {
        let mut rng = StdRng::seed_from_u64(7);
        for _ in 0..200 {
            let (graph, fixed) = random_graph(&mut rng);
            let s = HessianStructure::new(&graph, &fixed).unwrap();
            let mut buffer: Vec<f64> = (0..s.buffer_len).map(|_| rng.random()).collect();
            let mut dense = DMatrix::<f64>::zeros(s.dim, s.dim);
            let mut dense_gradient = vec![0.0; s.dim];
            for (g, &start) in graph.factor_groups().iter().zip(&s.group_offset) {
                let dims = g.vertex_dims();
                let stride = layout::stride(dims);
                for e in 0..g.len() {
                    let slot = start + e * stride;
                    let vs = g.vertices(e);
                    for p in 0..vs.len() {
                        let Some(cp) = s.column[vs[p]] else { continue };
                        for q in p..vs.len() {
                            let Some(cq) = s.column[vs[q]] else { continue };
                            let off = slot + layout::block_offset(dims, p, q);
                            for j in 0..dims[q] {
                                for i in 0..dims[p] {
                                    let k = off + i + j * dims[p];
                                    if p == q && i > j {
                                        // Diagonal blocks are symmetric.
                                        buffer[k] = buffer[off + j + i * dims[p]];
                                    }
                                    dense[(cp + i, cq + j)] += buffer[k];
                                    if p != q {
                                        dense[(cq + j, cp + i)] += buffer[k];
                                    }
                                }
                            }
                        }
                        let off = slot + layout::gradient_offset(dims, p);
                        for i in 0..dims[p] {
                            dense_gradient[cp + i] += buffer[off + i];
                        }
                    }
                }
            }
            let mut values = vec![0.0; s.nnz()];
            s.assemble_hessian(&buffer, &mut values);
            let (col_ptr, row_idx) = (s.pattern.col_ptr(), s.pattern.row_idx());
            let mut seen = DMatrix::<f64>::zeros(s.dim, s.dim);
            for j in 0..s.dim {
                assert!(row_idx[col_ptr[j]..col_ptr[j + 1]].is_sorted());
                for k in col_ptr[j]..col_ptr[j + 1] {
                    let i = row_idx[k];
                    assert!(i <= j);
                    assert!((values[k] - dense[(i, j)]).abs() < 1e-12, "H({i}, {j})");
                    seen[(i, j)] = 1.0;
                }
            }
            // Nothing outside the pattern: every structural entry of the dense sum is stored.
            for j in 0..s.dim {
                for i in 0..=j {
                    assert!(dense[(i, j)] == 0.0 || seen[(i, j)] == 1.0, "({i}, {j})");
                }
                assert_eq!(s.pattern.row_idx()[s.diagonal[j]], j);
                assert!(col_ptr[j] <= s.diagonal[j] && s.diagonal[j] < col_ptr[j + 1]);
            }
            let mut gradient = vec![0.0; s.dim];
            s.assemble_gradient(&buffer, &mut gradient);
            for (a, b) in gradient.iter().zip(&dense_gradient) {
                assert!((a - b).abs() < 1e-12);
            }
        }
    }
}
