//! The whole run as one pose/landmark graph, solved by Cairn: the start
//! (held), a pose per scan tied to the one before by its odometry step, and
//! range/bearing sightings of landmarks as `EDGE_SE2_XY` under a Cauchy
//! kernel. Given the true associations it is the upper bound of a front end
//! (`cairn fs-smooth`).

use cairn_core::edges::{EdgeSE2, EdgeSE2XY};
use cairn_core::{Graph, GraphError, RobustKernel, SE2};
use cairn_slam::frontend::OptimiseError;
use cairn_solvers::{Algorithm, Initialization, SolverConfig, Summary, optimize};
use nalgebra::{Matrix2, Matrix3, Vector2};

/// The Cauchy kernel's width on the sightings' χ² (as `cairn solve
/// --robust-kernel cauchy --robust-kernel-width 1`).
pub const CAUCHY_WIDTH: f64 = 1.0;

/// Landmark ids start at this vertex id, clear of any log's scans.
const LANDMARK_BASE: i64 = 1 << 40;

/// A sighting of landmark `landmark` from scan `scan`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatchSighting {
    /// The scan (0-based).
    pub scan: usize,
    /// The landmark (index into [`Batch::landmarks`]).
    pub landmark: usize,
    /// The detection in the vehicle frame.
    pub z: Vector2<f64>,
    /// Its information matrix.
    pub information: Matrix2<f64>,
}

/// The run's graph and its current estimate.
#[derive(Clone, Debug, Default)]
pub struct Batch {
    /// `poses[0]` is the start, `poses[k + 1]` scan k's pose.
    pub poses: Vec<SE2>,
    /// Scan k's odometry step from the pose before and its information.
    pub steps: Vec<(SE2, Matrix3<f64>)>,
    /// The sightings.
    pub sightings: Vec<BatchSighting>,
    /// Landmark positions; those no sighting names stay out of the graph.
    pub landmarks: Vec<Vector2<f64>>,
}

impl Batch {
    /// A run that starts at `start`.
    pub fn new(start: SE2) -> Self {
        Self {
            poses: vec![start],
            ..Self::default()
        }
    }

    /// Solves with Levenberg-Marquardt from `init` for at most
    /// `iterations` and takes the estimate.
    pub fn solve(
        &mut self,
        init: Initialization,
        iterations: usize,
    ) -> Result<Summary, OptimiseError> {
        let (mut graph, in_graph) = self.graph()?;
        let config = SolverConfig {
            algorithm: Algorithm::LevenbergMarquardt,
            max_iterations: iterations,
            init,
            ..SolverConfig::default()
        };
        let summary = optimize(&mut graph, config)?;
        for (k, pose) in self.poses.iter_mut().enumerate() {
            *pose = graph.value::<SE2, 3>(k as i64)?;
        }
        for (l, p) in self.landmarks.iter_mut().enumerate() {
            if in_graph[l] {
                *p = graph.value::<Vector2<f64>, 2>(LANDMARK_BASE + l as i64)?;
            }
        }
        Ok(summary)
    }

    /// The graph, and which landmarks are in it.
    pub fn graph(&self) -> Result<(Graph, Vec<bool>), GraphError> {
        let mut graph = Graph::new();
        let scans = self.steps.len().min(self.poses.len().saturating_sub(1));
        for (k, pose) in self.poses.iter().enumerate().take(scans + 1) {
            graph.add_vertex(k as i64, *pose)?;
        }
        graph.set_fixed(0, true)?;
        for (k, (delta, information)) in self.steps.iter().take(scans).enumerate() {
            graph.add_edge(k as i64, k as i64 + 1, EdgeSE2::new(*delta), *information)?;
        }
        let mut in_graph = vec![false; self.landmarks.len()];
        for s in self.sightings.iter().filter(|s| s.scan < scans) {
            if !in_graph[s.landmark] {
                in_graph[s.landmark] = true;
                graph.add_vertex(
                    LANDMARK_BASE + s.landmark as i64,
                    self.landmarks[s.landmark],
                )?;
            }
            let vertex = LANDMARK_BASE + s.landmark as i64;
            let e = graph.add_edge(
                s.scan as i64 + 1,
                vertex,
                EdgeSE2XY::new(s.z),
                s.information,
            )?;
            graph.set_robust_kernel(e, Some(RobustKernel::Cauchy(CAUCHY_WIDTH)));
        }
        Ok((graph, in_graph))
    }
}
