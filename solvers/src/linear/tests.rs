use super::*;

/// Upper block pattern (with diagonal) of the given undirected couplings.
fn pattern(n: usize, couplings: &[(u32, u32)]) -> SymbolicSparseColMat<u32> {
    let mut rows: Vec<Vec<u32>> = (0..n as u32).map(|c| vec![c]).collect();
    for &(a, b) in couplings {
        rows[a.max(b) as usize].push(a.min(b));
    }
    let mut col_ptr = vec![0];
    let mut row_idx = Vec::new();
    for mut r in rows {
        r.sort_unstable();
        r.dedup();
        row_idx.extend(r);
        col_ptr.push(row_idx.len() as u32);
    }
    SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx)
}

#[test]
fn schur_order_puts_isolated_landmarks_first() {
    // Poses 0-1-2-3 in a chain; landmark 4 seen from 0 and 3; landmarks 5
    // and 6 joined to each other, so neither can be eliminated on its own.
    let p = pattern(
        7,
        &[
            (0, 1),
            (1, 2),
            (2, 3),
            (0, 4),
            (3, 4),
            (1, 5),
            (5, 6),
            (2, 6),
        ],
    );
    let is_pose = [true, true, true, true, false, false, false];
    let dims = [3, 3, 3, 3, 2, 2, 2];
    let order = schur_order(Blocks {
        pattern: p.as_ref(),
        dims: &dims,
        is_pose: &is_pose,
    })
    .unwrap();
    assert_eq!(order[0], 4);
    let mut sorted = order.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, (0..7).collect::<Vec<_>>());
}

/// Values of another length than the analysed layout's are refused before
/// any factorisation reads them, for every kind of factor.
#[test]
fn values_of_the_wrong_length_are_refused() {
    use crate::hessian_layout::HessianLayout;
    let blocks = pattern(3, &[(0, 1), (1, 2)]);
    let usize_pattern = SymbolicSparseColMat::new_checked(
        3,
        3,
        blocks.col_ptr().iter().map(|&p| p as usize).collect(),
        None,
        blocks.row_idx().iter().map(|&r| r as usize).collect(),
    );
    let layout = HessianLayout::new(usize_pattern, vec![3, 3, 2]).unwrap();
    for (factorization, ordering) in [
        (Factorization::Simplicial, Ordering::BlockAmd),
        (Factorization::Supernodal, Ordering::BlockAmd),
        (Factorization::Auto, Ordering::Amd),
    ] {
        let config = LinearSolverConfig {
            factorization,
            ordering,
            parallel: false,
        };
        let mut cholesky = SparseCholesky::analyze(&layout, &config).unwrap();
        let short = vec![1.0; layout.nnz() - 1];
        let refused = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let _ = cholesky.factorize(&short);
        }));
        assert!(refused.is_err(), "{factorization:?} {ordering:?}");
    }
}
