//! Random block-structured Hessians for the factorisation tests.

use crate::hessian_layout::HessianLayout;
use faer::Side;
use faer::sparse::SymbolicSparseColMat;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use rand::Rng;
use rand::rngs::StdRng;

/// A random H ([`block_h`]) with blocks of sizes 1–8 (rows formed
/// together up to 6, one by one above): a chain of blocks plus random
/// couplings.
pub(crate) fn random_h(
    rng: &mut StdRng,
) -> (
    SymbolicSparseColMat<usize>,
    Vec<usize>,
    SymbolicSparseColMat<usize>,
    Vec<f64>,
) {
    let nb: usize = rng.random_range(1..40);
    let dims: Vec<usize> = (0..nb).map(|_| rng.random_range(1..=8)).collect();
    // Each block with itself and the one before.
    let mut rows: Vec<Vec<usize>> = (0..nb).map(|c| vec![c.saturating_sub(1), c]).collect();
    for _ in 0..nb {
        let (a, b) = (rng.random_range(0..nb), rng.random_range(0..nb));
        rows[a.max(b)].push(a.min(b));
    }
    block_h(rng, dims, rows)
}

/// The H with blocks of sizes `dims` whose upper block triangle holds, in
/// block column c, the blocks of the rows `rows[c]` (c itself among them):
/// dense blocks of random values, diagonally dominant. Returns the block
/// pattern, the sizes, the scalar pattern and its values (upper triangles).
pub(crate) fn block_h(
    rng: &mut StdRng,
    dims: Vec<usize>,
    mut rows: Vec<Vec<usize>>,
) -> (
    SymbolicSparseColMat<usize>,
    Vec<usize>,
    SymbolicSparseColMat<usize>,
    Vec<f64>,
) {
    let nb = dims.len();
    // Each block's first scalar column, and the dimension at the end.
    let first: Vec<usize> = std::iter::once(0)
        .chain(dims.iter().scan(0, |end, &d| {
            *end += d;
            Some(*end)
        }))
        .collect();
    let (mut bp, mut bi, mut sp, mut si) = (vec![0], vec![], vec![0], vec![]);
    for (c, r) in rows.iter_mut().enumerate() {
        r.sort_unstable();
        r.dedup();
        bi.extend(r.iter().copied());
        bp.push(bi.len());
        for col in first[c]..first[c + 1] {
            for &b in r.iter() {
                let end = if b == c { col + 1 } else { first[b + 1] };
                si.extend(first[b]..end);
            }
            sp.push(si.len());
        }
    }
    let n = first[nb];
    let mut values = vec![0.0; si.len()];
    let mut row_sum = vec![0.0; n];
    for c in 0..n {
        for k in sp[c]..sp[c + 1] {
            if si[k] != c {
                values[k] = rng.random_range(-1.0..1.0);
                row_sum[si[k]] += f64::abs(values[k]);
                row_sum[c] += f64::abs(values[k]);
            }
        }
    }
    for c in 0..n {
        values[sp[c + 1] - 1] = row_sum[c] + rng.random_range(0.1..2.0);
    }
    (
        SymbolicSparseColMat::new_checked(nb, nb, bp, None, bi),
        dims,
        SymbolicSparseColMat::new_checked(n, n, sp, None, si),
        values,
    )
}

/// The layout of the H that [`block_h`] makes from `blocks` and `dims`.
pub(crate) fn layout(blocks: &SymbolicSparseColMat<usize>, dims: &[usize]) -> HessianLayout {
    HessianLayout::new(blocks.clone(), dims.to_vec()).expect("block_h's pattern")
}

/// H·x for the symmetric H whose upper triangle is `pattern` and `values`.
pub(crate) fn upper_times(
    pattern: &SymbolicSparseColMat<usize>,
    values: &[f64],
    x: &[f64],
) -> Vec<f64> {
    let mut out = vec![0.0; x.len()];
    for j in 0..x.len() {
        let range = pattern.col_ptr()[j]..pattern.col_ptr()[j + 1];
        for (&i, &h) in pattern.row_idx()[range.clone()].iter().zip(&values[range]) {
            out[i] += h * x[j];
            if i != j {
                out[j] += h * x[i];
            }
        }
    }
    out
}

/// faer's symbolic analysis of the upper triangle `pattern`, unpermuted.
pub(crate) fn faer_analysis(
    pattern: &SymbolicSparseColMat<usize>,
    params: CholeskySymbolicParams<'_>,
) -> Result<SymbolicCholesky<usize>, faer::sparse::FaerError> {
    factorize_symbolic_cholesky(
        pattern.as_ref(),
        Side::Upper,
        SymmetricOrdering::Identity,
        params,
    )
}
