//! The graph-SLAM front end: odometry → pose chain, detections → landmarks
//! (each refined by its own EKF), local pose optimisation per scan, loop
//! closure → full optimisation on Cairn's solver, then localisation on the
//! fixed map.

pub(crate) mod align;
pub mod association;
pub(crate) mod bias;
mod bias_walk;
mod calibration;
mod candidates;
mod config;
pub(crate) mod dispersion;
pub(crate) mod edges;
mod fits;
pub mod grid;
mod hindsight;
mod landmarks;
mod latency;
mod loop_closure;
mod noise;
mod optimise;
pub(crate) mod place_votes;
mod pose;
mod relocalise;
mod remap;
mod window;
pub use calibration::Calibration;
pub use config::{ConfigError, FrontEndConfig};
use edges::OdometryEdge;
pub use edges::nearest_information;
pub(crate) use landmarks::{Beside, beside};
pub use noise::DetectorNoise;
pub(crate) use optimise::MERGE_RADIUS;

use crate::files::{Association, StampedPose};
use crate::log::{Detection, Record};
use crate::map::Cone;
use crate::motion::{Odometry, compose_with_cov};
use crate::sighting::{ColorRate, MIN_LOOP, Sighting};
use association::{Correlation, associate};
use cairn_core::SE2;
use nalgebra::{Matrix2, Matrix3, Vector2};
use std::collections::HashMap;
use std::time::Instant;

pub use crate::motion::{MotionModel, MotionNoise};

/// Mapping or localisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Building the map.
    Mapping,
    /// Map fixed; only the pose is estimated.
    Localising,
}

#[derive(Clone, Debug)]
struct Landmark {
    mean: Vector2<f64>,
    cov: Matrix2<f64>,
    removed: bool,
    sighting: Sighting,
    /// What the poses behind the smoothing window saw of it.
    prior: window::Prior,
}

struct Observation {
    pose: usize,
    landmark: usize,
    z: Vector2<f64>,
    information: Matrix2<f64>,
}

/// Why a full optimisation failed.
#[derive(Debug, thiserror::Error)]
pub enum OptimiseError {
    /// The graph could not be built.
    #[error(transparent)]
    Graph(#[from] cairn_core::GraphError),
    /// The solver failed.
    #[error(transparent)]
    Solve(#[from] cairn_solvers::SolveError),
}

/// Timings of a run.
#[derive(Clone, Debug, Default)]
pub struct Timing {
    /// Seconds per scan update (association, local optimisation, EKFs).
    pub updates: Vec<f64>,
    /// Seconds of each scan update that closed a loop, all of it: place
    /// recognition, the full optimisation, matching the start area again.
    pub loop_closures: Vec<f64>,
    /// Seconds of the optimisation at the end of the run ([`GraphSlam::finish`]).
    pub final_optimisation: Option<f64>,
}

/// The graph-SLAM front end. Feed it records with [`GraphSlam::process`];
/// read the map, trajectory and associations at any time.
pub struct GraphSlam {
    config: FrontEndConfig,
    mode: Mode,
    pose: SE2,
    pose_cov: Matrix3<f64>,
    /// Motion since the last keyframe and its covariance (in that keyframe's frame).
    motion: Odometry,
    poses: Vec<StampedPose>,
    odometry: Vec<OdometryEdge>,
    /// Every sighting, in pose order (the smoothing window folds them so).
    observations: Vec<Observation>,
    landmarks: Vec<Landmark>,
    /// Merged landmark → the one it was merged into.
    alias: Vec<usize>,
    tracker: HashMap<u64, usize>,
    detections: Vec<(usize, usize, Option<usize>)>,
    scans: usize,
    started: bool,
    /// False until the first scan has been placed on a given map.
    aligned: bool,
    /// Tries at placing the car on a given map.
    placement: align::Placement,
    loop_closures: usize,
    /// Distance driven at the last loop closure.
    closed_at: Option<f64>,
    /// The scans' votes for the corrections of the pose that place
    /// recognition found near the start.
    place_votes: place_votes::PlaceVotes,
    calibration: Calibration,
    timing: Timing,
    window: window::Window,
    /// Scans near the start before the loop closed, matched again once it has.
    near_start_scans: Vec<loop_closure::PendingScan>,
    /// Distance driven when the car came back near the start.
    returned_at: Option<f64>,
    /// Every scan placed on the map, matched again by [`GraphSlam::finish`]
    /// (a few kB per second of driving).
    scan_log: Vec<loop_closure::PendingScan>,
    warnings: Vec<String>,
    colors: ColorRate,
    /// Scans waiting, unmatched, for the pose to be found on the map again
    /// ([`relocalise`]).
    lost_scans: Vec<loop_closure::PendingScan>,
    /// Times the pose was found on the map again.
    relocalisations: usize,
    /// Where mapping went on after relocalisation gave up
    /// ([`GraphSlam::merge_remapped`]).
    remapped: Vec<remap::Remapped>,
    /// The motion since the last scan that matched a landmark, and its
    /// covariance: how far the pose may have drifted from the map.
    drift: (SE2, Matrix3<f64>),
    /// The detector's noise as configured, and as learned from the matches.
    assumed_noise: [f64; 3],
    noise: noise::NoiseLearner,
    /// How much wider the innovations run than assumed: JCBB's joint test
    /// is widened by it.
    innovation_scale: dispersion::InnovationScale,
}

impl GraphSlam {
    /// A front end that starts mapping at the origin (or the log's `start`).
    pub fn new(config: FrontEndConfig) -> Self {
        let window = window::Window::new(config.yaw_rate_bias_prior(), config.sideslip_sigma);
        let colors = ColorRate::new(&config);
        let mut calibration = Calibration::default();
        calibration.yaw_rate_bias_walk = config.yaw_rate_bias_walk;
        calibration.scan_latency = config.scan_latency;
        let assumed_noise = config.detector_sigma();
        Self {
            motion: Odometry::new(config.motion, config.motion_noise())
                .with_scan_latency(config.scan_latency),
            config,
            mode: Mode::Mapping,
            pose: SE2::identity(),
            pose_cov: Matrix3::identity() * 1e-9,
            poses: Vec::new(),
            odometry: Vec::new(),
            observations: Vec::new(),
            landmarks: Vec::new(),
            alias: Vec::new(),
            tracker: HashMap::new(),
            detections: Vec::new(),
            scans: 0,
            started: false,
            aligned: true,
            placement: align::Placement::default(),
            loop_closures: 0,
            closed_at: None,
            place_votes: place_votes::PlaceVotes::default(),
            calibration,
            timing: Timing::default(),
            window,
            near_start_scans: Vec::new(),
            returned_at: None,
            scan_log: Vec::new(),
            warnings: Vec::new(),
            colors,
            lost_scans: Vec::new(),
            relocalisations: 0,
            remapped: Vec::new(),
            drift: (SE2::identity(), Matrix3::zeros()),
            assumed_noise,
            noise: noise::NoiseLearner::new(),
            innovation_scale: dispersion::InnovationScale::new(),
        }
    }

    /// A front end that localises on a given map from the first scan; the
    /// initial pose is found by aligning the first scans to the map.
    pub fn with_map(config: FrontEndConfig, map: &[Cone]) -> Self {
        let mut slam = GraphSlam::new(config);
        slam.mode = Mode::Localising;
        slam.aligned = false;
        for c in map {
            let cov = c.prior_covariance();
            slam.landmarks.push(Landmark {
                mean: c.position,
                cov,
                removed: false,
                sighting: Sighting::known(c.color),
                prior: window::Prior::default(),
            });
            slam.alias.push(slam.alias.len());
        }
        slam
    }

    /// Mapping or localising.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Loop closures detected so far.
    pub fn loop_closures(&self) -> usize {
        self.loop_closures
    }

    /// Times the pose, grown too uncertain to match detections one by one,
    /// was found on the map again from several scans together.
    pub fn relocalisations(&self) -> usize {
        self.relocalisations
    }

    /// Update and optimisation times.
    pub fn timing(&self) -> &Timing {
        &self.timing
    }

    /// Loop-closure optimisations that failed; the run went on with the
    /// estimate as it was before each.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The odometry corrections learnt so far.
    pub fn calibration(&self) -> Calibration {
        self.calibration
    }

    /// The current pose estimate.
    pub fn pose(&self) -> SE2 {
        self.pose
    }

    /// Ends the run. Landmarks mapped again after relocalisation gave up are
    /// first fitted back onto the earlier map where they clearly fit
    /// (`remap.rs`). When this run closed its loop (or found itself on its
    /// map again after drifting, or merged such landmarks), the detections left unmatched in real
    /// time are matched again from the poses as they now stand, within the
    /// χ² [`FINAL_GATE`]; every pose and landmark is optimised once more
    /// with all sightings, the laps driven on the fixed map included; and
    /// landmarks the whole run calls clutter leave the map. Unless
    /// [`FrontEndConfig::hindsight`] is off, every detection is then
    /// matched again (with tracking association along its tracker id's
    /// chain of sightings, with the other methods scan by scan) and the map
    /// optimised once more, for [`FrontEndConfig::hindsight_rounds`] or
    /// until the matches settle. Not real-time: its time is reported apart from
    /// the loop closures ([`Timing::final_optimisation`]). A failed solve
    /// keeps the estimate as it was. docs/bench/frontend-options.md has the
    /// measurements behind each step.
    pub fn finish(&mut self) -> Result<(), OptimiseError> {
        if self.timing.final_optimisation.is_some() {
            return Ok(());
        }
        let start = Instant::now();
        let merged = self.merge_remapped();
        if self.loop_closures == 0 && self.relocalisations == 0 && merged == 0 {
            return Ok(());
        }
        // Matching again skips the scans whose detections are all matched.
        let scans = std::mem::take(&mut self.scan_log);
        let gate = self.config.gate.max(FINAL_GATE);
        self.match_again(&scans, gate);
        // The last optimisation gives the map its covariances.
        let hindsight = self.matches_in_hindsight();
        let mut result = self.optimise(optimise::Batch::last(!hindsight));
        self.drop_clutter();
        if hindsight && result.is_ok() {
            self.widen_noise_to_residuals();
            self.drop_surplus_landmarks();
            result = self.settle_in_hindsight(&scans, gate);
            // Judged again on the colours of the detections as now matched.
            self.drop_clutter();
        }
        self.timing.final_optimisation = Some(start.elapsed().as_secs_f64());
        result
    }

    /// Processes one log record.
    pub fn process(&mut self, record: &Record) {
        match record {
            Record::Start { pose, .. } => {
                if !self.started {
                    self.pose = *pose;
                }
            }
            Record::Odom {
                t,
                v,
                yaw_rate,
                steer,
                vy,
            } => {
                let correction = self.calibration.correction();
                self.motion
                    .record(*t, (*v, *vy), *yaw_rate, *steer, correction);
            }
            Record::Cones { t, cones } => {
                // A `start` record once the run has begun is ignored.
                self.started = true;
                let t = self
                    .motion
                    .advance_to_scan(*t, self.calibration.correction());
                let (start, closures) = (Instant::now(), self.loop_closures);
                self.update(t, cones);
                let seconds = start.elapsed().as_secs_f64();
                self.timing.updates.push(seconds);
                if self.loop_closures > closures {
                    self.timing.loop_closures.push(seconds);
                }
            }
            Record::Points { .. } => {}
        }
    }

    fn update(&mut self, t: f64, cones: &[Detection]) {
        self.colors.learn(cones, &mut self.config);
        let scan = self.scans;
        self.scans += 1;
        if !self.aligned && !self.align_to_map(cones) {
            // Not placed on the map yet: these detections stay unassociated.
            self.detections
                .extend((0..cones.len()).map(|i| (scan, i, None)));
            self.pose = self.pose.compose(&self.motion.take().0);
            return;
        }
        // Predict the pose from the last keyframe.
        let previous = self.pose;
        // The heading's variance beyond the bias the full optimisation
        // estimates: the yaw rate's white noise and the turns' own error.
        let white = self
            .motion
            .white_heading_variance(self.config.yaw_rate_noise);
        let steps = (white, self.motion.slip_jacobian());
        let (delta, delta_cov) = self.motion.take();
        let (pred, pred_cov) = compose_with_cov(&previous, &self.pose_cov, &delta, &delta_cov);
        self.drift = compose_with_cov(&self.drift.0, &self.drift.1, &delta, &delta_cov);
        if self.mode == Mode::Mapping && self.config.relocalise_sigma > 0.0 {
            let limit = self.config.relocalise_sigma;
            let uncertain = cones
                .iter()
                .any(|d| relocalise::pose_sigma_at(&self.drift.1, d.position.norm()) > limit);
            let waiting = !self.lost_scans.is_empty();
            if waiting || (uncertain && self.map_near(&pred)) {
                self.wait_lost(t, scan, cones, (pred, pred_cov), (delta, delta_cov), steps);
                return;
            }
        }

        let covs: Vec<Matrix2<f64>> = cones.iter().map(|d| self.config.detection_cov(d)).collect();
        let (candidates, nearest) =
            self.candidates(&pred, &pred_cov, cones, &covs, self.config.gate);
        let tracked: Vec<Option<usize>> = cones
            .iter()
            .map(|d| {
                d.id.and_then(|id| self.tracker.get(&id))
                    .map(|&l| self.resolve(l))
            })
            .collect();
        self.innovation_scale.observe(&nearest);
        let scale = self.innovation_scale.scale();
        let joint_gate = |pairs: usize| scale * chi2_99(2 * pairs);
        let assigned = associate(
            self.config.association,
            &candidates,
            &tracked,
            joint_gate,
            Correlation::ThroughPose(&pred_cov),
        );

        // Local pose optimisation: odometry prior plus the matched landmarks.
        let (pose, pose_cov) = self.localise(&pred, &pred_cov, cones, &covs, &assigned);
        if self.config.learn_detector_noise {
            self.learn_noise(&pose, cones, &covs, &assigned);
        }
        let anchors = assigned
            .iter()
            .flatten()
            .filter(|&&l| self.landmarks[l].sighting.seen >= 2)
            .count();
        let used = self.calibration.correction();
        if anchors >= 3 {
            let dt = self.poses.last().map_or(0.0, |p| t - p.t);
            let outside_window = self.mode != Mode::Mapping;
            self.calibration
                .learn(&previous, &pred, (&pose, &pose_cov), dt, outside_window);
        }
        let keyframe = self.push_keyframe(t, (pose, pose_cov), (delta, delta_cov), steps, used);

        if assigned.iter().any(Option::is_some) {
            self.drift = (SE2::identity(), Matrix3::zeros());
        }
        let mut returned = 0;
        let mut associated = vec![false; self.landmarks.len()];
        let mut taken = vec![false; self.landmarks.len()];
        for &l in assigned.iter().flatten() {
            taken[l] = true;
        }
        for (i, d) in cones.iter().enumerate() {
            let mut landmark = assigned[i];
            if landmark.is_none()
                && self.mode == Mode::Mapping
                && self.is_new_cone(&pose, d, nearest[i], &taken)
            {
                landmark = Some(self.new_landmark(&pose, &pose_cov, d, &covs[i], scan));
                associated.push(true);
            }
            self.detections.push((scan, i, landmark));
            let Some(l) = landmark else { continue };
            if let Some(id) = d.id {
                self.tracker.insert(id, l);
            }
            associated[l] = true;
            // After the loop closes, later laps' sightings wait for the final optimisation.
            if self.mode == Mode::Mapping || self.loop_closures > 0 {
                self.observations.push(Observation {
                    pose: keyframe,
                    landmark: l,
                    z: d.position,
                    information: nearest_information(&covs[i]),
                });
            }
            if self.mode == Mode::Mapping {
                self.refine(l, &pose, &pose_cov, d, &covs[i]);
            } else {
                // The later laps' colours judge clutter seen too few times
                // to judge while mapping.
                let confirm = self.config.confirm_after;
                self.landmarks[l].sighting.count(d.color, confirm);
            }
            let (distance, heading) = (self.motion.distance(), self.pose.theta);
            if self.landmarks[l].sighting.revisit(scan, distance, heading) {
                returned += 1;
            }
        }
        let first = self.detections.len() - cones.len();
        self.scan_log.push(loop_closure::PendingScan {
            keyframe,
            first,
            cones: cones.to_vec(),
        });
        if self.mode != Mode::Mapping {
            self.count_misses(&pose, &associated, scan);
            return;
        }
        self.smooth_window();
        let pose = self.pose;
        self.count_misses(&pose, &associated, scan);
        // A lap ends near where it began; a parallel stretch of track that
        // passes the start area elsewhere must not count.
        // Once back without a start line mapped, recognition goes on while
        // the start area is in view: a correction beyond half a spacing
        // needs scans to confirm it. (With the start line it anchors them;
        // going on there made a phantom on eufs_rand, `hard` seed 0.)
        let still = !self.near_start_scans.is_empty()
            && !self.start_line_mapped()
            && self.start_area_in_reach();
        if !self.back_at_start(&pose) && !still {
            self.near_start_scans.clear();
            self.place_votes.clear();
            self.returned_at = None;
            return;
        }
        self.returned_at.get_or_insert(self.motion.distance());
        self.near_start_scans.push(loop_closure::PendingScan {
            keyframe,
            first,
            cones: cones.to_vec(),
        });
        // One closure per lap, when mapping goes on after the first.
        let lap_driven = self
            .closed_at
            .is_none_or(|d| self.motion.distance() > d + MIN_LOOP);
        if lap_driven
            && (returned >= self.config.loop_min_returned
                || self.recognise_place(cones, &covs, keyframe))
        {
            self.close_loop();
        }
    }

    fn resolve(&self, mut l: usize) -> usize {
        while self.alias[l] != l {
            l = self.alias[l];
        }
        l
    }

    /// Whether landmark `l` is part of the map: confirmed, not removed and
    /// not merged into another.
    fn in_map(&self, l: usize) -> bool {
        let lm = &self.landmarks[l];
        self.alias[l] == l && !lm.removed && lm.sighting.confirmed
    }

    /// The landmarks of the map, in output order, with their internal indices.
    fn map_rows(&self) -> Vec<usize> {
        (0..self.landmarks.len())
            .filter(|&l| self.in_map(l))
            .collect()
    }

    /// The map: confirmed landmarks, with their covariances: each
    /// landmark's EKF's (relative to the poses that saw it) during the run,
    /// the marginals of the final optimisation (in the world frame, the
    /// start pose given) once [`Self::finish`] has run.
    pub fn map(&self) -> Vec<Cone> {
        self.map_rows()
            .into_iter()
            .map(|l| {
                let lm = &self.landmarks[l];
                Cone {
                    position: lm.mean,
                    color: lm.sighting.color(),
                    covariance: lm.cov,
                }
            })
            .collect()
    }

    /// Every sighting of a landmark of the map, as the graph holds it: the
    /// scan's pose index and the detection in the vehicle frame. A detection
    /// is one sighting, however often re-matching moved it.
    pub fn sightings(&self) -> impl Iterator<Item = (usize, Vector2<f64>)> + '_ {
        self.observations
            .iter()
            .filter(|o| self.in_map(self.resolve(o.landmark)))
            .map(|o| (o.pose, o.z))
    }

    /// The pose of every scan.
    pub fn trajectory(&self) -> &[StampedPose] {
        &self.poses
    }

    /// For every detection, its row in [`GraphSlam::map`] (or none).
    pub fn associations(&self) -> Vec<Association> {
        crate::files::in_map_rows(
            self.detections
                .iter()
                .map(|&(scan, det, l)| (scan, det, l.map(|l| self.resolve(l)))),
            self.landmarks.len(),
            &self.map_rows(),
        )
    }
}

/// Gate of the matching at the end of the run (χ², 2 dof, 99.99%): the
/// poses are optimised by then, and the final optimisation's robust kernel
/// takes the sting out of the few wrong matches a wide gate lets in.
pub const FINAL_GATE: f64 = 18.42;

/// χ² quantile at 99% for `dof` degrees of freedom (Wilson–Hilferty).
pub fn chi2_99(dof: usize) -> f64 {
    if dof == 0 {
        return 0.0;
    }
    let k = dof as f64;
    let z = 2.326_347_874;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}
