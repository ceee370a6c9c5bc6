use super::*;

/// Upper block pattern (with diagonal) of the given undirected couplings.
fn pattern(n: usize, couplings: &[(usize, usize)]) -> SymbolicSparseColMat<usize> {
    let mut rows: Vec<Vec<usize>> = (0..n).map(|c| vec![c]).collect();
    for &(a, b) in couplings {
        rows[a.max(b)].push(a.min(b));
    }
    let mut col_ptr = vec![0];
    let mut row_idx = Vec::new();
    for mut r in rows {
        r.sort_unstable();
        r.dedup();
        row_idx.extend(r);
        col_ptr.push(row_idx.len());
    }
    SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx)
}

#[test]
fn dot_in_lanes_is_the_dot_product_for_every_length() {
    for n in 0..40 {
        let a: Vec<f64> = (0..n).map(|k| (k as f64 * 0.7).sin()).collect();
        let b: Vec<f64> = (0..n).map(|k| 1.0 + k as f64 * 0.25).collect();
        let plain: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
        assert!(
            (dot_in_lanes(&a, &b) - plain).abs() <= 1e-12 * (1.0 + plain.abs()),
            "{n}"
        );
    }
}

#[test]
fn lower_triangle_holds_the_transpose_of_the_upper_one() {
    let upper = pattern(6, &[(0, 3), (1, 3), (2, 5), (4, 5), (0, 5), (1, 2)]);
    let values: Vec<f64> = (0..upper.row_idx().len()).map(|k| k as f64 + 0.5).collect();
    let mut lower = LowerTriangle::new(upper.as_ref());
    let h = lower.fill(&values);
    let mut seen = 0;
    for j in 0..6 {
        let rows = h.symbolic().row_idx_of_col_raw(j);
        assert!(rows.is_sorted(), "column {j}: {rows:?}");
        for (&i, &v) in rows.iter().zip(h.val_of_col(j)) {
            assert!(i >= j);
            // Entry (i, j) of the lower triangle is (j, i) of the upper one.
            let k = upper
                .col_range(i)
                .find(|&k| upper.row_idx()[k] == j)
                .unwrap();
            assert_eq!(v, values[k]);
            seen += 1;
        }
    }
    assert_eq!(seen, values.len());
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
