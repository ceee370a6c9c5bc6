//! Levenberg-Marquardt over the same linear system as Gauss-Newton.

use super::{max_abs, record, since};
use crate::config::{Damping, IterationStats, PhaseTimes, Summary, Termination};
use crate::optimizer::Optimizer;
use cairn_core::Graph;
use std::time::Instant;

impl Optimizer {
    /// LM's damping D at the current H: 1 (Levenberg), or the diagonal of H
    /// kept within [1e-6, 1e32] (Marquardt, as Ceres).
    fn set_damping(&mut self) {
        match self.config.lm.damping {
            Damping::Levenberg => self.damping.fill(1.0),
            Damping::Marquardt => {
                for (d, &k) in self.damping.iter_mut().zip(&self.structure.diagonal) {
                    *d = self.hessian[k].clamp(1e-6, 1e32);
                }
            }
        }
    }

    /// Damped Gauss-Newton steps (H + λD) s = −g, λ from τ and Nielsen's
    /// update; each trial point is linearised once, into a second H that
    /// becomes the current one if the step lowers χ².
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
            .diagonal
            .iter()
            .fold(0.0f64, |m, &d| m.max(self.hessian[d].abs()));
        let mut lambda = match self.config.lm.damping {
            Damping::Marquardt => self.config.lm.tau,
            Damping::Levenberg => self.config.lm.tau * max_diagonal.max(f64::MIN_POSITIVE),
        };
        let mut ni = 2.0;
        for iteration in 0..self.config.max_iterations {
            let began = Instant::now();
            let mut phases = PhaseTimes::default();
            let gradient_max = max_abs(&self.gradient);
            if gradient_max < self.config.gradient_tolerance || chi2 == 0.0 {
                return Termination::GradientNorm;
            }
            self.set_damping();
            self.save(graph);
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
                }
                // Decrease of χ² the damped linear model predicts, sᵀ(λDs − g),
                // with g2o's 1e-3 guard against a zero prediction.
                let predicted: f64 = (self.step.iter().zip(&self.gradient))
                    .zip(&self.damping)
                    .map(|((s, g), d)| s * (lambda * d * s - g))
                    .sum::<f64>()
                    + 1e-3;
                let rho = (chi2 - trial_chi2) / predicted;
                if solved && rho > 0.0 && trial_chi2.is_finite() {
                    let alpha = (1.0 - (2.0 * rho - 1.0).powi(3)).min(2.0 / 3.0);
                    lambda *= alpha.max(1.0 / 3.0);
                    ni = 2.0;
                    break Some(trial_chi2);
                }
                lambda *= ni;
                ni *= 2.0;
                // A step too small to matter that fails is rounding at the
                // optimum: raising λ would only shrink it further.
                rejected_small_step = solved && self.step_is_small(graph);
                if solved {
                    let t = Instant::now();
                    self.restore(graph);
                    phases.update += since(t);
                }
                if rejected_small_step || trials >= self.config.lm.max_trials || !lambda.is_finite()
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
                return if rejected_small_step {
                    Termination::StepSize
                } else {
                    Termination::NoImprovement
                };
            };
            let clock = (began, start);
            if let Some(end) =
                self.end_iteration(graph, chi2, new_chi2, stats, clock, summary, on_iteration)
            {
                return end;
            }
            chi2 = new_chi2;
        }
        Termination::MaxIterations
    }
}
