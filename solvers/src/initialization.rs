//! Where an optimisation starts, and [`Optimizer::optimize`], which starts
//! there: the graph's values, a spanning tree, a chordal relaxation, or (by
//! default) the graph's values if Gauss-Newton converges from them quickly
//! and otherwise the lowest of them and the two chordal starts.

use crate::chordal::{ChordalWeights, anchors, chordal_initialize_holding};
use crate::config::{
    AUTO_TRUSTED_ITERATIONS, Algorithm, Gauge, Initialization, IterationStats, SolverConfig,
    Summary, Termination,
};
use crate::{Optimizer, SolveError};
use cairn_core::Graph;

/// Sets the free vertices' values by breadth-first spanning tree from the fixed
/// vertices and the automatic gauge.
pub fn spanning_tree_initialize(graph: &mut Graph) -> Result<(), SolveError> {
    let keep = anchors(graph, &Gauge::Auto)?;
    spanning_tree_holding(graph, &keep);
    Ok(())
}

fn spanning_tree_holding(graph: &mut Graph, keep: &[bool]) {
    let unknown: Vec<bool> = keep.iter().map(|k| !k).collect();
    graph.initialize_spanning_tree(&unknown);
}

/// Optimises `graph` with `config`: a one-shot [`Optimizer`]. To ask for
/// marginal covariances after, keep the optimizer instead
/// ([`Optimizer::marginals`]).
pub fn optimize(graph: &mut Graph, config: SolverConfig) -> Result<Summary, SolveError> {
    Optimizer::new(graph, config)?.optimize(graph)
}

impl Optimizer {
    /// Optimises the graph's values in place, from the start
    /// [`SolverConfig::init`] names: by default [`Initialization::Auto`], as
    /// `cairn solve`. The result is never worse than the values the graph
    /// held ([`Summary::kept_start`]).
    pub fn optimize(&mut self, graph: &mut Graph) -> Result<Summary, SolveError> {
        self.optimize_with(graph, &mut |_| {})
    }

    /// [`Optimizer::optimize`], calling `on_iteration` after every iteration
    /// of every run (for progress output in g2o's style).
    pub fn optimize_with(
        &mut self,
        graph: &mut Graph,
        on_iteration: &mut dyn FnMut(&IterationStats),
    ) -> Result<Summary, SolveError> {
        if (graph.num_vertices(), graph.num_edges()) != self.shape() {
            return Err(SolveError::GraphChanged);
        }
        let init = self.config().init;
        let before = graph.values().params().to_vec();
        // χ² at the graph's values: the first run's start for File and Auto.
        let mut entry_chi2 = None;
        if !matches!(init, Initialization::File | Initialization::Auto) {
            entry_chi2 = Some(graph.chi2());
        }
        let mut summary = match init {
            Initialization::File => self.iterate(graph, init, on_iteration)?,
            Initialization::Auto => {
                let (summary, file_start) = self.auto(graph, &before, on_iteration)?;
                entry_chi2 = Some(file_start);
                summary
            }
            Initialization::SpanningTree => {
                let keep = anchors(graph, &self.config().gauge)?;
                spanning_tree_holding(graph, &keep);
                self.iterate(graph, init, on_iteration)?
            }
            Initialization::Chordal | Initialization::ChordalIsotropic => {
                let keep = anchors(graph, &self.config().gauge)?;
                chordal_initialize_holding(graph, weights(init), &keep)?;
                self.iterate(graph, init, on_iteration)?
            }
        };
        let entry_chi2 = entry_chi2.unwrap_or(summary.initial_chi2);
        let end = summary.final_chi2;
        if end.is_nan() || (end > entry_chi2 && graph.chi2_is_objective()) {
            graph.values_mut().params_mut().copy_from_slice(&before);
            summary.final_chi2 = entry_chi2;
            summary.kept_start = true;
        }
        Ok(summary)
    }

    /// [`Initialization::Auto`] from the graph's values, `initial`; also
    /// returns χ² there.
    fn auto(
        &mut self,
        graph: &mut Graph,
        initial: &[f64],
        on_iteration: &mut dyn FnMut(&IterationStats),
    ) -> Result<(Summary, f64), SolveError> {
        let cap = self.config().max_iterations;
        let budget = cap.min(AUTO_TRUSTED_ITERATIONS);
        let file = self.run(graph, Initialization::File, None, budget, on_iteration)?;
        let file_start = file.initial_chi2;
        if file.termination.converged() {
            return Ok((file, file_start));
        }
        let cut = file.termination == Termination::MaxIterations && cap > budget;
        let mut best = Best {
            estimate: graph.values().params().to_vec(),
            summary: file,
        };
        // A failure from a chordal start only rules that start out.
        let keep = anchors(graph, &self.config().gauge)?;
        for start in [Initialization::Chordal, Initialization::ChordalIsotropic] {
            graph.values_mut().params_mut().copy_from_slice(initial);
            // A graph without poses has no chordal start but its own values.
            let moved = chordal_initialize_holding(graph, weights(start), &keep)
                .is_ok_and(|report| report.poses + report.landmarks > 0);
            if moved {
                let _ = self.run_guarded(graph, start, &mut best, on_iteration);
            }
        }
        graph
            .values_mut()
            .params_mut()
            .copy_from_slice(&best.estimate);
        if best.summary.init == Initialization::File && cut {
            let more = self.run(
                graph,
                Initialization::File,
                None,
                cap - budget,
                on_iteration,
            )?;
            best.summary = continued(best.summary, more);
        }
        Ok((best.summary, file_start))
    }

    /// One run from the graph's values (named `start`), with `algorithm` in
    /// place of the configured one if given, and at most `iterations`.
    fn run(
        &mut self,
        graph: &mut Graph,
        start: Initialization,
        algorithm: Option<Algorithm>,
        iterations: usize,
        on_iteration: &mut dyn FnMut(&IterationStats),
    ) -> Result<Summary, SolveError> {
        let (configured, cap) = (self.config().algorithm, self.config().max_iterations);
        let config = self.config_mut();
        config.algorithm = algorithm.unwrap_or(configured);
        config.max_iterations = iterations;
        let summary = self.iterate(graph, start, on_iteration);
        let config = self.config_mut();
        config.algorithm = configured;
        config.max_iterations = cap;
        summary
    }

    /// A run from `start` with the configured algorithm; if that is
    /// Gauss-Newton and it overshot, Levenberg-Marquardt from the same start
    /// as well. Each run's estimate replaces `best` if it ends lower.
    fn run_guarded(
        &mut self,
        graph: &mut Graph,
        start: Initialization,
        best: &mut Best,
        on_iteration: &mut dyn FnMut(&IterationStats),
    ) -> Result<(), SolveError> {
        let values = graph.values().params().to_vec();
        let cap = self.config().max_iterations;
        let summary = self.run(graph, start, None, cap, on_iteration)?;
        let retry = self.config().algorithm == Algorithm::GaussNewton && overshot(&summary);
        best.keep_if_lower(summary, graph);
        if retry {
            graph.values_mut().params_mut().copy_from_slice(&values);
            let lm = Some(Algorithm::LevenbergMarquardt);
            let summary = self.run(graph, start, lm, cap, on_iteration)?;
            best.keep_if_lower(summary, graph);
        }
        Ok(())
    }
}

fn weights(start: Initialization) -> ChordalWeights {
    if start == Initialization::ChordalIsotropic {
        ChordalWeights::Isotropic
    } else {
        ChordalWeights::Information
    }
}

/// Whether χ² rose in some iteration.
fn overshot(summary: &Summary) -> bool {
    let mut previous = summary.initial_chi2;
    summary.trace.iter().any(|it| {
        let rose = it.chi2 > previous;
        previous = it.chi2;
        rose
    })
}

/// `first` carried on by `more`, from where it stopped: one run's summary.
fn continued(mut first: Summary, more: Summary) -> Summary {
    let offset = first.trace.len();
    first.trace.extend(more.trace.into_iter().map(|mut s| {
        s.iteration += offset;
        s
    }));
    first.iterations = first.trace.len();
    first.final_chi2 = more.final_chi2;
    first.termination = more.termination;
    first.returned_lowest = more.returned_lowest;
    first.solve_time += more.solve_time;
    first.phases.add(&more.phases);
    first
}

/// The run of the lowest final χ² so far: its summary and estimate.
struct Best {
    summary: Summary,
    estimate: Vec<f64>,
}

impl Best {
    /// Keeps the graph's values if `summary` ends lower than the best so far.
    fn keep_if_lower(&mut self, summary: Summary, graph: &Graph) {
        if summary.final_chi2 < self.summary.final_chi2 {
            self.estimate.copy_from_slice(graph.values().params());
            self.summary = summary;
        }
    }
}
