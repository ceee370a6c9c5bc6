//! EKF-SLAM's end of the run: detections its gates left unmatched while
//! driving are matched again from the map as it ended.

use super::{EkfSlam, predict};
use crate::filter::innovation;
use nalgebra::{Matrix2, Vector2};
use std::collections::HashSet;

impl EkfSlam {
    /// Matches again every detection left without a mapped landmark (a
    /// true match the 99% gate turned away, or one that started a landmark
    /// the filter later dropped): from the pose the filter had at its scan
    /// (with that pose's covariance) and the final map, to the one
    /// landmark whose χ² is within the gate while every other's is beyond
    /// the new-landmark gate, and that the scan matched no other way. The
    /// map itself does not change; the real-time associations are those
    /// before this (`hindsight = false` keeps them).
    pub fn finish(&mut self) {
        if !self.run.config.hindsight {
            return;
        }
        let mapped: Vec<(usize, Vector2<f64>, Matrix2<f64>)> = self
            .map_rows()
            .into_iter()
            .filter_map(|l| {
                let slot = self.landmarks[l].slot?;
                let mean = self.x.fixed_rows::<2>(slot).into_owned();
                let cov = self.p.fixed_view::<2, 2>(slot, slot).into_owned();
                Some((l, mean, cov))
            })
            .collect();
        let live: HashSet<usize> = mapped.iter().map(|(l, _, _)| *l).collect();
        let mut taken: HashSet<(usize, usize)> = self
            .detections
            .iter()
            .filter_map(|&(scan, _, l)| Some((scan, l.filter(|l| live.contains(l))?)))
            .collect();
        let (gate, ambiguous) = (self.run.config.gate, self.run.config.new_landmark_gate);
        let reach2 = (self.run.config.max_range + 1.0).powi(2);
        for k in 0..self.detections.len() {
            let (scan, _, landmark) = self.detections[k];
            if landmark.is_some_and(|l| live.contains(&l)) {
                continue;
            }
            let (Some(at), Some(pose_cov)) = (self.poses.get(scan), self.pose_covs.get(scan))
            else {
                continue;
            };
            let (z, r) = &self.measured[k];
            // The best and second-best χ² over the landmarks in reach.
            let (mut best, mut second) = ((f64::INFINITY, usize::MAX), f64::INFINITY);
            for (l, mean, cov) in &mapped {
                if (mean - at.pose.t).norm_squared() > reach2 {
                    continue;
                }
                let Some(pred) = predict(&at.pose, mean) else {
                    continue;
                };
                let s = pred.h_pose * pose_cov * pred.h_pose.transpose()
                    + pred.h_landmark * cov * pred.h_landmark.transpose()
                    + r;
                let Some(s_inv) = s.try_inverse() else {
                    continue;
                };
                let nu = innovation(z, &pred.z);
                let chi2 = (nu.transpose() * s_inv * nu)[(0, 0)];
                if chi2 < best.0 {
                    second = best.0;
                    best = (chi2, *l);
                } else if chi2 < second {
                    second = chi2;
                }
            }
            let (chi2, l) = best;
            if chi2 < gate && second > ambiguous && taken.insert((scan, l)) {
                self.detections[k].2 = Some(l);
            }
        }
    }
}
