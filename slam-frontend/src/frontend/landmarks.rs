//! Landmark bookkeeping of the graph front end: starting landmarks, each
//! landmark's own EKF, and counting the misses that drop spurious ones.

use super::optimise::{MERGE_RADIUS, pairs_within};
use super::{GraphSlam, Landmark, Mode, window};
use crate::log::Detection;
use crate::sighting::{Sighting, hits_and_misses, in_view};
use cairn_core::{DisjointSets, SE2};
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2};

/// The share of a cluster's scans that must see all its landmarks for them
/// to stand for as many cones: pᵏ is 0.41 for three cones at the `hard`
/// preset's detection probability 0.8 (0.64 for two), against the few
/// scans where clutter completes a duplicate. At most this, and at most
/// [`SEEN_WHOLE_SHARE`] of pᵏ.
const SEEN_WHOLE: f64 = 0.1;

/// Where the detector misses often, a cluster is seen whole in fewer scans:
/// at the MRCLAM camera's p = 0.5 a group of three tubes 0.15–0.25 m apart
/// is seen whole in about p³ = 1/8 of its scans, and the fixed share had
/// dropped one tube of every such group (Dataset 6: 57 → 62 of the five
/// robots' 75 landmarks mapped with maximum likelihood, association 70.8 →
/// 73.8%). A quarter of pᵏ leaves every cluster of up to four cones on the
/// simulator presets (p ≥ 0.8) at [`SEEN_WHOLE`].
const SEEN_WHOLE_SHARE: f64 = 0.25;

/// A distance below which an unmatched detection is taken for a poorly
/// matched old landmark rather than a new cone (m), unless that landmark
/// explains another detection of the same scan.
const NEW_LANDMARK_CLEARANCE: f64 = 0.8;

/// What stands within [`NEW_LANDMARK_CLEARANCE`] of an unmatched detection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Beside {
    /// No landmark: the detection starts one beyond `new_landmark_gate`.
    Nothing,
    /// Only landmarks that explain another detection of the scan. One
    /// landmark explains one detection per scan, so this is a second cone
    /// beside them (cones 0.3–0.45 m apart had been left unmapped by the
    /// filters). The filters ask the detection to lie beyond the
    /// individual `gate` too: within it, it may be the cone whose landmark
    /// another detection took.
    TakenOnly,
    /// A landmark no detection of the scan explains: most likely this
    /// detection's, poorly matched.
    Free,
}

/// What lies within [`NEW_LANDMARK_CLEARANCE`] of `point` among the
/// landmarks (index and mean); `taken(l)` says landmark `l` explains a
/// detection of the scan.
pub(crate) fn beside<'a>(
    point: &Vector2<f64>,
    landmarks: impl Iterator<Item = (usize, &'a Vector2<f64>)>,
    taken: impl Fn(usize) -> bool,
) -> Beside {
    let mut found = Beside::Nothing;
    for (l, m) in landmarks {
        if (m - point).norm() <= NEW_LANDMARK_CLEARANCE {
            if !taken(l) {
                return Beside::Free;
            }
            found = Beside::TakenOnly;
        }
    }
    found
}

impl GraphSlam {
    /// Whether an unmatched detection starts a new landmark: no free live
    /// landmark lies within [`NEW_LANDMARK_CLEARANCE`] (it would be a
    /// poorly matched old one), and either a landmark this scan already
    /// matched does ([`Beside::TakenOnly`], like the start's paired big
    /// orange cones) or the nearest landmark is beyond the new-landmark
    /// gate.
    pub(super) fn is_new_cone(
        &self,
        pose: &SE2,
        d: &Detection,
        nearest: f64,
        taken: &[bool],
    ) -> bool {
        let world = pose.transform_point(&d.position);
        let live = self.landmarks.iter().enumerate();
        let live = live.filter(|&(l, lm)| !lm.removed && self.alias[l] == l);
        // Landmarks made in this scan explain a detection of it too.
        let taken = |l: usize| taken.get(l).copied().unwrap_or(true);
        match beside(&world, live.map(|(l, lm)| (l, &lm.mean)), taken) {
            Beside::Free => false,
            Beside::TakenOnly => true,
            Beside::Nothing => nearest > self.config.new_landmark_gate,
        }
    }

    pub(super) fn world_cov(
        &self,
        pose: &SE2,
        pose_cov: &Matrix3<f64>,
        d: &Detection,
        r: &Matrix2<f64>,
    ) -> Matrix2<f64> {
        let rot = pose.rotation();
        let dr = Matrix2::new(0.0, -1.0, 1.0, 0.0) * rot;
        let mut j = SMatrix::<f64, 2, 3>::zeros();
        j.fixed_view_mut::<2, 2>(0, 0)
            .copy_from(&Matrix2::identity());
        j.fixed_view_mut::<2, 1>(0, 2).copy_from(&(dr * d.position));
        rot * r * rot.transpose() + j * pose_cov * j.transpose()
    }

    pub(super) fn new_landmark(
        &mut self,
        pose: &SE2,
        pose_cov: &Matrix3<f64>,
        d: &Detection,
        r: &Matrix2<f64>,
        scan: usize,
    ) -> usize {
        self.landmarks.push(Landmark {
            mean: pose.transform_point(&d.position),
            cov: self.world_cov(pose, pose_cov, d, r),
            removed: false,
            sighting: Sighting::new(d.color, scan, self.motion.distance(), pose.theta),
            prior: window::Prior::default(),
        });
        self.alias.push(self.alias.len());
        self.landmarks.len() - 1
    }

    /// The landmark's own EKF: a direct, world-frame observation of a static point.
    pub(super) fn refine(
        &mut self,
        l: usize,
        pose: &SE2,
        pose_cov: &Matrix3<f64>,
        d: &Detection,
        r: &Matrix2<f64>,
    ) {
        let z = pose.transform_point(&d.position);
        let rw = self.world_cov(pose, pose_cov, d, r);
        let lm = &mut self.landmarks[l];
        if lm.sighting.seen > 0
            && let Some(inv) = (lm.cov + rw).try_inverse()
        {
            let k = lm.cov * inv;
            lm.mean += k * (z - lm.mean);
            lm.cov = (Matrix2::identity() - k) * lm.cov;
            lm.cov = 0.5 * (lm.cov + lm.cov.transpose());
        }
        lm.sighting.count(d.color, self.config.confirm_after);
    }

    /// At the end of the run, drops the landmarks that colours and
    /// detections over the whole run call clutter. While mapping, an object
    /// seen fewer than six times is not judged by its colours, and one
    /// seen in half the scans survives the misses; on eufs_rand that kept
    /// 32 of its 134 clutter objects per run. The final poses say in which
    /// scans each landmark was in view, with a margin for their errors
    /// ([`ViewMargin::FINAL`](crate::sighting::ViewMargin::FINAL)) rather
    /// than the mapping's. Judged once: judged after every scan, a cone
    /// misread a few times early in the second lap was dropped
    /// (epfl_track_3).
    pub(super) fn drop_clutter(&mut self) {
        let mut seen_from: Vec<Vec<usize>> = vec![Vec::new(); self.landmarks.len()];
        for o in &self.observations {
            seen_from[self.resolve(o.landmark)].push(o.pose);
        }
        let inverses: Vec<SE2> = self.poses.iter().map(|p| p.pose.inverse()).collect();
        for l in self.map_rows() {
            let seen = &mut seen_from[l];
            seen.sort_unstable();
            seen.dedup();
            let mean = self.landmarks[l].mean;
            let (hits, misses) =
                hits_and_misses(&self.config, inverses.iter().enumerate(), &mean, seen);
            if self.landmarks[l]
                .sighting
                .is_clutter(hits, misses, &self.config)
            {
                self.landmarks[l].removed = true;
            }
        }
    }

    /// At the end of the run, before the matching in hindsight, drops the
    /// landmarks of a cluster that the scans do not show as that many cones.
    /// A cluster (landmarks of compatible colours, each within
    /// [`MERGE_RADIUS`] of another) of k cones is seen whole in about pᵏ of
    /// the scans that see any of it (p the detection probability: half of
    /// them for three cones at p = 0.8). A landmark that a later lap started
    /// beside a big orange pair, and that scans then matched with either
    /// cone of the pair, is seen with each, so it never merged into one
    /// (`merge_duplicates`), but the three are seen together only where
    /// clutter fills the third place. While a cluster is seen whole in fewer
    /// than [`SEEN_WHOLE`] of its scans, its least seen landmark leaves the
    /// map; the matching in hindsight then gives its detections to the rest.
    pub(super) fn drop_surplus_landmarks(&mut self) {
        let live = self.map_rows();
        // Labelled by their place in `live`.
        let points: Vec<(usize, Vector2<f64>)> = live
            .iter()
            .enumerate()
            .map(|(k, &l)| (k, self.landmarks[l].mean))
            .collect();
        let mut sets = DisjointSets::new(live.len());
        for (a, b) in pairs_within(&points, MERGE_RADIUS) {
            let (ca, cb) = (
                self.landmarks[live[a]].sighting.color(),
                self.landmarks[live[b]].sighting.color(),
            );
            if ca.compatible(cb) {
                sets.union(a, b);
            }
        }
        let members = sets
            .groups()
            .into_iter()
            .map(|group| group.into_iter().map(|k| live[k]).collect::<Vec<usize>>());
        for landmarks in members.filter(|m| m.len() > 1) {
            // Each scan's landmarks of the cluster.
            let seen: Vec<(usize, usize)> = self
                .detections
                .iter()
                .filter_map(|&(scan, _, l)| Some((scan, self.resolve(l?))))
                .filter(|(_, l)| landmarks.contains(l))
                .collect();
            let sightings: Vec<(usize, u32)> = landmarks
                .iter()
                .map(|&l| (l, self.landmarks[l].sighting.seen))
                .collect();
            let p = self.config.detection_probability;
            for l in surplus(&sightings, seen, p) {
                self.landmarks[l].removed = true;
            }
        }
    }

    /// Counts misses of landmarks well inside the field of view, removes
    /// those missed more often than seen, and tracks which left the view.
    pub(super) fn count_misses(&mut self, pose: &SE2, associated: &[bool], scan: usize) {
        let inverse = pose.inverse();
        let mapping = self.mode == Mode::Mapping;
        let distance = self.motion.distance();
        for l in 0..self.landmarks.len() {
            if self.landmarks[l].removed || self.alias[l] != l {
                continue;
            }
            // The gates leave the start area out until the loop closes, so
            // it cannot be missed meanwhile: counted, the misses removed
            // a big orange cone seen only six times on the way out.
            let gated = !self.awaits_loop_closure(l);
            let lm = &mut self.landmarks[l];
            let visible = gated && in_view(&self.config, &inverse, &lm.mean);
            let seen = associated.get(l).copied().unwrap_or(false);
            if lm
                .sighting
                .after_scan(&self.config, visible, seen, mapping, scan, distance)
            {
                lm.removed = true;
            }
        }
    }
}

/// The landmarks of one cluster, given as (landmark, times seen), that the
/// scans do not show as separate cones, least seen first: while fewer than
/// [`SEEN_WHOLE`] (or a [`SEEN_WHOLE_SHARE`] of pᵏ, for the detection
/// probability `p` and the k landmarks left) of the scans that saw any of
/// the rest saw them all, the least seen goes. `seen` lists (scan,
/// landmark) pairs.
fn surplus(sightings: &[(usize, u32)], mut seen: Vec<(usize, usize)>, p: f64) -> Vec<usize> {
    let mut order = sightings.to_vec();
    order.sort_unstable_by_key(|&(l, n)| (n, l));
    seen.sort_unstable();
    seen.dedup();
    let mut dropped = Vec::new();
    for &(weakest, _) in &order[..order.len().saturating_sub(1)] {
        let left = sightings.len() - dropped.len();
        let (mut scans, mut whole) = (0, 0);
        for run in seen.chunk_by(|a, b| a.0 == b.0) {
            scans += 1;
            whole += usize::from(run.len() == left);
        }
        let needed = SEEN_WHOLE.min(SEEN_WHOLE_SHARE * p.powi(left as i32));
        if whole as f64 >= needed * scans as f64 {
            break;
        }
        dropped.push(weakest);
        seen.retain(|&(_, l)| l != weakest);
    }
    dropped
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (scan, landmark) for landmarks `a` and `b` seen in these scans.
    fn scans(landmark: usize, scans: impl IntoIterator<Item = usize>) -> Vec<(usize, usize)> {
        scans.into_iter().map(|s| (s, landmark)).collect()
    }

    #[test]
    fn a_pair_seen_together_stays_two_cones() {
        // Each cone of a pair seen in 8 of 10 scans, together in 6.
        let mut seen = scans(1, [0, 1, 2, 3, 4, 5, 6, 7]);
        seen.extend(scans(2, [2, 3, 4, 5, 6, 7, 8, 9]));
        assert!(surplus(&[(1, 8), (2, 8)], seen, 0.8).is_empty());
    }

    #[test]
    fn a_third_landmark_beside_a_pair_goes_when_never_seen_with_both() {
        // Landmark 9 takes either cone's detections in scans where that
        // cone's own landmark missed it; all three are never seen at once.
        let mut seen = scans(1, 0..20);
        seen.extend(scans(2, (0..20).filter(|s| s % 3 != 0)));
        seen.extend(scans(9, (0..20).filter(|s| s % 3 == 0)));
        assert_eq!(surplus(&[(1, 20), (2, 13), (9, 7)], seen, 0.8), vec![9]);
    }

    #[test]
    fn a_third_cone_seen_with_the_pair_stays() {
        // Three cones, each seen in 4 of 5 scans: all three in 2 of 5.
        let mut seen = Vec::new();
        for l in 0..3 {
            seen.extend(scans(l, (0..50).filter(|s| s % 5 != l)));
        }
        assert!(surplus(&[(0, 40), (1, 40), (2, 40)], seen, 0.8).is_empty());
    }

    #[test]
    fn duplicates_of_one_cone_leave_one() {
        // Three landmarks that take turns: never two in one scan.
        let seen: Vec<(usize, usize)> = (0..30).map(|s| (s, s % 3)).collect();
        let mut dropped = surplus(&[(0, 10), (1, 10), (2, 10)], seen, 0.8);
        dropped.sort_unstable();
        assert_eq!(dropped, vec![0, 1]);
    }

    #[test]
    fn a_detector_that_misses_often_keeps_a_group_seen_whole_rarely() {
        // Three tubes, each seen in about half the scans: all three at once
        // in 1 of 16 (p³/2), pairs in 1 of 4 or 8.
        let mut seen = Vec::new();
        for s in 0..160 {
            for l in 0..3 {
                if (s >> l) & 1 == 1 && !(l == 2 && s % 16 == 15) {
                    seen.push((s, l));
                }
            }
        }
        let sightings = [(0, 80), (1, 80), (2, 70)];
        assert!(surplus(&sightings, seen.clone(), 0.5).is_empty());
        // Where the detector is said to see 90% of the cones, the same
        // scans are two cones and a duplicate.
        assert_eq!(surplus(&sightings, seen, 0.9).len(), 1);
    }
}
