//! The block analysis and factorisation against faer, pivots, flops.

use super::*;
use faer::Par;
use faer::Side;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::SymbolicSparseColMat;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholeskyRaw, SymmetricOrdering, factorize_symbolic_cholesky,
};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// A random H with dense blocks of sizes 1–8 (rows formed together up
/// to 6, one by one above): a chain of blocks plus
/// random couplings, diagonally dominant. Returns the block pattern,
/// the sizes, the scalar pattern and its values (upper triangles).
fn random_h(
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
    let mut first = vec![0];
    for &d in &dims {
        first.push(first.last().unwrap() + d);
    }
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

/// H·x for the symmetric H whose upper triangle is `pattern` and `values`.
fn upper_times(pattern: &SymbolicSparseColMat<usize>, values: &[f64], x: &[f64]) -> Vec<f64> {
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
        let ours = SimplicialSymbolic::analyze(blocks.as_ref(), &dims).unwrap();
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
            ..Default::default()
        };
        let faer_symbolic = factorize_symbolic_cholesky(
            scalar.as_ref(),
            Side::Upper,
            SymmetricOrdering::Identity,
            params,
        )
        .unwrap();
        let SymbolicCholeskyRaw::Simplicial(l) = faer_symbolic.raw() else {
            panic!("simplicial forced");
        };
        // Same column lengths, and each column's rows (diagonal, rest of
        // its block, the blocks below) are faer's.
        assert_eq!(ours.col_ptr, l.col_ptr());
        for jb in 0..dims.len() {
            for j in ours.rows(jb as u32) {
                let mut rows: Vec<usize> = (j..ours.rows(jb as u32).end).collect();
                for &ib in ours.below(jb) {
                    rows.extend(ours.rows(ib));
                }
                assert_eq!(rows, l.row_idx()[l.col_ptr()[j]..l.col_ptr()[j + 1]]);
            }
        }

        let mut chol = SimplicialCholesky::new(ours).unwrap();
        if trial % 4 == 0 {
            let mut bad = values.clone();
            let c = rng.random_range(0..n);
            bad[scalar.col_ptr()[c + 1] - 1] = -1.0;
            let h = SparseColMatRef::new(scalar.as_ref(), &bad);
            let err = chol.factorize(h).unwrap_err();
            assert!(err.pivot <= c + 1, "pivot {} after column {c}", err.pivot);
            assert!(chol.work.iter().all(|&w| w == 0.0));
        }
        chol.factorize(SparseColMatRef::new(scalar.as_ref(), &values))
            .unwrap();
        let mut faer_values = vec![0.0; faer_symbolic.len_val()];
        let mut mem = MemBuffer::new(
            faer_symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        );
        faer_symbolic
            .factorize_numeric_llt(
                &mut faer_values,
                SparseColMatRef::new(scalar.as_ref(), &values),
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

/// The supernodal factor's solve (Cairn's loops over faer's factor)
/// gives the simplicial factor's solution, and H x = b, on random block
/// matrices of up to a few hundred columns.
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
            let mut c =
                SparseCholesky::analyze(scalar.as_ref(), blocks.as_ref(), &dims, &config).unwrap();
            c.factorize(scalar.as_ref(), &values).unwrap();
            let mut x = b.clone();
            assert!(c.solve_in_place(&mut x));
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

/// A non-positive pivot is reported at its 1-based column, as faer does.
#[test]
fn a_non_positive_pivot_names_its_column() {
    // Three 1×1 blocks in a chain; column 1's pivot is 1 - 2² < 0.
    let blocks =
        SymbolicSparseColMat::new_checked(3, 3, vec![0, 1, 3, 5], None, vec![0, 0, 1, 1, 2]);
    let symbolic = SimplicialSymbolic::analyze(blocks.as_ref(), &[1, 1, 1]).unwrap();
    let mut chol = SimplicialCholesky::new(symbolic).unwrap();
    let values = [1.0, 2.0, 1.0, 0.0, 1.0];
    let h = SparseColMatRef::new(blocks.as_ref(), &values);
    assert_eq!(chol.factorize(h), Err(NotPositiveDefinite { pivot: 2 }));
    // Inside one 3×3 block (its rows formed together): the same pivot.
    let block = SymbolicSparseColMat::new_checked(1, 1, vec![0, 1], None, vec![0]);
    let scalar =
        SymbolicSparseColMat::new_checked(3, 3, vec![0, 1, 3, 6], None, vec![0, 0, 1, 0, 1, 2]);
    let symbolic = SimplicialSymbolic::analyze(block.as_ref(), &[3]).unwrap();
    let mut chol = SimplicialCholesky::new(symbolic).unwrap();
    let values = [1.0, 2.0, 1.0, 0.0, 0.0, 1.0];
    let h = SparseColMatRef::new(scalar.as_ref(), &values);
    assert_eq!(chol.factorize(h), Err(NotPositiveDefinite { pivot: 2 }));
    assert!(chol.work.iter().all(|&w| w == 0.0));
}

/// faer's flop count (its column counts give the same ratio).
#[test]
fn flops_per_value_counts_as_faer() {
    // One dense 3×3 block: columns of 3, 2 and 1 values.
    let blocks = SymbolicSparseColMat::new_checked(1, 1, vec![0, 1], None, vec![0]);
    let symbolic = SimplicialSymbolic::analyze(blocks.as_ref(), &[3]).unwrap();
    let flops = (3.0 + 6.0) + (2.0 + 3.0) + (1.0 + 1.0);
    assert_eq!(symbolic.flops_per_value(), flops / 6.0);
}
