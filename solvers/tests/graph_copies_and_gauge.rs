//! A graph's copies and how its gauge is fixed.

use cairn_core::{EdgeSE2, Graph, SE2};
use cairn_solvers::{Algorithm, SolverConfig, Termination, optimize};
use nalgebra::{Matrix2, Matrix3, Vector2};

mod common;
use common::noisy_loop;

fn config(algorithm: Algorithm) -> SolverConfig {
    SolverConfig {
        algorithm,
        ..Default::default()
    }
}

#[test]
fn a_cloned_graph_solves_apart_from_its_original() {
    let g = noisy_loop(25, 11);
    let start = g.values().params().to_vec();
    let mut copy = g.clone();
    assert_eq!(
        (copy.num_vertices(), copy.num_edges()),
        (g.num_vertices(), g.num_edges())
    );
    assert_eq!(copy.chi2(), g.chi2());
    copy.set_robust_kernel(0, Some(cairn_core::RobustKernel::Huber(1.0)));
    assert!(
        g.edge(0).kernel().is_none(),
        "the kernel went to the copy only"
    );
    copy.set_robust_kernel(0, None);
    let solved = optimize(&mut copy, config(Algorithm::GaussNewton)).unwrap();
    assert_eq!(g.values().params(), &start[..], "the original is untouched");
    let mut original = g.clone();
    let again = optimize(&mut original, config(Algorithm::GaussNewton)).unwrap();
    assert_eq!(again.final_chi2, solved.final_chi2);
    assert_eq!(original.values().params(), copy.values().params());
}

/// A position-only prior (a GPS fix): rank 2 on an SE2 pose.
#[derive(Clone)]
struct Gps(Vector2<f64>);

impl cairn_core::UnaryEdge<2, 3> for Gps {
    type V = SE2;
    const NAME: &'static str = "GPS";
    fn error(&self, x: &SE2) -> nalgebra::SVector<f64, 2> {
        x.t - self.0
    }
}

#[test]
fn gauge_none_leaves_two_gps_fixes_to_hold_the_graph() {
    // Two poses 1 m apart, each with a GPS fix that the odometry agrees
    // with, but the first pose starts 0.3 m off its fix.
    let mut g = Graph::new();
    g.add_vertex(0, SE2::new(0.3, 0.2, 0.0)).unwrap();
    g.add_vertex(1, SE2::new(1.0, 0.0, 0.1)).unwrap();
    g.add_edge(
        0,
        1,
        EdgeSE2::new(SE2::new(1.0, 0.0, 0.0)),
        Matrix3::identity(),
    )
    .unwrap();
    g.add_unary_edge(0, Gps(Vector2::new(0.0, 0.0)), Matrix2::identity())
        .unwrap();
    g.add_unary_edge(1, Gps(Vector2::new(1.0, 0.0)), Matrix2::identity())
        .unwrap();
    // Auto pins pose 0 where it starts: the fixes cannot move it.
    let mut auto = g.clone();
    let pinned = optimize(&mut auto, config(Algorithm::GaussNewton)).unwrap();
    assert_eq!(pinned.gauge, vec![0]);
    assert!(pinned.final_chi2 > 0.1, "{}", pinned.final_chi2);
    // None lets the fixes place both poses: χ² ≈ 0, pose 0 on its fix.
    let free = SolverConfig {
        gauge: cairn_solvers::Gauge::None,
        ..config(Algorithm::GaussNewton)
    };
    let s = optimize(&mut g, free.clone()).unwrap();
    assert!(s.gauge.is_empty());
    assert!(s.final_chi2 < 1e-12, "{}", s.final_chi2);
    let x0: SE2 = g.value(0).unwrap();
    assert!(x0.t.norm() < 1e-6 && x0.theta.abs() < 1e-6, "{x0:?}");
    // One fix does not hold the graph: without the gauge H is singular.
    let mut one = Graph::new();
    one.add_vertex(0, SE2::new(0.3, 0.2, 0.0)).unwrap();
    one.add_unary_edge(0, Gps(Vector2::new(0.0, 0.0)), Matrix2::identity())
        .unwrap();
    let s = optimize(&mut one, free.clone()).unwrap();
    assert_eq!(s.termination, Termination::NotPositiveDefinite);
    // Named vertices hold instead of the automatic choice: pose 1 keeps the
    // value it was given, not marked fixed, and pose 0 moves towards its fix.
    let mut held = auto.clone();
    held.set_value(1, &SE2::new(1.5, 0.5, 0.0)).unwrap();
    let at_one = SolverConfig {
        gauge: cairn_solvers::Gauge::Vertices(vec![1]),
        ..free.clone()
    };
    let s = optimize(&mut held, at_one).unwrap();
    assert_eq!(s.gauge, vec![1]);
    assert!(!held.is_fixed(1).unwrap());
    let x1: SE2 = held.value(1).unwrap();
    assert_eq!((x1.t.x, x1.t.y, x1.theta), (1.5, 0.5, 0.0));
    let x0: SE2 = held.value(0).unwrap();
    assert!((x0.t - Vector2::new(0.5, 0.5)).norm() > 0.05, "{x0:?}");
    let nowhere = SolverConfig {
        gauge: cairn_solvers::Gauge::Vertices(vec![7]),
        ..free
    };
    assert_eq!(
        optimize(&mut held, nowhere).unwrap_err(),
        cairn_solvers::SolveError::UnknownVertex(7)
    );
}

/// The graph's API speaks ids: the gauge it picks and whether a vertex is
/// fixed are given by id, as `set_fixed` takes it and `Summary::gauge`
/// reports it, not by insertion index.
#[test]
fn the_gauge_and_fixed_vertices_are_named_by_id() {
    let mut graph = Graph::new();
    // Inserted out of id order, two components.
    for (id, x) in [(30, 2.0), (10, 0.0), (20, 1.0), (41, 5.0), (40, 4.0)] {
        graph.add_vertex(id, SE2::new(x, 0.0, 0.0)).unwrap();
    }
    let step = EdgeSE2::new(SE2::new(1.0, 0.0, 0.0));
    graph
        .add_edge(10, 20, step.clone(), Matrix3::identity())
        .unwrap();
    graph
        .add_edge(20, 30, step.clone(), Matrix3::identity())
        .unwrap();
    graph.add_edge(40, 41, step, Matrix3::identity()).unwrap();
    assert_eq!(graph.gauge_vertices(), vec![10, 40]);
    graph.set_fixed(41, true).unwrap();
    assert_eq!(graph.is_fixed(41).ok(), Some(true));
    assert_eq!(graph.is_fixed(40).ok(), Some(false));
    assert!(graph.is_fixed(99).is_err());
    // A fixed vertex anchors its component: only the first needs a gauge.
    assert_eq!(graph.gauge_vertices(), vec![10]);
    let summary = optimize(&mut graph, SolverConfig::default()).unwrap();
    assert_eq!(summary.gauge, vec![10]);
}

/// x³ = 1 from x = 100: Gauss-Newton (Newton's method here) needs more
/// iterations than `Auto` trusts, and a graph without poses has no chordal
/// start, so `Auto` carries the file's run on to convergence: one run, its
/// iterations numbered on.
#[derive(Clone, Debug)]
struct Cube;

impl cairn_core::NumericUnaryEdge<1> for Cube {
    type V = nalgebra::Vector1<f64>;
    const NAME: &'static str = "CUBE";
    fn error(&self, x: &nalgebra::Vector1<f64>) -> nalgebra::Vector1<f64> {
        nalgebra::Vector1::new(x[0].powi(3) - 1.0)
    }
}

#[test]
fn auto_carries_a_slow_run_from_the_file_on() {
    let mut g = Graph::new();
    g.add_vertex(0, nalgebra::Vector1::new(100.0)).unwrap();
    g.add_unary_edge(0, Cube, nalgebra::Matrix1::new(1.0))
        .unwrap();
    let s = optimize(&mut g, SolverConfig::default()).unwrap();
    assert_eq!(s.init, cairn_solvers::Initialization::File);
    assert!(
        s.iterations > cairn_solvers::AUTO_TRUSTED_ITERATIONS,
        "{}",
        s.iterations
    );
    assert!(s.termination.converged(), "{:?}", s.termination);
    let numbers: Vec<usize> = s.trace.iter().map(|t| t.iteration).collect();
    assert_eq!(numbers, (0..s.iterations).collect::<Vec<_>>());
    let x: nalgebra::Vector1<f64> = g.value(0).unwrap();
    assert!((x[0] - 1.0).abs() < 1e-9, "{x}");
}
