//! A batch smoother given the associations: what the log allows when the
//! data association is solved, an upper bound for the front ends.
//!
//! Every scan is a pose, tied to the one before (the first to the log's
//! start) by the odometry integrated between them (the front end's motion
//! model and [`FrontEndConfig`]'s noise); every detection with a
//! known landmark is a range/bearing sighting as an `EDGE_SE2_XY` with the
//! assumed detector noise under a Cauchy kernel ([`Batch`]). The start is
//! held; the poses start from dead reckoning and the landmarks from their
//! first sighting, and Cairn's Levenberg-Marquardt solves it.

use crate::batch::{Batch, BatchSighting};
use cairn_core::{Graph, GraphError, SE2};
use cairn_slam::Cone;
use cairn_slam::files::{Association, StampedPose};
use cairn_slam::frontend::{FrontEndConfig, OptimiseError, nearest_information};
use cairn_slam::log::Record;
use cairn_slam::motion::{Correction, Odometry};
use cairn_solvers::{Initialization, Summary};
use nalgebra::Vector2;
use std::collections::HashMap;

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
    /// start (held), scan k vertex k + 1, the landmarks from vertex 2⁴⁰ in
    /// the order the associations first name them.
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
    /// The graph could not be built or solved.
    #[error(transparent)]
    Optimise(#[from] OptimiseError),
    /// The graph could not be built.
    #[error(transparent)]
    Graph(#[from] GraphError),
}

/// Scans added between two solves of the growing graph.
const CHUNK: usize = 100;

/// Builds the graph of `log` with the landmark of every detection that
/// `associations` gives, and solves it. The graph grows 100 scans at a
/// time, each solve starting from the last one's estimate, so that the
/// dead reckoning of a long log (metres off) never has to be undone at once;
/// the last solve also tries the chordal starts ([`Initialization::Auto`]).
pub fn smooth(
    log: &[Record],
    associations: &[Association],
    config: &FrontEndConfig,
) -> Result<Smoothed, SmoothError> {
    let mut motion =
        Odometry::new(config.motion, config.motion_noise()).with_scan_latency(config.scan_latency);
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
                vy,
            } => motion.record(*t, (*v, *vy), *yaw_rate, *steer, Correction::NONE),
            Record::Cones { t, cones } => {
                let t = motion.advance_to_scan(*t, Correction::NONE);
                let (delta, cov) = motion.take();
                // A robot standing still has a step of zero covariance: the
                // ridge keeps its information finite.
                steps.push((delta, nearest_information(&cov)));
                times.push(t);
                scans.push(cones);
            }
            _ => {}
        }
    }
    if times.is_empty() {
        return Err(SmoothError::NoScan);
    }
    // Landmark ids as the associations give them → rows of the batch.
    let mut row: HashMap<usize, usize> = HashMap::new();
    let mut ids = Vec::new();
    let mut sightings = Vec::new();
    for (k, a) in associations.iter().enumerate() {
        let d =
            scans
                .get(a.scan)
                .and_then(|cones| cones.get(a.det))
                .ok_or(SmoothError::NotInLog {
                    row: k,
                    scan: a.scan,
                    det: a.det,
                })?;
        if let Some(id) = a.landmark {
            let landmark = *row.entry(id).or_insert_with(|| {
                ids.push(id);
                ids.len() - 1
            });
            let information = nearest_information(&config.detection_cov(d));
            sightings.push(BatchSighting {
                scan: a.scan,
                landmark,
                z: d.position,
                information,
            });
        }
    }
    sightings.sort_by_key(|s| s.scan);
    let mut batch = Batch::new(start);
    let mut placed = vec![false; ids.len()];
    batch.landmarks = vec![Vector2::zeros(); ids.len()];
    let n = times.len();
    let mut summary = None;
    for end in (CHUNK..n).step_by(CHUNK).chain(std::iter::once(n)) {
        while batch.poses.len() <= end {
            let k = batch.poses.len() - 1;
            let next = batch.poses[k].compose(&steps[k].0);
            batch.poses.push(next);
        }
        let seen = sightings.partition_point(|s| s.scan < end);
        for s in &sightings[..seen] {
            if !placed[s.landmark] {
                placed[s.landmark] = true;
                batch.landmarks[s.landmark] = batch.poses[s.scan + 1].transform_point(&s.z);
            }
        }
        batch.steps = steps[..end].to_vec();
        batch.sightings = sightings[..seen].to_vec();
        let init = if end == n {
            Initialization::Auto
        } else {
            Initialization::File
        };
        summary = Some(batch.solve(init, 200)?);
    }
    let trajectory = times
        .iter()
        .zip(&batch.poses[1..])
        .map(|(&t, &pose)| StampedPose { t, pose })
        .collect();
    // The map in the order of the landmarks' ids.
    let mut order: Vec<usize> = (0..ids.len()).collect();
    order.sort_by_key(|&l| ids[l]);
    let mut map_row = vec![0; ids.len()];
    for (r, &l) in order.iter().enumerate() {
        map_row[l] = r;
    }
    let map = order
        .iter()
        .map(|&l| {
            Cone::new(
                batch.landmarks[l].x,
                batch.landmarks[l].y,
                cairn_slam::Color::Unknown,
            )
        })
        .collect();
    let associations = associations
        .iter()
        .map(|a| Association {
            landmark: a.landmark.map(|id| map_row[row[&id]]),
            ..*a
        })
        .collect();
    let (graph, _) = batch.graph()?;
    Ok(Smoothed {
        map,
        associations,
        trajectory,
        summary: summary.ok_or(SmoothError::NoScan)?,
        graph,
    })
}
