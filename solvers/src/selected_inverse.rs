//! Selected inversion: the entries of H⁻¹ on the pattern of its Cholesky
//! factor L, by Takahashi, Fagan and Chen's recurrences. The pattern holds
//! every vertex's diagonal block, so one pass gives every marginal
//! covariance for about the cost of a factorisation, where solving for H⁻¹'s
//! columns costs a pair of triangular solves per column (g2o's marginals use
//! the same recurrences, entry by entry). Supernodal factors run them a
//! supernode at a time on dense blocks (Lin et al.'s SelInv), as their
//! factorisation does; column factors, which are sparse, a column at a time.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_inverse::invert_lower_triangular;
use faer::linalg::triangular_solve::solve_upper_triangular_in_place;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, MatMut, MatRef, Par};

/// A lower-triangular factor L (H = LLᵀ, or P H Pᵀ = LLᵀ) by columns: each
/// column's diagonal first, then its other rows ascending.
#[derive(Debug)]
pub(crate) struct LowerFactor {
    pub(crate) col_ptr: Vec<usize>,
    pub(crate) row_idx: Vec<usize>,
    pub(crate) values: Vec<f64>,
}

/// A supernodal factor: supernode s holds columns `begin[s]..end[s]`, its
/// values `values[val_ptr[s]..val_ptr[s + 1]]` column-major, the diagonal
/// block's rows first, then the rows `row_idx[row_ptr[s]..]` below it.
#[derive(Debug)]
pub(crate) struct Supernodes {
    pub(crate) begin: Vec<usize>,
    pub(crate) end: Vec<usize>,
    pub(crate) val_ptr: Vec<usize>,
    pub(crate) row_ptr: Vec<usize>,
    pub(crate) row_idx: Vec<usize>,
    pub(crate) values: Vec<f64>,
}

impl Supernodes {
    /// (first column, width, rows, rows below the diagonal block) of `s`.
    fn shape(&self, s: usize) -> (usize, usize, usize, &[usize]) {
        let (start, size) = (self.begin[s], self.end[s] - self.begin[s]);
        let rows = (self.val_ptr[s + 1] - self.val_ptr[s]) / size;
        (
            start,
            size,
            rows,
            &self.row_idx[self.row_ptr[s]..][..rows - size],
        )
    }
}

impl LowerFactor {
    /// Sorts each column's rows (the diagonal, the least, comes first).
    pub(crate) fn sort_columns(&mut self) {
        let mut column: Vec<(usize, f64)> = Vec::new();
        for j in 0..self.col_ptr.len() - 1 {
            let range = self.col_ptr[j]..self.col_ptr[j + 1];
            column.clear();
            column.extend(
                self.row_idx[range.clone()]
                    .iter()
                    .copied()
                    .zip(self.values[range.clone()].iter().copied()),
            );
            column.sort_unstable_by_key(|&(row, _)| row);
            for ((row, value), (r, v)) in column.iter().zip(
                self.row_idx[range.clone()]
                    .iter_mut()
                    .zip(&mut self.values[range]),
            ) {
                (*r, *v) = (*row, *value);
            }
        }
    }
}

/// H⁻¹ on the pattern of L.
#[derive(Debug)]
pub(crate) struct SelectedInverse {
    /// Z = H⁻¹ laid out as L is.
    z: Layout,
    /// The column of L of each column of H, when the factor is permuted.
    position: Option<Vec<usize>>,
}

#[derive(Debug)]
enum Layout {
    Columns(LowerFactor),
    Supernodes {
        supernodes: Supernodes,
        /// The supernode of each column.
        owner: Vec<usize>,
    },
}

const NONE: usize = usize::MAX;

impl SelectedInverse {
    /// Runs the recurrences from the last column to the first:
    ///
    /// Z[i, j] = −(1 / L[j, j]) Σₖ L[k, j] Z[i, k] for i > j in L's column j,
    /// Z[j, j] = (1 / L[j, j]) (1 / L[j, j] − Σₖ L[k, j] Z[k, j]),
    ///
    /// k over the rows of column j below its diagonal. Every Z[i, k] they
    /// read lies in a later column's pattern, since the rows of a column of
    /// L that are below k are rows of column k.
    pub(crate) fn from_columns(factor: LowerFactor, position: Option<Vec<usize>>) -> Self {
        let LowerFactor {
            col_ptr,
            row_idx,
            values,
        } = factor;
        let n = col_ptr.len() - 1;
        let mut z = vec![0.0; values.len()];
        // Where each row of the current column sits in it.
        let mut slot = vec![NONE; n];
        let mut sum = Vec::new();
        for j in (0..n).rev() {
            let (diagonal, end) = (col_ptr[j], col_ptr[j + 1]);
            let rows = &row_idx[diagonal + 1..end];
            let l = &values[diagonal + 1..end];
            let Some(&last) = rows.last() else {
                z[diagonal] = values[diagonal].powi(-2);
                continue;
            };
            for (a, &r) in rows.iter().enumerate() {
                slot[r] = a;
            }
            // sum[a] = Σₖ L[k, j] Z[rows[a], k], each pair of rows once.
            sum.clear();
            sum.resize(rows.len(), 0.0);
            for (b, &k) in rows.iter().enumerate() {
                let lk = l[b];
                sum[b] += lk * z[col_ptr[k]];
                for q in col_ptr[k] + 1..col_ptr[k + 1] {
                    let r = row_idx[q];
                    if r > last {
                        break;
                    }
                    let a = slot[r];
                    if a != NONE {
                        sum[a] += lk * z[q];
                        sum[b] += l[a] * z[q];
                    }
                }
            }
            let d = values[diagonal];
            let mut zjj = 1.0 / d;
            for (a, s) in sum.iter().enumerate() {
                let zij = -s / d;
                z[diagonal + 1 + a] = zij;
                zjj -= l[a] * zij;
            }
            z[diagonal] = zjj / d;
            for &r in rows {
                slot[r] = NONE;
            }
        }
        let z = LowerFactor {
            col_ptr,
            row_idx,
            values: z,
        };
        Self {
            z: Layout::Columns(z),
            position,
        }
    }

    /// The same recurrences a supernode s at a time, its columns J and the
    /// rows I below them: with L̂ = L[I, J] L[J, J]⁻¹,
    ///
    /// Z[I, J] = −Z[I, I] L̂,
    /// Z[J, J] = L[J, J]⁻ᵀ L[J, J]⁻¹ − L̂ᵀ Z[I, J],
    ///
    /// Z[I, I] gathered from the later supernodes (the rows of I below each
    /// of its columns are rows of that column's supernode).
    pub(crate) fn from_supernodes(l: Supernodes, position: Option<Vec<usize>>) -> Self {
        let count = l.begin.len();
        let n = l.end.last().copied().unwrap_or(0);
        let mut owner = vec![0; n];
        let (mut widest, mut tallest) = (0, 0);
        for s in 0..count {
            owner[l.begin[s]..l.end[s]].fill(s);
            let (_, size, rows, _) = l.shape(s);
            widest = widest.max(size);
            tallest = tallest.max(rows - size);
        }
        let mut z = vec![0.0; l.values.len()];
        // Work space for the largest supernode: Z[I, I], L̂ᵀ, L[J, J]⁻¹.
        let mut z_ii = vec![0.0; tallest * tallest];
        let mut lhat_t = vec![0.0; widest * tallest];
        let mut inverse = vec![0.0; widest * widest];
        for s in (0..count).rev() {
            let (_, k, rows, below) = l.shape(s);
            let m = below.len();
            let values = &l.values[l.val_ptr[s]..l.val_ptr[s + 1]];
            let l_s = MatRef::from_column_major_slice(values, rows, k);
            let l_jj = l_s.subrows(0, k);
            // L̂ᵀ = L[J, J]⁻ᵀ L[I, J]ᵀ.
            let mut lhat_t = MatMut::from_column_major_slice_mut(&mut lhat_t[..k * m], k, m);
            lhat_t.copy_from(l_s.subrows(k, m).transpose());
            solve_upper_triangular_in_place(l_jj.transpose(), lhat_t.rb_mut(), Par::Seq);
            // Z[I, I], column by column: column I[b] lives in its supernode t.
            let mut z_ii = MatMut::from_column_major_slice_mut(&mut z_ii[..m * m], m, m);
            for (b, &c) in below.iter().enumerate() {
                let t = owner[c];
                let (t_start, t_size, t_rows, t_below) = l.shape(t);
                let column = &z[l.val_ptr[t] + (c - t_start) * t_rows..][..t_rows];
                let mut p = 0;
                for (a, &r) in below.iter().enumerate().skip(b) {
                    let index = if r < t_start + t_size {
                        r - t_start
                    } else {
                        while p < t_below.len() && t_below[p] < r {
                            p += 1;
                        }
                        t_size + p
                    };
                    let value = column.get(index).copied().unwrap_or(0.0);
                    z_ii[(a, b)] = value;
                    z_ii[(b, a)] = value;
                }
            }
            let z_s = &mut z[l.val_ptr[s]..l.val_ptr[s + 1]];
            let mut z_s = MatMut::from_column_major_slice_mut(z_s, rows, k);
            let (mut z_jj, mut z_ij) = z_s.rb_mut().split_at_row_mut(k);
            // Z[I, J] = −Z[I, I] L̂.
            matmul(
                z_ij.rb_mut(),
                Accum::Replace,
                z_ii.rb(),
                lhat_t.rb().transpose(),
                -1.0,
                Par::Seq,
            );
            // Z[J, J] = L[J, J]⁻ᵀ L[J, J]⁻¹ − L̂ᵀ Z[I, J].
            let mut inverse = MatMut::from_column_major_slice_mut(&mut inverse[..k * k], k, k);
            inverse.fill(0.0);
            invert_lower_triangular(inverse.rb_mut(), l_jj, Par::Seq);
            for j in 0..k {
                for i in 0..j {
                    inverse[(i, j)] = 0.0;
                }
            }
            matmul(
                z_jj.rb_mut(),
                Accum::Replace,
                inverse.rb().transpose(),
                inverse.rb(),
                1.0,
                Par::Seq,
            );
            matmul(
                z_jj.rb_mut(),
                Accum::Add,
                lhat_t.rb(),
                z_ij.rb(),
                -1.0,
                Par::Seq,
            );
        }
        let supernodes = Supernodes { values: z, ..l };
        Self {
            z: Layout::Supernodes { supernodes, owner },
            position,
        }
    }

    /// H⁻¹[i, j] (in H's order), if it lies on L's pattern.
    pub(crate) fn get(&self, i: usize, j: usize) -> Option<f64> {
        let (i, j) = match &self.position {
            Some(p) => (p[i], p[j]),
            None => (i, j),
        };
        let (row, col) = (i.max(j), i.min(j));
        match &self.z {
            Layout::Columns(z) => {
                let start = z.col_ptr[col];
                if row == col {
                    return Some(z.values[start]);
                }
                let rows = &z.row_idx[start + 1..z.col_ptr[col + 1]];
                let q = rows.binary_search(&row).ok()?;
                Some(z.values[start + 1 + q])
            }
            Layout::Supernodes { supernodes, owner } => {
                let t = owner[col];
                let (start, size, rows, below) = supernodes.shape(t);
                let index = if row < start + size {
                    row - start
                } else {
                    size + below.binary_search(&row).ok()?
                };
                Some(supernodes.values[supernodes.val_ptr[t] + (col - start) * rows + index])
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng, rngs::StdRng};

    /// A random sparse SPD matrix of dimension `n`, its dense Cholesky
    /// factor, and that as a [`LowerFactor`] (every fill entry kept, zeros
    /// dropped).
    fn random_spd(rng: &mut StdRng, n: usize) -> (DMatrix<f64>, DMatrix<f64>, LowerFactor) {
        let mut h = DMatrix::<f64>::zeros(n, n);
        for i in 0..n {
            h[(i, i)] = n as f64;
            for j in 0..i {
                if rng.random_bool(0.2) {
                    let v = rng.random_range(-1.0..1.0);
                    h[(i, j)] = v;
                    h[(j, i)] = v;
                }
            }
        }
        let l = h
            .clone()
            .cholesky()
            .map(|c| c.l())
            .unwrap_or_else(|| unreachable!());
        let mut factor = LowerFactor {
            col_ptr: vec![0],
            row_idx: Vec::new(),
            values: Vec::new(),
        };
        for j in 0..n {
            for i in j..n {
                if i == j || l[(i, j)] != 0.0 {
                    factor.row_idx.push(i);
                    factor.values.push(l[(i, j)]);
                }
            }
            factor.col_ptr.push(factor.row_idx.len());
        }
        (h, l, factor)
    }

    #[test]
    fn the_selected_entries_equal_the_dense_inverse() {
        let mut rng = StdRng::seed_from_u64(11);
        for _ in 0..30 {
            let n = rng.random_range(1..40);
            let (h, _, factor) = random_spd(&mut rng, n);
            let pattern: Vec<(usize, usize)> = (0..n)
                .flat_map(|j| {
                    let f = &factor;
                    (f.col_ptr[j]..f.col_ptr[j + 1]).map(move |q| (f.row_idx[q], j))
                })
                .collect();
            let inverse = h.try_inverse().unwrap_or_else(|| unreachable!());
            let z = SelectedInverse::from_columns(factor, None);
            for (i, j) in pattern {
                let expected = inverse[(i, j)];
                let got = z.get(i, j).unwrap_or(f64::NAN);
                assert!(
                    (got - expected).abs() < 1e-12 * (1.0 + expected.abs()),
                    "{i},{j}"
                );
                assert_eq!(z.get(j, i), Some(got));
            }
        }
    }

    #[test]
    fn a_permuted_factor_is_read_in_the_matrix_order() {
        let mut rng = StdRng::seed_from_u64(5);
        let n = 12;
        let (h, _, factor) = random_spd(&mut rng, n);
        // H' = P H Pᵀ has the factor above when column c of H' is column
        // position[c] of the factored matrix.
        let position: Vec<usize> = (0..n).map(|c| (c * 5) % n).collect();
        let permuted = DMatrix::from_fn(n, n, |i, j| h[(position[i], position[j])]);
        let inverse = permuted.try_inverse().unwrap_or_else(|| unreachable!());
        let z = SelectedInverse::from_columns(factor, Some(position));
        for c in 0..n {
            let got = z.get(c, c).unwrap_or(f64::NAN);
            assert!((got - inverse[(c, c)]).abs() < 1e-12);
        }
    }

    #[test]
    fn supernodes_of_any_width_give_the_dense_inverse() {
        let mut rng = StdRng::seed_from_u64(8);
        for _ in 0..30 {
            let n = rng.random_range(1..30);
            let (h, l, _) = random_spd(&mut rng, n);
            // Columns in supernodes of 1–5, every row below kept; the
            // diagonal block's upper part holds junk, which L is not.
            let mut f = Supernodes {
                begin: Vec::new(),
                end: Vec::new(),
                val_ptr: vec![0],
                row_ptr: vec![0],
                row_idx: Vec::new(),
                values: Vec::new(),
            };
            let mut start = 0;
            while start < n {
                let end = (start + rng.random_range(1..6)).min(n);
                f.begin.push(start);
                f.end.push(end);
                f.row_idx.extend(end..n);
                f.row_ptr.push(f.row_idx.len());
                for j in start..end {
                    for i in start..n {
                        f.values.push(if i < j { 99.0 } else { l[(i, j)] });
                    }
                }
                f.val_ptr.push(f.values.len());
                start = end;
            }
            let inverse = h.try_inverse().unwrap_or_else(|| unreachable!());
            let z = SelectedInverse::from_supernodes(f, None);
            for i in 0..n {
                for j in 0..n {
                    let got = z.get(i, j).unwrap_or(f64::NAN);
                    let expected = inverse[(i, j)];
                    assert!(
                        (got - expected).abs() < 1e-12 * (1.0 + expected.abs()),
                        "{i},{j}"
                    );
                }
            }
        }
    }

    #[test]
    fn columns_in_any_order_are_sorted_with_the_diagonal_first() {
        let mut f = LowerFactor {
            col_ptr: vec![0, 3, 5, 6],
            row_idx: vec![2, 0, 1, 2, 1, 2],
            values: vec![20.0, 0.5, 10.0, 21.0, 11.0, 22.0],
        };
        f.sort_columns();
        assert_eq!(f.row_idx, vec![0, 1, 2, 1, 2, 2]);
        assert_eq!(f.values, vec![0.5, 10.0, 20.0, 11.0, 21.0, 22.0]);
    }
}
