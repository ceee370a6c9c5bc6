//! Marginal covariances against the dense inverse of H.

use cairn_core::{BinaryEdge, EdgeSE2, EdgeSE2XY};
use cairn_solvers::{Optimizer, SolveError, SolverConfig};
use nalgebra::{Matrix2, Vector2};

mod common;
use common::noisy_loop;

#[test]
fn marginals_equal_blocks_of_the_dense_inverse() {
    let mut g = noisy_loop(12, 9);
    g.add_vertex(50, Vector2::new(2.0, 3.0)).unwrap();
    g.add_edge(
        4,
        50,
        EdgeSE2XY::new(Vector2::new(1.0, 1.0)),
        Matrix2::new(4.0, 0.5, 0.5, 2.0),
    )
    .unwrap();
    g.add_edge(
        7,
        50,
        EdgeSE2XY::new(Vector2::new(-1.0, 2.0)),
        Matrix2::identity(),
    )
    .unwrap();
    let mut opt = Optimizer::new(&g, SolverConfig::default()).unwrap();
    opt.optimize(&mut g).unwrap();

    // Dense H from the analytic Jacobians: H = Σ JᵀΩJ over the free vertices.
    let free: Vec<i64> = g.vertices().filter(|v| v.id != 0).map(|v| v.id).collect();
    let offset = |id: i64| -> Option<usize> {
        let mut off = 0;
        for &f in &free {
            if f == id {
                return Some(off);
            }
            off += g.vertex(g.vertex_index(f).unwrap()).kind.dim;
        }
        None
    };
    let n = free
        .iter()
        .map(|&f| g.vertex(g.vertex_index(f).unwrap()).kind.dim)
        .sum();
    let mut h = nalgebra::DMatrix::<f64>::zeros(n, n);
    for e in g.edges() {
        let ids: Vec<i64> = e.vertices().iter().map(|&v| g.vertex(v).id).collect();
        let (jacobians, dims): (Vec<nalgebra::DMatrix<f64>>, Vec<usize>) =
            if let Some(edge) = e.edge().downcast_ref::<EdgeSE2>() {
                let (a, b) = edge.jacobians(&g.value(ids[0]).unwrap(), &g.value(ids[1]).unwrap());
                (
                    vec![
                        nalgebra::DMatrix::from_column_slice(3, 3, a.as_slice()),
                        nalgebra::DMatrix::from_column_slice(3, 3, b.as_slice()),
                    ],
                    vec![3, 3],
                )
            } else {
                let edge = e.edge().downcast_ref::<EdgeSE2XY>().unwrap();
                let (a, b) = edge.jacobians(&g.value(ids[0]).unwrap(), &g.value(ids[1]).unwrap());
                (
                    vec![
                        nalgebra::DMatrix::from_column_slice(2, 3, a.as_slice()),
                        nalgebra::DMatrix::from_column_slice(2, 2, b.as_slice()),
                    ],
                    vec![3, 2],
                )
            };
        let k = e.error_dim();
        let omega = nalgebra::DMatrix::from_column_slice(k, k, e.information());
        for p in 0..2 {
            for q in 0..2 {
                if let (Some(op), Some(oq)) = (offset(ids[p]), offset(ids[q])) {
                    let block = jacobians[p].transpose() * &omega * &jacobians[q];
                    let mut view = h.view_mut((op, oq), (dims[p], dims[q]));
                    view += block;
                }
            }
        }
    }
    let inverse = h.try_inverse().unwrap();
    // A few vertices (solved for), and all of them (selected inversion), on
    // every kind of factor.
    for ids in [vec![3, 50, 11], free.clone()] {
        for ordering in [
            cairn_solvers::Ordering::BlockAmd,
            cairn_solvers::Ordering::Amd,
            cairn_solvers::Ordering::Schur,
        ] {
            for factorization in [
                cairn_solvers::Factorization::Simplicial,
                cairn_solvers::Factorization::Supernodal,
            ] {
                let mut config = SolverConfig::default();
                config.linear.ordering = ordering;
                config.linear.factorization = factorization;
                let mut opt = Optimizer::new(&g, config).unwrap();
                let marginals = opt.marginals(&g, &ids).unwrap();
                for (id, m) in ids.iter().zip(&marginals) {
                    let (o, d) = (offset(*id).unwrap(), m.nrows());
                    let expected = inverse.view((o, o), (d, d));
                    assert!(
                        (m - expected).amax() <= 1e-9 * expected.amax(),
                        "vertex {id}, {ordering:?} {factorization:?}:\n{m}\n{expected}"
                    );
                }
            }
        }
    }
    assert_eq!(
        opt.marginals(&g, &[0]).unwrap_err(),
        SolveError::FixedVertex(0)
    );
    assert_eq!(
        opt.marginals(&g, &[77]).unwrap_err(),
        SolveError::UnknownVertex(77)
    );
}
