//! False loop closures for robustness experiments, and the trajectory error
//! that measures recovery.

use cairn_core::{EdgeSE2, EdgeSE3, Graph, GraphError, SE2, SE3};
use nalgebra::{Matrix3, Matrix6, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::any::TypeId;
use std::f64::consts::PI;

/// Adds `round(fraction × edges)` false loop closures between random pairs of
/// poses that are not neighbours in id order, each measuring a random relative
/// pose (translation uniform in ±`spread` m per axis, rotation uniform) with the
/// information matrix of the graph's first edge of that type (identity if none).
/// Seeded. Returns the numbers of the added edges.
pub fn add_false_loop_closures(
    graph: &mut Graph,
    fraction: f64,
    spread: f64,
    seed: u64,
) -> Result<Vec<usize>, GraphError> {
    let mut rng = StdRng::seed_from_u64(seed);
    let se2: Vec<i64> = graph
        .vertices()
        .filter(|v| v.kind.type_id == TypeId::of::<SE2>())
        .map(|v| v.id)
        .collect();
    let se3: Vec<i64> = graph
        .vertices()
        .filter(|v| v.kind.type_id == TypeId::of::<SE3>())
        .map(|v| v.id)
        .collect();
    let (poses, planar) = if se2.len() >= se3.len() {
        (se2, true)
    } else {
        (se3, false)
    };
    let count = (fraction.max(0.0) * graph.num_edges() as f64).round() as usize;
    if poses.len() < 3 || count == 0 {
        return Ok(Vec::new());
    }
    let info2 = graph
        .edges()
        .find(|e| e.edge().is::<EdgeSE2>())
        .map_or(Matrix3::identity(), |e| {
            Matrix3::from_column_slice(e.information())
        });
    let info3 = graph
        .edges()
        .find(|e| e.edge().is::<EdgeSE3>())
        .map_or(Matrix6::identity(), |e| {
            Matrix6::from_column_slice(e.information())
        });
    let mut added = Vec::with_capacity(count);
    while added.len() < count {
        let (a, b) = (
            rng.random_range(0..poses.len()),
            rng.random_range(0..poses.len()),
        );
        if a.abs_diff(b) < 2 {
            continue;
        }
        let (i, j) = (poses[a], poses[b]);
        let t = |rng: &mut StdRng| rng.random_range(-spread..spread);
        let k = if planar {
            let z = SE2::new(t(&mut rng), t(&mut rng), rng.random_range(-PI..PI));
            graph.add_edge(i, j, EdgeSE2::new(z), info2)?
        } else {
            let axis = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let q = UnitQuaternion::from_scaled_axis(axis.normalize() * rng.random_range(0.0..PI));
            let z = SE3::new(Vector3::new(t(&mut rng), t(&mut rng), t(&mut rng)), q);
            graph.add_edge(i, j, EdgeSE3::new(z), info3)?
        };
        added.push(k);
    }
    Ok(added)
}

/// Root-mean-square distance between the positions of the poses (SE2 or SE3)
/// that both graphs have, by id; `None` if they share none. Both graphs should
/// share their gauge (e.g. the same fixed first pose), so no alignment is done.
pub fn position_rms(a: &Graph, b: &Graph) -> Option<f64> {
    let mut sum = 0.0;
    let mut n = 0usize;
    for v in a.vertices() {
        let Some(w) = b.vertex_index(v.id).map(|i| b.vertex(i)) else {
            continue;
        };
        if v.kind.type_id != w.kind.type_id || !(v.kind.is_pose) {
            continue;
        }
        let dims = if v.kind.type_id == TypeId::of::<SE2>() {
            2
        } else {
            3
        };
        sum += (0..dims)
            .map(|k| (v.params[k] - w.params[k]).powi(2))
            .sum::<f64>();
        n += 1;
    }
    (n > 0).then(|| (sum / n as f64).sqrt())
}

/// Puts `kernel` on every edge, or with `loop_closures_only` on every edge except
/// those between vertices with consecutive ids (odometry), g2o's
/// `-nonSequential`. Returns how many edges got it.
pub fn set_robust_kernel(
    graph: &mut Graph,
    kernel: cairn_core::RobustKernel,
    loop_closures_only: bool,
) -> usize {
    let mut count = 0;
    for k in 0..graph.num_edges() {
        let ids: Vec<i64> = graph
            .edge(k)
            .vertices()
            .iter()
            .map(|&v| graph.vertex(v).id)
            .collect();
        let sequential = ids.len() == 2 && (ids[0] - ids[1]).abs() == 1;
        if !(loop_closures_only && sequential) {
            graph.set_robust_kernel(k, Some(kernel));
            count += 1;
        }
    }
    count
}
