//! One interface over the estimators: the graph front end
//! ([`GraphSlam`]), EKF-SLAM ([`EkfSlam`]) and FastSLAM 1.0/2.0
//! ([`FastSlam`]). They read the same log records and give the same outputs,
//! so the command line, the evaluation and the study treat them alike.

use crate::files::{Association, StampedPose};
use crate::filter::ekf::EkfSlam;
use crate::filter::fastslam::{FastSlam, ParticleConfig, Version};
use crate::frontend::{
    Calibration, DetectorNoise, FrontEndConfig, GraphSlam, Mode, OptimiseError, Timing,
};
use crate::log::Record;
use crate::map::Cone;
use crate::points::{Clustered, PointCloudConfig};

/// A SLAM estimator fed one log record at a time.
pub trait Estimator {
    /// Processes one log record.
    fn process(&mut self, record: &Record);
    /// The map: confirmed landmarks with their covariances.
    fn map(&self) -> Vec<Cone>;
    /// One pose per scan.
    fn trajectory(&self) -> Vec<StampedPose>;
    /// For every detection, its row in [`Estimator::map`] (or none).
    fn associations(&self) -> Vec<Association>;
    /// Update and loop-closure times.
    fn timing(&self) -> &Timing;
    /// Loop closures detected so far.
    fn loop_closures(&self) -> usize;
    /// Times the pose, too uncertain to match detections one by one, was
    /// found on the map again (the graph front end's relocalisation).
    fn relocalisations(&self) -> usize {
        0
    }
    /// The detector's noise as assumed and as learned from the matches
    /// (the graph front end with `learn_detector_noise`); `None` where the
    /// estimator does not learn it.
    fn detector_noise(&self) -> Option<DetectorNoise> {
        None
    }
    /// The odometry's speed scale, yaw-rate bias and the car's sideslip
    /// as learnt while driving (the graph front end); `None` where the
    /// estimator does not learn them.
    fn calibration(&self) -> Option<Calibration> {
        None
    }
    /// Mapping or localising.
    fn mode(&self) -> Mode;
    /// Ends the run after the last record (the graph front end's final
    /// optimisation, [`GraphSlam::finish`]; EKF-SLAM's matching again,
    /// [`EkfSlam::finish`]).
    fn finish(&mut self) -> Result<(), OptimiseError> {
        Ok(())
    }
    /// Optimisations that failed during the run, the estimate kept (the
    /// graph front end's loop closures, FastSLAM's smoothings).
    fn warnings(&self) -> &[String] {
        &[]
    }
}

/// The estimators, by command-line name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EstimatorKind {
    /// Pose/landmark graph with per-landmark EKFs and full optimisation at
    /// loop closure.
    Graph,
    /// Joint EKF over pose and landmarks.
    Ekf,
    /// FastSLAM 1.0.
    FastSlam1,
    /// FastSLAM 2.0.
    FastSlam2,
}

impl EstimatorKind {
    /// Every estimator.
    pub const ALL: [EstimatorKind; 4] = [
        EstimatorKind::Graph,
        EstimatorKind::Ekf,
        EstimatorKind::FastSlam1,
        EstimatorKind::FastSlam2,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            EstimatorKind::Graph => "graph",
            EstimatorKind::Ekf => "ekf",
            EstimatorKind::FastSlam1 => "fastslam1",
            EstimatorKind::FastSlam2 => "fastslam2",
        }
    }

    /// The estimator with this command-line name.
    pub fn by_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// How to build an estimator: which one, its settings, and optionally a
/// map to localise on and known correspondences.
#[derive(Clone, Debug)]
pub struct EstimatorBuilder<'a> {
    /// Which estimator.
    pub kind: EstimatorKind,
    /// Shared front-end settings.
    pub config: FrontEndConfig,
    /// FastSLAM particles.
    pub particles: usize,
    /// FastSLAM sampler seed.
    pub seed: u64,
    /// Localise on this map from the first scan.
    pub map: Option<&'a [Cone]>,
    /// Known correspondences (filters only; the graph ignores them).
    pub known: Option<&'a [Association]>,
    /// Extract detections from `points` records with these settings.
    pub points: Option<PointCloudConfig>,
}

impl<'a> EstimatorBuilder<'a> {
    /// Defaults: 100 particles, seed 0, mapping, unknown correspondences.
    pub fn new(kind: EstimatorKind, config: FrontEndConfig) -> Self {
        Self {
            kind,
            config,
            particles: 100,
            seed: 0,
            map: None,
            known: None,
            points: None,
        }
    }

    /// The estimator.
    pub fn build(&self) -> Box<dyn Estimator> {
        match &self.points {
            Some(points) => {
                // Clusters carry no colour, so an unknown reading says
                // nothing about clutter.
                let config = FrontEndConfig {
                    color_unknown: 1.0,
                    ..self.config.clone()
                };
                Box::new(Clustered::new(self.build_inner(config), points.clone()))
            }
            None => self.build_inner(self.config.clone()),
        }
    }

    fn build_inner(&self, config: FrontEndConfig) -> Box<dyn Estimator> {
        match self.kind {
            EstimatorKind::Graph => Box::new(match self.map {
                Some(map) => GraphSlam::with_map(config, map),
                None => GraphSlam::new(config),
            }),
            EstimatorKind::Ekf => {
                let ekf = match self.map {
                    Some(map) => EkfSlam::with_map(config, map),
                    None => EkfSlam::new(config),
                };
                Box::new(match self.known {
                    Some(truth) => ekf.with_known(truth),
                    None => ekf,
                })
            }
            EstimatorKind::FastSlam1 | EstimatorKind::FastSlam2 => {
                let version = if self.kind == EstimatorKind::FastSlam1 {
                    Version::One
                } else {
                    Version::Two
                };
                let mut settings = ParticleConfig::new(version);
                settings.particles = self.particles;
                settings.seed = self.seed;
                let slam = match self.map {
                    Some(map) => FastSlam::with_map(config, settings, map),
                    None => FastSlam::new(config, settings),
                };
                Box::new(match self.known {
                    Some(truth) => slam.with_known(truth),
                    None => slam,
                })
            }
        }
    }
}

impl Estimator for GraphSlam {
    fn process(&mut self, record: &Record) {
        GraphSlam::process(self, record)
    }
    fn finish(&mut self) -> Result<(), OptimiseError> {
        GraphSlam::finish(self)
    }
    fn warnings(&self) -> &[String] {
        GraphSlam::warnings(self)
    }
    fn map(&self) -> Vec<Cone> {
        GraphSlam::map(self)
    }
    fn trajectory(&self) -> Vec<StampedPose> {
        GraphSlam::trajectory(self).to_vec()
    }
    fn associations(&self) -> Vec<Association> {
        GraphSlam::associations(self)
    }
    fn timing(&self) -> &Timing {
        GraphSlam::timing(self)
    }
    fn loop_closures(&self) -> usize {
        GraphSlam::loop_closures(self)
    }
    fn relocalisations(&self) -> usize {
        GraphSlam::relocalisations(self)
    }
    fn detector_noise(&self) -> Option<DetectorNoise> {
        GraphSlam::detector_noise(self)
    }
    fn calibration(&self) -> Option<Calibration> {
        Some(GraphSlam::calibration(self))
    }
    fn mode(&self) -> Mode {
        GraphSlam::mode(self)
    }
}

impl Estimator for EkfSlam {
    fn process(&mut self, record: &Record) {
        EkfSlam::process(self, record)
    }
    fn map(&self) -> Vec<Cone> {
        EkfSlam::map(self)
    }
    fn trajectory(&self) -> Vec<StampedPose> {
        EkfSlam::trajectory(self).to_vec()
    }
    fn associations(&self) -> Vec<Association> {
        EkfSlam::associations(self)
    }
    fn finish(&mut self) -> Result<(), OptimiseError> {
        EkfSlam::finish(self);
        Ok(())
    }
    fn timing(&self) -> &Timing {
        EkfSlam::timing(self)
    }
    fn loop_closures(&self) -> usize {
        EkfSlam::loop_closures(self)
    }
    fn mode(&self) -> Mode {
        EkfSlam::mode(self)
    }
}

impl Estimator for FastSlam {
    fn process(&mut self, record: &Record) {
        FastSlam::process(self, record)
    }
    fn map(&self) -> Vec<Cone> {
        FastSlam::map(self)
    }
    fn trajectory(&self) -> Vec<StampedPose> {
        FastSlam::trajectory(self)
    }
    fn associations(&self) -> Vec<Association> {
        FastSlam::associations(self)
    }
    fn finish(&mut self) -> Result<(), OptimiseError> {
        FastSlam::finish(self);
        Ok(())
    }
    fn warnings(&self) -> &[String] {
        FastSlam::warnings(self)
    }
    fn timing(&self) -> &Timing {
        FastSlam::timing(self)
    }
    fn loop_closures(&self) -> usize {
        FastSlam::loop_closures(self)
    }
    fn mode(&self) -> Mode {
        FastSlam::mode(self)
    }
}
