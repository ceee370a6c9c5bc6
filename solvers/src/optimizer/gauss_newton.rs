//! Gauss-Newton: the full step from the same linear system as the others,
//! returning the lowest-χ² iterate.

use super::{Pending, dot, max_abs, record, since};
use crate::config::{IterationStats, PhaseTimes, Summary, Termination};
use crate::optimizer::Optimizer;
use cairn_core::Graph;
use std::time::Instant;

impl Optimizer {
    /// Full Gauss-Newton steps H δ = −g, carrying on through a step that
    /// raises χ² (as g2o) unless `stop_on_increase`; where χ² is the
    /// objective, the lowest-χ² estimate met is the one returned.
    pub(super) fn gauss_newton(
        &mut self,
        graph: &mut Graph,
        summary: &mut Summary,
        start: Instant,
        on_iteration: &mut dyn FnMut(&IterationStats),
    ) -> Termination {
        let mut chi2 = summary.initial_chi2;
        // The lowest-χ² estimate, saved when a step first leaves it (where
        // χ² is the objective).
        let keep_lowest = graph.chi2_is_objective();
        let (mut lowest, mut lowest_chi2) = (Vec::new(), chi2);
        let termination = 'run: {
            for iteration in 0..self.config.max_iterations {
                let began = Instant::now();
                let mut phases = PhaseTimes::default();
                let gradient_max = max_abs(&self.gradient);
                if self.gradient_is_small(chi2) {
                    break 'run Termination::GradientNorm;
                }
                if !self.compute_step(0.0, &mut phases) {
                    break 'run Termination::NotPositiveDefinite;
                }
                let t = Instant::now();
                self.save(graph);
                self.apply_step(graph);
                phases.update += since(t);
                // H is not needed again unless the step may be taken back: the
                // new point's replaces it (on more than one thread it is
                // assembled below unless this was the last iteration).
                let keep_current = self.config.stop_on_increase;
                let new_chi2 = self.linearize_trial(graph, &mut phases, keep_current);
                if !new_chi2.is_finite() {
                    self.restore(graph);
                    self.linearize(graph, &mut phases);
                    break 'run Termination::NonFinite;
                }
                if keep_lowest && new_chi2 > chi2 && chi2 <= lowest_chi2 {
                    // `backup` holds the point the step left.
                    lowest.clone_from(&self.backup);
                    lowest_chi2 = chi2;
                }
                let mut stats = IterationStats {
                    iteration,
                    trials: 1,
                    gradient_max,
                    phases,
                    ..Default::default()
                };
                let clock = (began, start);
                // (A step too small to count is no rise: χ² ≈ 0 goes up and down
                // in its last bits.)
                if self.config.stop_on_increase && new_chi2 > chi2 && !self.step_is_small(graph) {
                    // Back to the estimate before the step; H is still its own.
                    self.restore(graph);
                    self.pending = Pending::Nothing;
                    stats.chi2 = new_chi2;
                    stats.step_max = max_abs(&self.step);
                    record(stats, began, start, summary, on_iteration);
                    break 'run Termination::ErrorIncreased;
                }
                if let Some(end) =
                    self.end_iteration(graph, chi2, new_chi2, stats, clock, summary, on_iteration)
                {
                    break 'run end;
                }
                let more = iteration + 1 < self.config.max_iterations;
                if more && self.next_step_is_negligible(chi2, new_chi2) {
                    break 'run Termination::RelativeDecrease;
                }
                chi2 = new_chi2;
            }
            Termination::MaxIterations
        };
        self.return_lowest(graph, summary, &lowest, lowest_chi2);
        termination
    }

    /// Whether the next Gauss-Newton step can be skipped (H and the
    /// gradient hold the new point's): once χ² fell from
    /// `old_chi2` to `new_chi2` by less than √`relative_decrease` (the
    /// iterates converge quadratically there), the step the last
    /// factorisation gives from the new gradient, δ = −H⁻¹g, is predicted
    /// to lower χ² by gᵀH⁻¹g; below a hundredth of `relative_decrease` that
    /// step would change χ² by less than the rounding of its reports, and a
    /// factorisation is saved.
    fn next_step_is_negligible(&mut self, old_chi2: f64, new_chi2: f64) -> bool {
        let decrease = (old_chi2 - new_chi2) / old_chi2;
        let tolerance = self.config.relative_decrease;
        if !(0.0..tolerance.sqrt()).contains(&decrease) {
            return false;
        }
        let Some(cholesky) = self.cholesky.as_mut() else {
            return false;
        };
        self.predicted.copy_from_slice(&self.gradient);
        if !cholesky.solve_in_place(&mut self.predicted) {
            return false;
        }
        let predicted = dot(&self.gradient, &self.predicted);
        (0.0..tolerance / 100.0 * new_chi2).contains(&predicted)
    }

    /// Puts the graph back at the `lowest`-χ² estimate met if the solve
    /// ended above it, and says so in the summary.
    pub(super) fn return_lowest(
        &self,
        graph: &mut Graph,
        summary: &mut Summary,
        lowest: &[f64],
        lowest_chi2: f64,
    ) {
        if summary.final_chi2 > lowest_chi2 && !lowest.is_empty() {
            graph.values_mut().params_mut().copy_from_slice(lowest);
            summary.final_chi2 = lowest_chi2;
            summary.returned_lowest = true;
        }
    }
}
