//! Golden parses of every file in ../shared/datasets/parser, with the expected
//! values written here (counts, chosen values, χ² at the file's vertices and at
//! the optimum from the MANIFEST's independent computation).

mod common;

use approx::assert_relative_eq;
use cairn::core::{Graph, SE2, SE3};
use cairn::g2o::{G2oError, LoadReport, ReadOptions, read_file};
use cairn::solvers::{SolverConfig, optimize};
use nalgebra::Vector2;

fn load(name: &str) -> Option<(Graph, LoadReport)> {
    let path = common::dataset(&format!("parser/{name}"))?;
    Some(read_file(&path, &ReadOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}")))
}

fn optimum(graph: &mut Graph) -> f64 {
    optimize(graph, SolverConfig::default())
        .expect("solves")
        .final_chi2
}

#[test]
fn klaus3() {
    let Some((mut g, r)) = load("Klaus3.g2o") else {
        return;
    };
    assert_eq!((g.num_vertices(), g.num_edges(), r.lines), (3, 3, 6));
    let x0: SE3 = g.value(0).unwrap();
    assert_relative_eq!(x0.t.x, -1.6618596980158338);
    assert_relative_eq!(x0.t.z, -3.3319774096611026);
    // The printed quaternion is not quite unit; it is normalised on reading.
    assert_relative_eq!(x0.q.quaternion().norm(), 1.0, epsilon = 1e-15);
    assert_relative_eq!(x0.q.quaternion().w, 0.99922, epsilon = 1e-5);
    assert_relative_eq!(g.chi2(), 0.21463, max_relative = 1e-4);
    assert_relative_eq!(optimum(&mut g), 0.009118, max_relative = 1e-3);
}

#[test]
fn example_with_vertices_skips_trackxyz_and_has_no_edges() {
    let Some((g, r)) = load("example_with_vertices.g2o") else {
        return;
    };
    assert_eq!((g.num_vertices(), g.num_edges()), (8, 0));
    assert_eq!(r.unknown.get("VERTEX_TRACKXYZ"), Some(&8));
    let x2: SE3 = g.value(2).unwrap();
    assert_relative_eq!(x2.t.y, 40.0);
    assert_relative_eq!(x2.t.x, -1.6986e-08);
}

#[test]
fn noisy_toy_graph() {
    let Some((mut g, r)) = load("noisyToyGraph.txt") else {
        return;
    };
    assert_eq!((g.num_vertices(), g.num_edges()), (4, 5));
    assert_eq!(r.records.get("EDGE_SE2"), Some(&5));
    let x1: SE2 = g.value(1).unwrap();
    assert_eq!((x1.t.x, x1.t.y, x1.theta), (0.774115, 1.183389, 1.576173));
    assert_relative_eq!(g.chi2(), 0.783275, max_relative = 1e-5);
    assert_relative_eq!(optimum(&mut g), 0.136652, max_relative = 1e-5);
}

#[test]
fn pose2example_without_final_newline() {
    let Some((mut g, r)) = load("pose2example.txt") else {
        return;
    };
    assert_eq!((g.num_vertices(), g.num_edges(), r.lines), (11, 12, 23));
    let x3: SE2 = g.value(3).unwrap();
    assert_eq!((x3.t.x, x3.t.y, x3.theta), (3.015097, -0.442395, -0.345514));
    let last = g.edge(11);
    assert_eq!(last.information()[8], 30.901699);
    assert_relative_eq!(g.chi2(), 6.852392, max_relative = 1e-6);
    assert_relative_eq!(optimum(&mut g), 1.098934, max_relative = 1e-5);
}

#[test]
fn pose3example_off_diagonal_information() {
    let Some((g, _)) = load("pose3example-offdiagonal.txt") else {
        return;
    };
    assert_eq!((g.num_vertices(), g.num_edges()), (2, 1));
    let info = g.edge(0).information();
    // Upper triangle row by row: I11 = 10000, I12 … I16 = 1, I22 = 10000, I23 = 2 …
    assert_eq!(
        (info[0], info[6], info[1], info[7], info[13]),
        (10000.0, 1.0, 1.0, 10000.0, 2.0)
    );
}

#[test]
fn pose3example() {
    let Some((mut g, _)) = load("pose3example.txt") else {
        return;
    };
    assert_eq!((g.num_vertices(), g.num_edges()), (5, 6));
    assert_relative_eq!(g.chi2(), 95358.59347, max_relative = 1e-6);
    assert_relative_eq!(optimum(&mut g), 17781.78698, max_relative = 1e-5);
}

#[test]
fn test_r2_counts_the_junk_line() {
    let Some((g, r)) = load("test_r2.g2o") else {
        return;
    };
    assert_eq!((g.num_vertices(), g.num_edges()), (2, 0));
    assert_eq!(r.unknown.get("This"), Some(&1));
    let p: Vector2<f64> = g.value(1).unwrap();
    assert_eq!(p, Vector2::zeros());
}

#[test]
fn test_se2_has_an_indefinite_information_matrix() {
    let Some(dir) = common::shared() else { return };
    let path = dir.join("datasets/parser/test_se2.g2o");
    match read_file(&path, &ReadOptions::default()) {
        Err(G2oError::IndefiniteInformation { count: 1, lines }) => assert_eq!(lines, vec![6]),
        other => panic!(
            "expected an indefinite-information error, got {:?}",
            other.map(|_| ())
        ),
    }
    let (g, r) = read_file(
        &path,
        &ReadOptions {
            repair_information: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((g.num_vertices(), g.num_edges()), (4, 1));
    assert_eq!(r.repaired_information, vec![6]);
    assert_eq!(r.unknown.get("PARAMS_SE2OFFSET"), Some(&1));
    assert_eq!(r.unknown.get("This"), Some(&1));
}

#[test]
fn test_se3_mixes_se3_poses_and_xy_points() {
    let Some(dir) = common::shared() else { return };
    let path = dir.join("datasets/parser/test_se3.g2o");
    let (g, r) = read_file(
        &path,
        &ReadOptions {
            repair_information: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((g.num_vertices(), g.num_edges()), (4, 1));
    assert_eq!(r.repaired_information, vec![6]);
    let x1: SE3 = g.value(1).unwrap();
    assert_relative_eq!(x1.q.quaternion().w, 0.5);
    assert_eq!((x1.t.y, x1.t.z), (1.0, 2.0));
}

#[test]
fn toy_example_reaches_zero() {
    let Some((mut g, _)) = load("toyExample.g2o") else {
        return;
    };
    assert_eq!((g.num_vertices(), g.num_edges()), (5, 6));
    assert_relative_eq!(g.chi2(), 1700.022498, max_relative = 1e-6);
    assert!(optimum(&mut g) < 1e-9);
}
