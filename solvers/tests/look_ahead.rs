//! Gauss-Newton's look ahead: the last factorisation predicts the next
//! step's decrease, and a negligible one is not taken.

mod common;

use cairn_core::{EdgeSE2, SE2};
use cairn_solvers::{Algorithm, Initialization, SolverConfig, Termination, optimize};
use common::noisy_loop;
use nalgebra::Matrix3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// Gauss-Newton from the graph's own values.
fn config(algorithm: Algorithm) -> SolverConfig {
    SolverConfig {
        algorithm,
        init: Initialization::File,
        ..Default::default()
    }
}

/// Gauss-Newton stops without the last factorisation once the model
/// predicts a step that lowers χ² by less than a hundredth of the
/// tolerance: it ends within that of the χ² reached by iterating until the
/// gradient vanishes.
#[test]
fn gauss_newton_skips_a_negligible_last_step() {
    let tolerance = 1e-5;
    let mut skipped = 0;
    for seed in 0..10 {
        // A loop whose measurements disagree: χ² stays well above 0.
        let mut g = noisy_loop(60, seed);
        let mut rng = StdRng::seed_from_u64(seed);
        let info = Matrix3::from_diagonal(&nalgebra::Vector3::new(100.0, 100.0, 1000.0));
        for i in 0..60 {
            let z = SE2::new(
                1.0 + rng.random_range(-0.1..0.1),
                rng.random_range(-0.1..0.1),
                0.1 + rng.random_range(-0.05..0.05),
            );
            g.add_edge(i, (i + 2) % 60, EdgeSE2::new(z), info).unwrap();
        }
        let mut h = g.clone();
        let stopping = SolverConfig {
            relative_decrease: tolerance,
            ..config(Algorithm::GaussNewton)
        };
        let stopped = optimize(&mut g, stopping).unwrap();
        let exhaustive = SolverConfig {
            relative_decrease: 0.0,
            ..config(Algorithm::GaussNewton)
        };
        let full = optimize(&mut h, exhaustive).unwrap();
        let gap = (stopped.final_chi2 - full.final_chi2) / full.final_chi2;
        assert!(
            (0.0..=2.0 * tolerance / 100.0).contains(&gap),
            "seed {seed}: {gap}"
        );
        // Skipped: it stopped though χ² fell by more than the tolerance.
        let chi2: Vec<f64> = std::iter::once(stopped.initial_chi2)
            .chain(stopped.trace.iter().map(|t| t.chi2))
            .collect();
        let last = (chi2[chi2.len() - 2] - stopped.final_chi2) / stopped.final_chi2;
        if stopped.termination == Termination::RelativeDecrease && last >= tolerance {
            skipped += 1;
            assert!(stopped.iterations < full.iterations, "seed {seed}");
        }
    }
    assert!(skipped > 0, "the look ahead never saved a factorisation");
}
