//! Levenberg-Marquardt's non-monotonic steps on poor starts: generated
//! Manhattan worlds whose odometry-chained start is far from the optimum.

mod common;

use cairn::generate::{ManhattanOptions, manhattan};
use cairn::solvers::{Termination, optimize};

fn solve(seed: u64, nonmonotonic_steps: usize) -> (cairn::solvers::Summary, f64) {
    let mut graph = manhattan(&ManhattanOptions {
        poses: 1500,
        sigma_rotation: 0.08,
        seed,
        ..Default::default()
    })
    .unwrap();
    let summary = optimize(&mut graph, common::lm_config(nonmonotonic_steps)).unwrap();
    (summary, graph.chi2())
}

#[test]
fn non_monotonic_lm_keeps_the_lowest_chi2_it_met() {
    let mut climbed = 0;
    let mut left_lowest = 0;
    for seed in 0..6 {
        let (monotone, _) = solve(seed, 0);
        assert!(
            monotone.trace.windows(2).all(|w| w[1].chi2 <= w[0].chi2),
            "seed {seed}: a monotone step raised χ²"
        );
        let (s, chi2) = solve(seed, 5);
        let lowest = (s.trace.iter().map(|t| t.chi2)).fold(s.initial_chi2, f64::min);
        let last = s.trace.last().map_or(s.initial_chi2, |t| t.chi2);
        eprintln!(
            "seed {seed}: {} iterations, last χ² {last}, lowest {lowest}; monotone {}",
            s.iterations, monotone.final_chi2
        );
        assert_eq!(s.final_chi2, lowest, "seed {seed}");
        // The graph holds that estimate.
        assert!(
            (chi2 - lowest).abs() <= 1e-9 * lowest,
            "seed {seed}: {chi2}"
        );
        if s.termination == Termination::RelativeDecrease {
            // Converged only on a new lowest χ², never on a step that fell
            // a little but stayed above it.
            assert_eq!(last, lowest, "seed {seed}");
        }
        climbed += s.trace.windows(2).any(|w| w[1].chi2 > w[0].chi2) as usize;
        left_lowest += (last > lowest) as usize;
    }
    // The starts are poor enough for some runs to climb, and for some to
    // end above their lowest point, so both paths are exercised.
    assert!(climbed > 0 && left_lowest > 0, "{climbed} {left_lowest}");
}
