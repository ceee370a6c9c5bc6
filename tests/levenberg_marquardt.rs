//! Levenberg-Marquardt on poor starts (non-monotonic steps, the look-ahead,
//! the line search): generated Manhattan worlds and spheres whose
//! odometry-chained start is far from the optimum.

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

/// LM with the default options on a generated Manhattan world of 500 poses,
/// with and without the Gauss-Newton look-ahead, and Gauss-Newton.
fn look_ahead_runs(sigma_rotation: f64, seed: u64) -> [cairn::solvers::Summary; 3] {
    use cairn::solvers::{Algorithm, SolverConfig};
    let options = ManhattanOptions {
        poses: 500,
        size: 22,
        sigma_rotation,
        seed,
        ..Default::default()
    };
    let with = common::lm_config(5);
    let mut without = with.clone();
    without.lm.lookahead_steps = 0;
    let gn = SolverConfig {
        algorithm: Algorithm::GaussNewton,
        ..Default::default()
    };
    [with, without, gn].map(|config| optimize(&mut manhattan(&options).unwrap(), config).unwrap())
}

#[test]
fn lm_follows_a_gauss_newton_path_that_climbs_and_settles_below_the_start() {
    let [with, without, gn] = look_ahead_runs(0.08, 4);
    let path = with.trace.iter().take_while(|t| t.lambda == Some(0.0));
    let path: Vec<f64> = path.map(|t| t.chi2).collect();
    eprintln!(
        "path {path:?}; LM {} iterations to {}, without the look-ahead {} to {}, GN {} to {}",
        with.iterations,
        with.final_chi2,
        without.iterations,
        without.final_chi2,
        gn.iterations,
        gn.final_chi2
    );
    // The first step climbs, each one after it descends, and the last ends
    // below the start, settled.
    assert!(path.len() >= 3 && path[0] > with.initial_chi2, "{path:?}");
    assert!(path.windows(2).all(|w| w[1] < w[0]), "{path:?}");
    let (last, before) = (path[path.len() - 1], path[path.len() - 2]);
    assert!(last < with.initial_chi2 && (before - last) / before < 1e-3);
    // It ends where Gauss-Newton does, in about as many iterations and
    // factorisations, where damped steps from the start take twice as many.
    assert!((with.final_chi2 - gn.final_chi2).abs() <= 1e-6 * gn.final_chi2);
    assert!(with.iterations <= gn.iterations + 1);
    let solves = |s: &cairn::solvers::Summary| s.trace.iter().map(|t| t.trials).sum::<usize>();
    assert_eq!(solves(&with), with.iterations);
    assert!(without.iterations >= 2 * with.iterations);
    assert!(solves(&without) >= 3 * solves(&with));
}

#[test]
fn lm_goes_back_to_the_start_when_the_gauss_newton_path_does_not_settle() {
    let [with, without, _] = look_ahead_runs(0.1, 9);
    // The first step was rejected after the look-ahead: the run is the one
    // without it, to the bit.
    assert!(with.trace[0].trials > 1);
    assert!(with.trace.iter().all(|t| t.lambda != Some(0.0)));
    assert_eq!(with.iterations, without.iterations);
    assert_eq!(with.final_chi2.to_bits(), without.final_chi2.to_bits());
}

/// LM with the default options on a generated sphere of 400 poses (20
/// rings), from its odometry-chained start, with and without the line
/// search.
fn line_search_runs(sigma_rotation: f64, seed: u64) -> [cairn::solvers::Summary; 2] {
    use cairn::generate::{SphereOptions, sphere};
    let options = SphereOptions {
        sigma_rotation,
        seed,
        ..Default::default()
    };
    let with = common::lm_config(5);
    let mut without = with.clone();
    without.lm.line_search = false;
    [with, without].map(|config| optimize(&mut sphere(&options).unwrap(), config).unwrap())
}

#[test]
fn lm_shortens_steps_that_overshoot() {
    // 0.08 rad rotation noise, seed 1: the whole steps overshoot, and LM
    // without the line search spends its 100 iterations far above the
    // minimum (χ² about 85,000 against 2,288).
    let [with, without] = line_search_runs(0.08, 1);
    eprintln!(
        "with: {} iterations, χ² {}; without: {} iterations, χ² {}",
        with.iterations, with.final_chi2, without.iterations, without.final_chi2
    );
    assert_eq!(with.termination, Termination::RelativeDecrease);
    assert!(with.iterations <= 20, "{}", with.iterations);
    assert!(with.final_chi2 < 0.1 * without.final_chi2);
    // At the minimum: Gauss-Newton from LM's estimate does not lower it.
    let mut graph = cairn::generate::sphere(&cairn::generate::SphereOptions {
        sigma_rotation: 0.08,
        seed: 1,
        ..Default::default()
    })
    .unwrap();
    let lm = optimize(&mut graph, common::lm_config(5)).unwrap();
    let gn = optimize(&mut graph, cairn::solvers::SolverConfig::default()).unwrap();
    assert_eq!(lm.final_chi2, with.final_chi2);
    assert!(
        gn.final_chi2 >= lm.final_chi2 * (1.0 - 1e-6),
        "{}",
        gn.final_chi2
    );
}

#[test]
fn the_line_search_leaves_steps_that_fit_their_model_whole() {
    // 0.05 rad: every step lowers χ² by most of what its model predicts, so
    // the runs are the same to the bit.
    let [with, without] = line_search_runs(0.05, 1);
    assert_eq!(with.final_chi2, without.final_chi2);
    let chi2s = |s: &cairn::solvers::Summary| s.trace.iter().map(|t| t.chi2).collect::<Vec<_>>();
    assert_eq!(chi2s(&with), chi2s(&without));
}
