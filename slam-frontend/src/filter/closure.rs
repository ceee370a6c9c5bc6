//! What FastSLAM does with the chosen particle at a loop closure: move it to
//! where the start landmarks put it, drop the landmarks it mapped twice, tie
//! the detections the gates left alone on the way back to the landmarks they
//! fall on, and smooth its path and map with Cairn's solver.
//!
//! A particle's map is fixed by the path it was built along: resampling can
//! only choose among the particles' maps, and after a lap they all descend
//! from one ancestor (path degeneracy), so none has undone the lap's drift.
//! The smoothing solves the chosen particle's own odometry and sightings,
//! with its own associations, in the graph front end's terms: each pose
//! carries the gyro's yaw-rate bias, so the integrated turns are weighed by
//! the yaw rate's white noise and not by a σ wide enough to cover the bias.

use super::landmark_from;
use super::particle::{Particle, Step};
use crate::color::Color;
use crate::files::StampedPose;
use crate::frontend::MERGE_RADIUS;
use crate::frontend::bias::{OdometryBias, PoseBias, SightingBias, StartPrior};
use crate::frontend::edges::{OdometryEdge, odometry_information};
use crate::log::Detection;
use crate::motion::Odometry;
use crate::sighting::Sighting;
use cairn_core::{EdgeSE2XY, Graph, GraphError, RobustKernel, SE2};
use cairn_solvers::{
    Algorithm, Factorization, Initialization, Optimizer, SolveError, SolverConfig,
};
use nalgebra::{Matrix2, Matrix3, Vector2};
use std::rc::Rc;

/// What the filter saw at one scan, the same for every particle: the
/// odometry since the scan before and each detection's range, bearing and
/// covariance, and its colour.
#[derive(Clone, Debug)]
pub(super) struct ScanEvidence {
    pub(super) t: f64,
    pub(super) odometry: OdometryEdge,
    pub(super) measurements: Vec<(Vector2<f64>, Matrix2<f64>)>,
    pub(super) colors: Vec<Color>,
}

/// Takes the motion since the last scan from `motion` and keeps it, with
/// the scan's `measurements` and the `cones` they are of, in `evidence`; returns the motion and its
/// covariance. The heading's variance beyond the gyro's bias is that of
/// `yaw_rate_noise` (rad/s), the gyro's white noise.
pub(super) fn record(
    evidence: &mut Vec<ScanEvidence>,
    t: f64,
    motion: &mut Odometry,
    yaw_rate_noise: f64,
    measurements: &[(Vector2<f64>, Matrix2<f64>)],
    cones: &[Detection],
) -> (SE2, Matrix3<f64>) {
    let heading_variance = motion.white_heading_variance(yaw_rate_noise);
    let slip_jacobian = motion.slip_jacobian();
    let (delta, cov) = motion.take();
    evidence.push(ScanEvidence {
        t,
        odometry: OdometryEdge {
            delta,
            information: odometry_information(&cov),
            dt: evidence.last().map_or(0.0, |e| t - e.t),
            // The filters integrate the odometry as measured.
            yaw_rate_bias: 0.0,
            slip_jacobian,
            slip_made: Vector2::zeros(),
            heading_variance,
        },
        measurements: measurements.to_vec(),
        colors: cones.iter().map(|d| d.color).collect(),
    });
    (delta, cov)
}

/// Why a smoothing was not applied.
#[derive(Debug, thiserror::Error)]
pub(super) enum SmoothError {
    #[error(transparent)]
    Graph(#[from] GraphError),
    #[error(transparent)]
    Solve(#[from] SolveError),
    #[error("the particle's path and the scans seen differ in length")]
    Path,
}

/// Huber's width on a sighting's whitened error: a wrong association of the
/// particle's pulls linearly, and the convex cost keeps a lap's drift from
/// being mistaken for outliers.
const SIGHTING_HUBER: f64 = 3.0;
/// The vertex of the run's start; scan k's pose is [`pose_id`]`(k)`, and
/// landmark l's is `pose_id(scans + l)`.
const START_ID: i64 = 0;

fn pose_id(k: usize) -> i64 {
    k as i64 + 1
}

/// Iterations of the smoothing.
const ITERATIONS: usize = 20;

/// Moves `particle` to `place`. The landmarks it made within `recent`
/// (distance travelled) of now carry the same drift, so they move with it;
/// those that then fall on an older landmark of a compatible colour are
/// duplicates and go, their sightings counted in the older one's (a cone
/// seen twice at the start and again at the lap's end is confirmed). Returns (duplicate, the older landmark) pairs.
pub(super) fn snap(particle: &mut Particle, place: &SE2, recent: f64) -> Vec<(usize, usize)> {
    let correction = place.compose(&particle.pose.inverse());
    if correction.t.norm() < 1e-9 && correction.theta.abs() < 1e-9 {
        return Vec::new();
    }
    particle.pose = *place;
    let older: Vec<(usize, Vector2<f64>, Color)> = (particle.map.iter().enumerate())
        .filter(|(_, lm)| !lm.removed && lm.sighting.created_distance < recent)
        .map(|(l, lm)| (l, lm.mean, lm.sighting.color()))
        .collect();
    let rotation = correction.rotation();
    let mut merged = Vec::new();
    for (l, slot) in particle.map.iter_mut().enumerate() {
        if slot.removed || slot.sighting.created_distance < recent {
            continue;
        }
        let lm = Rc::make_mut(slot);
        lm.mean = correction.transform_point(&lm.mean);
        lm.cov = rotation * lm.cov * rotation.transpose();
        let color = lm.sighting.color();
        let onto = older
            .iter()
            .filter(|(_, m, c)| (m - lm.mean).norm() < MERGE_RADIUS && c.compatible(color))
            .min_by(|a, b| (a.1 - lm.mean).norm().total_cmp(&(b.1 - lm.mean).norm()));
        if let Some((older, _, _)) = onto {
            lm.removed = true;
            merged.push((l, *older));
        }
    }
    for &(duplicate, older) in &merged {
        let sighting = particle.map[duplicate].sighting.clone();
        Rc::make_mut(&mut particle.map[older])
            .sighting
            .absorb(&sighting);
    }
    merged
}

/// Farthest a detection may fall from a landmark to be tied to it after
/// the closure (m), as in the graph's place recognition.
const REMATCH_RADIUS: f64 = 0.6;

/// Ties the detections that `particle`'s steps from scan `first` on left
/// without a landmark (the gates leave the start area out until the loop
/// closes) to the landmark nearest where the closure's `correction` puts
/// them, within [`REMATCH_RADIUS`], one detection per landmark and scan;
/// `seen` counts each tie in the landmark's sighting with the detection's
/// colour.
pub(super) fn rematch(
    particle: &mut Particle,
    evidence: &[ScanEvidence],
    correction: &SE2,
    first: usize,
    mut seen: impl FnMut(&mut Sighting, Color),
) {
    let recent: Vec<Rc<Step>> = std::iter::successors(particle.path.clone(), |s| s.parent.clone())
        .take_while(|s| s.scan >= first)
        .collect();
    let Some(oldest) = recent.last() else {
        return;
    };
    let live: Vec<(u32, Vector2<f64>)> = (particle.map.iter().enumerate())
        .filter(|(_, lm)| !lm.removed)
        .map(|(l, lm)| (l as u32, lm.mean))
        .collect();
    let mut path = oldest.parent.clone();
    for step in recent.iter().rev() {
        let pose = correction.compose(&step.pose.pose);
        let mut choices = step.choices.clone();
        let Some(scan) = evidence.get(step.scan) else {
            continue;
        };
        for (i, ((z, _), color)) in scan.measurements.iter().zip(&scan.colors).enumerate() {
            if choices.get(i).is_none_or(|c| c.is_some()) {
                continue;
            }
            let (w, _, _) = landmark_from(&pose, z);
            let nearest = live
                .iter()
                .filter(|(l, _)| !choices.contains(&Some(*l)))
                .map(|(l, m)| (*l, (m - w).norm()))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((l, d)) = nearest
                && d < REMATCH_RADIUS
            {
                choices[i] = Some(l);
                seen(
                    &mut Rc::make_mut(&mut particle.map[l as usize]).sighting,
                    *color,
                );
            }
        }
        path = Some(Rc::new(Step {
            scan: step.scan,
            pose: step.pose,
            choices,
            parent: path,
        }));
    }
    particle.path = path;
}

/// Smooths `particle`'s path and map: one pose per scan, chained by the
/// odometry of `evidence`, and every landmark it kept, seen as its steps
/// associated them (a duplicate's sightings go to the landmark of
/// `merged` it fell on). The first scan's pose follows from `start`, where
/// the run started, by the odometry before it; the yaw-rate bias walks at
/// `bias_walk` (rad/s/√s). The path is rewritten with the smoothed poses
/// and redirected associations; a path of one scan is left as it is.
pub(super) fn smooth(
    particle: &mut Particle,
    evidence: &[ScanEvidence],
    merged: &[(usize, usize)],
    (start, bias_walk): (&SE2, f64),
) -> Result<(), SmoothError> {
    let mut steps: Vec<Rc<Step>> =
        std::iter::successors(particle.path.clone(), |s| s.parent.clone()).collect();
    steps.reverse();
    let n = steps.len();
    if n < 2 {
        return Ok(());
    }
    if n != evidence.len() || steps.iter().enumerate().any(|(k, s)| s.scan != k) {
        return Err(SmoothError::Path);
    }
    let mut target: Vec<usize> = (0..particle.map.len()).collect();
    for &(duplicate, older) in merged {
        target[duplicate] = older;
    }
    let removed: Vec<bool> = particle.map.iter().map(|lm| lm.removed).collect();
    let resolve = |c: &Option<u32>| {
        let l = target.get((*c)? as usize).copied()?;
        (!removed[l]).then_some(l)
    };

    let mut graph = Graph::new();
    for (k, step) in steps.iter().enumerate() {
        let pose = if k + 1 == n {
            particle.pose
        } else {
            step.pose.pose
        };
        let vertex = PoseBias {
            pose,
            ..PoseBias::default()
        };
        graph.add_vertex(pose_id(k), vertex)?;
    }
    // The run's start, held by a prior, and the odometry to the first scan.
    let start = PoseBias {
        pose: *start,
        ..PoseBias::default()
    };
    graph.add_vertex(START_ID, start)?;
    graph.add_unary_edge(START_ID, StartPrior(start), StartPrior::information())?;
    for (k, scan) in evidence.iter().enumerate() {
        let (edge, information) = OdometryBias::new(&scan.odometry, bias_walk);
        let from = k.checked_sub(1).map_or(START_ID, pose_id);
        graph.add_edge(from, pose_id(k), edge, information)?;
    }
    let mut vertex: Vec<Option<i64>> = vec![None; particle.map.len()];
    for (k, step) in steps.iter().enumerate() {
        for (i, c) in step.choices.iter().enumerate() {
            let (Some(l), Some((z, r))) = (resolve(c), evidence[k].measurements.get(i)) else {
                continue;
            };
            let v = match vertex[l] {
                Some(v) => v,
                None => {
                    let v = pose_id(n + l);
                    graph.add_vertex(v, particle.map[l].mean)?;
                    vertex[l] = Some(v);
                    v
                }
            };
            // The sighting in the pose's frame, and its covariance there.
            let (xy, _, j_z) = landmark_from(&SE2::identity(), z);
            let Some(information) = (j_z * r * j_z.transpose()).try_inverse() else {
                continue;
            };
            let information = 0.5 * (information + information.transpose());
            // The scan's latency is not learnt here: no speed, no turn.
            let edge = SightingBias {
                sighting: EdgeSE2XY::new(xy),
                speed: 0.0,
                yaw_rate: 0.0,
            };
            let e = graph.add_edge(pose_id(k), v, edge, information)?;
            graph.set_robust_kernel(e, Some(RobustKernel::Huber(SIGHTING_HUBER)));
        }
    }
    let mut config = SolverConfig {
        algorithm: Algorithm::LevenbergMarquardt,
        max_iterations: ITERATIONS,
        relative_decrease: 1e-4,
        init: Initialization::File,
        ..SolverConfig::default()
    };
    // Landmarks seen from many poses give dense fronts, where the
    // supernodal factorisation is the faster (as in the graph's solve).
    config.linear.factorization = Factorization::Supernodal;
    let before = graph.chi2();
    let mut optimizer = Optimizer::new(&graph, config)?;
    optimizer.optimize(&mut graph)?;
    // Nothing is written when the solve did not improve (or is not finite).
    if graph.chi2().partial_cmp(&before) == Some(std::cmp::Ordering::Greater)
        || !graph.chi2().is_finite()
    {
        return Ok(());
    }

    for (l, v) in vertex.iter().enumerate() {
        if let Some(v) = v {
            Rc::make_mut(&mut particle.map[l]).mean = graph.value(*v)?;
        }
    }
    let mut path = None;
    for (k, step) in steps.iter().enumerate() {
        let pose = StampedPose {
            t: step.pose.t,
            pose: graph.value::<PoseBias, 5>(pose_id(k))?.pose,
        };
        let choices = step.choices.iter().map(|c| resolve(c).map(|l| l as u32));
        path = Some(Rc::new(Step {
            scan: step.scan,
            pose,
            choices: choices.collect(),
            parent: path,
        }));
    }
    particle.pose = graph.value::<PoseBias, 5>(pose_id(n - 1))?.pose;
    particle.path = path;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::particle::{Landmark, push_step};
    use crate::sighting::Sighting;

    fn landmark(mean: Vector2<f64>, distance: f64) -> Rc<Landmark> {
        Rc::new(Landmark {
            mean,
            cov: Matrix2::identity() * 0.01,
            removed: false,
            sighting: Sighting::new(Color::Blue, 0, distance, 0.0),
        })
    }

    fn particle(pose: SE2, map: Vec<Rc<Landmark>>) -> Particle {
        Particle {
            pose,
            log_weight: 0.0,
            map,
            path: None,
            returned: 0,
        }
    }

    #[test]
    fn a_snap_moves_the_recent_landmarks_and_merges_those_mapped_twice() {
        let older = landmark(Vector2::new(0.0, 2.0), 0.0);
        let twice = landmark(Vector2::new(1.0, 2.0), 100.0);
        let new = landmark(Vector2::new(5.0, 2.0), 100.0);
        let mut p = particle(SE2::new(1.0, 0.0, 0.0), vec![older, twice, new]);
        let merged = snap(&mut p, &SE2::identity(), 90.0);
        assert_eq!(merged, vec![(1, 0)]);
        assert!(p.map[1].removed && !p.map[0].removed && !p.map[2].removed);
        assert!((p.map[2].mean - Vector2::new(4.0, 2.0)).norm() < 1e-12);
        assert!((p.map[0].mean - Vector2::new(0.0, 2.0)).norm() < 1e-12);
        assert_eq!(p.pose, SE2::identity());
    }

    #[test]
    fn a_merged_duplicate_confirms_the_landmark_it_falls_on() {
        // A cone seen twice at the start (tentative) and confirmed on the
        // way back must stay in the map once its duplicate goes.
        let mut start = Sighting::new(Color::Blue, 0, 0.0, 0.0);
        start.count(Color::Blue, 3);
        start.count(Color::Blue, 3);
        let mut back = Sighting::new(Color::Blue, 800, 100.0, 0.0);
        for _ in 0..4 {
            back.count(Color::Blue, 3);
        }
        back.last_seen = 805;
        let mut older = landmark(Vector2::new(0.0, 2.0), 0.0);
        Rc::make_mut(&mut older).sighting = start;
        let mut twice = landmark(Vector2::new(1.0, 2.0), 100.0);
        Rc::make_mut(&mut twice).sighting = back;
        let blue = |l: &Rc<Landmark>| l.sighting.votes[Color::Blue.index()];
        let votes = blue(&older) + blue(&twice);
        let mut p = particle(SE2::new(1.0, 0.0, 0.0), vec![older, twice]);
        assert_eq!(snap(&mut p, &SE2::identity(), 90.0), vec![(1, 0)]);
        let kept = &p.map[0].sighting;
        assert!(kept.confirmed, "{kept:?}");
        assert_eq!((kept.seen, blue(&p.map[0])), (6, votes));
        assert_eq!(kept.last_seen, 805);
    }

    #[test]
    fn rematch_ties_the_approach_detections_to_the_landmarks_they_fall_on() {
        // Two landmarks 1.5 m apart; the path drifted 1 m along x, which
        // the closure's correction takes out. Of scan 1's three detections
        // (all unmatched), two fall on the landmarks and one on nothing;
        // scan 0, before the approach, is left alone.
        let map = vec![
            landmark(Vector2::new(5.0, 1.0), 0.0),
            landmark(Vector2::new(6.5, 1.0), 0.0),
        ];
        let mut p = particle(SE2::new(1.0, 0.0, 0.0), map);
        let drifted = SE2::new(1.0, 0.0, 0.0);
        let r = Matrix2::identity() * 1e-4;
        // Range and bearing from the true pose, the origin.
        let seen_from = |w: Vector2<f64>| Vector2::new(w.norm(), w.y.atan2(w.x));
        let detections = [
            Vector2::new(5.1, 1.0),
            Vector2::new(6.4, 1.1),
            Vector2::new(9.0, -1.0),
        ];
        let mut evidence = Vec::new();
        for k in 0..2 {
            evidence.push(ScanEvidence {
                t: 0.1 * k as f64,
                odometry: OdometryEdge {
                    delta: SE2::identity(),
                    information: Matrix3::identity(),
                    dt: 0.1,
                    yaw_rate_bias: 0.0,
                    slip_jacobian: Vector2::zeros(),
                    slip_made: Vector2::zeros(),
                    heading_variance: 1e-6,
                },
                measurements: detections.iter().map(|w| (seen_from(*w), r)).collect(),
                colors: vec![Color::Yellow; 3],
            });
            let stamped = StampedPose {
                t: 0.1 * k as f64,
                pose: drifted,
            };
            push_step(&mut p, k, stamped, vec![None; 3]);
        }
        let mut counted = Vec::new();
        rematch(&mut p, &evidence, &drifted.inverse(), 1, |s, c| {
            s.count(c, 3);
            counted.push(c);
        });
        let last = p.path.as_ref().unwrap();
        assert_eq!(&*last.choices, &[Some(0), Some(1), None]);
        assert_eq!(last.pose.pose, drifted, "the path's poses stay");
        let first = last.parent.as_ref().unwrap();
        assert_eq!(&*first.choices, &[None, None, None]);
        assert_eq!(counted, vec![Color::Yellow; 2]);
        assert_eq!(p.map[0].sighting.votes[Color::Yellow.index()], 1);
    }

    #[test]
    fn smoothing_takes_the_drift_out_of_a_path_and_its_map() {
        // 20 m straight, cones every 3 m on both sides, exact odometry and
        // sightings; the particle's path turned 2 mrad per scan and its map
        // shifted 0.1 m. The smoothing must put both back.
        let truth: Vec<SE2> = (0..41)
            .map(|k| SE2::new(0.5 * k as f64, 0.0, 0.0))
            .collect();
        let cones: Vec<Vector2<f64>> = (0..8)
            .flat_map(|i| [-2.0, 2.0].map(|y| Vector2::new(1.0 + 3.0 * i as f64, y)))
            .collect();
        let r = Matrix2::from_diagonal(&Vector2::new(0.02f64.powi(2), 0.005f64.powi(2)));
        let mut evidence = Vec::new();
        let mut p = particle(
            SE2::identity(),
            cones
                .iter()
                .map(|c| landmark(c + Vector2::new(0.1, -0.1), 0.0))
                .collect(),
        );
        let mut drifted = SE2::identity();
        for (k, pose) in truth.iter().enumerate() {
            let delta = if k == 0 {
                SE2::identity()
            } else {
                truth[k - 1].inverse().compose(pose)
            };
            let seen: Vec<(u32, Vector2<f64>)> = (cones.iter().enumerate())
                .filter_map(|(l, c)| {
                    let local = pose.inverse().transform_point(c);
                    (local.norm() < 10.0).then(|| {
                        let z = Vector2::new(local.norm(), local.y.atan2(local.x));
                        (l as u32, z)
                    })
                })
                .collect();
            evidence.push(ScanEvidence {
                t: 0.1 * k as f64,
                odometry: OdometryEdge {
                    delta,
                    information: Matrix3::from_diagonal(&nalgebra::Vector3::new(1e4, 1e4, 2.5e5)),
                    dt: if k == 0 { 0.0 } else { 0.1 },
                    yaw_rate_bias: 0.0,
                    slip_jacobian: Vector2::zeros(),
                    slip_made: Vector2::zeros(),
                    heading_variance: 1e-6,
                },
                measurements: seen.iter().map(|(_, z)| (*z, r)).collect(),
                colors: vec![Color::Blue; seen.len()],
            });
            drifted = drifted.compose(&delta).compose(&SE2::new(0.0, 0.0, 0.002));
            let stamped = StampedPose {
                t: 0.1 * k as f64,
                pose: drifted,
            };
            push_step(
                &mut p,
                k,
                stamped,
                seen.iter().map(|(l, _)| Some(*l)).collect(),
            );
        }
        p.pose = drifted;
        smooth(&mut p, &evidence, &[], (&SE2::identity(), 1e-5)).unwrap();

        let steps: Vec<Rc<Step>> =
            std::iter::successors(p.path.clone(), |s| s.parent.clone()).collect();
        assert_eq!(steps.len(), truth.len());
        for (step, pose) in steps.iter().rev().zip(&truth) {
            let error = step.pose.pose.inverse().compose(pose);
            assert!(error.t.norm() < 0.01, "{:?} against {pose:?}", step.pose);
            assert!(error.theta.abs() < 1e-3, "{:?} against {pose:?}", step.pose);
        }
        for (lm, cone) in p.map.iter().zip(&cones) {
            assert!(
                (lm.mean - cone).norm() < 0.01,
                "{:?} against {cone:?}",
                lm.mean
            );
        }
        assert!((p.pose.t - truth[40].t).norm() < 0.01, "{:?}", p.pose);
    }

    #[test]
    fn a_path_that_does_not_match_the_scans_is_refused() {
        let mut p = particle(SE2::identity(), Vec::new());
        let stamped = StampedPose {
            t: 0.0,
            pose: SE2::identity(),
        };
        push_step(&mut p, 0, stamped, Vec::new());
        push_step(&mut p, 1, stamped, Vec::new());
        let result = smooth(&mut p, &[], &[], (&SE2::identity(), 1e-5));
        assert!(matches!(result, Err(SmoothError::Path)));
    }
}
