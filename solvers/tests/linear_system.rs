//! The exported linear system: JᵀJ = H and −Jᵀe = b to rounding on SE2,
//! SE2 + XY and SE3 graphs (with fixed vertices, the gauge and a robust
//! kernel), Matrix Market files that read back to the same matrices, and
//! H that solves to the optimiser's first Gauss-Newton step.

use cairn_core::{EdgePriorSE2, EdgeSE2, EdgeSE2XY, EdgeSE3, Graph, RobustKernel, SE2, SE3};
use cairn_solvers::{Algorithm, LinearSystem, Optimizer, SolverConfig};
use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, Matrix6, UnitQuaternion, Vector2, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sprs::CsMat;

mod common;
use common::noisy_loop;

/// Poses in a loop with landmarks seen from them; pose 3 held; one
/// sighting under a Cauchy kernel.
fn poses_and_landmarks(seed: u64) -> Graph {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut g = noisy_loop(12, seed);
    for l in 0..5 {
        let p = Vector2::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
        g.add_vertex(100 + l, p).unwrap();
        for k in 0..4 {
            let pose = (l * 2 + k) % 12;
            let z = Vector2::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
            let info = Matrix2::new(40.0, 5.0, 5.0, 20.0);
            let e = g.add_edge(pose, 100 + l, EdgeSE2XY::new(z), info).unwrap();
            if l == 2 && k == 0 {
                g.set_robust_kernel(e, Some(RobustKernel::Cauchy(1.0)));
            }
        }
    }
    g.set_fixed(3, true).unwrap();
    g
}

/// Two GPS-like priors fix the gauge of a small SE2 chain (no vertex held).
fn chain_with_priors() -> Graph {
    let mut g = Graph::new();
    for i in 0..6 {
        g.add_vertex(
            i,
            SE2::new(i as f64 + 0.1 * (i as f64).sin(), 0.2, 0.05 * i as f64),
        )
        .unwrap();
    }
    for i in 0..5 {
        g.add_edge(
            i,
            i + 1,
            EdgeSE2::new(SE2::new(1.0, 0.0, 0.0)),
            Matrix3::identity() * 10.0,
        )
        .unwrap();
    }
    g.add_unary_edge(
        0,
        EdgePriorSE2::new(SE2::new(0.0, 0.0, 0.0)),
        Matrix3::identity(),
    )
    .unwrap();
    g.add_unary_edge(
        5,
        EdgePriorSE2::new(SE2::new(5.0, 0.0, 0.0)),
        Matrix3::identity(),
    )
    .unwrap();
    g
}

/// A noisy SE3 chain with a loop closure and non-diagonal information.
fn se3_chain(seed: u64) -> Graph {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut g = Graph::new();
    let mut noise = || {
        let axis = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        SE3::new(axis * 0.1, UnitQuaternion::from_scaled_axis(axis * 0.05))
    };
    let step = SE3::new(
        Vector3::new(1.0, 0.0, 0.1),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.1, 0.5)),
    );
    let mut truth = SE3::identity();
    for i in 0..8 {
        g.add_vertex(i, truth.compose(&noise())).unwrap();
        truth = truth.compose(&step);
    }
    let mut info = Matrix6::identity() * 50.0;
    info[(0, 4)] = 3.0;
    info[(4, 0)] = 3.0;
    for i in 0..7 {
        g.add_edge(i, i + 1, EdgeSE3::new(step), info).unwrap();
    }
    g.add_edge(0, 7, EdgeSE3::new(SE3::identity()), info)
        .unwrap();
    g
}

fn dense(m: &CsMat<f64>) -> DMatrix<f64> {
    let mut d = DMatrix::zeros(m.rows(), m.cols());
    for (&v, (r, c)) in m.iter() {
        d[(r, c)] += v;
    }
    d
}

fn system(graph: &Graph) -> LinearSystem {
    let config = SolverConfig {
        algorithm: Algorithm::GaussNewton,
        ..Default::default()
    };
    Optimizer::new(graph, config)
        .unwrap()
        .linear_system(graph)
        .unwrap()
}

fn assert_close(a: &DMatrix<f64>, b: &DMatrix<f64>, what: &str) {
    let scale = b.amax().max(1.0);
    let diff = (a - b).amax();
    assert!(
        diff <= 1e-10 * scale,
        "{what}: differs by {diff} (scale {scale})"
    );
}

#[test]
fn the_jacobian_squares_to_the_hessian_and_gives_the_rhs() {
    for (name, graph, free) in [
        ("SE2 loop", noisy_loop(30, 4), 29 * 3),
        ("SE2 + XY", poses_and_landmarks(5), 11 * 3 + 5 * 2),
        ("SE2 with priors", chain_with_priors(), 6 * 3),
        ("SE3 chain", se3_chain(6), 7 * 6),
    ] {
        let s = system(&graph);
        assert_eq!(
            s.columns.len(),
            free,
            "{name}: the fixed and gauge vertices are left out"
        );
        let rows: usize = graph.edges().map(|e| e.error_dim()).sum();
        assert_eq!(
            (s.jacobian.rows(), s.rows.len(), s.error.len()),
            (rows, rows, rows),
            "{name}"
        );
        let j = dense(&s.jacobian);
        let h = dense(&s.hessian_full());
        assert_close(&(j.transpose() * &j), &h, name);
        let b = -(j.transpose() * DVector::from_vec(s.error.clone()));
        assert_close(
            &DMatrix::from_column_slice(b.len(), 1, b.as_slice()),
            &DMatrix::from_column_slice(b.len(), 1, &s.rhs),
            name,
        );
        // The upper triangle holds no entry below the diagonal.
        assert!(s.hessian.iter().all(|(_, (r, c))| r <= c), "{name}");
        // ½ Σ‖Ue‖² is half the (non-robust) χ² where no kernel is set.
        if graph.edges().all(|e| e.kernel().is_none()) {
            let squared: f64 = s.error.iter().map(|e| e * e).sum();
            assert!(
                (squared - s.chi2).abs() <= 1e-9 * s.chi2.max(1.0),
                "{name}: {squared} vs {}",
                s.chi2
            );
        }
    }
}

#[test]
fn columns_and_rows_name_vertices_and_edges() {
    let graph = poses_and_landmarks(5);
    let s = system(&graph);
    // Vertex 0 is the lowest-id pose but pose 3 is held: no gauge is added.
    assert!(s.columns.contains(&(0, 0)) && !s.columns.iter().any(|&(id, _)| id == 3));
    assert!(s.columns.contains(&(104, 1)));
    // The rows run over the edges in insertion order, each error component.
    assert_eq!(s.rows[0], (0, 0));
    assert_eq!(s.rows[2], (0, 2));
    assert_eq!(*s.rows.last().unwrap(), (graph.num_edges() - 1, 1));
}

#[test]
fn matrix_market_files_read_back_to_the_same_matrices() {
    let s = system(&poses_and_landmarks(7));
    let dir = std::env::temp_dir().join(format!("cairn-mtx-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, m) in [("h.mtx", s.hessian.clone()), ("j.mtx", s.jacobian.clone())] {
        let path = dir.join(name);
        sprs::io::write_matrix_market(&path, &m).unwrap();
        let back: sprs::TriMat<f64> = sprs::io::read_matrix_market(&path).unwrap();
        assert_eq!(dense(&back.to_csc()), dense(&m), "{name}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_hessian_solves_to_the_first_gauss_newton_step() {
    // SE2 poses and XY landmarks update additively, so the step is the
    // change of their parameters.
    let mut graph = poses_and_landmarks(9);
    let s = system(&graph);
    let h = dense(&s.hessian_full());
    let step = h
        .cholesky()
        .expect("H is positive definite")
        .solve(&DVector::from_vec(s.rhs.clone()));
    let before: Vec<f64> = graph.values().params().to_vec();
    let config = SolverConfig {
        algorithm: Algorithm::GaussNewton,
        max_iterations: 1,
        init: cairn_solvers::Initialization::File,
        ..Default::default()
    };
    Optimizer::new(&graph, config)
        .unwrap()
        .optimize(&mut graph)
        .unwrap();
    for (c, &(id, k)) in s.columns.iter().enumerate() {
        let v = graph.vertex_index(id).unwrap();
        let at =
            graph.vertex(v).params.as_ptr() as usize - graph.values().params().as_ptr() as usize;
        let p = at / std::mem::size_of::<f64>() + k;
        let mut moved = graph.values().params()[p] - before[p];
        if graph.vertex(v).kind.dim == 3 && k == 2 {
            // SE2 keeps its heading in (−π, π].
            moved = cairn_core::se2::normalize_angle(moved);
        }
        assert!(
            (moved - step[c]).abs() < 1e-9 * step.amax().max(1.0),
            "column {c} ({id}, {k}): {moved} vs {}",
            step[c]
        );
    }
}
