//! One simulated run end to end, as the report, the study and the tests use it.

use crate::estimator::{Estimator, EstimatorBuilder};
use crate::eval::{Report, evaluate, latency_ms};
use crate::frontend::{FrontEndConfig, GraphSlam};
use crate::sim::Simulation;

/// Feeds a simulated log to a new graph front end and scores the result.
pub fn run_and_score(sim: &Simulation, config: FrontEndConfig) -> (GraphSlam, Report) {
    let mut slam = GraphSlam::new(config);
    for record in &sim.log {
        slam.process(record);
    }
    if let Err(e) = slam.finish() {
        eprintln!("final optimisation failed: {e}");
    }
    let report = score(sim, &slam);
    (slam, report)
}

/// Feeds a simulated log to the estimator `builder` describes and scores it.
pub fn run_estimator(sim: &Simulation, builder: &EstimatorBuilder) -> (Box<dyn Estimator>, Report) {
    let mut slam = builder.build();
    for record in &sim.log {
        slam.process(record);
    }
    if let Err(e) = slam.finish() {
        eprintln!("final optimisation failed: {e}");
    }
    let report = score(sim, slam.as_ref());
    (slam, report)
}

/// Scores an estimator's current output against the simulation's truth.
pub fn score(sim: &Simulation, slam: &dyn Estimator) -> Report {
    let mut report = evaluate(
        &sim.truth_map,
        &slam.map(),
        &sim.truth,
        &slam.trajectory(),
        &sim.truth_associations,
        &slam.associations(),
    );
    report.latency_ms = latency_ms(&slam.timing().updates);
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
