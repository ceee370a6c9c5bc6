//! EKF-SLAM's end of the run: detections its gates left unmatched while
//! driving are matched again from the map as it ended.

use super::{EkfSlam, predict};
use crate::filter::innovation;
use crate::frontend::association::Pair;
use nalgebra::{Matrix2, Vector2};
use std::collections::HashSet;

impl EkfSlam {
    /// Matches again every detection left without a mapped landmark (a
    /// true match the 99% gate turned away, or one that started a landmark
    /// the filter later dropped): from the pose the filter had at its scan
    /// (with that pose's covariance) and the final map, to the one
    /// landmark whose χ² is within the gate while every other's is beyond
    /// the new-landmark gate (by [`Pair::new`], without the colours, which
    /// the filter does not keep), and that the scan matched no other way. The
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
            // The landmarks in reach within the new-landmark gate: one alone.
            let mut pairs = mapped
                .iter()
                .filter(|(_, mean, _)| (mean - at.pose.t).norm_squared() <= reach2)
                .filter_map(|(l, mean, cov)| {
                    let pred = predict(&at.pose, mean)?;
                    let s_landmark = pred.h_landmark * cov * pred.h_landmark.transpose();
                    let nu = innovation(z, &pred.z);
                    Pair::new(
                        *l,
                        nu,
                        pred.h_pose,
                        r,
                        &s_landmark,
                        pose_cov,
                        0.0,
                        ambiguous,
                    )
                });
            if let (Some(only), None) = (pairs.next(), pairs.next())
                && only.d2 < gate
                && taken.insert((scan, only.landmark))
            {
                self.detections[k].2 = Some(only.landmark);
            }
        }
    }
}
