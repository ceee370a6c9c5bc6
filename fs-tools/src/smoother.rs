//! A batch smoother given the associations: what the log allows when the
//! data association is solved, an upper bound for the front ends.
//!
//! Every scan is a pose, tied to the one before (the first to the log's
//! start) by the odometry integrated between them (the front end's motion
//! model, [`FrontEndConfig`]'s noise);
//! every detection with a known landmark is a range/bearing sighting as an
//! `EDGE_SE2_XY` with the assumed detector noise under a Cauchy kernel. The
//! start is held; the poses start from dead
//! reckoning and the landmarks from their first sighting, and Cairn's
//! Levenberg-Marquardt solves it from the best of the file's and the chordal
//! starts ([`Initialization::Auto`]).

use cairn_core::edges::{EdgeSE2, EdgeSE2XY};
use cairn_core::{Graph, GraphError, RobustKernel, SE2};
use cairn_slam::files::{Association, StampedPose};
use cairn_slam::frontend::FrontEndConfig;
use cairn_slam::log::Record;
use cairn_slam::motion::Odometry;
use cairn_slam::track::Cone;
use cairn_solvers::{Algorithm, Initialization, SolveError, SolverConfig, Summary, optimize_from};
use nalgebra::{Matrix2, Matrix3, Vector2};
use std::collections::HashMap;

/// The Cauchy kernel's width on the sightings' χ² (as `cairn solve
/// --robust-kernel cauchy --robust-kernel-width 1`).
pub const CAUCHY_WIDTH: f64 = 1.0;

/// Variance added to every odometry step's covariance: a robot standing
/// still has a step of zero covariance, whose information would be infinite.
const STEP_FLOOR: [f64; 3] = [1e-8, 1e-8, 1e-10];

/// The smoothed map and trajectory.
pub struct Smoothed {
    /// The landmarks that some detection names, in the order of their ids.
    pub map: Vec<Cone>,
    /// The associations given, the landmarks named by their row in `map`.
    pub associations: Vec<Association>,
    /// One pose per scan.
    pub trajectory: Vec<StampedPose>,
    /// The solver's summary.
    pub summary: Summary,
    /// The graph as solved, for `cairn solve` and g2o: vertex 0 is the
    /// start (held), scan k vertex k + 1, landmark id l vertex 2⁴⁰ + l.
    pub graph: Graph,
}

/// Why the smoother could not run.
#[derive(Debug, thiserror::Error)]
pub enum SmoothError {
    /// The log has no scan.
    #[error("the log has no scan")]
    NoScan,
    /// An association names a scan or detection the log does not have.
    #[error("association row {row}: scan {scan}, detection {det} is not in the log")]
    NotInLog {
        /// 0-based row of the associations.
        row: usize,
        /// Its scan.
        scan: usize,
        /// Its detection.
        det: usize,
    },
    /// The graph could not be built.
    #[error(transparent)]
    Graph(#[from] GraphError),
    /// The solver failed.
    #[error(transparent)]
    Solve(#[from] SolveError),
}

/// Scans added between two solves of the growing graph.
const CHUNK: usize = 100;

/// A sighting of a known landmark from a scan.
struct Sighting {
    scan: usize,
    landmark: usize,
    z: Vector2<f64>,
    information: Matrix2<f64>,
}

/// Builds the graph of `log` with the landmark of every detection that
/// `associations` gives, and solves it. The graph grows [`CHUNK`] scans at a
/// time, each solve starting from the last one's estimate, so that the
/// dead reckoning of a long log (metres off) never has to be undone at once.
pub fn smooth(
    log: &[Record],
    associations: &[Association],
    config: &FrontEndConfig,
) -> Result<Smoothed, SmoothError> {
    let mut motion = Odometry::new(config.motion, config.motion_noise());
    let mut start = SE2::identity();
    let mut times = Vec::new();
    let mut steps = Vec::new();
    let mut scans = Vec::new();
    for record in log {
        match record {
            Record::Start { pose, .. } if times.is_empty() => start = *pose,
            Record::Odom {
                t,
                v,
                yaw_rate,
                steer,
                ..
            } => motion.record(*t, *v, *yaw_rate, *steer, (1.0, 0.0)),
            Record::Cones { t, cones } => {
                motion.advance(*t, (1.0, 0.0));
                let (delta, cov) = motion.take();
                let floor = Matrix3::from_diagonal(&STEP_FLOOR.into());
                let information = (cov + floor).try_inverse().unwrap_or_else(Matrix3::zeros);
                steps.push((delta, information));
                times.push(*t);
                scans.push(cones);
            }
            _ => {}
        }
    }
    if times.is_empty() {
        return Err(SmoothError::NoScan);
    }
    let mut sightings = Vec::new();
    for (row, a) in associations.iter().enumerate() {
        let d = scans
            .get(a.scan)
            .and_then(|cones| cones.get(a.det))
            .ok_or(SmoothError::NotInLog {
                row,
                scan: a.scan,
                det: a.det,
            })?;
        if let Some(landmark) = a.landmark {
            sightings.push(Sighting {
                scan: a.scan,
                landmark,
                z: d.position,
                information: config
                    .detection_cov(d)
                    .try_inverse()
                    .unwrap_or_else(Matrix2::zeros),
            });
        }
    }
    sightings.sort_by_key(|s| s.scan);
    // poses[0] is the start, poses[k + 1] scan k's.
    let mut poses = vec![start];
    let mut landmarks: HashMap<usize, Vector2<f64>> = HashMap::new();
    let n = times.len();
    let mut summary = None;
    let mut graph = Graph::new();
    let ends = (CHUNK..n).step_by(CHUNK).chain(std::iter::once(n));
    for end in ends {
        while poses.len() <= end {
            let k = poses.len() - 1;
            let next = poses[k].compose(&steps[k].0);
            poses.push(next);
        }
        let seen = sightings.partition_point(|s| s.scan < end);
        for s in &sightings[..seen] {
            landmarks
                .entry(s.landmark)
                .or_insert_with(|| poses[s.scan + 1].transform_point(&s.z));
        }
        graph = build(&poses, &steps[..end], &sightings[..seen], &landmarks)?;
        let solver = SolverConfig {
            algorithm: Algorithm::LevenbergMarquardt,
            max_iterations: 200,
            ..SolverConfig::default()
        };
        let init = if end == n { Initialization::Auto } else { Initialization::File };
        summary = Some(optimize_from(&mut graph, solver, init, &mut |_, _| {})?.0);
        for (k, pose) in poses.iter_mut().enumerate() {
            *pose = graph.value::<SE2, 3>(k as i64)?;
        }
        for (l, p) in landmarks.iter_mut() {
            *p = graph.value::<Vector2<f64>, 2>(landmark_vertex(*l))?;
        }
    }
    let trajectory = times
        .iter()
        .zip(&poses[1..])
        .map(|(&t, &pose)| StampedPose { t, pose })
        .collect();
    let mut seen: Vec<usize> = landmarks.keys().copied().collect();
    seen.sort_unstable();
    let row: HashMap<usize, usize> = seen.iter().enumerate().map(|(r, &l)| (l, r)).collect();
    let map = seen
        .iter()
        .map(|l| Cone::new(landmarks[l].x, landmarks[l].y, cairn_slam::Color::Unknown))
        .collect();
    let associations = associations
        .iter()
        .map(|a| Association {
            landmark: a.landmark.and_then(|l| row.get(&l).copied()),
            ..*a
        })
        .collect();
    Ok(Smoothed {
        map,
        associations,
        trajectory,
        summary: summary.ok_or(SmoothError::NoScan)?,
        graph,
    })
}

/// Landmark ids start at this vertex id, clear of any log's scans.
const LANDMARK_BASE: i64 = 1 << 40;

fn landmark_vertex(landmark: usize) -> i64 {
    LANDMARK_BASE + landmark as i64
}

/// The graph of the start (held), the poses `poses[1..]` tied by `steps`,
/// and the `sightings` of `landmarks`.
fn build(
    poses: &[SE2],
    steps: &[(SE2, Matrix3<f64>)],
    sightings: &[Sighting],
    landmarks: &HashMap<usize, Vector2<f64>>,
) -> Result<Graph, GraphError> {
    let mut graph = Graph::new();
    for (k, pose) in poses.iter().enumerate().take(steps.len() + 1) {
        graph.add_vertex(k as i64, *pose)?;
    }
    graph.set_fixed(0, true)?;
    for (k, (delta, information)) in steps.iter().enumerate() {
        graph.add_edge(k as i64, k as i64 + 1, EdgeSE2::new(*delta), *information)?;
    }
    let mut ids: Vec<usize> = sightings.iter().map(|s| s.landmark).collect();
    ids.sort_unstable();
    ids.dedup();
    for l in ids {
        graph.add_vertex(landmark_vertex(l), landmarks[&l])?;
    }
    for s in sightings {
        let edge = EdgeSE2XY::new(s.z);
        let e = graph.add_edge(s.scan as i64 + 1, landmark_vertex(s.landmark), edge, s.information)?;
        graph.set_robust_kernel(e, Some(RobustKernel::Cauchy(CAUCHY_WIDTH)));
    }
    Ok(graph)
}
