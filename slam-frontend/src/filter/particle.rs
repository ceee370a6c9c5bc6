//! A FastSLAM particle: its pose, its map of landmark EKFs (shared
//! copy-on-write with its relatives) and its path, and the per-particle
//! filtering steps.

use super::{Choice, innovation, predict};
use crate::files::StampedPose;
use crate::sighting::Sighting;
use cairn_core::SE2;
use cairn_core::se2::normalize_angle;
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use std::rc::Rc;

#[derive(Clone, Debug)]
pub(super) struct Landmark {
    pub(super) mean: Vector2<f64>,
    pub(super) cov: Matrix2<f64>,
    pub(super) removed: bool,
    pub(super) sighting: Sighting,
}

/// One step of a particle's path: its pose after a scan and what each
/// detection was associated with. Steps are shared between the particles
/// that descend from the same ancestor.
#[derive(Debug)]
pub(super) struct Step {
    pub(super) scan: usize,
    pub(super) pose: StampedPose,
    pub(super) choices: Box<[Option<u32>]>,
    pub(super) parent: Option<Rc<Step>>,
}

impl Drop for Step {
    /// Unlinks the chain iteratively: a recursive drop of a long path would
    /// overflow the stack.
    fn drop(&mut self) {
        let mut next = self.parent.take();
        while let Some(step) = next {
            match Rc::try_unwrap(step) {
                Ok(mut step) => next = step.parent.take(),
                Err(_) => break,
            }
        }
    }
}

#[derive(Clone, Debug)]
pub(super) struct Particle {
    pub(super) pose: SE2,
    pub(super) log_weight: f64,
    /// Landmarks shared with other particles until one of them changes.
    pub(super) map: Vec<Rc<Landmark>>,
    pub(super) path: Option<Rc<Step>>,
    /// Landmarks that came back at the start of a lap in the last scan.
    pub(super) returned: usize,
}

pub(super) fn push_step(
    p: &mut Particle,
    scan: usize,
    pose: StampedPose,
    choices: Vec<Option<u32>>,
) {
    let parent = p.path.take();
    p.path = Some(Rc::new(Step {
        scan,
        pose,
        choices: choices.into_boxed_slice(),
        parent,
    }));
}

/// FastSLAM 2.0's proposal: the Gaussian over the pose given the motion and
/// the matched observations, folded in one at a time (each relinearised at
/// the current mean), sampled with the standard-normal `noise`.
pub(super) fn proposal(
    predicted: &SE2,
    motion_cov: &Matrix3<f64>,
    map: &[Rc<Landmark>],
    choices: &[Choice],
    measurements: &[(Vector2<f64>, Matrix2<f64>)],
    noise: &Vector3<f64>,
) -> SE2 {
    // A floor keeps Σ invertible when the car stands still.
    let mut cov = motion_cov + Matrix3::identity() * 1e-10;
    let mut mean = predicted.to_vector();
    for (c, (z, r)) in choices.iter().zip(measurements) {
        let Choice::Landmark(l) = c else { continue };
        let lm = &map[*l];
        let at = SE2::from_vector(&mean);
        let Some(pred) = predict(&at, &lm.mean) else {
            continue;
        };
        let q = pred.h_landmark * lm.cov * pred.h_landmark.transpose() + r;
        let (Some(q_inv), Some(cov_inv)) = (q.try_inverse(), cov.try_inverse()) else {
            continue;
        };
        let Some(next) = (pred.h_pose.transpose() * q_inv * pred.h_pose + cov_inv).try_inverse()
        else {
            continue;
        };
        cov = 0.5 * (next + next.transpose());
        mean += cov * pred.h_pose.transpose() * q_inv * innovation(z, &pred.z);
        mean[2] = normalize_angle(mean[2]);
    }
    let sample = match cov.cholesky() {
        Some(c) => mean + c.l() * noise,
        None => mean,
    };
    SE2::from_vector(&sample)
}

/// The landmark's EKF update with a range-bearing measurement from `pose`.
pub(super) fn refine(lm: &mut Landmark, pose: &SE2, z: &Vector2<f64>, r: &Matrix2<f64>) {
    let Some(pred) = predict(pose, &lm.mean) else {
        return;
    };
    let h = pred.h_landmark;
    let pht = lm.cov * h.transpose();
    let Some(s_inv) = (h * pht + r).try_inverse() else {
        return;
    };
    let k = pht * s_inv;
    lm.mean += k * innovation(z, &pred.z);
    let cov = (Matrix2::identity() - k * h) * lm.cov;
    lm.cov = 0.5 * (cov + cov.transpose());
}
