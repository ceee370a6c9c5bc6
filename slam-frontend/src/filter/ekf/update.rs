//! EKF-SLAM's measurement updates: a landmark's range and bearing, jointly
//! or on a fixed map, and a recognised place as a measurement of the pose.

use super::storage::PENDING;
use super::{EkfSlam, PLACE_FIX_CHI2, PLACE_SIGMA, POSE, ROBOT};
use crate::filter::{innovation, predict};
use crate::log::Detection;
use cairn_core::se2::normalize_angle;
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2};

impl EkfSlam {
    /// Back in the start area with a drift the gates do not cover: where
    /// place recognition puts the car
    /// ([`Run::recognise_once`](crate::filter::Run::recognise_once)) is fused as a
    /// measurement of the pose, so the pose and, through their
    /// correlations, the landmarks move towards it, and the scan's
    /// detections can then match the start's landmarks and close the loop.
    pub(super) fn fix_pose_by_recognition(&mut self, cones: &[Detection]) {
        let pose = self.pose();
        let live = self.landmarks.iter().filter_map(|lm| {
            let slot = lm.slot?;
            Some((self.x.fixed_rows::<2>(slot).into_owned(), &lm.sighting))
        });
        let Some(place) = self.run.recognise_once(&pose, cones, live) else {
            return;
        };
        let mut nu = place.to_vector() - pose.to_vector();
        nu[2] = normalize_angle(nu[2]);
        let p_rr = self.pose_cov();
        let beyond_gates = p_rr
            .try_inverse()
            .is_some_and(|inverse| nu.dot(&(inverse * nu)) > PLACE_FIX_CHI2);
        let r = Matrix3::from_diagonal(&PLACE_SIGMA.map(|s| s * s));
        let Some(l_inv) = (p_rr + r)
            .cholesky()
            .and_then(|c| c.l().try_inverse())
            .filter(|_| beyond_gates)
        else {
            return;
        };
        // H = [I₃ 0]: P Hᵀ is P's first three columns; the downdate is
        // W Wᵀ with W = P Hᵀ L⁻ᵀ, as in a landmark's update.
        self.flush();
        let n = self.dim;
        let mut w = self.pending.view_mut((0, 0), (n, POSE));
        w.gemm(
            1.0,
            &self.p.view((0, 0), (n, POSE)),
            &l_inv.transpose(),
            0.0,
        );
        self.x.rows_mut(0, n).gemv(1.0, &w, &(l_inv * nu), 1.0);
        self.x[2] = normalize_angle(self.x[2]);
        self.rank = POSE;
        self.flush();
    }

    /// The joint EKF update with one range-bearing measurement of the
    /// landmark at `slot`; H is non-zero in the pose and landmark columns
    /// only, so P Hᵀ takes 5 columns of P and the update is a rank-2
    /// downdate of P, left pending (see [`EkfSlam::flush`]). False when the
    /// prediction is degenerate.
    pub(super) fn update_joint(&mut self, slot: usize, z: &Vector2<f64>, r: &Matrix2<f64>) -> bool {
        if self.rank + 2 > PENDING {
            self.flush();
        }
        let (n, rank) = (self.dim, self.rank);
        let pose = self.pose();
        let m = self.x.fixed_rows::<2>(slot).into_owned();
        let Some(pred) = predict(&pose, &m) else {
            return false;
        };
        let nu = innovation(z, &pred.z);
        let p = self.p.view((0, 0), (n, n));
        let mut pht = self.pht.view_mut((0, 0), (n, 2));
        pht.gemm(1.0, &p.columns(0, POSE), &pred.h_pose.transpose(), 0.0);
        pht.gemm(1.0, &p.columns(slot, 2), &pred.h_landmark.transpose(), 1.0);
        if rank > 0 {
            // With the downdates pending, P Hᵀ = P₀ Hᵀ − U (H U)ᵀ.
            let u = self.pending.view((0, 0), (n, rank));
            let mut uht = SMatrix::<f64, PENDING, 2>::zeros();
            let mut uht = uht.rows_mut(0, rank);
            uht.gemm_tr(1.0, &u.rows(0, POSE), &pred.h_pose.transpose(), 0.0);
            uht.gemm_tr(1.0, &u.rows(slot, 2), &pred.h_landmark.transpose(), 1.0);
            pht.gemm(-1.0, &u, &uht, 1.0);
        }
        let s =
            pred.h_pose * pht.fixed_rows::<3>(0) + pred.h_landmark * pht.fixed_rows::<2>(slot) + r;
        // S = LLᵀ; with W = P Hᵀ L⁻ᵀ the gain is W L⁻¹ and the downdate
        // P Hᵀ S⁻¹ H P is W Wᵀ, symmetric by construction.
        let Some(l_inv) = s.cholesky().and_then(|c| c.l().try_inverse()) else {
            return false;
        };
        let mut w = self.pending.view_mut((0, rank), (n, 2));
        w.gemm(1.0, &pht, &l_inv.transpose(), 0.0);
        self.x.rows_mut(0, n).gemv(1.0, &w, &(l_inv * nu), 1.0);
        self.x[2] = normalize_angle(self.x[2]);
        self.rank += 2;
        true
    }

    /// Localisation on the fixed map: only the pose and the bias are
    /// updated, with the landmark's own uncertainty added to the
    /// measurement noise.
    pub(super) fn update_pose(&mut self, slot: usize, z: &Vector2<f64>, r: &Matrix2<f64>) -> bool {
        self.flush();
        let pose = self.pose();
        let m = self.x.fixed_rows::<2>(slot).into_owned();
        let Some(pred) = predict(&pose, &m) else {
            return false;
        };
        let nu = innovation(z, &pred.z);
        let p_rr = self.p.fixed_view::<ROBOT, ROBOT>(0, 0).into_owned();
        let p_mm = self.p.fixed_view::<2, 2>(slot, slot).into_owned();
        let pht: SMatrix<f64, ROBOT, 2> =
            p_rr.fixed_view::<ROBOT, 3>(0, 0) * pred.h_pose.transpose();
        let s = pred.h_pose * pht.fixed_rows::<3>(0)
            + pred.h_landmark * p_mm * pred.h_landmark.transpose()
            + r;
        let Some(s_inv) = s.try_inverse() else {
            return false;
        };
        let k = pht * s_inv;
        let x = self.x.fixed_rows::<ROBOT>(0) + k * nu;
        self.x.fixed_rows_mut::<ROBOT>(0).copy_from(&x);
        self.x[2] = normalize_angle(self.x[2]);
        let p_rr = p_rr - k * pht.transpose();
        self.p
            .fixed_view_mut::<ROBOT, ROBOT>(0, 0)
            .copy_from(&(0.5 * (p_rr + p_rr.transpose())));
        true
    }
}
