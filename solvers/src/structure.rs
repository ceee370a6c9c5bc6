//! The sparsity pattern of the Hessian H = JᵀΩJ, built once per graph, and
//! where every edge's blocks add into it.
//!
//! On one thread each edge adds its blocks straight into H, in edge order.
//! On more, the edges write their blocks into their own slots of one buffer
//! (in parallel, see [`cairn_core::layout`]) and every entry of H then sums
//! its sources in the same edge order. No locks, and the same bits for any
//! number of threads.

use crate::SolveError;
use crate::linear::{Blocks, Ordering, block_order};
use cairn_core::Graph;
use cairn_core::layout::{self, BlockTarget, Scatter};
use faer::sparse::SymbolicSparseColMat;

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
    /// Each vertex's block (its position in column order), `u32::MAX` if fixed.
    pub(crate) block_of: Vec<u32>,
    /// First scalar column of each block column (and `dim` at the end).
    pub(crate) block_column: Vec<usize>,
    /// Offset of each block's first row within each of its scalar columns.
    pub(crate) row_offset: Vec<u32>,
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
    let new_index = &new_index;
    let pairs: Vec<(u32, u32)> = (0..order.len())
        .flat_map(|c| {
            row_idx[col_ptr[c]..col_ptr[c + 1]].iter().map(move |&r| {
                let (a, b) = (new_index[r as usize], new_index[c]);
                (a.max(b), a.min(b))
            })
        })
        .collect();
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
    /// Works block by block (one row and column per free vertex); only the
    /// scalar pattern that the Cholesky needs is expanded.
    pub fn new(graph: &Graph, fixed: &[bool], ordering: Ordering) -> Result<Self, SolveError> {
        let n = graph.num_vertices();
        let vdim: Vec<usize> = graph.vertices().map(|v| v.kind.dim).collect();
        // Free vertices in column order: the fill-reducing block order when
        // there is one, so that H is assembled already permuted (faer then
        // factorises it as it is, instead of permuting it every iteration).
        let mut free: Vec<usize> = (0..n).filter(|&v| !fixed[v]).collect();
        let (mut block_col_ptr, mut block_row_idx) = block_pattern(graph, &block_indices(n, &free));
        if matches!(ordering, Ordering::BlockAmd | Ordering::Schur) {
            let pattern = SymbolicSparseColMat::new_checked(
                free.len(),
                free.len(),
                block_col_ptr.clone(),
                None,
                block_row_idx.iter().map(|&r| r as usize).collect(),
            );
            let dims: Vec<usize> = free.iter().map(|&v| vdim[v]).collect();
            let is_pose: Vec<bool> = free.iter().map(|&v| graph.vertex(v).kind.is_pose).collect();
            let order = block_order(
                Blocks {
                    pattern: pattern.as_ref(),
                    dims: &dims,
                    is_pose: &is_pose,
                },
                ordering,
            )?;
            (block_col_ptr, block_row_idx) = permuted(&block_col_ptr, &block_row_idx, &order);
            free = order.iter().map(|&k| free[k]).collect();
        }
        let block_of = block_indices(n, &free);
        let mut column_of_block = Vec::with_capacity(free.len() + 1);
        let mut dim = 0;
        for &v in &free {
            column_of_block.push(dim);
            dim += vdim[v];
        }
        column_of_block.push(dim);
        let column: Vec<Option<usize>> = (0..n)
            .map(|v| (block_of[v] != u32::MAX).then(|| column_of_block[block_of[v] as usize]))
            .collect();
        let blocks = free.len();
        // Block (r, c), r ≤ c: the diagonal block comes last in its column.
        let block_index = |r: u32, c: u32| -> usize {
            let range = block_col_ptr[c as usize]..block_col_ptr[c as usize + 1];
            match r == c {
                true => range.end - 1,
                false => range.start + block_row_idx[range].binary_search(&r).unwrap_or(0),
            }
        };

        // Where every edge's blocks and gradient segments add: (block of H,
        // transposed) for each block, u32::MAX if a vertex is fixed.
        let mut targets: Vec<(u32, bool)> = Vec::new();
        let mut column_targets = Vec::new();
        let mut group_targets = Vec::new();
        let (mut edges, mut buffer_len) = (0, 0);
        for g in graph.factor_groups() {
            group_targets.push([targets.len(), column_targets.len(), edges]);
            edges += g.len();
            buffer_len += g.len() * layout::stride(g.vertex_dims());
            for i in 0..g.len() {
                let vs = g.vertices(i);
                for (p, &vp) in vs.iter().enumerate() {
                    let bp = block_of[vp];
                    for &vq in &vs[p..] {
                        let bq = block_of[vq];
                        targets.push(match bp == u32::MAX || bq == u32::MAX {
                            true => (u32::MAX, false),
                            false => (block_index(bp.min(bq), bp.max(bq)) as u32, bp > bq),
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

        // The scalar pattern: column by column; within a scalar column, block
        // row by block row (only the upper triangle of the diagonal block).
        let nnz: usize = (0..blocks)
            .map(|c| {
                let d = vdim[free[c]];
                let above: usize = block_row_idx[block_col_ptr[c]..block_col_ptr[c + 1] - 1]
                    .iter()
                    .map(|&r| vdim[free[r as usize]])
                    .sum();
                above * d + d * (d + 1) / 2
            })
            .sum();
        if nnz >= u32::MAX as usize {
            return Err(SolveError::TooLarge { entries: nnz });
        }
        let mut col_ptr = Vec::with_capacity(dim + 1);
        let mut row_idx = Vec::with_capacity(nnz);
        let mut row_offset = vec![0u32; block_row_idx.len()];
        let mut diagonal = Vec::with_capacity(dim);
        let mut above = Vec::new();
        col_ptr.push(0usize);
        for c in 0..blocks {
            let dc = vdim[free[c]];
            let mut offset = 0;
            for k in block_col_ptr[c]..block_col_ptr[c + 1] {
                row_offset[k] = offset as u32;
                offset += vdim[free[block_row_idx[k] as usize]];
            }
            // The rows above the diagonal block (it comes last), the same
            // in every scalar column of the block column.
            above.clear();
            for &r in &block_row_idx[block_col_ptr[c]..block_col_ptr[c + 1] - 1] {
                let cr = column_of_block[r as usize];
                above.extend(cr..cr + vdim[free[r as usize]]);
            }
            let cc = column_of_block[c];
            for j in 0..dc {
                row_idx.extend_from_slice(&above);
                diagonal.push(row_idx.len() + j);
                row_idx.extend(cc..=cc + j);
                col_ptr.push(row_idx.len());
            }
        }
        // Each block of H's entry (0, 0), and the rows above the diagonal in
        // its block column (the diagonal block's offset: it comes last).
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
        let block_targets = targets
            .into_iter()
            .map(|(k, transposed)| match k {
                u32::MAX => BlockTarget::NONE,
                k => BlockTarget {
                    transposed,
                    ..block_first[k as usize]
                },
            })
            .collect();

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
            diagonal,
            block_of,
            block_column: column_of_block,
            row_offset,
            edges,
            buffer_len,
            block_targets,
            column_targets,
            group_targets,
        })
    }

    /// Number of stored entries of the upper triangle of H.
    pub fn nnz(&self) -> usize {
        self.pattern.row_idx().len()
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::Assembly;
    use cairn_core::{EdgePriorSE2, EdgeSE2, EdgeSE2XY, EdgeSE3, RobustKernel, SE2, SE3};
    use nalgebra::{Matrix2, Matrix3, Matrix6, UnitQuaternion, Vector2, Vector3};
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};
    use std::collections::{HashMap, HashSet};

    /// A random graph of up to `size` poses and as many landmarks, some
    /// fixed, with odometry, loop closures, sightings and priors, the ids
    /// shuffled so that block order differs from edge order.
    fn random_graph(rng: &mut StdRng, size: usize) -> (Graph, Vec<bool>) {
        let mut g = Graph::new();
        let (poses, landmarks) = (rng.random_range(2..size), rng.random_range(0..size));
        let mut ids: Vec<i64> = (0..(poses + landmarks) as i64).collect();
        for i in (1..ids.len()).rev() {
            ids.swap(i, rng.random_range(0..=i));
        }
        let (pose_ids, landmark_ids) = ids.split_at(poses);
        for &p in pose_ids {
            g.add_vertex(p, SE2::new(rng.random(), rng.random(), 0.1))
                .unwrap();
        }
        for &l in landmark_ids {
            g.add_vertex(l, Vector2::new(rng.random(), rng.random()))
                .unwrap();
        }
        for _ in 0..rng.random_range(1..3 * size) {
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

    /// Linearising straight into H on one thread gives exactly the bits of
    /// linearising into the buffer and assembling from it: H, the gradient
    /// and χ², with fixed vertices, landmarks, priors and robust kernels,
    /// in every block order, on SE2 and SE3 graphs.
    #[test]
    fn linearizing_into_h_matches_the_buffer_bit_for_bit() {
        let mut rng = StdRng::seed_from_u64(11);
        let orderings = [Ordering::BlockAmd, Ordering::Identity, Ordering::Schur];
        let mut graphs: Vec<(Graph, Vec<bool>)> = (0..60)
            .map(|k| random_graph(&mut rng, if k % 10 == 0 { 400 } else { 15 }))
            .collect();
        for _ in 0..10 {
            graphs.push(random_se3_graph(&mut rng));
        }
        for (k, (mut graph, fixed)) in graphs.into_iter().enumerate() {
            for v in 0..graph.num_vertices() {
                let dim = graph.vertex(v).kind.dim;
                let delta: Vec<f64> = (0..dim).map(|_| rng.random_range(-0.5..0.5)).collect();
                graph.oplus(v, &delta);
            }
            for e in 0..graph.num_edges() {
                let kernel = [
                    None,
                    Some(RobustKernel::Huber(0.5)),
                    Some(RobustKernel::Cauchy(1.0)),
                ][rng.random_range(0..3)];
                graph.set_robust_kernel(e, kernel);
            }
            let s = HessianStructure::new(&graph, &fixed, orderings[k % 3]).unwrap();
            let a = Assembly::new(&s, &graph);
            let mut buffer = vec![0.0; a.buffer_len];
            for (g, &start) in graph.factor_groups().iter().zip(&a.group_offset) {
                let len = g.len() * layout::stride(g.vertex_dims());
                g.linearize(graph.values(), &mut buffer[start..start + len]);
            }
            let (mut h1, mut g1) = (vec![f64::NAN; s.nnz()], vec![f64::NAN; s.dim]);
            a.assemble(&s, &buffer, &mut h1, &mut g1);
            let (mut h2, mut g2) = (vec![f64::NAN; s.nnz()], vec![f64::NAN; s.dim]);
            let mut terms = vec![f64::NAN; s.num_edges()];
            let chi2 = s.linearize_into(&graph, &mut h2, &mut g2, &mut terms);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&h1), bits(&h2), "graph {k}: H");
            assert_eq!(bits(&g1), bits(&g2), "graph {k}: gradient");
            assert_eq!(a.chi2(&buffer).to_bits(), chi2.to_bits(), "graph {k}: χ²");
            assert!(chi2 > 0.0);
        }
    }

    /// A random SE3 pose graph (odometry chain and loop closures), some
    /// vertices fixed, ids shuffled.
    fn random_se3_graph(rng: &mut StdRng) -> (Graph, Vec<bool>) {
        let mut g = Graph::new();
        let n = rng.random_range(3..40);
        let mut ids: Vec<i64> = (0..n as i64).collect();
        for i in (1..ids.len()).rev() {
            ids.swap(i, rng.random_range(0..=i));
        }
        let pose = |rng: &mut StdRng| {
            let t = Vector3::new(rng.random(), rng.random(), rng.random());
            let r = UnitQuaternion::from_euler_angles(rng.random(), rng.random(), rng.random());
            SE3::new(t, r)
        };
        for &id in &ids {
            g.add_vertex(id, pose(rng)).unwrap();
        }
        let mut information = Matrix6::identity();
        information[(0, 4)] = 0.3;
        information[(4, 0)] = 0.3;
        for i in 1..n {
            g.add_edge(ids[i - 1], ids[i], EdgeSE3::new(pose(rng)), information)
                .unwrap();
        }
        for _ in 0..n {
            let (a, b) = (rng.random_range(0..n), rng.random_range(0..n));
            if a != b {
                g.add_edge(ids[a], ids[b], EdgeSE3::new(pose(rng)), information)
                    .unwrap();
            }
        }
        let fixed = (0..n).map(|_| rng.random_bool(0.2)).collect();
        (g, fixed)
    }

    /// H and the gradient assembled from a buffer of random blocks equal the
    /// sums of every edge's blocks at its vertices' columns, on small graphs
    /// and on graphs large enough to be assembled in several parallel parts,
    /// with the vertices' columns in their own order and in fill-reducing ones.
    #[test]
    fn assembly_matches_a_plain_sum_of_the_edges_blocks() {
        let mut rng = StdRng::seed_from_u64(7);
        let orderings = [Ordering::BlockAmd, Ordering::Identity, Ordering::Schur];
        for (k, size) in [12; 200].into_iter().chain([3000; 4]).enumerate() {
            let (graph, fixed) = random_graph(&mut rng, size);
            let s = HessianStructure::new(&graph, &fixed, orderings[k % 3]).unwrap();
            let a = Assembly::new(&s, &graph);
            let mut buffer: Vec<f64> = (0..a.buffer_len).map(|_| rng.random()).collect();
            // Every (row, column) of H, both triangles, and the gradient.
            let mut expected: HashMap<(usize, usize), f64> = HashMap::new();
            let mut expected_gradient = vec![0.0; s.dim];
            for (g, &start) in graph.factor_groups().iter().zip(&a.group_offset) {
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
                                    *expected.entry((cp + i, cq + j)).or_default() += buffer[k];
                                    if p != q {
                                        *expected.entry((cq + j, cp + i)).or_default() += buffer[k];
                                    }
                                }
                            }
                        }
                        let off = slot + layout::gradient_offset(dims, p);
                        for i in 0..dims[p] {
                            expected_gradient[cp + i] += buffer[off + i];
                        }
                    }
                }
            }
            let mut values = vec![f64::NAN; s.nnz()];
            let mut gradient = vec![f64::NAN; s.dim];
            a.assemble(&s, &buffer, &mut values, &mut gradient);
            let (col_ptr, row_idx) = (s.pattern.col_ptr(), s.pattern.row_idx());
            let mut stored = HashSet::new();
            for j in 0..s.dim {
                assert!(row_idx[col_ptr[j]..col_ptr[j + 1]].is_sorted());
                for k in col_ptr[j]..col_ptr[j + 1] {
                    let i = row_idx[k];
                    assert!(i <= j);
                    let want = expected.get(&(i, j)).copied().unwrap_or(0.0);
                    assert!((values[k] - want).abs() < 1e-9, "H({i}, {j})");
                    stored.insert((i, j));
                }
                assert_eq!(row_idx[s.diagonal[j]], j);
                assert!(col_ptr[j] <= s.diagonal[j] && s.diagonal[j] < col_ptr[j + 1]);
            }
            // Nothing outside the pattern.
            for &(i, j) in expected.keys() {
                assert!(stored.contains(&(i.min(j), i.max(j))), "({i}, {j})");
            }
            for (a, b) in gradient.iter().zip(&expected_gradient) {
                assert!((a - b).abs() < 1e-9);
            }
            if size > 1000 {
                assert!(a.chunks.len() > 3, "{} parts", a.chunks.len() - 1);
            }
        }
    }
}
