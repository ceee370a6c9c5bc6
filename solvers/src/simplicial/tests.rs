//! The block analysis and factorisation against faer, pivots, flops.

use super::*;
use crate::test_matrices::{faer_analysis, layout, random_h, upper_times};
use faer::Par;
use faer::Side;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::SymbolicSparseColMat;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{CholeskySymbolicParams, SymbolicCholeskyRaw};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// The block analysis gives faer's simplicial structure of the scalar
/// matrix exactly, the factorisation faer's values (to rounding), the
/// solve H⁻¹b; an indefinite H fails at its pivot and leaves the work
/// space clean for the next factorisation.
#[test]
fn block_simplicial_factor_matches_faer() {
    let mut rng = StdRng::seed_from_u64(11);
    for trial in 0..200 {
        let (blocks, dims, scalar, values) = random_h(&mut rng);
        let n = scalar.ncols();
        let layout = layout(&blocks, &dims);
        let ours = SimplicialSymbolic::analyze(&layout).unwrap();
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
            ..Default::default()
        };
        let faer_symbolic = faer_analysis(&scalar, params).unwrap();
        let SymbolicCholeskyRaw::Simplicial(l) = faer_symbolic.raw() else {
            panic!("simplicial forced");
        };
        // Same column lengths, and each column's rows (diagonal, rest of
        // its block, the blocks below) are faer's.
        // The tree and the rows below each block are those columns' too.
        assert_eq!(ours.col_ptr, l.col_ptr());
        let (col_start, col_blocks) = ours.columns();
        for jb in 0..dims.len() {
            let below = &col_blocks[col_start[jb]..col_start[jb + 1]];
            assert_eq!(ours.parent(jb), below.first().map(|&p| p as usize));
            let degree: usize = below.iter().map(|&ib| dims[ib as usize]).sum();
            assert_eq!(ours.degree(jb), degree);
            for j in ours.rows(jb as u32) {
                let mut rows: Vec<usize> = (j..ours.rows(jb as u32).end).collect();
                for &ib in below {
                    rows.extend(ours.rows(ib));
                }
                assert_eq!(rows, l.row_idx()[l.col_ptr()[j]..l.col_ptr()[j + 1]]);
            }
        }

        let mut chol = SimplicialCholesky::new(ours, &layout).unwrap();
        if trial % 4 == 0 {
            let mut bad = values.clone();
            let c = rng.random_range(0..n);
            bad[scalar.col_ptr()[c + 1] - 1] = -1.0;
            let err = chol.factorize(&bad).unwrap_err();
            assert!(err.pivot <= c + 1, "pivot {} after column {c}", err.pivot);
            assert!(chol.work.iter().all(|&w| w == 0.0));
        }
        chol.factorize(&values).unwrap();
        let mut faer_values = vec![0.0; faer_symbolic.len_val()];
        let mut mem = MemBuffer::new(
            faer_symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        );
        faer_symbolic
            .factorize_numeric_llt(
                &mut faer_values,
                faer::sparse::SparseColMatRef::new(scalar.as_ref(), &values),
                Side::Upper,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .unwrap();
        for (a, b) in chol.values.iter().zip(&faer_values) {
            assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
        }

        let x: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut b = upper_times(&scalar, &values, &x);
        chol.solve_in_place(&mut b);
        for (got, want) in b.iter().zip(&x) {
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
    }
}

/// A non-positive pivot is reported at its 1-based column, as faer does.
#[test]
fn a_non_positive_pivot_names_its_column() {
    // Three 1×1 blocks in a chain; column 1's pivot is 1 - 2² < 0.
    let blocks =
        SymbolicSparseColMat::new_checked(3, 3, vec![0, 1, 3, 5], None, vec![0, 0, 1, 1, 2]);
    let chain = layout(&blocks, &[1, 1, 1]);
    let symbolic = SimplicialSymbolic::analyze(&chain).unwrap();
    let mut chol = SimplicialCholesky::new(symbolic, &chain).unwrap();
    let values = [1.0, 2.0, 1.0, 0.0, 1.0];
    assert_eq!(
        chol.factorize(&values),
        Err(NotPositiveDefinite { pivot: 2 })
    );
    // Inside one 3×3 block (its rows formed together): the same pivot.
    let block = SymbolicSparseColMat::new_checked(1, 1, vec![0, 1], None, vec![0]);
    let one_block = layout(&block, &[3]);
    let symbolic = SimplicialSymbolic::analyze(&one_block).unwrap();
    let mut chol = SimplicialCholesky::new(symbolic, &one_block).unwrap();
    // Column by column: (0, 0); (0, 1) (1, 1); (0, 2) (1, 2) (2, 2).
    let values = [1.0, 2.0, 1.0, 0.0, 0.0, 1.0];
    assert_eq!(
        chol.factorize(&values),
        Err(NotPositiveDefinite { pivot: 2 })
    );
    assert!(chol.work.iter().all(|&w| w == 0.0));
}

/// faer's flop count (its column counts give the same ratio).
#[test]
fn flops_per_value_counts_as_faer() {
    // One dense 3×3 block: columns of 3, 2 and 1 values.
    let blocks = SymbolicSparseColMat::new_checked(1, 1, vec![0, 1], None, vec![0]);
    let symbolic = SimplicialSymbolic::analyze(&layout(&blocks, &[3])).unwrap();
    let flops = (3.0 + 6.0) + (2.0 + 3.0) + (1.0 + 1.0);
    assert_eq!(symbolic.flops_per_value(), flops / 6.0);
}
