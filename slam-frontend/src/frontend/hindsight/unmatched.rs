//! Cones the mapping never gave a landmark: their detections, left to
//! clutter by the matching in hindsight, gather on one spot.

use super::super::GraphSlam;
use super::super::loop_closure::PendingScan;
use super::super::optimise::{MERGE_RADIUS, pairs_within};
use crate::color::Color;
use crate::sighting::{JUDGE_AFTER, ViewMargin, in_view_within};
use cairn_core::{DisjointSets, SE2};
use nalgebra::Vector2;

/// Unmatched detections closer than this (m, in the world from their
/// optimised poses) are of one object: the `hard` preset's noise at 10–15 m
/// is 0.3–0.4 m, and the EUFS tracks' cones stand 1–2 m apart.
const LINK_RADIUS: f64 = 0.5;

/// A track's cones stand within this distance (m) of the path the car
/// drove: the shared loop tracks' within 1.5–4.8 m (eufs_rand the widest).
/// The objects beside the track that the `hard` detector takes for cones
/// now and then stand farther out (eufs_rand: 8–15 m).
const TRACK_REACH: f64 = 6.0;

/// A detection no landmark explains.
struct Unmatched {
    /// Its scan's place in the scans matched again.
    scan: usize,
    /// Its place in the scan.
    index: usize,
    /// Where it puts the object, from its scan's optimised pose.
    position: Vector2<f64>,
    color: Color,
}

impl GraphSlam {
    /// Gives a landmark to each spot where detections that no landmark
    /// explains gather from at least [`JUDGE_AFTER`] poses, farther than
    /// [`MERGE_RADIUS`] from every landmark of a compatible colour. Such a
    /// cone's detections went to its neighbours' landmarks while mapping
    /// (eufs_boa_constrictor `hard` seed 1: the landmark begun for a yellow
    /// cone between two others drifted onto one of them, and the matching in
    /// hindsight left 32 of the cone's 41 detections to clutter and the rest
    /// to its neighbours). Clutter is spread over the view: a false positive
    /// or two per scan over hundreds of square metres rarely falls twice
    /// within [`LINK_RADIUS`]; the objects beside the track that the
    /// detector takes for cones now and then are told apart by
    /// [`GraphSlam::is_missed_cone`].
    pub(super) fn map_unmatched_clusters(&mut self, scans: &[PendingScan]) {
        let unmatched = self.unmatched(scans);
        let points: Vec<(usize, Vector2<f64>)> = unmatched
            .iter()
            .enumerate()
            .map(|(j, u)| (j, u.position))
            .collect();
        let mut sets = DisjointSets::new(unmatched.len());
        for (a, b) in pairs_within(&points, LINK_RADIUS) {
            if unmatched[a].color.compatible(unmatched[b].color) {
                sets.union(a, b);
            }
        }
        for group in sets.groups() {
            let spot: Vec<&Unmatched> = group.iter().map(|&j| &unmatched[j]).collect();
            if self.is_missed_cone(&spot, scans) {
                self.found_landmark(&spot, scans);
            }
        }
    }

    fn unmatched(&self, scans: &[PendingScan]) -> Vec<Unmatched> {
        let mut unmatched = Vec::new();
        for (scan, s) in scans.iter().enumerate() {
            let pose = self.poses[s.keyframe].pose;
            for (index, d) in s.cones.iter().enumerate() {
                if self.detections[s.first + index].2.is_none() {
                    unmatched.push(Unmatched {
                        scan,
                        index,
                        position: pose.transform_point(&d.position),
                        color: d.color,
                    });
                }
            }
        }
        unmatched
    }

    /// Whether the detections of `spot` are a cone without a landmark: seen
    /// from at least [`JUDGE_AFTER`] poses, in at least half as many of the
    /// scans that had the spot well in view as the detector sees a cone
    /// (a cone is detected in most of them; an object beside the track now
    /// and then: eufs_rand, 6 times in two laps), within [`TRACK_REACH`] of
    /// the path, and not where a landmark of a compatible colour stands.
    fn is_missed_cone(&self, spot: &[&Unmatched], scans: &[PendingScan]) -> bool {
        let mut poses: Vec<usize> = spot.iter().map(|u| scans[u.scan].keyframe).collect();
        poses.sort_unstable();
        poses.dedup();
        if poses.len() < JUDGE_AFTER.max(self.config.confirm_after) as usize {
            return false;
        }
        let mean = spot.iter().map(|u| u.position).sum::<Vector2<f64>>() / spot.len() as f64;
        if !self
            .poses
            .iter()
            .any(|p| (p.pose.t - mean).norm() <= TRACK_REACH)
        {
            return false;
        }
        let in_view = self
            .poses
            .iter()
            .filter(|p| {
                let inverse: SE2 = p.pose.inverse();
                in_view_within(&self.config, &inverse, &mean, ViewMargin::FINAL)
            })
            .count();
        if (poses.len() as f64) < 0.5 * self.config.detection_probability * in_view as f64 {
            return false;
        }
        !self.map_rows().into_iter().any(|l| {
            let lm = &self.landmarks[l];
            (lm.mean - mean).norm() < MERGE_RADIUS && lm.sighting.color().compatible(spot[0].color)
        })
    }

    /// A landmark for the detections of `spot`, refined by its EKF with each
    /// in turn, unless their colours say clutter (as while mapping).
    fn found_landmark(&mut self, spot: &[&Unmatched], scans: &[PendingScan]) {
        let pose_cov = self.pose_cov;
        let mut landmark = None;
        for u in spot {
            let s = &scans[u.scan];
            let (pose, d) = (self.poses[s.keyframe].pose, &s.cones[u.index]);
            let r = self.config.detection_cov(d);
            let scan = self.detections[s.first + u.index].0;
            let l =
                *landmark.get_or_insert_with(|| self.new_landmark(&pose, &pose_cov, d, &r, scan));
            self.refine(l, &pose, &pose_cov, d, &r);
        }
        let Some(l) = landmark else { return };
        if self.landmarks[l].sighting.looks_like_clutter(&self.config) {
            self.landmarks[l].removed = true;
            return;
        }
        for u in spot {
            self.detections[scans[u.scan].first + u.index].2 = Some(l);
        }
    }
}
