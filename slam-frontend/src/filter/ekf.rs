//! EKF-SLAM: one Gaussian over the pose, the gyro's bias and every
//! landmark, with the full covariance (Thrun et al., Probabilistic Robotics,
//! 10.2). Each prediction costs O(n) and each range-bearing update O(n²) in
//! the state size n. Once its loop closes it starts no new landmarks but
//! keeps updating those it has jointly with the pose, so later laps refine
//! the map; a map given with [`EkfSlam::with_map`] stays fixed.

use super::{Choice, Run, candidates, landmark_from, measurement, predict};
use crate::files::{Association, StampedPose};
use crate::frontend::association::{Correlation, Pair};
use crate::frontend::{FrontEndConfig, Mode, Timing, beside};
use crate::log::{Detection, Record};
use crate::map::Cone;
use crate::motion::{compose_jacobians, with_heading_variance, without_bias};
use crate::sighting::{Sighting, in_view};
use cairn_core::SE2;
use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, SMatrix, Vector2, Vector3};
use std::time::Instant;

mod rematch;
mod storage;
#[cfg(test)]
mod tests;
mod update;

use storage::PENDING;

/// State entries of the pose (x, y, θ).
const POSE: usize = 3;
/// The state entry of the yaw-rate bias (rad/s), after the pose.
const BIAS: usize = 3;
/// State entries before the landmarks': the pose and the bias.
const ROBOT: usize = 4;

/// χ² (3 degrees of freedom, 99%) of a recognised place's offset from the
/// pose beyond which the gates would not have matched the start's
/// landmarks, and the place is fused as a measurement of the pose.
const PLACE_FIX_CHI2: f64 = 11.34;

/// σ of a recognised place (m, m, rad): the start landmarks fitted to a
/// scan's detections.
const PLACE_SIGMA: Vector3<f64> = Vector3::new(0.1, 0.1, 0.01);

/// The robot's block of the covariance.
type RobotMatrix = SMatrix<f64, ROBOT, ROBOT>;

#[derive(Clone, Debug)]
struct Landmark {
    /// Index of the landmark's x in the state; `None` once removed.
    slot: Option<usize>,
    sighting: Sighting,
}

/// The EKF-SLAM estimator. Feed it records with [`EkfSlam::process`].
#[derive(Clone, Debug)]
pub struct EkfSlam {
    run: Run,
    /// Mean; the first `dim` entries are live, the rest is spare capacity.
    x: DVector<f64>,
    /// Covariance, live in its leading `dim` × `dim` block.
    p: DMatrix<f64>,
    dim: usize,
    landmarks: Vec<Landmark>,
    /// Landmark owning each slot, by (slot − 4) / 2.
    owners: Vec<usize>,
    poses: Vec<StampedPose>,
    /// The pose's covariance after each scan.
    pose_covs: Vec<Matrix3<f64>>,
    detections: Vec<(usize, usize, Option<usize>)>,
    /// Each detection's (range, bearing) and covariance, in the order of
    /// `detections`.
    measured: Vec<(Vector2<f64>, Matrix2<f64>)>,
    /// P Hᵀ of the current update (capacity × 2).
    pht: DMatrix<f64>,
    /// The downdates not yet applied to `p`: the covariance is
    /// P − U Uᵀ with U the first `rank` columns (capacity × [`PENDING`]).
    pending: DMatrix<f64>,
    rank: usize,
    /// The bias's random walk (rad/s/√s).
    bias_walk: f64,
}

impl EkfSlam {
    /// A filter that starts mapping at the origin (or the log's `start`).
    pub fn new(config: FrontEndConfig) -> Self {
        let capacity = ROBOT + 2 * 64;
        let mut p = DMatrix::zeros(capacity, capacity);
        for i in 0..POSE {
            p[(i, i)] = 1e-9;
        }
        // The bias is known to the yaw-rate σ that covers it; the heading
        // then takes the yaw rate's white noise alone.
        p[(BIAS, BIAS)] = config.yaw_rate_bias_prior().powi(2);
        let walk = config.yaw_rate_bias_walk;
        let config = FrontEndConfig {
            yaw_rate_sigma: config.yaw_rate_noise,
            ..config
        };
        Self {
            run: Run::new(config),
            x: DVector::zeros(capacity),
            p,
            dim: ROBOT,
            landmarks: Vec::new(),
            owners: Vec::new(),
            poses: Vec::new(),
            pose_covs: Vec::new(),
            detections: Vec::new(),
            measured: Vec::new(),
            pht: DMatrix::zeros(capacity, 2),
            pending: DMatrix::zeros(capacity, PENDING),
            rank: 0,
            bias_walk: walk,
        }
    }

    /// A filter that localises on `map` (its landmarks fixed, their
    /// covariances kept), placed by aligning the first scans to it.
    pub fn with_map(config: FrontEndConfig, map: &[Cone]) -> Self {
        let mut ekf = Self::new(config);
        for c in map {
            let cov = c.prior_covariance();
            let slot = ekf.push_slot(ekf.landmarks.len());
            ekf.x.fixed_rows_mut::<2>(slot).copy_from(&c.position);
            ekf.p.fixed_view_mut::<2, 2>(slot, slot).copy_from(&cov);
            ekf.landmarks.push(Landmark {
                slot: Some(slot),
                sighting: Sighting::known(c.color),
            });
        }
        ekf.run.start_on(map);
        ekf
    }

    /// Known correspondences: every detection is associated as the truth
    /// file says (landmark column = true cone), instead of by a method.
    pub fn with_known(mut self, truth: &[Association]) -> Self {
        self.run.set_known(truth);
        self
    }

    /// Processes one log record.
    pub fn process(&mut self, record: &Record) {
        if let Some((t, cones)) = self.run.next_scan(record) {
            let (start, closures) = (Instant::now(), self.run.loop_closures);
            self.update(t, cones);
            self.run
                .record_update(start.elapsed().as_secs_f64(), closures);
        }
    }

    /// The current pose estimate.
    pub fn pose(&self) -> SE2 {
        SE2::from_vector(&self.x.fixed_rows::<3>(0).into_owned())
    }

    /// The yaw-rate bias estimated so far (rad/s): true yaw rate =
    /// measured − this.
    pub fn yaw_rate_bias(&self) -> f64 {
        self.x[BIAS]
    }

    /// The current pose covariance.
    pub fn pose_cov(&self) -> Matrix3<f64> {
        self.p.fixed_view::<3, 3>(0, 0).into_owned()
    }

    /// Mapping or localising.
    pub fn mode(&self) -> Mode {
        self.run.mode
    }

    /// Loop closures detected so far.
    pub fn loop_closures(&self) -> usize {
        self.run.loop_closures
    }

    /// Update times.
    pub fn timing(&self) -> &Timing {
        &self.run.timing
    }

    /// The size of the joint state (3 + 2 per live landmark).
    pub fn state_size(&self) -> usize {
        self.dim
    }

    fn update(&mut self, t: f64, cones: &[Detection]) {
        let scan = self.run.scans;
        self.run.scans += 1;
        if scan == 0 {
            self.x
                .fixed_rows_mut::<3>(0)
                .copy_from(&self.run.start.to_vector());
        }
        // Every scan leaves a pose: the last one's time is the last scan's.
        let dt = self.poses.last().map_or(0.0, |last| (t - last.t).max(0.0));
        self.predict_motion(dt);
        match self.run.place(&self.pose(), cones) {
            Err(()) => {
                // Not placed on the given map yet: nothing is associated.
                self.detections
                    .extend((0..cones.len()).map(|i| (scan, i, None)));
                self.measured
                    .extend(cones.iter().map(|d| measurement(&self.run.config, d)));
                self.poses.push(StampedPose {
                    t,
                    pose: self.pose(),
                });
                self.pose_covs.push(self.pose_cov());
                return;
            }
            Ok(Some(pose)) => {
                self.x.fixed_rows_mut::<3>(0).copy_from(&pose.to_vector());
                self.p
                    .fixed_view_mut::<3, 3>(0, 0)
                    .copy_from(&Matrix3::from_diagonal(&Vector3::new(0.25, 0.25, 0.05)));
                // The placement says nothing of the bias.
                self.p.fixed_view_mut::<3, 1>(0, BIAS).fill(0.0);
                self.p.fixed_view_mut::<1, 3>(BIAS, 0).fill(0.0);
            }
            Ok(None) => {}
        }
        if self.run.back_at_start(&self.pose()) {
            self.fix_pose_by_recognition(cones);
        }

        let measurements: Vec<_> = cones
            .iter()
            .map(|d| measurement(&self.run.config, d))
            .collect();
        let choices = self.choose(scan, cones, &measurements);
        let mut associated = vec![false; self.landmarks.len()];
        let mut returned = 0;
        for (i, d) in cones.iter().enumerate() {
            let (z, r) = &measurements[i];
            let landmark = match choices[i] {
                Choice::Landmark(l) => {
                    let ok = match self.landmarks[l].slot {
                        Some(slot) if self.run.map_given => self.update_pose(slot, z, r),
                        Some(slot) => self.update_joint(slot, z, r),
                        None => false,
                    };
                    ok.then_some(l)
                }
                Choice::New => Some(self.add_landmark(z, r, d, scan)),
                Choice::Reject => None,
            };
            self.detections.push((scan, i, landmark));
            self.measured.push((*z, *r));
            let Some(l) = landmark else { continue };
            self.run.remember(scan, i, d, l);
            if l < associated.len() {
                associated[l] = true;
            }
            let (distance, heading) = (self.run.motion.distance(), self.x[2]);
            let sighting = &mut self.landmarks[l].sighting;
            if self.run.mode == Mode::Mapping {
                sighting.count(d.color, self.run.config.confirm_after);
            }
            if sighting.revisit(scan, distance, heading) {
                returned += 1;
            }
        }
        self.flush();
        let pose = self.pose();

        self.count_misses(&pose, &associated, scan);
        if self.run.lap_closed(&pose, returned) {
            self.run.close_loop();
            for lm in &mut self.landmarks {
                lm.sighting.settle();
            }
        }
        self.poses.push(StampedPose { t, pose });
        self.pose_covs.push(self.pose_cov());
    }

    /// Moves the pose by the odometry of the last `dt` seconds, its turn
    /// less the bias: with F the robot's Jacobian, P_rr ← F P_rr Fᵀ + Q and
    /// P_rm ← F P_rm. The bias is a state, so the turn is weighed by the
    /// yaw rate's white noise alone, as in the graph's full optimisation.
    fn predict_motion(&mut self, dt: f64) {
        let white = self
            .run
            .motion
            .white_heading_variance(self.run.config.yaw_rate_noise);
        let (delta, q) = self.run.motion.take();
        let q = with_heading_variance(&q, white);
        let pose = self.pose();
        let bias = self.x[BIAS];
        let (delta, by_bias) = without_bias(&delta, bias, dt);
        let (j_pose, j_delta) = compose_jacobians(&pose, &delta);
        let by_bias = j_delta * by_bias;
        let mut f = RobotMatrix::identity();
        f.fixed_view_mut::<3, 3>(0, 0).copy_from(&j_pose);
        f.fixed_view_mut::<3, 1>(0, BIAS).copy_from(&by_bias);
        let mut noise = RobotMatrix::zeros();
        noise
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(j_delta * q * j_delta.transpose()));
        noise[(BIAS, BIAS)] = self.bias_walk.powi(2) * dt;
        let n = self.dim;
        let p_rr = self.p.fixed_view::<ROBOT, ROBOT>(0, 0).into_owned();
        let p_rr = f * p_rr * f.transpose() + noise;
        self.p
            .fixed_view_mut::<ROBOT, ROBOT>(0, 0)
            .copy_from(&(0.5 * (p_rr + p_rr.transpose())));
        if n > ROBOT {
            let cross = f * self.p.view((0, ROBOT), (ROBOT, n - ROBOT));
            self.p
                .view_mut((0, ROBOT), (ROBOT, n - ROBOT))
                .copy_from(&cross);
            self.p
                .view_mut((ROBOT, 0), (n - ROBOT, ROBOT))
                .copy_from(&cross.transpose());
        }
        self.x
            .fixed_rows_mut::<3>(0)
            .copy_from(&pose.compose(&delta).to_vector());
    }

    /// The association of every detection of the scan.
    fn choose(
        &mut self,
        scan: usize,
        cones: &[Detection],
        measurements: &[(Vector2<f64>, Matrix2<f64>)],
    ) -> Vec<Choice> {
        let pose = self.pose();
        let pose_cov = self.pose_cov();
        let localising = self.run.mode == Mode::Localising;
        let live = self.landmarks.iter().enumerate().filter_map(|(l, lm)| {
            let slot = lm.slot?;
            (!localising || lm.sighting.confirmed).then(|| {
                let view = super::Landmark {
                    mean: self.x.fixed_rows::<2>(slot).into_owned(),
                    cov: self.p.fixed_view::<2, 2>(slot, slot).into_owned(),
                    cross: self.p.fixed_view::<3, 2>(0, slot).into_owned(),
                    sighting: &lm.sighting,
                };
                (l, view)
            })
        });
        let (candidates, nearest) = candidates(
            &self.run.config,
            &pose,
            &pose_cov,
            measurements,
            cones,
            live,
        );
        self.run.spread(&nearest);
        let tracked = self
            .run
            .tracked(cones, |l| self.landmarks[l].slot.is_some());
        let means: Vec<(usize, Vector2<f64>)> = self
            .owners
            .iter()
            .enumerate()
            .map(|(k, &l)| (l, self.x.fixed_rows::<2>(ROBOT + 2 * k).into_owned()))
            .collect();
        // Pairs of different detections are correlated through the pose
        // and through the landmarks' joint covariance: H_a P H_bᵀ.
        let correlation = |a: &Pair, b: &Pair| -> Matrix2<f64> {
            let part = |p: &Pair| {
                let slot = self.landmarks[p.landmark].slot.unwrap_or(0);
                let m = self.x.fixed_rows::<2>(slot).into_owned();
                let h = predict(&pose, &m).map_or(Matrix2::zeros(), |r| r.h_landmark);
                (slot, h)
            };
            let ((sa, ha), (sb, hb)) = (part(a), part(b));
            let p = &self.p;
            a.h_pose * pose_cov * b.h_pose.transpose()
                + a.h_pose * p.fixed_view::<3, 2>(0, sb) * hb.transpose()
                + ha * p.fixed_view::<2, 3>(sa, 0) * b.h_pose.transpose()
                + ha * p.fixed_view::<2, 2>(sa, sb) * hb.transpose()
        };
        self.run.choose(
            scan,
            &candidates,
            &nearest,
            &tracked,
            Correlation::General(&correlation),
            |i, taken| {
                let point = pose.transform_point(&cones[i].position);
                beside(&point, means.iter().map(|(l, m)| (*l, m)), taken)
            },
        )
    }

    /// Appends a landmark seen as `z` (covariance `r`) from the current
    /// pose, with its cross-covariances through the inverse measurement
    /// model's Jacobians. Returns its index.
    fn add_landmark(
        &mut self,
        z: &Vector2<f64>,
        r: &Matrix2<f64>,
        d: &Detection,
        scan: usize,
    ) -> usize {
        self.flush();
        let pose = self.pose();
        let (m, j_pose, j_z) = landmark_from(&pose, z);
        let l = self.landmarks.len();
        let n = self.dim;
        let slot = self.push_slot(l);
        // Cross-covariance with everything: Jₚ P[0..3, :].
        let cross = j_pose * self.p.view((0, 0), (3, n));
        self.p.view_mut((slot, 0), (2, n)).copy_from(&cross);
        self.p
            .view_mut((0, slot), (n, 2))
            .copy_from(&cross.transpose());
        let p_rr = self.pose_cov();
        let p_mm = j_pose * p_rr * j_pose.transpose() + j_z * r * j_z.transpose();
        self.p
            .fixed_view_mut::<2, 2>(slot, slot)
            .copy_from(&(0.5 * (p_mm + p_mm.transpose())));
        self.x.fixed_rows_mut::<2>(slot).copy_from(&m);
        let distance = self.run.motion.distance();
        self.landmarks.push(Landmark {
            slot: Some(slot),
            sighting: Sighting::new(d.color, scan, distance, pose.theta),
        });
        l
    }

    /// Counts misses of landmarks well inside the field of view and drops
    /// tentative ones missed more often than seen.
    fn count_misses(&mut self, pose: &SE2, associated: &[bool], scan: usize) {
        let inverse = pose.inverse();
        let mapping = self.run.mode == Mode::Mapping;
        let distance = self.run.motion.distance();
        let mut dropped = Vec::new();
        for (l, lm) in self.landmarks.iter_mut().enumerate() {
            let Some(slot) = lm.slot else { continue };
            let mean = self.x.fixed_rows::<2>(slot).into_owned();
            let visible = in_view(&self.run.config, &inverse, &mean);
            let seen = associated.get(l).copied().unwrap_or(true);
            if lm
                .sighting
                .after_scan(&self.run.config, visible, seen, mapping, scan, distance)
            {
                dropped.push(l);
            }
        }
        for l in dropped {
            self.remove(l);
        }
    }

    /// Live, confirmed landmarks in index order, less those the whole run
    /// judges clutter.
    fn map_rows(&self) -> Vec<usize> {
        let live = (0..self.landmarks.len())
            .filter(|&l| self.landmarks[l].slot.is_some() && self.landmarks[l].sighting.confirmed);
        let poses: Vec<(usize, SE2)> = self.poses.iter().map(|p| p.pose).enumerate().collect();
        let matched = self
            .detections
            .iter()
            .filter_map(|&(s, _, l)| Some((s, l?)));
        let clutter = super::judged_clutter(
            &self.run.config,
            &poses,
            matched,
            live.clone().map(|l| {
                let slot = self.landmarks[l].slot.unwrap_or(0);
                (
                    l,
                    self.x.fixed_rows::<2>(slot).into_owned(),
                    &self.landmarks[l].sighting,
                )
            }),
        );
        live.filter(|l| !clutter.contains(l)).collect()
    }

    /// The map: confirmed landmarks with their marginal covariances.
    pub fn map(&self) -> Vec<Cone> {
        self.map_rows()
            .into_iter()
            .map(|l| {
                let lm = &self.landmarks[l];
                let slot = lm.slot.unwrap_or(0);
                Cone {
                    position: self.x.fixed_rows::<2>(slot).into_owned(),
                    color: lm.sighting.color(),
                    covariance: self.p.fixed_view::<2, 2>(slot, slot).into_owned(),
                }
            })
            .collect()
    }

    /// The pose after every scan's update.
    pub fn trajectory(&self) -> &[StampedPose] {
        &self.poses
    }

    /// For every detection, its row in [`EkfSlam::map`] (or none).
    pub fn associations(&self) -> Vec<Association> {
        crate::files::in_map_rows(
            self.detections.iter().copied(),
            self.landmarks.len(),
            &self.map_rows(),
        )
    }
}
