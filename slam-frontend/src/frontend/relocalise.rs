//! Relocalisation: when the pose has grown too uncertain for one detection
//! to say which landmark it is (after a long stretch without detections, or
//! a spin on commanded velocities), scans are not matched one by one, where
//! a landmark never mapped yet falls within the wide gate of a mapped one
//! and the wrong match turns the pose. They wait, placed by odometry, until
//! together they fit the map geometrically; then the pose is corrected and
//! they are matched from there. Nothing here reads a start line: it
//! recognises revisits from the landmarks themselves.

use super::GraphSlam;
use super::grid::Grid;
use super::loop_closure::PendingScan;
use crate::log::Detection;
use crate::points::two_point;
use cairn_core::SE2;
use nalgebra::{Matrix3, Vector2, Vector3};

/// Detections within this distance of a map landmark after a candidate
/// correction agree with it (m).
pub(super) const AGREE: f64 = 0.35;

/// Two detections propose a correction only when this far apart (m): closer
/// ones fix the heading poorly.
pub(super) const BASELINE: f64 = 1.0;

/// Scans waited for a fit before the landmarks in view are taken as new.
const PATIENCE: usize = 40;

/// The waiting scans of the last this many seconds are aligned together:
/// odometry places them well relative to each other over that long.
const TOGETHER: f64 = 10.0;

/// How much better (in [`Fit::score`]) the chosen correction must be than
/// any other that differs by more than [`DISTINCT`]: two detections more,
/// or as many and a correction e² times likelier.
pub(super) const MARGIN: f64 = 2.0;

/// Corrections closer than this (m, or rad for the heading) are the same.
const DISTINCT: (f64, f64) = (0.5, 0.1);

/// Corrections tried per scan, at most, and the newest detections that
/// score them: the search's work stays bounded (a few milliseconds) on a
/// dense map and dense scans (a track's hundreds of cones, 30 per scan)
/// whatever the drift.
const MAX_TRIES: usize = 20_000;
const MAX_POINTS: usize = 60;

/// The pose covariance after a relocalisation: the fit's own accuracy.
fn relocalised_cov() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(
        0.1f64.powi(2),
        0.1f64.powi(2),
        0.03f64.powi(2),
    ))
}

/// σ of a detection at `range` m caused by the pose's uncertainty: the
/// position's largest σ and the heading's σ times the range.
pub(super) fn pose_sigma_at(pose_cov: &Matrix3<f64>, range: f64) -> f64 {
    let xy = pose_cov.fixed_view::<2, 2>(0, 0).into_owned();
    let largest = xy.symmetric_eigenvalues().max().max(0.0);
    (largest + range * range * pose_cov[(2, 2)].max(0.0)).sqrt()
}

/// A candidate correction: applied to the world, it maps the waiting
/// detections onto the map.
#[derive(Clone, Copy, Debug)]
struct Fit {
    correction: SE2,
    agreeing: usize,
    /// The agreeing detections plus the log-prior of the correction under
    /// the drift's covariance: of two fits that agree alike, the smaller
    /// correction is the likelier.
    score: f64,
}

impl GraphSlam {
    /// A scan the pose is too uncertain for: a keyframe at the predicted
    /// pose, its detections unmatched for now, waiting for relocalisation.
    pub(super) fn wait_lost(
        &mut self,
        t: f64,
        scan: usize,
        cones: &[Detection],
        predicted: (SE2, Matrix3<f64>),
        motion: (SE2, Matrix3<f64>),
        steps: (f64, Vector2<f64>),
    ) {
        let used = self.calibration.correction();
        let keyframe = self.push_keyframe(t, predicted, motion, steps, used);
        let first = self.detections.len();
        self.detections
            .extend((0..cones.len()).map(|i| (scan, i, None)));
        let pending = PendingScan {
            keyframe,
            first,
            cones: cones.to_vec(),
        };
        self.scan_log.push(pending.clone());
        // The window smooths the odometry first: relocalisation sets the
        // pose's covariance after it.
        self.smooth_window();
        self.relocalise(pending);
    }

    /// Waits with a scan the pose is too uncertain for, or places the
    /// waiting scans on the map when together they fit it. The scan's
    /// keyframe is already in the trajectory.
    fn relocalise(&mut self, scan: PendingScan) {
        self.lost_scans.push(scan);
        let Some(fit) = self.best_fit() else {
            if self.lost_scans.len() >= PATIENCE {
                // Nothing mapped fits: the landmarks in view are new ones.
                // Matching them one by one through the wide uncertainty
                // would take them for mapped ones nearby, so the pose is
                // taken as it stands and mapping goes on from it.
                self.lost_scans.clear();
                self.remapped.push(super::remap::Remapped {
                    keyframe: self.poses.len(),
                    landmark: self.landmarks.len(),
                });
                self.pose_cov = relocalised_cov();
                self.drift = (SE2::identity(), Matrix3::zeros());
            }
            return;
        };
        let lost = std::mem::take(&mut self.lost_scans);
        for scan in &lost {
            let p = &mut self.poses[scan.keyframe].pose;
            *p = fit.correction.compose(p);
        }
        self.pose = fit.correction.compose(&self.pose);
        self.pose_cov = relocalised_cov();
        self.drift = (SE2::identity(), Matrix3::zeros());
        let gate = self.config.gate;
        self.match_again(&lost, gate);
        self.relocalisations += 1;
    }

    /// Whether at least two mapped landmarks lie within the sensor's reach
    /// of `pose`: something to find the pose on.
    pub(super) fn map_near(&self, pose: &SE2) -> bool {
        let reach = self.config.max_range + 2.0;
        (0..self.landmarks.len())
            .filter(|&l| self.in_map(l) && (self.landmarks[l].mean - pose.t).norm() < reach)
            .nth(1)
            .is_some()
    }

    /// The correction that puts the most waiting detections on map
    /// landmarks, within three σ of the pose's uncertainty, if it is clearly
    /// the best.
    fn best_fit(&self) -> Option<Fit> {
        let newest = self.poses.last().map_or(0.0, |p| p.t);
        // The newest detections first, then reversed so the newest scan's
        // come last.
        let mut points: Vec<Vector2<f64>> = self
            .lost_scans
            .iter()
            .rev()
            .take_while(|s| newest - self.poses[s.keyframe].t <= TOGETHER)
            .flat_map(|s| {
                let pose = self.poses[s.keyframe].pose;
                s.cones
                    .iter()
                    .rev()
                    .map(move |d| pose.transform_point(&d.position))
            })
            .take(MAX_POINTS)
            .collect();
        points.reverse();
        if points.len() < 3 {
            return None;
        }
        // Pairs with a detection of the newest scan propose corrections,
        // which bounds the work per scan; every detection of the window
        // scores them.
        let newest = self.lost_scans.last().map_or(0, |s| s.cones.len());
        let first_new = points.len().saturating_sub(newest);
        let cov = self.drift.1;
        let information = super::nearest_information(&cov);
        let (max_turn, max_shift) = (
            3.0 * cov[(2, 2)].sqrt() + 0.1,
            3.0 * pose_sigma_at(&cov, 0.0) + 0.5,
        );
        let reach = self.config.max_range + max_shift + 1.0;
        let map: Vec<Vector2<f64>> = (0..self.landmarks.len())
            .filter(|&l| self.in_map(l) && (self.landmarks[l].mean - self.pose.t).norm() < reach)
            .map(|l| self.landmarks[l].mean)
            .collect();
        let near_map = Grid::new(map.clone(), AGREE);
        let on_map = |w: &Vector2<f64>| near_map.first_near(w, AGREE, |_| true).is_some();
        // Ordered pairs of landmarks by length, to find those as long as a
        // pair of detections without trying every one.
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (j, ma) in map.iter().enumerate() {
            for (k, mb) in map.iter().enumerate() {
                if j != k {
                    pairs.push(((mb - ma).norm(), j, k));
                }
            }
        }
        pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut fits: Vec<Fit> = Vec::new();
        let mut tries = 0;
        'search: for (i, a) in points.iter().enumerate() {
            for b in &points[(i + 1).max(first_new)..] {
                let length = (b - a).norm();
                if length < BASELINE {
                    continue;
                }
                let from = pairs.partition_point(|p| p.0 < length - 2.0 * AGREE);
                let to = pairs.partition_point(|p| p.0 <= length + 2.0 * AGREE);
                for &(_, j, k) in &pairs[from..to] {
                    tries += 1;
                    if tries > MAX_TRIES {
                        break 'search;
                    }
                    let Some(correction) = two_point(a, b, &map[j], &map[k]) else {
                        continue;
                    };
                    let moved = correction.transform_point(&self.pose.t) - self.pose.t;
                    if correction.theta.abs() > max_turn || moved.norm() > max_shift {
                        continue;
                    }
                    let agreeing = points
                        .iter()
                        .filter(|p| on_map(&correction.transform_point(p)))
                        .count();
                    let step = Vector3::new(moved.x, moved.y, correction.theta);
                    let prior = step.dot(&(information * step));
                    fits.push(Fit {
                        correction,
                        agreeing,
                        score: agreeing as f64 - 0.5 * prior,
                    });
                }
            }
        }
        let best = *fits.iter().max_by(|a, b| a.score.total_cmp(&b.score))?;
        let needed = 3.max(points.len().div_ceil(2));
        let rival = fits
            .iter()
            .filter(|f| !same(&f.correction, &best.correction, &self.pose.t))
            .map(|f| f.score)
            .fold(f64::NEG_INFINITY, f64::max);
        let clear = best.agreeing >= needed && best.score >= rival + MARGIN;
        (clear && spans_two_places(&best.correction, &points, &map)).then_some(best)
    }
}

/// Whether the detections that `correction` puts on map landmarks fall on
/// two places at least [`BASELINE`] apart, at least two on each: one group
/// of landmarks fits a scan turned about it, so it does not fix the heading.
fn spans_two_places(correction: &SE2, points: &[Vector2<f64>], map: &[Vector2<f64>]) -> bool {
    let hits: Vec<Vector2<f64>> = points
        .iter()
        .filter_map(|p| {
            let w = correction.transform_point(p);
            map.iter().find(|m| (*m - w).norm() < AGREE).copied()
        })
        .collect();
    hits.iter().any(|a| {
        let near = hits.iter().filter(|b| (*b - a).norm() < BASELINE).count();
        let far = hits.len() - near;
        near >= 2 && far >= 2
    })
}

/// Whether two corrections put the car (at `at`) in the same place.
fn same(a: &SE2, b: &SE2, at: &Vector2<f64>) -> bool {
    let turn = cairn_core::se2::normalize_angle(a.theta - b.theta).abs();
    (a.transform_point(at) - b.transform_point(at)).norm() < DISTINCT.0 && turn < DISTINCT.1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fit_must_put_detections_on_two_places() {
        let map = [
            Vector2::new(0.0, 0.0),
            Vector2::new(0.2, 0.0),
            Vector2::new(3.0, 0.0),
        ];
        let near_first = [Vector2::new(0.05, 0.0), Vector2::new(0.15, 0.05)];
        let none = SE2::identity();
        assert!(!spans_two_places(&none, &near_first, &map));
        let both = [
            near_first[0],
            near_first[1],
            Vector2::new(2.9, 0.1),
            Vector2::new(3.1, 0.0),
        ];
        assert!(spans_two_places(&none, &both, &map));
        // Turned about the first group, the far detections miss.
        let turned = SE2::new(0.0, 0.0, 0.5);
        assert!(!spans_two_places(&turned, &both, &map));
    }

    #[test]
    fn corrections_are_the_same_within_half_a_metre_and_a_tenth_of_a_radian() {
        let at = Vector2::new(1.0, 1.0);
        let a = SE2::new(0.0, 0.0, 0.0);
        assert!(same(&a, &SE2::new(0.3, 0.0, 0.05), &at));
        assert!(!same(&a, &SE2::new(0.6, 0.0, 0.0), &at));
        assert!(!same(&a, &SE2::new(0.0, 0.0, 0.2), &at));
    }

    #[test]
    fn the_pose_sigma_grows_with_range_through_the_heading() {
        let cov = Matrix3::from_diagonal(&Vector3::new(0.04, 0.01, 0.01));
        assert!((pose_sigma_at(&cov, 0.0) - 0.2).abs() < 1e-12);
        assert!((pose_sigma_at(&cov, 3.0) - (0.04f64 + 0.09).sqrt()).abs() < 1e-12);
    }
}
