//! Pairing each detection with the landmarks that could have made it: the
//! innovation, its covariance through the pose and the landmark's EKF, and
//! χ² against a gate, for the association methods to choose from.

use super::association::{Candidates, Pair};
use super::grid::Grid;
use super::{GraphSlam, Mode};
use crate::log::Detection;
use cairn_core::SE2;
use nalgebra::{Matrix2, Matrix3, SMatrix};

/// Farthest a detection is paired with a landmark, whatever the
/// uncertainty (m): no gate reaches this far for a cone, and it bounds the
/// pairs to score.
const INNOVATION: f64 = 4.0;

impl GraphSlam {
    /// Landmarks within the χ² `gate` of every detection (and within
    /// [`INNOVATION`] of it), best first, and the χ² of the nearest landmark
    /// even when it fails the gate.
    pub(super) fn candidates(
        &self,
        pose: &SE2,
        pose_cov: &Matrix3<f64>,
        cones: &[Detection],
        covs: &[Matrix2<f64>],
        gate: f64,
    ) -> (Candidates, Vec<f64>) {
        let rt = pose.rotation().transpose();
        let drt = Matrix2::new(0.0, 1.0, -1.0, 0.0) * rt;
        let reach = self.config.max_range + 5.0;
        // Until the loop closes, the start area's landmarks are matched only
        // through place recognition ([`Self::awaits_loop_closure`]).
        let nearby: Vec<usize> = (0..self.landmarks.len())
            .filter(|&l| {
                let lm = &self.landmarks[l];
                !lm.removed
                    && self.alias[l] == l
                    && (self.mode == Mode::Mapping || lm.sighting.confirmed)
                    && (lm.mean - pose.t).norm() < reach
                    && !self.awaits_loop_closure(l)
            })
            .collect();
        // The landmarks as the car sees them, bucketed to find those within
        // INNOVATION of a detection without a pass over all of them.
        let local = Grid::new(
            nearby
                .iter()
                .map(|&l| rt * (self.landmarks[l].mean - pose.t))
                .collect(),
            INNOVATION,
        );
        let mut near = Vec::new();
        cones
            .iter()
            .zip(covs)
            .map(|(d, r)| {
                // In landmark order, as the sort below keeps ties.
                near.clear();
                near.extend(local.near(&d.position, INNOVATION));
                near.sort_unstable();
                let mut pairs: Vec<Pair> = near
                    .iter()
                    .filter_map(|&k| {
                        let l = nearby[k];
                        let lm = &self.landmarks[l];
                        let diff = lm.mean - pose.t;
                        let innovation = d.position - local.point(k);
                        if innovation.norm() > INNOVATION {
                            return None;
                        }
                        let mut h_pose = SMatrix::<f64, 2, 3>::zeros();
                        h_pose.fixed_view_mut::<2, 2>(0, 0).copy_from(&(-rt));
                        h_pose.fixed_view_mut::<2, 1>(0, 2).copy_from(&(drt * diff));
                        let penalty = if lm.sighting.contradicts(d.color) {
                            self.config.color_penalty
                        } else {
                            0.0
                        };
                        Pair::new(
                            l,
                            innovation,
                            h_pose,
                            r,
                            &(rt * lm.cov * rt.transpose()),
                            pose_cov,
                            penalty,
                            self.config.new_landmark_gate,
                        )
                    })
                    .collect();
                pairs.sort_by(|a, b| a.d2.total_cmp(&b.d2));
                let nearest = pairs.first().map_or(f64::INFINITY, |p| p.d2);
                pairs.retain(|p| p.d2 <= gate);
                (pairs, nearest)
            })
            .collect()
    }
}
