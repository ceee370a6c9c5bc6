//! Where each entry of H's upper triangle sits among its values.
//!
//! H is stored column by column. Each scalar column lists the rows of its
//! block column's blocks in block-row order, the diagonal block last and
//! only down to the diagonal. So an entry's position follows from the
//! vertex blocks alone: the structure, the assembly and Cairn's
//! factorisations address H through this layout, and the scalar row
//! indices are built only for faer's own factor.

use crate::SolveError;
use faer::sparse::{SymbolicSparseColMat, SymbolicSparseColMatRef};
use std::ops::Range;

/// The layout of H's upper triangle, given by its vertex blocks.
///
/// ```
/// use cairn_solvers::HessianLayout;
/// use faer::sparse::SymbolicSparseColMat;
///
/// // A 3×3 block (an SE2 pose) and a 2×2 one (an XY landmark) coupled:
/// // block column 1 holds block rows 0 and 1.
/// let blocks = SymbolicSparseColMat::new_checked(2, 2, vec![0, 1, 3], None, vec![0, 0, 1]);
/// let layout = HessianLayout::new(blocks, vec![3, 2]).unwrap();
/// assert_eq!(layout.dim(), 5);
/// // The pose's upper triangle (6), then each landmark column: the pose's
/// // 3 rows and the landmark's rows down to the diagonal (4 and 5).
/// assert_eq!(layout.col_ptr(), &[0, 1, 3, 6, 10, 15]);
/// assert_eq!(layout.diagonal().collect::<Vec<_>>(), [0, 2, 5, 9, 14]);
/// ```
#[derive(Clone, Debug)]
pub struct HessianLayout {
    /// Upper block triangle: each column's block rows ascending, the
    /// diagonal block last.
    blocks: SymbolicSparseColMat<usize>,
    /// Tangent dimension of each block.
    dims: Vec<usize>,
    /// First scalar column of each block, and the dimension at the end.
    block_column: Vec<usize>,
    /// Where each scalar column starts among the values, and their number.
    col_ptr: Vec<usize>,
    /// Per block of the pattern, its first row's offset within each of its
    /// scalar columns.
    row_offset: Vec<u32>,
}

impl HessianLayout {
    /// The layout of H whose upper block triangle is `blocks` (each
    /// column's rows ascending, its diagonal block among them), with block
    /// sizes `dims`. Errs on any other pattern, and when H has more entries
    /// than 32-bit positions address.
    pub fn new(blocks: SymbolicSparseColMat<usize>, dims: Vec<usize>) -> Result<Self, SolveError> {
        let nb = dims.len();
        if blocks.nrows() != nb || blocks.ncols() != nb {
            return Err(SolveError::Analysis(format!(
                "a block pattern of {}×{} for {nb} blocks",
                blocks.nrows(),
                blocks.ncols()
            )));
        }
        let mut block_column = Vec::with_capacity(nb + 1);
        let mut dim = 0usize;
        for &d in &dims {
            block_column.push(dim);
            dim += d;
        }
        block_column.push(dim);
        let mut col_ptr = Vec::with_capacity(dim + 1);
        col_ptr.push(0usize);
        let mut row_offset = vec![0u32; blocks.row_idx().len()];
        for c in 0..nb {
            let range = blocks.col_ptr()[c]..blocks.col_ptr()[c + 1];
            let rows = &blocks.row_idx()[range.clone()];
            if rows.last() != Some(&c) || !rows.is_sorted_by(|a, b| a < b) {
                return Err(SolveError::Analysis(format!(
                    "block column {c} is not sorted with its diagonal block last"
                )));
            }
            let mut offset = 0usize;
            for (k, &r) in range.zip(rows) {
                row_offset[k] = offset as u32;
                offset += dims[r];
            }
            let above = offset - dims[c];
            let start = col_ptr[col_ptr.len() - 1];
            col_ptr.extend((1..=dims[c]).map(|j| start + above * j + j * (j + 1) / 2));
            let nnz = start + above * dims[c] + dims[c] * (dims[c] + 1) / 2;
            // The factorisations address H's entries with u32 positions.
            if nnz >= u32::MAX as usize {
                return Err(SolveError::TooLarge { entries: nnz });
            }
        }
        Ok(Self {
            blocks,
            dims,
            block_column,
            col_ptr,
            row_offset,
        })
    }

    /// Dimension of H.
    pub fn dim(&self) -> usize {
        self.col_ptr.len() - 1
    }

    /// Number of stored entries of H's upper triangle.
    pub fn nnz(&self) -> usize {
        self.col_ptr[self.dim()]
    }

    /// The upper block triangle.
    pub fn blocks(&self) -> SymbolicSparseColMatRef<'_, usize> {
        self.blocks.as_ref()
    }

    /// Tangent dimension of each block.
    pub fn dims(&self) -> &[usize] {
        &self.dims
    }

    /// First scalar column of each block, and the dimension at the end.
    pub fn block_column(&self) -> &[usize] {
        &self.block_column
    }

    /// Scalar columns of block `b`.
    pub fn columns(&self, b: usize) -> Range<usize> {
        self.block_column[b]..self.block_column[b + 1]
    }

    /// Where each scalar column starts among the values, and their number
    /// at the end.
    pub fn col_ptr(&self) -> &[usize] {
        &self.col_ptr
    }

    /// Per block of the pattern (in its order), the offset of its first
    /// row within each of its scalar columns.
    pub fn row_offset(&self) -> &[u32] {
        &self.row_offset
    }

    /// Position among the values of each diagonal entry (the last of its
    /// column), column by column.
    pub fn diagonal(&self) -> impl ExactSizeIterator<Item = usize> + '_ {
        self.col_ptr[1..].iter().map(|&end| end - 1)
    }

    /// The scalar pattern of H's upper triangle, for faer's factorisation.
    pub fn scalar_pattern(&self) -> SymbolicSparseColMat<usize> {
        let mut row_idx = Vec::with_capacity(self.nnz());
        let mut above = Vec::new();
        for c in 0..self.dims.len() {
            let blocks = self.blocks.row_idx_of_col_raw(c);
            above.clear();
            for &r in &blocks[..blocks.len() - 1] {
                above.extend(self.columns(r));
            }
            for j in self.columns(c) {
                row_idx.extend_from_slice(&above);
                row_idx.extend(self.block_column[c]..=j);
            }
        }
        let n = self.dim();
        SymbolicSparseColMat::new_checked(n, n, self.col_ptr.clone(), None, row_idx)
    }

    /// `out = H·x` for the symmetric H whose upper triangle is `values`.
    pub fn times(&self, values: &[f64], x: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        let (block_ptr, block_rows) = (self.blocks.col_ptr(), self.blocks.row_idx());
        for c in 0..self.dims.len() {
            for j in self.columns(c) {
                let mut at = self.col_ptr[j];
                let mut sum = 0.0;
                for &r in &block_rows[block_ptr[c]..block_ptr[c + 1]] {
                    let rows = match r == c {
                        true => self.block_column[c]..j,
                        false => self.columns(r),
                    };
                    let h = &values[at..at + rows.len()];
                    for (i, &hij) in rows.clone().zip(h) {
                        out[i] += hij * x[j];
                        sum += hij * x[i];
                    }
                    at += rows.len();
                }
                out[j] += sum + values[at] * x[j];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_matrices::{random_h, upper_times};
    use rand::SeedableRng;
    use rand::rngs::StdRng;

    /// The layout's scalar pattern is the one the test matrices build
    /// entry by entry, its diagonal positions are the diagonal's, and H·x
    /// through the blocks is H·x through the scalar pattern.
    #[test]
    fn the_layout_is_the_scalar_pattern_of_the_blocks() {
        let mut rng = StdRng::seed_from_u64(5);
        for _ in 0..200 {
            let (blocks, dims, scalar, values) = random_h(&mut rng);
            let layout = HessianLayout::new(blocks, dims).unwrap();
            let built = layout.scalar_pattern();
            assert_eq!(built.col_ptr(), scalar.col_ptr());
            assert_eq!(built.row_idx(), scalar.row_idx());
            assert_eq!(layout.nnz(), values.len());
            for (j, d) in layout.diagonal().enumerate() {
                assert_eq!(scalar.row_idx()[d], j);
            }
            let x: Vec<f64> = (0..layout.dim()).map(|i| (i as f64).sin()).collect();
            let mut out = vec![f64::NAN; x.len()];
            layout.times(&values, &x, &mut out);
            for (a, b) in out.iter().zip(upper_times(&scalar, &values, &x)) {
                assert!((a - b).abs() < 1e-12, "{a} against {b}");
            }
        }
    }

    /// A pattern without its diagonal block last, unsorted, or of the wrong
    /// size is refused, not laid out wrong.
    #[test]
    fn malformed_block_patterns_are_refused() {
        let pattern = |col_ptr: Vec<usize>, row_idx: Vec<usize>| {
            SymbolicSparseColMat::new_checked(2, 2, col_ptr, None, row_idx)
        };
        let ok = HessianLayout::new(pattern(vec![0, 1, 3], vec![0, 0, 1]), vec![3, 2]);
        assert_eq!(ok.unwrap().nnz(), 6 + 3 * 2 + 3);
        for bad in [
            (pattern(vec![0, 1, 2], vec![0, 0]), vec![3, 2]),
            (pattern(vec![0, 0, 1], vec![1]), vec![3, 2]),
            (pattern(vec![0, 1, 2], vec![0, 1]), vec![3]),
        ] {
            let err = HessianLayout::new(bad.0, bad.1).unwrap_err();
            assert!(matches!(err, SolveError::Analysis(_)), "{err}");
        }
    }
}
