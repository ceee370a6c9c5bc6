//! Both SE3 objectives: g2o's (t, q.xyz) and the Logmap one (t, Log R).
//! Each solve is scored by both objectives computed here from the poses and
//! the measurements, apart from the edge's own code, and each wins its own.

mod common;

use cairn::core::{EdgeSE3, Graph, SE3, Se3Error};
use cairn::g2o::{ReadOptions, read_file};
use cairn::solvers::{SolverConfig, optimize};
use nalgebra::{Matrix6, Vector6};

/// Σ eᵀΩe over the graph's SE3 edges, the rotation part of e being the
/// quaternion's vector part (g2o) or the rotation vector (Logmap).
fn objective(graph: &Graph, kind: Se3Error) -> f64 {
    let mut total = 0.0;
    for e in graph.edges() {
        let edge = e.edge().downcast_ref::<EdgeSE3>().expect("SE3 edges only");
        let [i, j] = [e.vertices()[0], e.vertices()[1]];
        let xi: SE3 = graph.value(graph.vertex(i).id).unwrap();
        let xj: SE3 = graph.value(graph.vertex(j).id).unwrap();
        let d = edge.measurement().inverse() * xi.inverse() * xj;
        let q = d.q.quaternion();
        let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
        let rotation = match kind {
            Se3Error::G2o => q.imag() * sign,
            Se3Error::Logmap => d.q.scaled_axis(),
        };
        let r = Vector6::new(d.t.x, d.t.y, d.t.z, rotation.x, rotation.y, rotation.z);
        let omega = Matrix6::from_column_slice(e.information());
        total += (r.transpose() * omega * r)[0];
    }
    total
}

fn solved(path: &std::path::Path, kind: Se3Error) -> Graph {
    let options = ReadOptions {
        se3_error: kind,
        ..Default::default()
    };
    let (mut graph, _) = read_file(path, &options).unwrap();
    let summary = optimize(&mut graph, SolverConfig::default()).unwrap();
    assert!(summary.termination.converged(), "{kind:?}: {summary:?}");
    // The solver's χ² is the objective it was asked for.
    let own = objective(&graph, kind);
    assert!((summary.final_chi2 - own).abs() <= 1e-9 * own, "{kind:?}");
    graph
}

#[test]
fn each_se3_objective_is_lowest_at_its_own_solution() {
    for file in ["3d/sphere2500.g2o", "3d/parking-garage.g2o"] {
        let Some(path) = common::dataset(file) else {
            return;
        };
        let g2o = solved(&path, Se3Error::G2o);
        let logmap = solved(&path, Se3Error::Logmap);
        let by = |g: &Graph, kind| objective(g, kind);
        eprintln!(
            "{file}: g2o solve {} / {}, logmap solve {} / {}",
            by(&g2o, Se3Error::G2o),
            by(&g2o, Se3Error::Logmap),
            by(&logmap, Se3Error::G2o),
            by(&logmap, Se3Error::Logmap)
        );
        assert!(
            by(&g2o, Se3Error::G2o) < by(&logmap, Se3Error::G2o),
            "{file}"
        );
        assert!(
            by(&logmap, Se3Error::Logmap) < by(&g2o, Se3Error::Logmap),
            "{file}"
        );
        // The rotation terms weigh about 4× g2o's: the Logmap optimum is
        // above g2o's, by less than that factor.
        let ratio = by(&logmap, Se3Error::Logmap) / by(&g2o, Se3Error::G2o);
        assert!((1.0..4.0).contains(&ratio), "{file}: {ratio}");
    }
}
