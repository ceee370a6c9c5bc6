//! A log or a simulated run end to end, as the command line, the report,
//! the study and the tests use it.

use crate::eval::{Report, evaluate, latency_ms, one_to_one_accuracy};
use crate::sim::Simulation;
use cairn_slam::estimator::{Estimator, EstimatorBuilder};
use cairn_slam::files::Association;
use cairn_slam::frontend::{FrontEndConfig, GraphSlam, OptimiseError};
use cairn_slam::log::{Log, Record};
use cairn_slam::points::PointCloudConfig;

/// A log run end to end ([`run_log`]).
pub struct LogRun {
    /// The estimator, finished.
    pub slam: Box<dyn Estimator>,
    /// The final optimisation's outcome: when it failed, the estimate is the
    /// one before it.
    pub finished: Result<(), OptimiseError>,
    /// The associations as they stood before the end-of-run pass: what the
    /// car knew while driving (landmark ids of the map as it stood then).
    pub real_time: Vec<Association>,
}

/// Runs the estimator `builder` describes over a whole log and finishes it.
/// A log of point clouds goes through the clustering front end first (with
/// default settings unless the builder has its own).
pub fn run_log(builder: &EstimatorBuilder, log: &Log) -> LogRun {
    let mut builder = builder.clone();
    let points = log
        .records
        .iter()
        .any(|r| matches!(r, Record::Points { .. }));
    if points && builder.points.is_none() {
        builder.points = Some(PointCloudConfig::default());
    }
    let mut slam = builder.build();
    for record in &log.records {
        slam.process(record);
    }
    let real_time = slam.associations();
    let finished = slam.finish();
    LogRun {
        slam,
        finished,
        real_time,
    }
}

/// Feeds a simulated log to a new graph front end and scores the result.
pub fn run_and_score(sim: &Simulation, config: FrontEndConfig) -> (GraphSlam, Report) {
    let mut slam = GraphSlam::new(config);
    let report = feed_and_score(sim, &mut slam);
    (slam, report)
}

/// Feeds a simulated log to the estimator `builder` describes and scores it.
pub fn run_estimator(sim: &Simulation, builder: &EstimatorBuilder) -> (Box<dyn Estimator>, Report) {
    let mut slam = builder.build();
    let report = feed_and_score(sim, slam.as_mut());
    (slam, report)
}

/// Feeds the log, scores the associations as they stand (real time),
/// finishes, and scores the result.
fn feed_and_score(sim: &Simulation, slam: &mut dyn Estimator) -> Report {
    for record in &sim.log {
        slam.process(record);
    }
    let real_time = one_to_one_accuracy(&sim.truth_associations, &slam.associations()).0;
    let finished = slam.finish();
    with_warnings(scored(sim, slam, Some(real_time)), slam, finished)
}

/// The report with the run's failed optimisations, the final one's included.
fn with_warnings(
    mut report: Report,
    slam: &dyn Estimator,
    finished: Result<(), OptimiseError>,
) -> Report {
    report.warnings = slam.warnings().to_vec();
    if let Err(e) = finished {
        report.warnings.push(format!(
            "the final optimisation failed ({e}); kept the estimate"
        ));
    }
    report
}

/// Scores an estimator's current output against the simulation's truth
/// (lost sightings counted as wrong associations).
pub fn score(sim: &Simulation, slam: &dyn Estimator) -> Report {
    scored(sim, slam, None)
}

/// [`score`], with the accuracy of the associations made in real time.
fn scored(sim: &Simulation, slam: &dyn Estimator, real_time: Option<f64>) -> Report {
    let mut report = evaluate(
        &sim.truth_map,
        &slam.map(),
        &sim.truth,
        &slam.trajectory(),
        &sim.truth_associations,
        &slam.associations(),
    );
    report.association_accuracy_real_time = real_time;
    report.count_lost_sightings(sim.lost_sightings);
    report.latency_ms = latency_ms(&slam.timing().updates);
    report.detector_sigma = slam.detector_noise().map(|n| [n.assumed, n.estimated]);
    report.loop_closure_ms = slam
        .timing()
        .loop_closures
        .iter()
        .copied()
        .reduce(f64::max)
        .map(|s| s * 1e3);
    report.final_optimisation_ms = slam.timing().final_optimisation.map(|s| s * 1e3);
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use cairn_slam::frontend::FrontEndConfig;

    /// A failed final optimisation reaches the report instead of stderr.
    #[test]
    fn a_failed_final_optimisation_is_reported() {
        let slam = GraphSlam::new(FrontEndConfig::default());
        let failed = Err(OptimiseError::Solve(
            cairn_solvers::SolveError::GraphChanged,
        ));
        let report = with_warnings(Report::default(), &slam, failed);
        assert_eq!(report.warnings.len(), 1);
        assert!(report.warnings[0].contains("final optimisation failed"));
        let report = with_warnings(Report::default(), &slam, Ok(()));
        assert!(report.warnings.is_empty());
    }
}
