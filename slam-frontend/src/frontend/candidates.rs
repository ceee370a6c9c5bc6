//! Pairing each detection with the landmarks that could have made it: the
//! innovation, its covariance through the pose and the landmark's EKF, and
//! χ² against a gate, for the association methods to choose from.

use super::association::{Candidates, Pair, beyond_gate};
use super::grid::Grid;
use super::{GraphSlam, Mode};
use crate::log::Detection;
use cairn_core::SE2;
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2};

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
        let pose_trace = pose_cov.trace();
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
                        let penalty = if lm.sighting.contradicts(d.color) {
                            self.config.color_penalty
                        } else {
                            0.0
                        };
                        // Pair::new's bound, before Hₚ and the rotated
                        // landmark covariance are formed: ‖Hₚ‖²_F = 2 + |diff|²
                        // (Hₚ = [−Rᵀ, J Rᵀ diff], both rotations) and the
                        // trace is the same in any frame.
                        // Wide enough to tell new cones apart; hindsight
                        // asks wider for the detector's tail.
                        let limit = self.config.new_landmark_gate.max(gate);
                        let local_trace = lm.cov.trace() + r.trace();
                        let h_norm2 = 2.0 + diff.norm_squared();
                        if beyond_gate(
                            innovation.norm_squared(),
                            h_norm2,
                            pose_trace,
                            local_trace,
                            limit - penalty,
                        ) {
                            return None;
                        }
                        let h_pose = pose_jacobian(&rt, &diff);
                        Pair::new(
                            l,
                            innovation,
                            h_pose,
                            r,
                            &(rt * lm.cov * rt.transpose()),
                            pose_cov,
                            penalty,
                            limit,
                        )
                    })
                    .collect();
                pairs.sort_by(|a, b| a.d2.total_cmp(&b.d2));
                let nearest = pairs.first().map_or(f64::INFINITY, |p| p.d2);
                pairs.retain(|p| p.within(gate));
                (pairs, nearest)
            })
            .collect()
    }
}

/// Jacobian of a landmark's position in the car's frame, Rᵀ(m − t), with
/// respect to the car's pose (x, y, θ), where `rt` is Rᵀ and `diff` is m − t.
/// Both parts are rotations, so its squared Frobenius norm is 2 + |diff|².
fn pose_jacobian(rt: &Matrix2<f64>, diff: &Vector2<f64>) -> SMatrix<f64, 2, 3> {
    let drt = Matrix2::new(0.0, 1.0, -1.0, 0.0) * rt;
    let mut h = SMatrix::<f64, 2, 3>::zeros();
    h.fixed_view_mut::<2, 2>(0, 0).copy_from(&(-rt));
    h.fixed_view_mut::<2, 1>(0, 2).copy_from(&(drt * diff));
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::Color;
    use crate::frontend::FrontEndConfig;
    use crate::log::Record;
    use cairn_core::SE2;
    use rand::{Rng, SeedableRng, rngs::StdRng};

    #[test]
    fn a_contradicting_colour_ranks_a_pair_lower_but_is_no_gate() {
        // A car standing still sees a yellow cone 10 m ahead, then reads it
        // blue with its range off by √χ² times its σ there: within the gate
        // by position, beyond it with the colour penalty.
        let config = FrontEndConfig::default();
        let (a, b, gate) = (config.range_sigma, config.range_sigma_relative, config.gate);
        assert!(config.color_penalty > 1.0);
        let mut slam = GraphSlam::new(config);
        let cone = |r: f64, color| Detection {
            position: Vector2::new(r, 0.0),
            range_bearing: Some((r, 0.0)),
            color,
            id: None,
            covariance: None,
        };
        let k = (gate - 1.0).sqrt();
        let off = (10.0 + a * k) / (1.0 - b * k);
        for step in 0..=12 {
            let t = 0.1 * f64::from(step);
            slam.process(&Record::Odom {
                t,
                v: 0.0,
                yaw_rate: 0.0,
                steer: None,
                vy: None,
            });
            let cones = if step < 12 {
                vec![cone(10.0, Color::Yellow)]
            } else {
                vec![cone(off, Color::Blue)]
            };
            slam.process(&Record::Cones { t, cones });
        }
        let matched = slam.associations();
        let yellow = matched[0].landmark;
        assert!(yellow.is_some(), "{matched:?}");
        assert_eq!(
            matched.last().map(|m| m.landmark),
            Some(yellow),
            "{matched:?}"
        );
    }

    #[test]
    fn the_pose_jacobian_matches_differences_and_its_norm_the_bound() {
        let mut rng = StdRng::seed_from_u64(5);
        let local = |pose: &SE2, m: &Vector2<f64>| pose.rotation().transpose() * (m - pose.t);
        for _ in 0..200 {
            let pose = SE2::new(
                rng.random_range(-50.0..50.0),
                rng.random_range(-50.0..50.0),
                rng.random_range(-3.0..3.0),
            );
            let m = Vector2::new(rng.random_range(-60.0..60.0), rng.random_range(-60.0..60.0));
            let h = pose_jacobian(&pose.rotation().transpose(), &(m - pose.t));
            assert!(
                (h.norm_squared() - (2.0 + (m - pose.t).norm_squared())).abs()
                    < 1e-9 * h.norm_squared()
            );
            // Central differences in x, y and θ.
            for k in 0..3 {
                let eps = 1e-6;
                let mut p = [pose.t.x, pose.t.y, pose.theta];
                let mut q = p;
                p[k] += eps;
                q[k] -= eps;
                let plus = local(&SE2::new(p[0], p[1], p[2]), &m);
                let minus = local(&SE2::new(q[0], q[1], q[2]), &m);
                let numeric = (plus - minus) / (2.0 * eps);
                assert!(
                    (numeric - h.column(k)).norm() < 1e-6 * (1.0 + m.norm()),
                    "{k}"
                );
            }
        }
    }
}
