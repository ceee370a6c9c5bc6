use super::*;
use rand::{Rng, SeedableRng, rngs::StdRng};

/// A random window of `m` poses, the bias, the sideslip and `landmarks` landmarks, each
/// seen from some of the poses, and the same system written out in full
/// (diagonally dominant, so positive definite).
fn random_window(
    rng: &mut StdRng,
    m: usize,
    landmarks: usize,
) -> (Window, DMatrix<f64>, DVector<f64>) {
    let n = 3 * m + GLOBALS;
    let size = n + 2 * landmarks;
    let entry = |rng: &mut StdRng| rng.random_range(-1.0..1.0);
    let mut h = DMatrix::zeros(size, size);
    for i in 0..n {
        for j in 0..=i {
            h[(i, j)] = entry(rng);
            h[(j, i)] = h[(i, j)];
        }
        h[(i, i)] = (n + 2 * landmarks + 1) as f64;
    }
    let mut w = Window::default();
    for slot in 0..landmarks {
        let row = n + 2 * slot;
        let off = entry(rng);
        h.fixed_view_mut::<2, 2>(row, row).copy_from(&Matrix2::new(
            (3 * m + 2) as f64,
            off,
            off,
            (3 * m + 2) as f64,
        ));
        for pose in 0..m {
            if rng.random_bool(0.6) {
                let block = SMatrix::<f64, 3, 2>::from_fn(|_, _| entry(rng));
                h.fixed_view_mut::<3, 2>(3 * pose, row).copy_from(&block);
                h.fixed_view_mut::<2, 3>(row, 3 * pose)
                    .copy_from(&block.transpose());
                w.unsorted.push(Coupling { pose, slot, block });
            }
        }
        w.members.push(slot);
        w.hll.push(h.fixed_view::<2, 2>(row, row).into_owned());
    }
    let b = DVector::from_fn(size, |_, _| rng.random_range(-1.0..1.0));
    w.hpp = h.view((0, 0), (n, n)).lower_triangle();
    w.bp = b.rows(0, n).into_owned();
    w.bl = (0..landmarks)
        .map(|slot| b.fixed_rows::<2>(n + 2 * slot).into_owned())
        .collect();
    w.group_by_slot();
    (w, h, b)
}

#[test]
fn the_reduced_solve_and_the_latest_marginal_match_the_full_system() {
    let mut rng = StdRng::seed_from_u64(3);
    for (m, landmarks) in [(1, 1), (2, 3), (5, 8), (25, 40)] {
        let (mut w, h, b) = random_window(&mut rng, m, landmarks);
        let step = w.solve(m, true).expect("positive definite");
        let inverse = h.clone().cholesky().expect("positive definite").inverse();
        let full = &inverse * &b;
        let n = 3 * m;
        let close = |a: f64, e: f64| (a - e).abs() <= 1e-9 * (1.0 + e.abs());
        for i in 0..n + GLOBALS {
            assert!(close(step.poses[i], full[i]), "pose {i} of {m}");
        }
        for (slot, dl) in step.landmarks.iter().enumerate() {
            for k in 0..2 {
                assert!(
                    close(dl[k], full[n + GLOBALS + 2 * slot + k]),
                    "landmark {slot} of {m}"
                );
            }
        }
        for i in 0..3 {
            for j in 0..3 {
                assert!(close(
                    step.latest_cov[(i, j)],
                    inverse[(n - 3 + i, n - 3 + j)]
                ));
            }
        }
        assert!(close(step.bias, full[n]));
        assert!(close(step.bias_variance, inverse[(n, n)]));
        assert!(close(step.slip, full[n + 1]));
        assert!(close(step.slip_variance, inverse[(n + 1, n + 1)]));
    }
}

#[test]
fn a_held_sideslip_solves_the_system_without_it() {
    let mut rng = StdRng::seed_from_u64(5);
    for (m, landmarks) in [(1, 1), (3, 4), (25, 40)] {
        let (mut w, h, b) = random_window(&mut rng, m, landmarks);
        let step = w.solve(m, false).expect("positive definite");
        let n = 3 * m;
        // The system with the sideslip's row and column taken out.
        let slip = n + 1;
        let keep: Vec<usize> = (0..h.nrows()).filter(|&i| i != slip).collect();
        let held = DMatrix::from_fn(keep.len(), keep.len(), |i, j| h[(keep[i], keep[j])]);
        let held_b = DVector::from_fn(keep.len(), |i, _| b[keep[i]]);
        let inverse = held.cholesky().expect("positive definite").inverse();
        let solution = &inverse * &held_b;
        let close = |a: f64, e: f64| (a - e).abs() <= 1e-8 * (1.0 + e.abs());
        for i in 0..=n {
            assert!(close(step.poses[i], solution[i]), "pose {i} of {m}");
        }
        assert!(close(step.poses[slip], 0.0), "{}", step.poses[slip]);
        for (slot, dl) in step.landmarks.iter().enumerate() {
            for k in 0..2 {
                assert!(
                    close(dl[k], solution[n + 1 + 2 * slot + k]),
                    "landmark {slot}"
                );
            }
        }
        for i in 0..3 {
            for j in 0..3 {
                let e = inverse[(n - 3 + i, n - 3 + j)];
                assert!(close(step.latest_cov[(i, j)], e), "{i} {j} of {m}");
            }
        }
        assert!(close(step.bias_variance, inverse[(n, n)]));
        // The sideslip's own step and variance are the joint system's.
        let joint = h.clone().cholesky().expect("positive definite").inverse();
        assert!(close(step.slip, (&joint * &b)[slip]));
        assert!(close(step.slip_variance, joint[(slip, slip)]));
    }
}
