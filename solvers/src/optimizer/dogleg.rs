//! Powell's dogleg over the same linear system as Gauss-Newton.

use super::{dot, max_abs, record, since};
use crate::config::{IterationStats, PhaseTimes, Summary, Termination};
use crate::optimizer::Optimizer;
use cairn_core::Graph;
use std::time::Instant;

impl Optimizer {
    /// One trust-region iteration per linearisation: the Gauss-Newton step if it
    /// fits in the radius, else the steepest-descent (Cauchy) step scaled to the
    /// radius, else the point on the segment between them at the radius. The
    /// model of χ² = Σ eᵀΩe is χ² + 2gᵀh + hᵀHh; the radius grows after good
    /// agreement (ρ > 0.75) and halves after poor agreement or a rejected step.
    /// If H is not positive definite, the Gauss-Newton step is damped (H + μI).
    pub(super) fn dogleg(
        &mut self,
        graph: &mut Graph,
        summary: &mut Summary,
        start: Instant,
        on_iteration: &mut dyn FnMut(&IterationStats),
    ) -> Termination {
        let n = self.structure.dim;
        let (mut gauss_newton, mut product) = (vec![0.0; n], vec![0.0; n]);
        let mut chi2 = summary.initial_chi2;
        let mut radius = self.config.dogleg.initial_radius;
        for iteration in 0..self.config.max_iterations {
            let began = Instant::now();
            let mut phases = PhaseTimes::default();
            let gradient_max = max_abs(&self.gradient);
            if self.gradient_is_small(chi2) {
                return Termination::GradientNorm;
            }
            if !self.damped_gauss_newton_step(&mut phases) {
                return Termination::NotPositiveDefinite;
            }
            gauss_newton.copy_from_slice(&self.step);
            let gn_norm = dot(&gauss_newton, &gauss_newton).sqrt();
            // Cauchy point: minimiser of the model along −g.
            self.structure
                .layout
                .times(&self.hessian, &self.gradient, &mut product);
            let g2 = dot(&self.gradient, &self.gradient);
            let curvature = dot(&self.gradient, &product);
            let t = if curvature > 0.0 {
                g2 / curvature
            } else {
                f64::INFINITY
            };
            let g_norm = g2.sqrt();

            self.save(graph);
            let mut trials = 0;
            let mut rejected_small_step = false;
            let accepted = loop {
                trials += 1;
                if gn_norm <= radius {
                    self.step.copy_from_slice(&gauss_newton);
                } else if t * g_norm >= radius {
                    let scale = radius / g_norm;
                    self.step
                        .iter_mut()
                        .zip(&self.gradient)
                        .for_each(|(s, g)| *s = -scale * g);
                } else {
                    // a = −t·g (inside), b = GN step (outside): |a + β(b − a)| = radius.
                    let (mut aa, mut ad, mut dd) = (0.0, 0.0, 0.0);
                    for (g, b) in self.gradient.iter().zip(&gauss_newton) {
                        let (a, d) = (-t * g, b + t * g);
                        aa += a * a;
                        ad += a * d;
                        dd += d * d;
                    }
                    let beta = (-ad + (ad * ad - dd * (aa - radius * radius)).max(0.0).sqrt()) / dd;
                    for ((s, g), b) in self.step.iter_mut().zip(&self.gradient).zip(&gauss_newton) {
                        *s = -t * g + beta * (b + t * g);
                    }
                }
                self.structure
                    .layout
                    .times(&self.hessian, &self.step, &mut product);
                let predicted =
                    -(2.0 * dot(&self.gradient, &self.step) + dot(&self.step, &product));
                let step_norm = dot(&self.step, &self.step).sqrt();
                let t0 = Instant::now();
                self.apply_step(graph);
                phases.update += since(t0);
                // Linearised at once, as in LM: an accepted step's H and g
                // become current below; a rejected one leaves them as they were.
                let trial = self.linearize_trial(graph, &mut phases, true);
                let rho = (chi2 - trial) / predicted;
                if trial.is_finite() && predicted > 0.0 && rho > 0.0 {
                    if rho > 0.75 {
                        radius = radius.max(3.0 * step_norm);
                    } else if rho < 0.25 {
                        radius *= 0.5;
                    }
                    break Some(trial);
                }
                let t0 = Instant::now();
                self.restore(graph);
                phases.update += since(t0);
                radius = 0.5 * radius.min(step_norm);
                // A step too small to matter that fails is rounding at the
                // optimum: shrinking the radius would not change that.
                rejected_small_step = self.step_is_small(graph);
                if rejected_small_step || trials >= self.config.dogleg.max_trials {
                    break None;
                }
            };
            let stats = IterationStats {
                iteration,
                chi2,
                radius: Some(radius),
                trials,
                gradient_max,
                phases,
                ..Default::default()
            };
            let Some(new_chi2) = accepted else {
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

    /// The Gauss-Newton step in `self.step`, damped (H + μI, μ from 1e-8·max
    /// diag H upwards by tens) only if H alone is not positive definite.
    fn damped_gauss_newton_step(&mut self, phases: &mut PhaseTimes) -> bool {
        let max_diagonal = self
            .structure
            .layout
            .diagonal()
            .fold(0.0f64, |m, d| m.max(self.hessian[d].abs()));
        self.damping.fill(1.0);
        let mut damping = 0.0;
        for _ in 0..12 {
            if self.compute_step(damping, phases) {
                return true;
            }
            damping = if damping == 0.0 {
                1e-8 * max_diagonal.max(f64::MIN_POSITIVE)
            } else {
                damping * 10.0
            };
        }
        false
    }
}
