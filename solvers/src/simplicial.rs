//! Simplicial (column by column) Cholesky H = LLᵀ that knows H's vertex
//! blocks. Every block of H is dense, so L's pattern is the block pattern's
//! fill expanded: the symbolic analysis runs on the vertex graph (a ninth of
//! the entries of the scalar one for 2D poses), and the numeric factorisation
//! reads each row's pattern from that analysis instead of searching the
//! elimination tree for it row by row, as a general sparse code must (a
//! third of faer's simplicial factorisation time on the 2D benchmark files).
//!
//! L is stored as faer stores a simplicial factor: by columns, each
//! column's diagonal first, then its rows ascending.

use crate::SolveError;
use crate::hessian_layout::HessianLayout;
use crate::linear::NotPositiveDefinite;
use crate::selected_inverse::LowerFactor;
use crate::structure::group_by_key;

/// The factor's structure from the block analysis, before any values.
#[derive(Debug)]
pub struct SimplicialSymbolic {
    /// For each block row K of L, the block columns J < K with L[K, J] ≠ 0
    /// (`row_blocks[row_start[K]..row_start[K + 1]]`), in the order the
    /// elimination tree meets them; [`SimplicialCholesky::new`] sorts them.
    row_start: Vec<usize>,
    row_blocks: Vec<u32>,
    /// Each block's parent in the elimination tree (`u32::MAX` for roots).
    parent: Vec<u32>,
    /// Scalar rows below each block's diagonal block in L.
    degree: Vec<usize>,
    /// First scalar column of each block, and the dimension at the end.
    block_column: Vec<usize>,
    /// Where each scalar column of L starts in the values: its diagonal,
    /// the rest of its diagonal block, then every row of the blocks below.
    col_ptr: Vec<usize>,
}

impl SimplicialSymbolic {
    /// Elimination tree and fill of the block pattern (Liu's algorithm: the
    /// blocks that row K of L reaches are those met walking up the tree from
    /// each block of H's column K), for H laid out by `layout`.
    pub fn analyze(layout: &HessianLayout) -> Result<Self, SolveError> {
        let (pattern, dims) = (layout.blocks(), layout.dims());
        let (nb, dim) = (dims.len(), layout.dim());
        const NONE: usize = usize::MAX;
        let mut parent = vec![NONE; nb];
        let mut degree = vec![0usize; nb];
        let mut visited = vec![NONE; nb];
        let mut row_start = Vec::with_capacity(nb + 1);
        let mut row_blocks: Vec<u32> = Vec::new();
        row_start.push(0);
        for k in 0..nb {
            visited[k] = k;
            for &first in pattern.row_idx_of_col_raw(k) {
                let mut i = first;
                while i < k && visited[i] != k {
                    visited[i] = k;
                    row_blocks.push(i as u32);
                    degree[i] += dims[k];
                    if parent[i] == NONE {
                        parent[i] = k;
                    }
                    i = parent[i];
                }
            }
            row_start.push(row_blocks.len());
        }
        let mut col_ptr = Vec::with_capacity(dim + 1);
        col_ptr.push(0usize);
        let mut len = 0usize;
        for j in 0..nb {
            for c in 0..dims[j] {
                len = len
                    .checked_add(dims[j] - c + degree[j])
                    .ok_or(SolveError::TooLarge {
                        entries: usize::MAX,
                    })?;
                col_ptr.push(len);
            }
        }
        Ok(Self {
            row_start,
            row_blocks,
            parent: parent.iter().map(|&p| p as u32).collect(),
            degree,
            block_column: layout.block_column().to_vec(),
            col_ptr,
        })
    }

    /// Dimension of H.
    pub fn dim(&self) -> usize {
        self.col_ptr.len() - 1
    }

    /// Stored values of L.
    pub fn len_val(&self) -> usize {
        self.col_ptr[self.dim()]
    }

    /// The flops of the factorisation per value of L, counted as faer
    /// counts them to choose between its simplicial and supernodal codes.
    pub fn flops_per_value(&self) -> f64 {
        let flops: f64 = self
            .col_ptr
            .windows(2)
            .map(|w| {
                let c = (w[1] - w[0]) as f64;
                c + c * (c + 1.0) / 2.0
            })
            .sum();
        flops / self.len_val().max(1) as f64
    }

    /// Scalar rows of block `b`.
    fn rows(&self, b: u32) -> std::ops::Range<usize> {
        self.block_column[b as usize]..self.block_column[b as usize + 1]
    }

    /// Block `b`'s parent in the elimination tree.
    pub(crate) fn parent(&self, b: usize) -> Option<usize> {
        Some(self.parent[b] as usize).filter(|_| self.parent[b] != u32::MAX)
    }

    /// Scalar rows below block `b`'s diagonal block in L.
    pub(crate) fn degree(&self, b: usize) -> usize {
        self.degree[b]
    }

    /// For each block column J of L, the block rows K > J with L[K, J] ≠ 0,
    /// ascending: `(start, blocks)` with J's at `start[J]..start[J + 1]`.
    fn columns(&self) -> (Vec<usize>, Vec<u32>) {
        let nb = self.block_column.len() - 1;
        let pairs: Vec<(u32, u32)> = (0..nb)
            .flat_map(|k| self.row(k).iter().map(move |&j| (j, k as u32)))
            .collect();
        // Grouped by column in row order, so ascending too.
        group_by_key(nb, &pairs)
    }

    /// The block columns J < `k` with L[k, J] ≠ 0, in no particular order
    /// (ascending once a simplicial factor holds the analysis).
    pub(crate) fn row(&self, k: usize) -> &[u32] {
        &self.row_blocks[self.row_start[k]..self.row_start[k + 1]]
    }

    /// First scalar column of each block, and the dimension at the end.
    pub(crate) fn block_column(&self) -> &[usize] {
        &self.block_column
    }
}

/// A simplicial factor: its structure, its values and the work space of the
/// numeric factorisation.
#[derive(Debug)]
pub struct SimplicialCholesky {
    symbolic: SimplicialSymbolic,
    /// Row of each value of L.
    row_idx: Vec<u32>,
    values: Vec<f64>,
    /// 1 / L[j, j]: multiplying by it keeps divisions off the dependent
    /// chains of the factorisation and the solves (as faer does).
    inverse_diagonal: Vec<f64>,
    /// Row k of L being formed; all zeros between rows.
    work: Vec<f64>,
    /// Position in `values` of the last value written in each column.
    last: Vec<usize>,
    /// H's layout, through which the factorisation reads H's columns.
    layout: HessianLayout,
}

impl SimplicialCholesky {
    /// Takes the analysis of H (laid out by `layout`, the layout it was
    /// made from) and lays out the factor's rows. `None` if H's dimension
    /// does not fit the `u32` row indices.
    pub fn new(mut symbolic: SimplicialSymbolic, layout: &HessianLayout) -> Option<Self> {
        let n = symbolic.dim();
        u32::try_from(n).ok()?;
        // The factorisation reads each row's columns in ascending order.
        for k in 0..symbolic.row_start.len() - 1 {
            let (start, end) = (symbolic.row_start[k], symbolic.row_start[k + 1]);
            symbolic.row_blocks[start..end].sort_unstable();
        }
        let mut row_idx: Vec<u32> = Vec::with_capacity(symbolic.len_val());
        let (col_start, col_blocks) = symbolic.columns();
        for jb in 0..symbolic.block_column.len() - 1 {
            let cols = symbolic.rows(jb as u32);
            for j in cols.clone() {
                row_idx.extend(j as u32..cols.end as u32);
                for &ib in &col_blocks[col_start[jb]..col_start[jb + 1]] {
                    let rows = symbolic.rows(ib);
                    row_idx.extend(rows.start as u32..rows.end as u32);
                }
            }
        }
        Some(Self {
            values: vec![0.0; row_idx.len()],
            row_idx,
            layout: layout.clone(),
            inverse_diagonal: vec![0.0; n],
            // Up to 6 rows formed at once.
            work: vec![0.0; 6 * n],
            last: vec![0; n],
            symbolic,
        })
    }

    /// Stored values of L.
    pub fn len_val(&self) -> usize {
        self.values.len()
    }

    /// Up-looking factorisation of H, given by the `values` of its upper
    /// triangle in the layout the factor was made with: the rows of L of each block solve a
    /// triangular system with the rows above them, formed in `work` from the
    /// block's columns of H. A block's rows share their pattern, so they are
    /// formed together (up to 6), each value of L above them read once for
    /// all of them; the operations, and so the bits, are those of forming
    /// the rows one by one, as larger blocks are.
    pub fn factorize(&mut self, h: &[f64]) -> Result<(), NotPositiveDefinite> {
        let s = &self.symbolic;
        self.last.copy_from_slice(&s.col_ptr[..s.dim()]);
        for kb in 0..s.block_column.len() - 1 {
            let result = match self.symbolic.rows(kb as u32).len() {
                1 => self.block_rows::<1>(h, kb),
                2 => self.block_rows::<2>(h, kb),
                3 => self.block_rows::<3>(h, kb),
                4 => self.block_rows::<4>(h, kb),
                5 => self.block_rows::<5>(h, kb),
                6 => self.block_rows::<6>(h, kb),
                _ => self.rows_one_by_one(h, kb),
            };
            if result.is_err() {
                self.work.fill(0.0);
                return result;
            }
        }
        Ok(())
    }

    /// Rows of block `kb` (of size B) together: row k + r's entry in column
    /// i of L is formed in `work[i·B + r]`.
    fn block_rows<const B: usize>(
        &mut self,
        h: &[f64],
        kb: usize,
    ) -> Result<(), NotPositiveDefinite> {
        let k = self.symbolic.block_column[kb];
        for r in 0..B {
            self.scatter_column(h, kb, k + r, B, r);
        }
        let Self {
            symbolic: s,
            row_idx,
            values,
            inverse_diagonal,
            work,
            last,
            ..
        } = self;
        // The diagonal block, upper triangle: a[t][r] for row k + r, column k + t.
        let mut a = [[0.0; B]; B];
        for (t, at) in a.iter_mut().enumerate() {
            for r in t..B {
                at[r] = std::mem::take(&mut work[(k + t) * B + r]);
            }
        }
        // The columns of the blocks above, ascending: column j's rows above
        // the block are final, and so is work[j] once every column before j
        // has been subtracted.
        let above = &s.row_blocks[s.row_start[kb]..s.row_start[kb + 1]];
        for j in above.iter().flat_map(|&jb| s.rows(jb)) {
            let mut l = [0.0; B];
            for (lr, w) in l.iter_mut().zip(&mut work[j * B..][..B]) {
                *lr = std::mem::take(w) * inverse_diagonal[j];
            }
            let (top, end) = (s.col_ptr[j] + 1, last[j] + 1);
            for (&i, &lij) in row_idx[top..end].iter().zip(&values[top..end]) {
                for (w, lr) in work[i as usize * B..][..B].iter_mut().zip(&l) {
                    *w -= lij * lr;
                }
            }
            for t in 0..B {
                for r in t..B {
                    a[t][r] -= l[t] * l[r];
                }
            }
            values[end..end + B].copy_from_slice(&l);
            last[j] += B;
        }
        // The diagonal block's own columns.
        let mut lb = [[0.0; B]; B];
        for r in 0..B {
            for t in 0..r {
                let lrt = a[t][r] * inverse_diagonal[k + t];
                lb[r][t] = lrt;
                for i in t + 1..r {
                    a[i][r] -= lb[i][t] * lrt;
                }
                a[r][r] -= lrt * lrt;
                values[s.col_ptr[k + t] + r - t] = lrt;
            }
            let d = a[r][r];
            // Not `d <= 0.0`: a NaN pivot fails too.
            if d.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return Err(NotPositiveDefinite { pivot: k + r + 1 });
            }
            let diagonal = d.sqrt();
            values[s.col_ptr[k + r]] = diagonal;
            inverse_diagonal[k + r] = diagonal.recip();
        }
        for t in 0..B {
            last[k + t] = s.col_ptr[k + t] + B - 1 - t;
        }
        Ok(())
    }

    /// Rows of block `kb` one by one (blocks larger than 6).
    fn rows_one_by_one(&mut self, h: &[f64], kb: usize) -> Result<(), NotPositiveDefinite> {
        let block = self.symbolic.rows(kb as u32);
        for k in block.clone() {
            self.scatter_column(h, kb, k, 1, 0);
            let s = &self.symbolic;
            let above = &s.row_blocks[s.row_start[kb]..s.row_start[kb + 1]];
            let mut d = std::mem::take(&mut self.work[k]);
            // Row k's columns ascending: the blocks above, then the
            // diagonal block's columns left of k.
            let columns = above.iter().flat_map(|&j| s.rows(j)).chain(block.start..k);
            for j in columns {
                self.last[j] += 1;
                let (done, next) = self.values.split_at_mut(self.last[j]);
                let rows = s.col_ptr[j] + 1..self.last[j];
                let lkj = std::mem::take(&mut self.work[j]) * self.inverse_diagonal[j];
                for (&i, &lij) in self.row_idx[rows.clone()].iter().zip(&done[rows]) {
                    self.work[i as usize] -= lij * lkj;
                }
                d -= lkj * lkj;
                next[0] = lkj;
            }
            // Not `d <= 0.0`: a NaN pivot fails too.
            if d.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return Err(NotPositiveDefinite { pivot: k + 1 });
            }
            let diagonal = d.sqrt();
            self.values[s.col_ptr[k]] = diagonal;
            self.inverse_diagonal[k] = diagonal.recip();
        }
        Ok(())
    }

    /// Adds H's column `j` (of block column `kb`) into `work`: its row i
    /// into `work[i·stride + r]`. Its rows are those of the blocks above
    /// the diagonal block, then the diagonal block's down to j.
    fn scatter_column(&mut self, h: &[f64], kb: usize, j: usize, stride: usize, r: usize) {
        let (s, col_ptr) = (&self.symbolic, self.layout.col_ptr());
        let mut values = &h[col_ptr[j]..col_ptr[j + 1]];
        // The blocks above the diagonal block, which comes last.
        let blocks = self.layout.blocks().row_idx_of_col_raw(kb);
        let above = blocks[..blocks.len() - 1]
            .iter()
            .map(|&b| self.layout.columns(b));
        for rows in above.chain(std::iter::once(s.block_column[kb]..j + 1)) {
            let (block, rest) = values.split_at(rows.len());
            for (i, &v) in rows.zip(block) {
                self.work[i * stride + r] += v;
            }
            values = rest;
        }
    }

    /// The factor's columns, for selected inversion (already each column's
    /// diagonal first, then its rows ascending).
    pub(crate) fn lower_factor(&self) -> LowerFactor {
        LowerFactor {
            col_ptr: self.symbolic.col_ptr.clone(),
            row_idx: self.row_idx.iter().map(|&r| r as usize).collect(),
            values: self.values.clone(),
        }
    }

    /// Solves LLᵀ x = rhs in place with the last factorisation.
    pub fn solve_in_place(&self, x: &mut [f64]) {
        let col_ptr = &self.symbolic.col_ptr;
        let below = |j: usize| {
            let range = col_ptr[j] + 1..col_ptr[j + 1];
            self.row_idx[range.clone()].iter().zip(&self.values[range])
        };
        for j in 0..x.len() {
            let xj = x[j] * self.inverse_diagonal[j];
            x[j] = xj;
            for (&i, &lij) in below(j) {
                x[i as usize] -= lij * xj;
            }
        }
        for j in (0..x.len()).rev() {
            let mut xj = x[j];
            for (&i, &lij) in below(j) {
                xj -= lij * x[i as usize];
            }
            x[j] = xj * self.inverse_diagonal[j];
        }
    }
}

#[cfg(test)]
mod tests;
