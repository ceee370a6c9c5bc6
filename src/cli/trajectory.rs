//! `solve --traj-out`: a solved graph's poses as a trajectory file, for evo
//! and other trajectory tools.

use super::CliError;
use cairn::core::{Graph, SE2, SE3};
use clap::ValueEnum;
use std::fmt::Write as _;

/// Trajectory file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TrajectoryFormat {
    /// TUM: `t x y z qx qy qz qw` per pose, t the vertex id (g2o files have no times).
    Tum,
    /// KITTI: the 3×4 matrix [R t] row by row per pose, in id order.
    Kitti,
}

/// The graph's SE2 and SE3 poses in id order, in `format`; SE2 poses lie in
/// the plane z = 0, turned about z. Other vertices (landmarks) are left out.
pub fn trajectory(graph: &Graph, format: TrajectoryFormat) -> Result<String, CliError> {
    let mut poses: Vec<(i64, SE3)> = graph
        .vertices()
        .filter_map(|v| match v.kind.name {
            "SE2" => Some((v.id, planar(&graph.value::<SE2, 3>(v.id).ok()?))),
            "SE3" => Some((v.id, graph.value::<SE3, 6>(v.id).ok()?)),
            _ => None,
        })
        .collect();
    if poses.is_empty() {
        return Err(CliError::input(
            "--traj-out: the graph has no SE2 or SE3 poses",
        ));
    }
    poses.sort_by_key(|(id, _)| *id);
    let mut out = String::new();
    for (id, pose) in &poses {
        let t = pose.t;
        match format {
            TrajectoryFormat::Tum => {
                let q = pose.q.quaternion();
                let _ = writeln!(
                    out,
                    "{id} {:?} {:?} {:?} {:?} {:?} {:?} {:?}",
                    t.x, t.y, t.z, q.i, q.j, q.k, q.w
                );
            }
            TrajectoryFormat::Kitti => {
                let r = pose.rotation();
                let row = |i: usize| {
                    format!("{:?} {:?} {:?} {:?}", r[(i, 0)], r[(i, 1)], r[(i, 2)], t[i])
                };
                let _ = writeln!(out, "{} {} {}", row(0), row(1), row(2));
            }
        }
    }
    Ok(out)
}

/// An SE2 pose as the SE3 pose in the plane z = 0.
fn planar(p: &SE2) -> SE3 {
    SE3::new(
        nalgebra::Vector3::new(p.t.x, p.t.y, 0.0),
        nalgebra::UnitQuaternion::from_axis_angle(&nalgebra::Vector3::z_axis(), p.theta),
    )
}
