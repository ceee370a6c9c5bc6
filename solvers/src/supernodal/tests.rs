//! Cairn's supernodal factorisation and solves against faer's and the
//! simplicial ones.

use super::*;
use crate::simplicial::SimplicialSymbolic;
use crate::test_matrices::{faer_analysis, layout, random_h, upper_times};
use faer::Side;
use faer::sparse::SparseColMatRef;
use faer::sparse::SymbolicSparseColMat;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw,
};
use faer::sparse::linalg::{SupernodalThreshold, SymbolicSupernodalParams};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// faer's supernodal analysis of the upper triangle `pattern`, unpermuted.
fn analyze(pattern: &SymbolicSparseColMat<usize>) -> SymbolicCholesky<usize> {
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
        ..Default::default()
    };
    faer_analysis(pattern, params).unwrap()
}

/// faer's own numeric factorisation: the values, or the failing pivot.
fn faer_factor(
    symbolic: &SymbolicCholesky<usize>,
    pattern: &SymbolicSparseColMat<usize>,
    values: &[f64],
) -> Result<Vec<f64>, usize> {
    let mut l = vec![0.0; symbolic.len_val()];
    let req = symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
    let mut scratch = MemBuffer::new(req);
    let result = symbolic.factorize_numeric_llt(
        &mut l,
        SparseColMatRef::new(pattern.as_ref(), values),
        Side::Upper,
        LltRegularization::default(),
        Par::Seq,
        MemStack::new(&mut scratch),
        Default::default(),
    );
    match result {
        Ok(_) => Ok(l),
        Err(LltError::NonPositivePivot { index }) => Err(index),
    }
}

/// Cairn's supernodal structure of the factor of the block matrix with
/// upper block triangle `blocks` and block sizes `dims`.
fn ours(blocks: &SymbolicSparseColMat<usize>, dims: &[usize]) -> SupernodalSymbolic {
    let analysis = SimplicialSymbolic::analyze(&layout(blocks, dims)).unwrap();
    SupernodalSymbolic::from_blocks(&analysis).unwrap()
}

/// The structure found on the blocks is faer's, found on the scalar
/// pattern: the same supernodes (fundamental ones, relaxed by the same
/// rule), rows and value layout, on random block matrices with blocks of
/// 1 to 8 columns (so merges of every width limit are met).
#[test]
fn supernodes_from_the_blocks_are_faers() {
    let mut rng = StdRng::seed_from_u64(41);
    let (mut merged, mut supernodes) = (0, 0);
    for _ in 0..300 {
        let (blocks, dims, pattern, _) = random_h(&mut rng);
        let faer = analyze(&pattern);
        let SymbolicCholeskyRaw::Supernodal(faer) = faer.raw() else {
            panic!("not supernodal")
        };
        let ours = ours(&blocks, &dims);
        assert_eq!(ours.n_supernodes(), faer.n_supernodes());
        assert_eq!(ours.val_ptr(), faer.col_ptr_for_val());
        for s in 0..faer.n_supernodes() {
            let (start, width, rows, below) = ours.supernode(s);
            assert_eq!(start, faer.supernode_begin()[s]);
            assert_eq!(start + width, faer.supernode_end()[s]);
            let faer_rows = &faer.row_idx()[faer.col_ptr_for_row_idx()[s]..][..rows - width];
            assert_eq!(below, faer_rows);
        }
        // How many fundamental supernodes the relaxation merged.
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            supernodal_params: SymbolicSupernodalParams { relax: None },
            ..Default::default()
        };
        let fundamental = faer_analysis(&pattern, params).unwrap();
        let SymbolicCholeskyRaw::Supernodal(fundamental) = fundamental.raw() else {
            panic!("not supernodal")
        };
        merged += fundamental.n_supernodes() - ours.n_supernodes();
        supernodes += fundamental.n_supernodes();
    }
    assert!(merged > supernodes / 4, "{merged} of {supernodes}");
}

/// L's entries on and below the diagonal, supernode by supernode (faer's
/// dense kernels leave scratch above the diagonal of the diagonal blocks).
fn lower_entries(symbolic: &SupernodalSymbolic, values: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    for s in 0..symbolic.n_supernodes() {
        let (_, width, rows, _) = symbolic.supernode(s);
        let panel = &values[symbolic.val_ptr()[s]..][..rows * width];
        for (j, column) in panel.chunks_exact(rows).enumerate() {
            out.extend_from_slice(&column[j..]);
        }
    }
    out
}

/// The right-looking factorisation gives faer's left-looking factor to
/// rounding on random block matrices of up to a few hundred columns, and
/// fails where faer does (at the same pivot) on indefinite ones; after a
/// failure the next factorisation is right again.
#[test]
fn supernodal_factor_matches_faer() {
    let mut rng = StdRng::seed_from_u64(23);
    let mut failures = 0;
    for _ in 0..200 {
        let (blocks, dims, pattern, mut values) = random_h(&mut rng);
        let symbolic = analyze(&pattern);
        let supernodal = &ours(&blocks, &dims);
        let layout = layout(&blocks, &dims);
        let mut numeric = SupernodalNumeric::new(supernodal, &layout, Par::Seq).unwrap();
        let mut ours = vec![f64::NAN; symbolic.len_val()];
        let want = faer_factor(&symbolic, &pattern, &values).unwrap();
        numeric
            .factorize(supernodal, &values, &mut ours, None)
            .unwrap();
        let want = lower_entries(supernodal, &want);
        let close = |ours: &[f64]| {
            let ours = lower_entries(supernodal, ours);
            assert_eq!(ours.len(), want.len());
            for (a, b) in ours.iter().zip(&want) {
                assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
            }
        };
        close(&ours);
        // Make a diagonal entry negative: both fail at the same pivot.
        let n = pattern.ncols();
        let c = rng.random_range(0..n);
        let diagonal = *pattern.col_range(c).last().as_ref().unwrap();
        let kept = values[diagonal];
        values[diagonal] = -1.0;
        let pivot = faer_factor(&symbolic, &pattern, &values).unwrap_err();
        let (mut rhs, mut work) = (vec![1.0; n], vec![0.0; n]);
        let err = numeric
            .factorize(supernodal, &values, &mut ours, Some((&mut rhs, &mut work)))
            .unwrap_err();
        assert_eq!(err, NotPositiveDefinite { pivot });
        failures += 1;
        values[diagonal] = kept;
        numeric
            .factorize(supernodal, &values, &mut ours, None)
            .unwrap();
        close(&ours);
    }
    assert_eq!(failures, 200);
}

/// The supernodal factor and solve, begun
/// in the factorisation or not, give the simplicial factor's solution, and
/// H x = b, on random block matrices of up to a few hundred columns.
#[test]
fn supernodal_solve_matches_the_simplicial_one() {
    use crate::linear::{Factorization, LinearSolverConfig, SparseCholesky};
    let mut rng = StdRng::seed_from_u64(5);
    let mut widest = 0;
    for _ in 0..200 {
        let (blocks, dims, scalar, values) = random_h(&mut rng);
        let n = scalar.ncols();
        let b: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let solve = |factorization| {
            let config = LinearSolverConfig {
                factorization,
                ..Default::default()
            };
            let mut c = SparseCholesky::analyze(&layout(&blocks, &dims), &config).unwrap();
            c.factorize(&values).unwrap();
            let mut x = b.clone();
            assert!(c.solve_in_place(&mut x));
            // The solve begun in the factorisation gives the same x.
            let mut y = b.clone();
            let begun = c.factorize_and_begin_solve(&values, &mut y).unwrap();
            c.finish_solve(begun, &mut y);
            for (a, b) in x.iter().zip(&y) {
                assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
            }
            (x, c.is_supernodal())
        };
        let (x, supernodal) = solve(Factorization::Supernodal);
        let (y, simplicial) = solve(Factorization::Simplicial);
        assert!(supernodal && !simplicial);
        for (a, b) in x.iter().zip(&y) {
            assert!((a - b).abs() <= 1e-10 * (1.0 + b.abs()), "{a} vs {b}");
        }
        for (a, b) in upper_times(&scalar, &values, &x).iter().zip(&b) {
            assert!((a - b).abs() <= 1e-9, "{a} vs {b}");
        }
        widest = widest.max(dims.iter().sum::<usize>());
    }
    assert!(widest > 100);
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

/// Where the supernodal plan would hold more positions than the factor has
/// values, the analysis falls back to the simplicial factor, which solves
/// H x = b. Each of k leaf blocks is coupled to all p hub blocks, and each
/// hub to a tail block of its own: the hubs' columns then differ by their
/// tails, so they split into many supernodes, and every leaf's update is
/// placed in each of them, from its first row there down.
#[test]
fn a_plan_larger_than_its_factor_falls_back_to_simplicial() {
    use crate::linear::{Factorization, LinearSolverConfig, SparseCholesky};
    use crate::test_matrices::block_h;
    let (k, p) = (300, 100);
    let rows: Vec<Vec<usize>> = (0..k)
        .map(|leaf| vec![leaf])
        .chain((k..k + p).map(|hub| (0..k).chain([hub]).collect()))
        .chain((k + p..k + 2 * p).map(|tail| vec![tail - p, tail]))
        .collect();
    let mut rng = StdRng::seed_from_u64(9);
    let (blocks, dims, scalar, values) = block_h(&mut rng, vec![1; k + 2 * p], rows);
    let symbolic = ours(&blocks, &dims);
    let supernodes = symbolic.n_supernodes();
    let layout = layout(&blocks, &dims);
    assert!(SupernodalNumeric::new(&symbolic, &layout, Par::Seq).is_none());
    let config = LinearSolverConfig {
        factorization: Factorization::Supernodal,
        ..Default::default()
    };
    let mut cholesky = SparseCholesky::analyze(&layout, &config).unwrap();
    assert!(!cholesky.is_supernodal(), "{supernodes} supernodes");
    let b: Vec<f64> = (0..dims.len())
        .map(|_| rng.random_range(-1.0..1.0))
        .collect();
    let mut x = b.clone();
    cholesky.factorize(&values).unwrap();
    assert!(cholesky.solve_in_place(&mut x));
    for (a, b) in upper_times(&scalar, &values, &x).iter().zip(&b) {
        assert!((a - b).abs() <= 1e-9, "{a} vs {b}");
    }
}
