//! Each scan's pose: corrected by the landmarks it matched, and made a
//! keyframe tied to the last by the odometry.

use super::edges::{OdometryEdge, odometry_information};
use super::{GraphSlam, nearest_information};
use crate::files::StampedPose;
use crate::log::Detection;
use crate::motion::Correction;
use cairn_core::SE2;
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2};

impl GraphSlam {
    /// Gauss-Newton on the pose alone, landmarks held at their EKF means.
    pub(super) fn localise(
        &self,
        pred: &SE2,
        pred_cov: &Matrix3<f64>,
        cones: &[Detection],
        covs: &[Matrix2<f64>],
        assigned: &[Option<usize>],
    ) -> (SE2, Matrix3<f64>) {
        let prior_info = nearest_information(pred_cov);
        let mut x = pred.to_vector();
        let mut h = prior_info;
        for _ in 0..3 {
            let pose = SE2::from_vector(&x);
            let rt = pose.rotation().transpose();
            let drt = Matrix2::new(0.0, 1.0, -1.0, 0.0) * rt;
            let mut dx = x - pred.to_vector();
            dx[2] = cairn_core::se2::normalize_angle(dx[2]);
            h = prior_info;
            let mut g = -(prior_info * dx);
            for (i, l) in assigned.iter().enumerate() {
                let Some(l) = *l else { continue };
                let lm = &self.landmarks[l];
                if lm.sighting.seen < 2 {
                    continue;
                }
                let diff = lm.mean - pose.t;
                let e = cones[i].position - rt * diff;
                let mut j = SMatrix::<f64, 2, 3>::zeros();
                j.fixed_view_mut::<2, 2>(0, 0).copy_from(&(-rt));
                j.fixed_view_mut::<2, 1>(0, 2).copy_from(&(drt * diff));
                let s = rt * lm.cov * rt.transpose() + covs[i];
                let w = nearest_information(&s);
                h += j.transpose() * w * j;
                g += j.transpose() * w * e;
            }
            let Some(step) = h.cholesky().map(|c| c.solve(&g)) else {
                break;
            };
            x += step;
            if step.norm() < 1e-9 {
                break;
            }
        }
        let cov = h.try_inverse().unwrap_or(*pred_cov);
        (SE2::from_vector(&x), 0.5 * (cov + cov.transpose()))
    }

    /// Makes the scan's pose the current one and a keyframe, tied to the
    /// last by the odometry (its heading variance beyond the yaw-rate bias
    /// and its sideslip Jacobian, integrated with the correction `used`);
    /// returns its index.
    pub(super) fn push_keyframe(
        &mut self,
        t: f64,
        (pose, pose_cov): (SE2, Matrix3<f64>),
        (delta, delta_cov): (SE2, Matrix3<f64>),
        (heading_variance, slip_jacobian): (f64, Vector2<f64>),
        used: Correction,
    ) -> usize {
        self.pose = pose;
        self.pose_cov = pose_cov;
        let keyframe = self.poses.len();
        self.poses.push(StampedPose { t, pose });
        if keyframe > 0 {
            self.odometry.push(OdometryEdge {
                delta,
                information: odometry_information(&delta_cov),
                dt: t - self.poses[keyframe - 1].t,
                yaw_rate_bias: used.yaw_rate_bias,
                heading_variance,
                slip_jacobian,
                slip_made: slip_jacobian * used.sideslip,
            });
        }
        keyframe
    }
}
