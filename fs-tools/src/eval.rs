//! Scoring a run against the truth: map RMSE (landmarks matched one-to-one
//! to true cones, with and without a best rigid alignment, overall and per
//! colour), trajectory error (ATE), data-association accuracy, missed and
//! phantom landmarks, latency.

use cairn_core::SE2;
use cairn_core::se2::normalize_angle;
use cairn_slam::Color;
use cairn_slam::Cone;
use cairn_slam::files::{Association, StampedPose};
use nalgebra::{Matrix2, Vector2};
use serde::Serialize;
use std::collections::HashMap;

/// A landmark matches a true cone only within this distance (m); one left
/// without a match is a phantom.
pub const MATCH_RADIUS: f64 = 1.0;

/// Everything `cairn fs-eval` reports.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Report {
    /// Landmarks in the estimated map.
    pub landmarks: usize,
    /// RMSE of matched landmarks to their true cones (m): each true cone
    /// matched to at most one landmark within [`MATCH_RADIUS`], the most
    /// pairs, then the smallest summed distance ([`crate::matching`]).
    pub map_rmse: f64,
    /// The same after the best rigid alignment of the map to the truth (m).
    pub map_rmse_aligned: f64,
    /// The map RMSE the map's own covariances predict: √(mean trace) over
    /// the matched landmarks; `None` when a landmark has no covariance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub map_rmse_predicted: Option<f64>,
    /// Mean of eᵀΣ⁻¹e over the matched landmarks (e: error to the true
    /// cone, Σ: the map's covariance): 2 when the covariances are right,
    /// more when they are over-confident.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub map_nees: Option<f64>,
    /// Whether the map and trajectory were placed on the truth by the
    /// associations first ([`placement_by_associations`]): the estimate
    /// was in its own frame.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub placed_by_associations: bool,
    /// Whether the map and trajectory were placed on the truth by the map's
    /// best rigid alignment first (`fs-eval --align`,
    /// [`crate::placement::best_placement`]).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub placed_by_alignment: bool,
    /// Per colour (of the true cone): (colour, RMSE, matched landmarks).
    pub map_rmse_by_color: Vec<(String, f64, usize)>,
    /// Landmarks left without a true cone by the one-to-one matching:
    /// clutter, and the second landmark of a duplicated cone.
    pub phantom: usize,
    /// True cones that were detected but matched no landmark.
    pub missed: usize,
    /// Position RMSE of the trajectory against the truth at the same times (m).
    pub ate: f64,
    /// The same after the best rigid alignment (m).
    pub ate_aligned: f64,
    /// Fraction of detections associated correctly, each true cone standing
    /// for at most one landmark ([`association_labels`]): the detections of
    /// a duplicated cone's second landmark are wrong.
    pub association_accuracy: f64,
    /// The same with each landmark standing for the true cone most of its
    /// detections came from: a relabelling by majority that forgives a
    /// duplicated cone, so never below `association_accuracy`.
    pub association_accuracy_majority: f64,
    /// `association_accuracy` of the estimate as it stood before the
    /// end-of-run pass (re-matching and the final optimisation): what the
    /// car knew while driving. `None` when not measured.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub association_accuracy_real_time: Option<f64>,
    /// Detections scored (with a simulated point-cloud run's lost sightings).
    pub detections: usize,
    /// Update latency percentiles (ms): p50, p99, p99.9, max.
    pub latency_ms: Option<[f64; 4]>,
    /// Longest scan update that closed a loop, all of it (ms).
    pub loop_closure_ms: Option<f64>,
    /// The optimisation at the end of the run (ms).
    pub final_optimisation_ms: Option<f64>,
    /// The detector's σ (range, its growth with range, bearing) as assumed
    /// and as the estimator learned it, where it learns it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detector_sigma: Option<[[f64; 3]; 2]>,
    /// Optimisations that failed during the run, the estimate kept.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

impl Report {
    /// Counts `lost` sightings that no detection stands for (a point-cloud
    /// run's clustering errors) as wrongly associated detections.
    pub fn count_lost_sightings(&mut self, lost: usize) {
        let all = self.detections + lost;
        if lost == 0 || all == 0 {
            return;
        }
        let kept = self.detections as f64 / all as f64;
        self.association_accuracy *= kept;
        self.association_accuracy_majority *= kept;
        if let Some(real_time) = &mut self.association_accuracy_real_time {
            *real_time *= kept;
        }
        self.detections = all;
    }
}

/// Scores a run.
pub fn evaluate(
    truth_map: &[Cone],
    map: &[Cone],
    truth_trajectory: &[StampedPose],
    trajectory: &[StampedPose],
    truth_associations: &[Association],
    associations: &[Association],
) -> Report {
    let mut report = Report {
        landmarks: map.len(),
        ..Default::default()
    };
    // Map: each landmark to at most one true cone, and back.
    let stands_for = map_labels(truth_map, map);
    let mut pairs = Vec::new();
    let mut matched: Vec<(&Cone, Vector2<f64>)> = Vec::new();
    let mut by_color: HashMap<Color, (f64, usize)> = HashMap::new();
    for (lm, cone) in map.iter().zip(&stands_for) {
        match cone {
            Some(i) => {
                let truth = &truth_map[*i];
                pairs.push((lm.position, truth.position));
                matched.push((lm, truth.position));
                let e = by_color.entry(truth.color).or_default();
                e.0 += (lm.position - truth.position).norm_squared();
                e.1 += 1;
            }
            None => report.phantom += 1,
        }
    }
    report.map_rmse = rms(pairs.iter().map(|(a, b)| (a - b).norm()));
    if let Some((predicted, nees)) = covariance_scores(&matched) {
        report.map_rmse_predicted = Some(predicted);
        report.map_nees = Some(nees);
    }
    let (est, truth): (Vec<_>, Vec<_>) = pairs.iter().copied().unzip();
    report.map_rmse_aligned = aligned_rms(&est, &truth);
    let mut colors: Vec<_> = by_color.into_iter().collect();
    colors.sort_by_key(|(c, _)| *c);
    report.map_rmse_by_color = colors
        .into_iter()
        .map(|(c, (sum, n))| (c.to_string(), (sum / n as f64).sqrt(), n))
        .collect();
    let seen: std::collections::HashSet<usize> = truth_associations
        .iter()
        .filter_map(|a| a.landmark)
        .collect();
    let found: std::collections::HashSet<usize> = stands_for.iter().flatten().copied().collect();
    report.missed = seen.iter().filter(|i| !found.contains(i)).count();
    // Trajectory at the estimate's times.
    let mut traj_est = Vec::new();
    let mut traj_truth = Vec::new();
    for p in trajectory {
        if let Some(q) = interpolate(truth_trajectory, p.t) {
            traj_est.push(p.pose.t);
            traj_truth.push(q);
        }
    }
    report.ate = rms(traj_est
        .iter()
        .zip(&traj_truth)
        .map(|(a, b)| (a - b).norm()));
    report.ate_aligned = aligned_rms(&traj_est, &traj_truth);
    let (accuracy, n) = one_to_one_accuracy(truth_associations, associations);
    report.association_accuracy = accuracy;
    report.detections = n;
    let majority = majority_labels(truth_associations, associations);
    report.association_accuracy_majority =
        association_accuracy(truth_associations, associations, &majority).0;
    report
}

/// (√(mean trace Σ), mean eᵀΣ⁻¹e) over landmarks matched to true cones,
/// or `None` if there are none or one has no invertible covariance.
fn covariance_scores(matched: &[(&Cone, Vector2<f64>)]) -> Option<(f64, f64)> {
    let terms: Vec<(f64, f64)> = matched
        .iter()
        .map(|(cone, truth)| {
            let sigma = cone.covariance;
            let inverse = sigma.try_inverse().filter(|_| sigma.trace() > 0.0)?;
            let error = cone.position - truth;
            Some((sigma.trace(), error.dot(&(inverse * error))))
        })
        .collect::<Option<_>>()?;
    let n = terms.len() as f64;
    (n > 0.0).then(|| {
        let trace: f64 = terms.iter().map(|t| t.0).sum();
        let nees: f64 = terms.iter().map(|t| t.1).sum();
        ((trace / n).sqrt(), nees / n)
    })
}

/// The true cone each landmark of `map` stands for: its one-to-one match
/// within [`MATCH_RADIUS`] ([`crate::matching::one_to_one`]), by map row.
pub fn map_labels(truth_map: &[Cone], map: &[Cone]) -> Vec<Option<usize>> {
    let positions = |cones: &[Cone]| cones.iter().map(|c| c.position).collect::<Vec<_>>();
    crate::matching::one_to_one(&positions(map), &positions(truth_map), MATCH_RADIUS)
}

/// [`association_accuracy`] with each true cone standing for one landmark
/// ([`association_labels`]): (accuracy, detections scored).
pub fn one_to_one_accuracy(truth: &[Association], estimate: &[Association]) -> (f64, usize) {
    association_accuracy(truth, estimate, &association_labels(truth, estimate))
}

/// How many detections each landmark got from each true cone (`None`:
/// from a false positive), by landmark id.
fn votes(truth: &[Association], estimate: &[Association]) -> Vec<HashMap<Option<usize>, i64>> {
    let truth_of: HashMap<(usize, usize), Option<usize>> = truth
        .iter()
        .map(|a| ((a.scan, a.det), a.landmark))
        .collect();
    let mut votes: Vec<HashMap<Option<usize>, i64>> = Vec::new();
    for a in estimate {
        if let (Some(l), Some(t)) = (a.landmark, truth_of.get(&(a.scan, a.det))) {
            if votes.len() <= l {
                votes.resize_with(l + 1, HashMap::new);
            }
            *votes[l].entry(*t).or_default() += 1;
        }
    }
    votes
}

/// The true cone each landmark stands for, each cone for at most one
/// landmark: the assignment that makes the most detections correct
/// ([`crate::matching::assign`]), by landmark id.
pub fn association_labels(truth: &[Association], estimate: &[Association]) -> Vec<Option<usize>> {
    let links: Vec<Vec<(usize, i64)>> = votes(truth, estimate)
        .into_iter()
        .map(|v| v.into_iter().filter_map(|(t, n)| Some((t?, n))).collect())
        .collect();
    let cones = links.iter().flatten().map(|l| l.0 + 1).max().unwrap_or(0);
    crate::matching::assign(&links, cones)
}

/// The true cone each landmark stands for when it is the one most of the
/// landmark's detections came from (ties to the higher index), by landmark
/// id: several landmarks may stand for one cone.
pub fn majority_labels(truth: &[Association], estimate: &[Association]) -> Vec<Option<usize>> {
    votes(truth, estimate)
        .into_iter()
        .map(|v| {
            v.into_iter()
                .max_by_key(|(t, n)| (*n, *t))
                .and_then(|(t, _)| t)
        })
        .collect()
}

/// The fraction of detections associated correctly, each landmark `l`
/// standing for the true cone `stands_for[l]` (none beyond its end): a
/// detection is correct when its landmark stands for its true cone, or when
/// a false positive was rejected. Returns (accuracy, detections scored).
pub fn association_accuracy(
    truth: &[Association],
    estimate: &[Association],
    stands_for: &[Option<usize>],
) -> (f64, usize) {
    let truth_of: HashMap<(usize, usize), Option<usize>> = truth
        .iter()
        .map(|a| ((a.scan, a.det), a.landmark))
        .collect();
    let mut correct = 0;
    let mut total = 0;
    for a in estimate {
        let Some(t) = truth_of.get(&(a.scan, a.det)) else {
            continue;
        };
        total += 1;
        let ok = match (a.landmark, t) {
            (None, None) => true,
            (Some(l), Some(c)) => stands_for.get(l).copied().flatten() == Some(*c),
            _ => false,
        };
        correct += usize::from(ok);
    }
    (
        if total > 0 {
            correct as f64 / total as f64
        } else {
            0.0
        },
        total,
    )
}

/// The estimate's position error (m) at each of its times within the
/// truth's, against the truth interpolated there: (time, error).
pub fn position_errors(truth: &[StampedPose], estimate: &[StampedPose]) -> Vec<(f64, f64)> {
    estimate
        .iter()
        .filter_map(|p| interpolate(truth, p.t).map(|q| (p.t, (p.pose.t - q).norm())))
        .collect()
}

/// The true position at time `t`, linearly interpolated.
fn interpolate(truth: &[StampedPose], t: f64) -> Option<Vector2<f64>> {
    pose_at(truth, t).map(|p| p.t)
}

/// The pose at time `t`, interpolated linearly (the heading the short way
/// round) between the trajectory's poses; `None` outside their times.
pub fn pose_at(truth: &[StampedPose], t: f64) -> Option<SE2> {
    let i = truth.partition_point(|p| p.t < t);
    let b = truth.get(i)?;
    if i == 0 || b.t == t {
        return (b.t - t < 1e-6).then_some(b.pose);
    }
    let a = &truth[i - 1];
    let u = (t - a.t) / (b.t - a.t);
    let turn = normalize_angle(b.pose.theta - a.pose.theta);
    Some(SE2::new(
        a.pose.t.x + u * (b.pose.t.x - a.pose.t.x),
        a.pose.t.y + u * (b.pose.t.y - a.pose.t.y),
        a.pose.theta + u * turn,
    ))
}

fn rms(errors: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = errors.fold((0.0, 0usize), |(s, n), e| (s + e * e, n + 1));
    if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
}

/// RMS distance after the least-squares rigid alignment of `a` onto `b`
/// (Arun, Huang & Blostein: SVD of the cross-covariance, reflection excluded).
pub fn aligned_rms(a: &[Vector2<f64>], b: &[Vector2<f64>]) -> f64 {
    if a.len() < 2 {
        return rms(a.iter().zip(b).map(|(p, q)| (p - q).norm()));
    }
    let (r, t) = rigid_alignment(a, b);
    rms(a.iter().zip(b).map(|(p, q)| (r * p + t - q).norm()))
}

/// Where a map estimated in its own frame (a log with no start pose, such
/// as MRCLAM's Dataset 1) stands on the truth: the rigid transform that
/// best puts each landmark on the true cone its detections name
/// ([`association_labels`]). `None` with fewer than two named landmarks.
pub fn placement_by_associations(
    truth_map: &[Cone],
    map: &[Cone],
    truth: &[Association],
    estimate: &[Association],
) -> Option<SE2> {
    let (a, b): (Vec<_>, Vec<_>) = association_labels(truth, estimate)
        .iter()
        .enumerate()
        .filter_map(|(l, c)| Some((map.get(l)?.position, truth_map.get((*c)?)?.position)))
        .unzip();
    if a.len() < 2 {
        return None;
    }
    let (r, t) = rigid_alignment(&a, &b);
    Some(SE2::new(t.x, t.y, r[(1, 0)].atan2(r[(0, 0)])))
}

/// Moves `map` (positions and covariances) and `trajectory` by `placement`.
pub fn place(placement: &SE2, map: &mut [Cone], trajectory: &mut [StampedPose]) {
    let r = placement.rotation();
    for cone in map {
        cone.position = placement.transform_point(&cone.position);
        cone.covariance = r * cone.covariance * r.transpose();
    }
    for p in trajectory {
        p.pose = placement.compose(&p.pose);
    }
}

/// The rotation and translation minimising Σ‖R aᵢ + t − bᵢ‖².
pub fn rigid_alignment(a: &[Vector2<f64>], b: &[Vector2<f64>]) -> (Matrix2<f64>, Vector2<f64>) {
    cairn_slam::points::arun(a, b).unwrap_or_else(|| {
        let n = a.len().min(b.len()).max(1) as f64;
        let mean = |s: &[Vector2<f64>]| s.iter().take(n as usize).sum::<Vector2<f64>>() / n;
        (Matrix2::identity(), mean(b) - mean(a))
    })
}

/// p50, p99, p99.9 and max of a list of durations in seconds, in
/// milliseconds (the nearest rank: on fewer than 1,000 updates p99.9 is the max).
pub fn latency_ms(seconds: &[f64]) -> Option<[f64; 4]> {
    if seconds.is_empty() {
        return None;
    }
    let mut s = seconds.to_vec();
    s.sort_by(f64::total_cmp);
    let at = |q: f64| s[((s.len() - 1) as f64 * q).round() as usize] * 1e3;
    Some([at(0.5), at(0.99), at(0.999), at(1.0)])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cone(x: f64, y: f64) -> Cone {
        Cone {
            position: Vector2::new(x, y),
            color: Color::Unknown,
            covariance: Matrix2::new(0.04, 0.0, 0.0, 0.01),
        }
    }

    #[test]
    fn a_map_in_its_own_frame_is_placed_where_its_detections_say() {
        let truth_map = vec![
            cone(0.0, 0.0),
            cone(4.0, 0.0),
            cone(4.0, 3.0),
            cone(0.0, 5.0),
        ];
        // The estimate: the truth seen from a frame turned 0.7 rad and moved,
        // its rows in another order, with one landmark a phantom.
        let frame = SE2::new(2.0, -1.0, 0.7);
        let order = [2, 0, 3, 1];
        let mut map: Vec<Cone> = order
            .iter()
            .map(|&i| {
                let mut c = truth_map[i].clone();
                c.position = frame.inverse().transform_point(&c.position);
                c
            })
            .collect();
        map.push(cone(9.0, 9.0));
        let mut truth = Vec::new();
        let mut estimate = Vec::new();
        for (row, &i) in order.iter().enumerate() {
            for scan in 0..3 {
                truth.push(Association {
                    scan,
                    det: row,
                    landmark: Some(i),
                });
                estimate.push(Association {
                    scan,
                    det: row,
                    landmark: Some(row),
                });
            }
        }
        // A false positive matched to the phantom names no cone.
        truth.push(Association {
            scan: 5,
            det: 0,
            landmark: None,
        });
        estimate.push(Association {
            scan: 5,
            det: 0,
            landmark: Some(4),
        });
        let placement =
            placement_by_associations(&truth_map, &map, &truth, &estimate).expect("placed");
        assert!((placement.t - frame.t).norm() < 1e-9);
        assert!((placement.theta - frame.theta).abs() < 1e-9);
        let mut trajectory = vec![StampedPose {
            t: 0.0,
            pose: frame.inverse(),
        }];
        place(&placement, &mut map, &mut trajectory);
        for (row, &i) in order.iter().enumerate() {
            assert!((map[row].position - truth_map[i].position).norm() < 1e-9);
        }
        // The covariance turns with the map: its long axis along the frame's x.
        let r = frame.rotation();
        assert!((map[0].covariance - r * truth_map[0].covariance * r.transpose()).norm() < 1e-12);
        assert!(trajectory[0].pose.t.norm() < 1e-9 && trajectory[0].pose.theta.abs() < 1e-9);
        // Fewer than two named landmarks cannot place a map.
        assert!(placement_by_associations(&truth_map, &map, &truth[..3], &estimate[..3]).is_none());
    }
}
