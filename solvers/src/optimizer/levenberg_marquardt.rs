//! Levenberg-Marquardt over the same linear system as Gauss-Newton.

use super::{dot, max_abs, record, since};
use crate::config::{Damping, IterationStats, PhaseTimes, Summary, Termination};
use crate::optimizer::Optimizer;
use cairn_core::Graph;
use std::time::Instant;

/// Added to the model's predicted decrease before the ratio of actual to
/// predicted decrease is taken, as a fraction of χ²: a guard against a zero
/// prediction. (g2o adds 1e-3, which makes the ratio depend on the scale of
/// the information.)
const PREDICTION_GUARD: f64 = 1e-12;

/// Which steps LM may accept when non-monotonic steps are allowed (Conn,
/// Gould and Toint's non-monotone trust region, as Ceres's
/// `use_nonmonotonic_steps`): a step may raise χ² if, measured from a
/// reference χ² of a few iterations back, the decrease so far is still a
/// fair share of what the models predicted. Such steps let LM follow a
/// Gauss-Newton path that climbs out of one valley on the way to a lower
/// one, where a monotone LM damps itself into the nearer minimum.
struct NonMonotone {
    /// Non-monotonic steps in a row before the reference moves up to the
    /// highest χ² met since the lowest (0: never, LM is monotone).
    max_steps: usize,
    /// The lowest χ² met so far.
    minimum: f64,
    /// χ² the ratio is measured from, and the predicted decreases since.
    reference: f64,
    predicted_since_reference: f64,
    /// The highest χ² since the lowest one, and the predicted decreases
    /// since it: the next reference.
    candidate: f64,
    predicted_since_candidate: f64,
    /// Accepted steps since the lowest χ².
    steps_above_minimum: usize,
}

impl NonMonotone {
    /// The least ratio of actual to predicted decrease, measured from the
    /// reference, for a step to count (Ceres's `min_relative_decrease`).
    const MIN_RATIO: f64 = 1e-3;

    fn new(chi2: f64, max_steps: usize) -> Self {
        Self {
            max_steps,
            minimum: chi2,
            reference: chi2,
            predicted_since_reference: 0.0,
            candidate: chi2,
            predicted_since_candidate: 0.0,
            steps_above_minimum: 0,
        }
    }

    /// The gain ratio a step gets: the usual one (`chi2` → `trial`), or
    /// the one measured from the reference if that one counts and is larger.
    fn ratio(&self, chi2: f64, trial: f64, predicted: f64) -> f64 {
        let rho = (chi2 - trial) / predicted;
        if self.max_steps == 0 {
            return rho;
        }
        let from_reference =
            (self.reference - trial) / (self.predicted_since_reference + predicted);
        if from_reference > Self::MIN_RATIO {
            rho.max(from_reference)
        } else {
            rho
        }
    }

    /// Records an accepted step to χ² `trial`; true if it is the lowest yet.
    fn accept(&mut self, trial: f64, predicted: f64) -> bool {
        self.predicted_since_reference += predicted;
        self.predicted_since_candidate += predicted;
        let lowest = trial < self.minimum;
        if lowest {
            self.minimum = trial;
            self.steps_above_minimum = 0;
            self.candidate = trial;
            self.predicted_since_candidate = 0.0;
        } else {
            self.steps_above_minimum += 1;
            if trial > self.candidate {
                self.candidate = trial;
                self.predicted_since_candidate = 0.0;
            }
        }
        if self.steps_above_minimum == self.max_steps {
            self.reference = self.candidate;
            self.predicted_since_reference = self.predicted_since_candidate;
        }
        lowest
    }
}

impl Optimizer {
    /// LM's damping D at the current H: 1 (Levenberg), or the diagonal of H
    /// kept above 1e-10 × its largest entry (Marquardt), so that an unknown
    /// without curvature is still damped. (Ceres bounds it by absolute
    /// values, [1e-6, 1e32], which changes the steps when all information
    /// is scaled.)
    fn set_damping(&mut self) {
        match self.config.lm.damping {
            Damping::Levenberg => self.damping.fill(1.0),
            Damping::Marquardt => {
                let diagonal = self.structure.layout.diagonal();
                let largest = diagonal.fold(0.0f64, |m, k| m.max(self.hessian[k]));
                let least = (1e-10 * largest).max(f64::MIN_POSITIVE);
                for (d, k) in self
                    .damping
                    .iter_mut()
                    .zip(self.structure.layout.diagonal())
                {
                    *d = self.hessian[k].max(least);
                }
            }
        }
    }

    /// Damped Gauss-Newton steps (H + λD) s = −g, λ from τ and Nielsen's
    /// update; each trial point is linearised once, into a second H that
    /// becomes the current one if the step is accepted. Steps that raise χ²
    /// may be accepted (see [`NonMonotone`]), and a first step that does
    /// may lead a Gauss-Newton path, kept if it settles below the start
    /// (see [`Self::follow_gauss_newton`]; its steps are reported with
    /// λ = 0); the estimate returned is the one with the lowest χ².
    pub(super) fn levenberg_marquardt(
        &mut self,
        graph: &mut Graph,
        summary: &mut Summary,
        start: Instant,
        on_iteration: &mut dyn FnMut(&IterationStats),
    ) -> Termination {
        let mut chi2 = summary.initial_chi2;
        let max_diagonal = self
            .structure
            .layout
            .diagonal()
            .fold(0.0f64, |m, d| m.max(self.hessian[d].abs()));
        let mut lambda = match self.config.lm.damping {
            Damping::Marquardt => self.config.lm.tau,
            Damping::Levenberg => self.config.lm.tau * max_diagonal.max(f64::MIN_POSITIVE),
        };
        let mut ni = 2.0;
        let mut steps = NonMonotone::new(chi2, self.config.lm.nonmonotonic_steps);
        // The lowest-χ² estimate, saved when a step first leaves it.
        let mut lowest = Vec::new();
        let mut iteration = 0;
        let termination = 'run: {
            'iterations: while iteration < self.config.max_iterations {
                let began = Instant::now();
                let mut phases = PhaseTimes::default();
                let gradient_max = max_abs(&self.gradient);
                if self.gradient_is_small(chi2) {
                    break 'run Termination::GradientNorm;
                }
                self.set_damping();
                self.save(graph);
                let minimum_before = steps.minimum;
                let mut trials = 0;
                let mut rejected_small_step = false;
                let new_chi2 = loop {
                    trials += 1;
                    let solved = self.compute_step(lambda, &mut phases);
                    let mut trial_chi2 = f64::INFINITY;
                    if solved {
                        let t = Instant::now();
                        self.apply_step(graph);
                        phases.update += since(t);
                        // Linearised at once: if the step is accepted, this
                        // becomes H and the gradient; if not, they still hold
                        // the last accepted point's.
                        trial_chi2 = self.linearize_trial(graph, &mut phases, true);
                        if self.config.lm.line_search {
                            trial_chi2 = self.shorten_poor_step(
                                graph,
                                chi2,
                                trial_chi2,
                                lambda,
                                &mut phases,
                            );
                        }
                    }
                    // The model's decrease, guarded against zero.
                    let predicted = self.model_decrease(lambda) + PREDICTION_GUARD * chi2;
                    let rho = steps.ratio(chi2, trial_chi2, predicted);
                    if solved && rho > 0.0 && trial_chi2.is_finite() {
                        let leaving_lowest = chi2 == steps.minimum;
                        if !steps.accept(trial_chi2, predicted) && leaving_lowest {
                            // `backup` holds the point the step left.
                            lowest.clone_from(&self.backup);
                        }
                        let alpha = (1.0 - (2.0 * rho - 1.0).powi(3)).min(2.0 / 3.0);
                        lambda *= alpha.max(1.0 / 3.0);
                        ni = 2.0;
                        break Some(trial_chi2);
                    }
                    // A step too small to matter that fails is rounding at the
                    // optimum: raising λ would only shrink it further.
                    rejected_small_step = solved && self.step_is_small(graph);
                    if iteration == 0
                        && trials == 1
                        && solved
                        && trial_chi2.is_finite()
                        && !rejected_small_step
                        && self.config.lm.lookahead_steps > 0
                        && self.config.lm.nonmonotonic_steps > 0
                    {
                        let first = (trial_chi2, predicted, gradient_max, phases);
                        match self.follow_gauss_newton(graph, chi2, first, began, start) {
                            Ok(path) => {
                                for (stats, predicted) in path {
                                    steps.accept(stats.chi2, predicted);
                                    chi2 = stats.chi2;
                                    iteration += 1;
                                    summary.final_chi2 = chi2;
                                    on_iteration(&stats);
                                    summary.trace.push(stats);
                                }
                                continue 'iterations;
                            }
                            Err(spent) => phases = spent,
                        }
                    }
                    lambda *= ni;
                    ni *= 2.0;
                    if solved {
                        let t = Instant::now();
                        self.restore(graph);
                        phases.update += since(t);
                    }
                    if rejected_small_step
                        || trials >= self.config.lm.max_trials
                        || !lambda.is_finite()
                    {
                        break None;
                    }
                };
                let stats = IterationStats {
                    iteration,
                    chi2,
                    lambda: Some(lambda),
                    trials,
                    gradient_max,
                    phases,
                    ..Default::default()
                };
                let Some(new_chi2) = new_chi2 else {
                    record(stats, began, start, summary, on_iteration);
                    break 'run if rejected_small_step {
                        Termination::StepSize
                    } else {
                        Termination::NoImprovement
                    };
                };
                let clock = (began, start);
                // Converged when the lowest χ² improves by less than the
                // tolerance; a step that stays above it (a non-monotonic
                // one) shows no decrease and never ends the run.
                if let Some(end) = self.end_iteration(
                    graph,
                    minimum_before,
                    new_chi2,
                    stats,
                    clock,
                    summary,
                    on_iteration,
                ) {
                    break 'run end;
                }
                chi2 = new_chi2;
                iteration += 1;
            }
            Termination::MaxIterations
        };
        debug_assert!(summary.final_chi2 <= steps.minimum || !lowest.is_empty());
        self.return_lowest(graph, summary, &lowest, steps.minimum);
        termination
    }
}

impl Optimizer {
    /// Decrease of χ² the damped linear model predicts for the step s,
    /// sᵀ(λDs − g).
    fn model_decrease(&self, lambda: f64) -> f64 {
        (self.step.iter().zip(&self.gradient))
            .zip(&self.damping)
            .map(|((s, g), d)| s * (lambda * d * s - g))
            .sum()
    }

    /// The line search of [`LevenbergMarquardtConfig::line_search`]: the
    /// graph is at the trial point x + s, linearised, with χ² `trial`
    /// (`chi2` at x). If the step lowered χ² by less than a quarter of what
    /// its model predicted, moves to x + αs at the minimum of the parabola
    /// through χ²(x), its slope along s and χ²(x + s), when that lowers χ²
    /// further; the step is then αs. Returns the χ² of the point the graph
    /// is left at (linearised there).
    ///
    /// [`LevenbergMarquardtConfig::line_search`]: crate::LevenbergMarquardtConfig::line_search
    fn shorten_poor_step(
        &mut self,
        graph: &mut Graph,
        chi2: f64,
        trial: f64,
        lambda: f64,
        phases: &mut PhaseTimes,
    ) -> f64 {
        /// Gain ratio below which a step's model is poor (the trust-region
        /// methods' usual 1/4).
        const POOR: f64 = 0.25;
        let slope = 2.0 * dot(&self.step, &self.gradient);
        let gain = (chi2 - trial) / self.model_decrease(lambda);
        // χ²(x + αs) ≈ χ² + slope·α + curvature·α².
        let curvature = trial - chi2 - slope;
        if !(gain > 0.0 && gain < POOR && curvature > 0.0) {
            return trial;
        }
        let alpha = -slope / (2.0 * curvature);
        if !(0.1..=0.9).contains(&alpha) {
            return trial;
        }
        self.rescale_step(graph, alpha, phases);
        let shorter = self.linearize_trial(graph, phases, true);
        if shorter < trial {
            return shorter;
        }
        self.rescale_step(graph, 1.0 / alpha, phases);
        self.linearize_trial(graph, phases, true)
    }

    /// Scales the step by `factor` and moves the graph from the saved
    /// point by the scaled step.
    fn rescale_step(&mut self, graph: &mut Graph, factor: f64, phases: &mut PhaseTimes) {
        let t = Instant::now();
        self.restore(graph);
        self.step.iter_mut().for_each(|s| *s *= factor);
        self.apply_step(graph);
        phases.update += since(t);
    }
}

/// A step of the Gauss-Newton path LM followed: its statistics (as an
/// iteration) and the decrease its model predicted.
type PathStep = (IterationStats, f64);

impl Optimizer {
    /// Follows the Gauss-Newton path from LM's rejected first step (the
    /// graph is at its trial point, `first` = its χ², predicted decrease,
    /// the start's largest gradient and the trial's phase times), as
    /// [`LevenbergMarquardtConfig::lookahead_steps`] describes. Returns the
    /// path's steps if it settled below `start_chi2`, H and the gradient
    /// being its end's; otherwise puts the graph, H and the gradient back
    /// at the start and returns the phase times spent.
    ///
    /// [`LevenbergMarquardtConfig::lookahead_steps`]: crate::LevenbergMarquardtConfig::lookahead_steps
    fn follow_gauss_newton(
        &mut self,
        graph: &mut Graph,
        start_chi2: f64,
        (trial_chi2, predicted, gradient_max, mut phases): (f64, f64, f64, PhaseTimes),
        mut began: Instant,
        start: Instant,
    ) -> Result<Vec<PathStep>, PhaseTimes> {
        /// A step that lowers χ² by less than this fraction ends the path.
        const SETTLED: f64 = 1e-3;
        let max_steps = self
            .config
            .lm
            .lookahead_steps
            .min(self.config.max_iterations);
        let mut path: Vec<PathStep> = Vec::new();
        let mut spent = PhaseTimes::default();
        let mut step = (trial_chi2, predicted, gradient_max);
        let mut previous = start_chi2;
        loop {
            let (chi2, predicted, gradient_max) = step;
            self.accept(&mut phases);
            let stats = IterationStats {
                iteration: path.len(),
                chi2,
                lambda: Some(0.0),
                trials: 1,
                gradient_max,
                step_max: max_abs(&self.step),
                time: since(began),
                cumulative_time: since(start),
                phases,
                ..Default::default()
            };
            spent.add(&phases);
            path.push((stats, predicted));
            if chi2 < start_chi2 && (previous - chi2) / previous < SETTLED {
                return Ok(path);
            }
            previous = chi2;
            if path.len() == max_steps {
                break;
            }
            began = Instant::now();
            phases = PhaseTimes::default();
            let gradient_max = max_abs(&self.gradient);
            if !self.compute_step(0.0, &mut phases) {
                spent.add(&phases);
                break;
            }
            let predicted = -dot(&self.step, &self.gradient) + PREDICTION_GUARD * chi2;
            let t = Instant::now();
            self.apply_step(graph);
            phases.update += since(t);
            let chi2 = self.linearize_trial(graph, &mut phases, true);
            // NaN ends the path too.
            if chi2.is_nan() || chi2 >= previous {
                spent.add(&phases);
                break;
            }
            step = (chi2, predicted, gradient_max);
        }
        self.restore(graph);
        self.linearize(graph, &mut spent);
        Err(spent)
    }
}

#[cfg(test)]
mod tests {
    use super::NonMonotone;

    #[test]
    fn monotone_ratio_is_the_usual_gain_ratio() {
        let steps = NonMonotone::new(100.0, 0);
        assert_eq!(steps.ratio(100.0, 90.0, 20.0), 0.5);
        assert_eq!(steps.ratio(100.0, 110.0, 20.0), -0.5);
    }

    #[test]
    fn a_step_up_counts_against_the_reference_until_it_moves() {
        let mut steps = NonMonotone::new(100.0, 2);
        // 100 → 50, predicted 60: the lowest yet.
        assert!(steps.accept(50.0, 60.0));
        // 50 → 70 raises χ², but from the reference (100) it is 30 of the
        // 60 + 20 predicted.
        assert_eq!(steps.ratio(50.0, 70.0, 20.0), 30.0 / 80.0);
        assert!(!steps.accept(70.0, 20.0));
        assert_eq!(steps.reference, 100.0);
        // A second step above the minimum (to 60) moves the reference to the
        // highest χ² since the minimum, with what was predicted since it.
        assert!(!steps.accept(60.0, 15.0));
        assert_eq!(
            (steps.reference, steps.predicted_since_reference),
            (70.0, 15.0)
        );
        // A step up from the reference no longer counts; the usual ratio stays.
        assert_eq!(steps.ratio(60.0, 75.0, 10.0), -1.5);
        // A new lowest χ² restarts the count.
        assert!(steps.accept(40.0, 25.0));
        assert_eq!((steps.minimum, steps.steps_above_minimum), (40.0, 0));
    }
}
