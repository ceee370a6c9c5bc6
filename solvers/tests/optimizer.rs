//! Behaviour of the optimiser: gauge, fixed vertices, failure modes and
//! recovery, determinism, reuse.

use cairn_core::{BinaryEdge, EdgeSE2, EdgeSE2XY, Graph, SE2};
use cairn_solvers::{
    Algorithm, LevenbergMarquardtConfig, Optimizer, SolveError, SolverConfig, Termination, optimize,
};
use nalgebra::{Matrix1, Matrix2, Matrix3, Vector1, Vector2};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// `algorithm` from the graph's own values.
fn config(algorithm: Algorithm) -> SolverConfig {
    SolverConfig {
        algorithm,
        init: cairn_solvers::Initialization::File,
        ..Default::default()
    }
}

mod common;
use common::noisy_loop;

/// Runs `f` in a pool of `threads` threads.
fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(f)
}

#[test]
fn gn_lm_and_dogleg_close_a_consistent_loop() {
    for algorithm in [
        Algorithm::GaussNewton,
        Algorithm::LevenbergMarquardt,
        Algorithm::Dogleg,
    ] {
        let mut g = noisy_loop(40, 1);
        let s = optimize(&mut g, config(algorithm)).unwrap();
        assert!(
            s.termination.converged(),
            "{algorithm:?}: {:?}",
            s.termination
        );
        assert!(
            s.final_chi2 < 1e-12 * s.initial_chi2.max(1.0),
            "{algorithm:?}: {}",
            s.final_chi2
        );
        assert_eq!(s.gauge, vec![0]);
        assert_eq!(s.iterations, s.trace.len());
        assert!(
            s.trace
                .iter()
                .all(|t| t.phases.factorize >= 0.0 && t.time >= 0.0)
        );
        // The last iterate's χ², unless an earlier one was lower (χ² ≈ 1e-27
        // goes up and down in its last bits) and was returned.
        let last = s.trace.last().unwrap().chi2;
        assert_eq!(s.returned_lowest, last > s.final_chi2, "{algorithm:?}");
        assert!(s.final_chi2 <= last, "{algorithm:?}");
        let lowest = s.trace.iter().fold(s.initial_chi2, |m, t| m.min(t.chi2));
        assert!(s.final_chi2 <= lowest, "{algorithm:?}");
    }
}

#[test]
fn fixed_vertices_do_not_move() {
    let mut g = noisy_loop(20, 2);
    g.set_fixed(5, true).unwrap();
    let before: SE2 = g.value(5).unwrap();
    let s = optimize(&mut g, SolverConfig::default()).unwrap();
    assert!(s.gauge.is_empty(), "a FIX vertex is the gauge");
    assert_eq!(g.value::<SE2, 3>(5).unwrap(), before);
}

#[test]
fn disconnected_components_each_get_a_gauge() {
    let mut g = noisy_loop(10, 3);
    for i in 100..103 {
        g.add_vertex(i, SE2::new(i as f64, 0.0, 0.0)).unwrap();
    }
    g.add_edge(
        100,
        101,
        EdgeSE2::new(SE2::new(1.0, 0.1, 0.0)),
        Matrix3::identity(),
    )
    .unwrap();
    g.add_edge(
        101,
        102,
        EdgeSE2::new(SE2::new(1.0, 0.1, 0.0)),
        Matrix3::identity(),
    )
    .unwrap();
    g.add_vertex(200, Vector2::new(1.0, 1.0)).unwrap(); // isolated landmark
    let s = optimize(&mut g, SolverConfig::default()).unwrap();
    assert_eq!(s.components, 3);
    assert_eq!(s.gauge, vec![0, 100, 200]);
    assert!(s.termination.converged());
}

/// Range-only observation: one equation for a 2D point, so H is singular.
#[derive(Clone, Debug)]
struct Range(f64);

impl BinaryEdge<1, 3, 2> for Range {
    type V1 = SE2;
    type V2 = Vector2<f64>;
    const NAME: &'static str = "RANGE";
    fn error(&self, x: &SE2, l: &Vector2<f64>) -> Vector1<f64> {
        Vector1::new((l - x.t).norm() - self.0)
    }
}

#[test]
fn a_singular_hessian_ends_gn_and_is_damped_by_lm_and_dogleg() {
    let build = || {
        let mut g = Graph::new();
        g.add_vertex(0, SE2::identity()).unwrap();
        g.add_vertex(1, Vector2::new(3.0, 1.0)).unwrap();
        g.add_edge(0, 1, Range(2.0), Matrix1::new(1.0)).unwrap();
        g
    };
    let mut g = build();
    let s = optimize(&mut g, config(Algorithm::GaussNewton)).unwrap();
    assert_eq!(s.termination, Termination::NotPositiveDefinite);
    assert_eq!(s.final_chi2, s.initial_chi2, "GN keeps the last estimate");

    let levenberg = SolverConfig {
        lm: LevenbergMarquardtConfig::g2o(),
        ..config(Algorithm::LevenbergMarquardt)
    };
    for config in [levenberg, config(Algorithm::Dogleg)] {
        let mut g = build();
        let s = optimize(&mut g, config.clone()).unwrap();
        let algorithm = config.algorithm;
        assert!(
            s.termination.converged(),
            "{algorithm:?}: {:?}",
            s.termination
        );
        assert!(s.final_chi2 < 1e-10, "{algorithm:?}");
        let l: Vector2<f64> = g.value(1).unwrap();
        assert!((l.norm() - 2.0).abs() < 1e-5, "{algorithm:?}");
    }
    // Marquardt's damping leaves the singular direction's step component
    // (see `Damping::Marquardt`): it damps H and lowers χ², without reaching 0.
    let mut g = build();
    let s = optimize(&mut g, config(Algorithm::LevenbergMarquardt)).unwrap();
    assert_ne!(s.termination, Termination::NotPositiveDefinite);
    assert!(s.final_chi2 < 0.05 * s.initial_chi2, "{}", s.final_chi2);
    // Non-monotonic steps: the estimate kept is the lowest χ² met.
    assert!(s.trace.iter().all(|t| s.final_chi2 <= t.chi2));
}

#[test]
fn non_finite_initial_chi2_names_the_edge() {
    let mut g = Graph::new();
    g.add_vertex(0, SE2::new(1e308, 0.0, 0.0)).unwrap();
    g.add_vertex(1, SE2::new(-1e308, 0.0, 0.0)).unwrap();
    g.add_vertex(2, Vector2::new(0.0, 0.0)).unwrap();
    g.add_edge(0, 2, EdgeSE2XY::new(Vector2::zeros()), Matrix2::identity())
        .unwrap();
    g.add_edge(0, 1, EdgeSE2::new(SE2::identity()), Matrix3::identity())
        .unwrap();
    match optimize(&mut g, SolverConfig::default()) {
        Err(SolveError::NonFiniteChi2 { name, vertices, .. }) => {
            assert_eq!(name, "EDGE_SE2_XY");
            assert_eq!(vertices, vec![0, 2]);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn everything_fixed_is_nothing_to_optimize() {
    let mut g = noisy_loop(5, 4);
    for i in 0..5 {
        g.set_fixed(i, true).unwrap();
    }
    let s = optimize(&mut g, SolverConfig::default()).unwrap();
    assert_eq!(s.termination, Termination::NothingToOptimize);
    assert_eq!(s.iterations, 0);
}

/// One thread adds the edges' blocks straight into H; more (with the
/// threshold at 0) linearise into a buffer in parallel and sum it: the same
/// bits, every iteration.
#[test]
fn results_do_not_depend_on_the_number_of_threads() {
    let run = |threads: usize, algorithm: Algorithm| {
        on_threads(threads, || {
            let mut g = noisy_loop(3000, 5);
            let config = SolverConfig {
                parallel_min_values: 0,
                ..config(algorithm)
            };
            let s = optimize(&mut g, config).unwrap();
            (
                g.values().params().to_vec(),
                s.trace.iter().map(|t| t.chi2.to_bits()).collect::<Vec<_>>(),
            )
        })
    };
    for algorithm in [
        Algorithm::GaussNewton,
        Algorithm::LevenbergMarquardt,
        Algorithm::Dogleg,
    ] {
        let one = run(1, algorithm);
        assert_eq!(one, run(2, algorithm), "{algorithm:?}");
        assert_eq!(one, run(3, algorithm), "{algorithm:?}");
    }
}

#[test]
fn an_optimizer_is_reused_and_refuses_a_changed_graph() {
    let mut g = noisy_loop(30, 6);
    let mut opt = Optimizer::new(&g, SolverConfig::default()).unwrap();
    let first = opt.optimize(&mut g).unwrap();
    let again = opt.optimize(&mut g).unwrap();
    assert!(
        again.iterations <= 2
            && (again.final_chi2 - first.final_chi2).abs() <= 1e-9 * first.final_chi2.max(1e-300)
    );
    g.add_vertex(99, SE2::identity()).unwrap();
    assert_eq!(opt.optimize(&mut g).unwrap_err(), SolveError::GraphChanged);
}

#[test]
fn lm_updates_lambda_by_nielsen_rule_with_either_damping() {
    // λ shrinks by at most 3 after a good step, and never grows after one.
    let monotone = LevenbergMarquardtConfig {
        nonmonotonic_steps: 0,
        ..Default::default()
    };
    for lm in [monotone, LevenbergMarquardtConfig::g2o()] {
        let mut g = noisy_loop(50, 7);
        let config = SolverConfig {
            lm,
            ..config(Algorithm::LevenbergMarquardt)
        };
        let s = optimize(&mut g, config).unwrap();
        let lambdas: Vec<f64> = s.trace.iter().filter_map(|t| t.lambda).collect();
        assert!(!lambdas.is_empty());
        // (The last record may be a rejected step at the optimum, after
        // which λ grows.)
        let accepted = if s.termination == Termination::StepSize {
            &s.trace[..s.trace.len() - 1]
        } else {
            &s.trace[..]
        };
        for w in accepted.windows(2) {
            if w[1].trials == 1 {
                let ratio = w[1].lambda.unwrap() / w[0].lambda.unwrap();
                assert!(
                    (1.0 / 3.0 - 1e-12..=2.0 / 3.0 + 1e-12).contains(&ratio),
                    "{:?}: λ ratio {ratio}",
                    lm.damping
                );
            }
        }
        assert!(
            s.trace.windows(2).all(|w| w[1].chi2 <= w[0].chi2),
            "LM never accepts an increase"
        );
    }
}

#[test]
fn default_lm_takes_gauss_newton_steps_where_they_work() {
    // A long loop with noisy measurements, started from the chained odometry:
    // the loop's bending modes are soft, and a λ sized by the stiffest
    // unknown (g2o's) holds them back.
    for seed in 0..4 {
        let build = || {
            let mut rng = StdRng::seed_from_u64(seed);
            let n = 400;
            let step = SE2::new(1.0, 0.0, 2.0 * std::f64::consts::PI / n as f64);
            let mut noisy = |z: SE2| {
                z.compose(&SE2::new(
                    rng.random_range(-0.05..0.05),
                    rng.random_range(-0.05..0.05),
                    rng.random_range(-0.01..0.01),
                ))
            };
            let info = Matrix3::from_diagonal(&nalgebra::Vector3::new(400.0, 400.0, 1e4));
            let odometry: Vec<SE2> = (0..n).map(|_| noisy(step)).collect();
            let mut g = Graph::new();
            let mut pose = SE2::identity();
            for (i, z) in (0..n).zip(&odometry) {
                g.add_vertex(i, pose).unwrap();
                pose = pose.compose(z);
            }
            for (i, z) in (0..n).zip(&odometry) {
                g.add_edge(i, (i + 1) % n, EdgeSE2::new(*z), info).unwrap();
            }
            for i in (0..n - 10).step_by(7) {
                let mut z = SE2::identity();
                for _ in 0..10 {
                    z = z.compose(&step);
                }
                g.add_edge(i, i + 10, EdgeSE2::new(noisy(z)), info).unwrap();
            }
            g
        };
        let run = |config: SolverConfig| optimize(&mut build(), config).unwrap();
        let gn = run(config(Algorithm::GaussNewton));
        let lm = run(config(Algorithm::LevenbergMarquardt));
        assert!(gn.termination.converged());
        assert!(
            lm.iterations <= gn.iterations + 1,
            "seed {seed}: LM {} iterations, GN {}",
            lm.iterations,
            gn.iterations
        );
        assert!(
            (lm.final_chi2 - gn.final_chi2).abs() <= 1e-6 * gn.final_chi2,
            "seed {seed}: LM χ² {}, GN {}",
            lm.final_chi2,
            gn.final_chi2
        );
    }
}

#[test]
fn every_ordering_and_factorization_gives_the_same_optimum() {
    use cairn_solvers::{Factorization, LinearSolverConfig, Ordering};
    let mut reference = None;
    for ordering in [
        Ordering::Amd,
        Ordering::BlockAmd,
        Ordering::Identity,
        Ordering::Schur,
    ] {
        for factorization in [
            Factorization::Auto,
            Factorization::Simplicial,
            Factorization::Supernodal,
        ] {
            // Landmarks seen from several poses each, so that eliminating
            // them first (Schur) couples those poses.
            let mut g = noisy_loop(200, 8);
            for l in 0..20 {
                let id = 1000 + l;
                g.add_vertex(id, Vector2::new(3.0 + l as f64, 3.0)).unwrap();
                for pose in [10 * l, 10 * l + 3, (10 * l + 57) % 200] {
                    g.add_edge(
                        pose,
                        id,
                        EdgeSE2XY::new(Vector2::new(1.0, 2.0 - 0.1 * l as f64)),
                        Matrix2::identity(),
                    )
                    .unwrap();
                }
            }
            let linear = LinearSolverConfig {
                ordering,
                factorization,
                ..Default::default()
            };
            let s = optimize(
                &mut g,
                SolverConfig {
                    linear,
                    ..Default::default()
                },
            )
            .unwrap();
            let chi2 = *reference.get_or_insert(s.final_chi2);
            assert!(
                (s.final_chi2 - chi2).abs() <= 1e-9 * chi2.max(1e-12),
                "{ordering:?} {factorization:?}"
            );
        }
    }
}

#[test]
fn dogleg_radius_shrinks_on_a_bad_start_and_never_accepts_an_increase() {
    let mut g = noisy_loop(60, 10);
    for i in 1..60 {
        // A poor start: headings scrambled.
        let x: SE2 = g.value(i).unwrap();
        g.set_value(i, &SE2::new(x.t.x, x.t.y, x.theta + 1.5 * (i % 3) as f64))
            .unwrap();
    }
    let mut cfg = config(Algorithm::Dogleg);
    cfg.dogleg.initial_radius = 1.0;
    let s = optimize(&mut g, cfg).unwrap();
    assert!(
        s.trace
            .iter()
            .all(|t| t.radius.is_some() && t.lambda.is_none())
    );
    assert!(s.trace.windows(2).all(|w| w[1].chi2 <= w[0].chi2));
    assert!(s.final_chi2 < s.initial_chi2);
}

#[test]
fn gn_asked_to_stop_on_a_rise_stops_there_and_keeps_the_estimate_before_it() {
    // Headings scrambled: GN climbs at its sixth step, then reaches the
    // exact optimum.
    let scrambled = || {
        let mut g = noisy_loop(60, 0);
        let mut rng = StdRng::seed_from_u64(100);
        for i in 1..60 {
            let x: SE2 = g.value(i).unwrap();
            let theta = x.theta + 2.0 * rng.random_range(-1.0..1.0);
            g.set_value(i, &SE2::new(x.t.x, x.t.y, theta)).unwrap();
        }
        g
    };
    // Unasked, GN carries on through its first rise (g2o's rule).
    let plain = optimize(&mut scrambled(), config(Algorithm::GaussNewton)).unwrap();
    let chi2_before = |k: usize| match k {
        0 => plain.initial_chi2,
        _ => plain.trace[k - 1].chi2,
    };
    let rise = (0..plain.iterations)
        .find(|&k| plain.trace[k].chi2 > chi2_before(k))
        .expect("this start makes GN overshoot");
    assert!(plain.termination.converged() && plain.final_chi2 < 1e-12);

    // Asked, on one thread and on two (linearising into the parallel buffer).
    let stopped = |threads: usize| {
        on_threads(threads, || {
            let mut g = scrambled();
            let cfg = SolverConfig {
                stop_on_increase: true,
                parallel_min_values: if threads > 1 { 0 } else { usize::MAX },
                ..config(Algorithm::GaussNewton)
            };
            let s = optimize(&mut g, cfg).unwrap();
            (s, g)
        })
    };
    let (s, g) = stopped(1);
    let (s2, g2) = stopped(2);
    assert_eq!(g.values().params(), g2.values().params());
    assert_eq!(s.final_chi2.to_bits(), s2.final_chi2.to_bits());
    assert_eq!(s.iterations, s2.iterations);
    assert_eq!(s.termination, Termination::ErrorIncreased);
    assert!(!s.termination.converged());
    assert_eq!(s.iterations, rise + 1);
    for k in 0..=rise {
        assert_eq!(s.trace[k].chi2, plain.trace[k].chi2, "iteration {k}");
    }
    // The rise is in the trace; the estimate is the one before it.
    assert_eq!(s.final_chi2, chi2_before(rise));
    assert_eq!(g.chi2(), s.final_chi2);
}

#[test]
fn gn_asked_to_stop_on_a_rise_ignores_rounding_at_the_optimum() {
    // Consistent loops solved to χ² ≈ 1e-26, then solved again: from there
    // χ² moves in its last bits, up or down. That is convergence, not a rise.
    let mut rises = 0;
    for seed in 0..20 {
        let solved = || {
            let mut g = noisy_loop(40, seed);
            optimize(&mut g, config(Algorithm::GaussNewton)).unwrap();
            g
        };
        // (No gradient test, which would stop both runs before a step.)
        let plain = SolverConfig {
            gradient_tolerance: 0.0,
            ..config(Algorithm::GaussNewton)
        };
        let again = optimize(&mut solved(), plain.clone()).unwrap();
        rises += usize::from(again.trace[0].chi2 > again.initial_chi2);
        let cfg = SolverConfig {
            stop_on_increase: true,
            ..plain
        };
        let s = optimize(&mut solved(), cfg).unwrap();
        assert!(
            s.termination.converged(),
            "seed {seed}: {:?}",
            s.termination
        );
        assert!(s.final_chi2 < 1e-12, "seed {seed}: {}", s.final_chi2);
    }
    assert!(rises > 0, "some of the loops go up in their last bits");
}

#[test]
fn chordal_initialisation_recovers_noise_free_graphs_exactly() {
    use cairn_core::{EdgeSE3, SE3};
    use cairn_solvers::{ChordalWeights, chordal_initialize_with};
    use nalgebra::{Matrix6, UnitQuaternion, Vector3, Vector6};
    let mut rng = StdRng::seed_from_u64(11);
    for weights in [ChordalWeights::Information, ChordalWeights::Isotropic] {
        // 2D: a noise-free loop with landmarks, started from scrambled values.
        let mut g = Graph::new();
        let truth: Vec<SE2> = (0..30)
            .map(|i| {
                SE2::new(
                    (i as f64 * 0.3).cos() * 10.0,
                    (i as f64 * 0.3).sin() * 10.0,
                    i as f64 * 0.3 + 1.6,
                )
            })
            .collect();
        for (i, x) in truth.iter().enumerate() {
            let scrambled = if i == 0 {
                *x
            } else {
                SE2::new(
                    rng.random_range(-50.0..50.0),
                    rng.random_range(-50.0..50.0),
                    rng.random_range(-3.0..3.0),
                )
            };
            g.add_vertex(i as i64, scrambled).unwrap();
        }
        for i in 0..30 {
            for j in [i + 1, i + 7] {
                let j = j % 30;
                g.add_edge(
                    i as i64,
                    j as i64,
                    EdgeSE2::new(truth[i].between(&truth[j])),
                    Matrix3::from_diagonal(&Vector3::from_fn(|_, _| rng.random_range(0.1..100.0))),
                )
                .unwrap();
            }
        }
        let landmark = Vector2::new(1.0, 2.0);
        g.add_vertex(100, Vector2::new(40.0, -40.0)).unwrap();
        for i in [3usize, 17] {
            let z = truth[i].inverse().transform_point(&landmark);
            g.add_edge(i as i64, 100, EdgeSE2XY::new(z), Matrix2::identity())
                .unwrap();
        }
        let report = chordal_initialize_with(&mut g, weights).unwrap();
        assert_eq!((report.poses, report.landmarks), (29, 1));
        assert!(g.chi2() < 1e-16, "χ² {}", g.chi2());
        assert!((g.value::<Vector2<f64>, 2>(100).unwrap() - landmark).norm() < 1e-9);

        // 3D: the same for SE3 poses.
        let mut g = Graph::new();
        let truth: Vec<SE3> = (0..20)
            .map(|i| {
                let a = i as f64 * 0.4;
                SE3::new(
                    Vector3::new(a.cos() * 5.0, a.sin() * 5.0, a),
                    UnitQuaternion::from_euler_angles(0.1 * a, -0.2, a),
                )
            })
            .collect();
        for (i, x) in truth.iter().enumerate() {
            let scrambled = if i == 0 {
                *x
            } else {
                SE3::new(
                    Vector3::new(rng.random_range(-9.0..9.0), 0.0, 3.0),
                    UnitQuaternion::from_euler_angles(rng.random_range(-3.0..3.0), 1.0, 0.5),
                )
            };
            g.add_vertex(i as i64, scrambled).unwrap();
        }
        for i in 0..20 {
            for j in [i + 1, i + 5] {
                let j = j % 20;
                g.add_edge(
                    i as i64,
                    j as i64,
                    EdgeSE3::new(truth[i].between(&truth[j])),
                    Matrix6::from_diagonal(&Vector6::from_fn(|_, _| rng.random_range(0.1..100.0))),
                )
                .unwrap();
            }
        }
        chordal_initialize_with(&mut g, weights).unwrap();
        assert!(g.chi2() < 1e-16, "χ² {}", g.chi2());
    }
}
