//! End-to-end solves of the public benchmark files: every file loads and
//! solves, and on the reference files the final χ² (g2o convention) matches or
//! beats g2o's for the same algorithm (../shared/peers/baseline.jsonl) and
//! equals the local minimum computed independently in the datasets' MANIFEST.

mod common;

use cairn::g2o::{G2oError, ReadOptions, read_file};
use cairn::solvers::{
    Algorithm, Damping, Initialization, LevenbergMarquardtConfig, SolverConfig, Termination,
    optimize,
};

/// Reference files, the MANIFEST's local minimum ("chi2 local min, chordal
/// init (computed)"), and whether g2o's Levenberg-Marquardt reaches it from the
/// file's vertices in 100 iterations (on city10000 it does not, and neither
/// does ours with g2o's damping, which follows g2o's schedule exactly).
const REFERENCE: [(&str, f64, bool); 10] = [
    ("2d/intel.g2o", 45.004696, true),
    ("2d/manhattanOlson3500.g2o", 146.076613, true),
    ("2d/input_M3500_g2o.g2o", 137.912951, true),
    ("2d/ring.g2o", 11.163101, true),
    ("2d/kitti_00.g2o", 98.322012, true),
    ("2d/city10000.g2o", 511.985164, false),
    ("landmarks/dlr.g2o", 56860.35268, true),
    ("landmarks/simulation-pose-landmark.g2o", 474.09954, true),
    ("3d/sphere2500.g2o", 727.149667, true),
    ("3d/parking-garage.g2o", 1.238691, true),
];

fn check_reference(algorithm: Algorithm, lm: LevenbergMarquardtConfig) {
    let algo = algorithm.short_name();
    let g2o_damping =
        algorithm == Algorithm::LevenbergMarquardt && lm.damping == Damping::Levenberg;
    for (file, minimum, g2o_lm_reaches) in REFERENCE {
        let Some(path) = common::dataset(file) else {
            return;
        };
        let (mut graph, _) = read_file(&path, &ReadOptions::default()).unwrap();
        let summary = optimize(
            &mut graph,
            SolverConfig {
                algorithm,
                lm,
                init: Initialization::File,
                ..Default::default()
            },
        )
        .unwrap();
        let chi2 = summary.final_chi2;
        let name = file.rsplit('/').next().unwrap_or(file);
        // g2o's dogleg is not in the baseline; hold ours to g2o's Gauss-Newton.
        let reference_algo = if algorithm == Algorithm::Dogleg {
            "gn"
        } else {
            algo
        };
        let (g2o, _) = common::g2o_baseline(name, reference_algo)
            .unwrap_or_else(|| panic!("no g2o {reference_algo} baseline for {name}"));
        let to_minimum = (chi2 - minimum) / minimum;
        eprintln!(
            "{name} {algo}: χ² {chi2:.10} after {} it; g2o {g2o:.10}; minimum {minimum}",
            summary.iterations
        );
        // Never below the true local minimum: that would mean a wrong objective.
        assert!(
            to_minimum > -1e-6,
            "{name} {algo}: χ² {chi2} is below the minimum {minimum}"
        );
        // As good as g2o. On SE3 files g2o keeps the files' slightly non-unit vertex
        // quaternions (|q|² − 1 up to 1.4e-6), so its rotations are not quite
        // orthonormal and its χ² can dip a few 1e-6 below the SE(3) minimum, which
        // we reach instead.
        assert!(
            chi2 <= g2o * (1.0 + 1e-6) || to_minimum.abs() <= 1e-6,
            "{name} {algo}: χ² {chi2} is worse than g2o's {g2o}"
        );
        if g2o_damping && !g2o_lm_reaches {
            // The same iterates as g2o: where g2o stalls after 100
            // iterations, at the same χ².
            assert!(
                (chi2 - g2o).abs() <= 1e-9 * g2o,
                "{name} {algo} (g2o damping): χ² {chi2} is not g2o's {g2o}"
            );
        }
        if !g2o_damping || g2o_lm_reaches {
            assert!(
                to_minimum.abs() <= 1e-6,
                "{name} {algo}: χ² {chi2} misses the minimum {minimum}"
            );
            assert!(
                summary.termination.converged(),
                "{name} {algo}: {:?}",
                summary.termination
            );
        }
    }
}

#[test]
fn gauss_newton_matches_g2o_on_reference_files() {
    check_reference(Algorithm::GaussNewton, LevenbergMarquardtConfig::default());
}

#[test]
fn levenberg_marquardt_reaches_the_minimum_on_reference_files() {
    check_reference(
        Algorithm::LevenbergMarquardt,
        LevenbergMarquardtConfig::default(),
    );
}

#[test]
fn levenberg_marquardt_with_g2o_damping_matches_g2o_on_reference_files() {
    check_reference(
        Algorithm::LevenbergMarquardt,
        LevenbergMarquardtConfig::g2o(),
    );
}

#[test]
fn dogleg_reaches_the_minimum_on_reference_files() {
    check_reference(Algorithm::Dogleg, LevenbergMarquardtConfig::default());
}

#[test]
fn levenberg_marquardt_stops_at_once_on_a_file_at_its_optimum() {
    // kitti_08's vertices are its optimum (χ² ≈ 1e-21): every step is
    // rounding, and raising λ to find a decrease would waste factorisations.
    let Some(path) = common::dataset("2d/kitti_08.g2o") else {
        return;
    };
    let (mut graph, _) = read_file(&path, &ReadOptions::default()).unwrap();
    let config = SolverConfig {
        algorithm: Algorithm::LevenbergMarquardt,
        ..Default::default()
    };
    let s = optimize(&mut graph, config).unwrap();
    let trials: usize = s.trace.iter().map(|t| t.trials).sum();
    assert!(trials <= 1, "{trials} trials, {:?}", s.termination);
    assert!(s.termination.converged(), "{:?}", s.termination);
    assert!(s.final_chi2 < 1e-15);
}

fn solve_all_in(folder: &str) {
    let Some(dir) = common::shared() else { return };
    let mut files: Vec<_> = std::fs::read_dir(dir.join("datasets").join(folder))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "g2o"))
        .collect();
    files.sort();
    assert!(!files.is_empty());
    for path in files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let repair = name == "cubicle.g2o";
        let (mut graph, report) = read_file(
            &path,
            &ReadOptions {
                repair_information: repair,
                ..Default::default()
            },
        )
        .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(graph.num_vertices() > 0, "{name}");
        assert_eq!(report.unknown_lines(), 0, "{name}: {:?}", report.unknown);
        let config = SolverConfig {
            algorithm: Algorithm::LevenbergMarquardt,
            init: Initialization::File,
            ..Default::default()
        };
        let s = optimize(&mut graph, config).unwrap_or_else(|e| panic!("{name}: {e}"));
        eprintln!(
            "{name}: {} → {} in {} it ({:?})",
            s.initial_chi2, s.final_chi2, s.iterations, s.termination
        );
        assert!(s.final_chi2.is_finite(), "{name}");
        assert!(s.final_chi2 <= s.initial_chi2, "{name}: LM increased χ²");
        assert!(
            s.final_chi2 < 0.5 * s.initial_chi2 || s.initial_chi2 < 1.0,
            "{name}: barely improved"
        );
    }
}

#[test]
fn every_2d_file_loads_and_solves() {
    solve_all_in("2d");
}

#[test]
fn every_3d_file_loads_and_solves() {
    solve_all_in("3d");
}

#[test]
fn every_landmark_file_loads_and_solves() {
    solve_all_in("landmarks");
}

#[test]
fn cubicle_is_refused_until_repaired() {
    let Some(path) = common::dataset("3d/cubicle.g2o") else {
        return;
    };
    match read_file(&path, &ReadOptions::default()) {
        Err(G2oError::IndefiniteInformation { count, lines }) => {
            assert_eq!(count, 5021);
            assert_eq!(lines.len(), 10);
            assert!(
                lines.windows(2).all(|w| w[0] < w[1]) && lines[0] > 5750,
                "edge lines: {lines:?}"
            );
        }
        other => panic!(
            "expected IndefiniteInformation, got {:?}",
            other.map(|_| ())
        ),
    }
    let (_, report) = read_file(
        &path,
        &ReadOptions {
            repair_information: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(report.repaired_information.len(), 5021);
}

#[test]
fn files_without_vertices_are_built_from_edges() {
    for (file, poses, landmarks) in [
        ("2d/kitti_00.g2o", 4541, 0),
        ("2d/CSAIL.g2o", 1045, 0),
        ("landmarks/victoriaPark.g2o", 6969, 151),
        ("landmarks/cityTrees10000.g2o", 10000, 100),
    ] {
        let Some(path) = common::dataset(file) else {
            return;
        };
        let (graph, report) = read_file(&path, &ReadOptions::default()).unwrap();
        assert_eq!(graph.num_vertices(), poses + landmarks, "{file}");
        assert_eq!(report.created_vertices, poses + landmarks, "{file}");
        let tree = report.spanning_tree.expect("initialised");
        assert_eq!(
            tree.roots.len(),
            1,
            "{file}: one connected component, one root"
        );
        assert_eq!(tree.predicted, poses + landmarks - 1, "{file}");
        assert_eq!(report.landmark_id_offset.is_some(), landmarks > 0, "{file}");
    }
}

#[test]
fn every_file_round_trips_exactly() {
    let Some(dir) = common::shared() else { return };
    for folder in ["2d", "3d", "landmarks", "parser"] {
        for entry in std::fs::read_dir(dir.join("datasets").join(folder)).unwrap() {
            let path = entry.unwrap().path();
            let opts = ReadOptions {
                repair_information: true,
                ..Default::default()
            };
            let Ok((a, _)) = read_file(&path, &opts) else {
                panic!("{}", path.display())
            };
            let text = cairn::g2o::to_string(&a).unwrap();
            let (b, report) =
                cairn::g2o::read_bytes(text.as_bytes(), &ReadOptions::default()).unwrap();
            assert_eq!(report.unknown_lines(), 0);
            assert_eq!(
                a.values().params(),
                b.values().params(),
                "{}",
                path.display()
            );
            assert_eq!(
                text,
                cairn::g2o::to_string(&b).unwrap(),
                "{}",
                path.display()
            );
            assert_eq!(a.chi2().to_bits(), b.chi2().to_bits(), "{}", path.display());
        }
    }
}

/// Files where every peer stops in a poor local minimum from the file's own
/// vertices, with the best-known minimum from the MANIFEST.
/// Files whose MANIFEST value is marked unverified: Cairn must reach at least
/// that low (it goes lower on both).
const UNVERIFIED: [(&str, f64); 2] = [
    ("2d/M3500c.g2o", 4011.124831),
    ("landmarks/victoriaPark.g2o", 13098.7279),
];

const HARD: [(&str, f64); 6] = [
    ("2d/MIT.g2o", 41.163269),
    ("2d/M3500a.g2o", 912.115012),
    ("2d/M3500b.g2o", 2054.715918),
    ("2d/input_INTEL_g2o.g2o", 215.830235),
    ("3d/torus3D.g2o", 14574.74644),
    ("3d/sphere_bignoise_vertex3.g2o", 743862.7209),
];

#[test]
fn chordal_initialisation_reaches_the_best_known_minima() {
    use cairn::solvers::optimize;
    let unverified = UNVERIFIED.iter().map(|&(f, m)| (f, m, false));
    for (file, minimum, exact) in HARD.iter().map(|&(f, m)| (f, m, true)).chain(unverified) {
        let Some(path) = common::dataset(file) else {
            return;
        };
        let (mut graph, _) = read_file(&path, &ReadOptions::default()).unwrap();
        let summary = optimize(&mut graph, SolverConfig::default()).unwrap();
        let used = summary.init;
        let gap = (summary.final_chi2 - minimum) / minimum;
        eprintln!(
            "{file}: χ² {:.6} from the {used:?} start; best known {minimum}",
            summary.final_chi2
        );
        let within = if exact { gap.abs() } else { gap };
        assert!(
            within <= 1e-4,
            "{file}: χ² {} vs {minimum}",
            summary.final_chi2
        );
    }
}

#[test]
fn levenberg_marquardt_is_not_held_back_on_a_long_chain() {
    // ais2klinik is a chain of 15,115 poses: its softest modes have about
    // 1/n² ≈ 4e-9 of the diagonal's curvature, so a first λ of 1e-9 damped
    // them and LM crawled (12 iterations to 173.12 under the peers' 1e-5
    // rule). Gauss-Newton reaches the MANIFEST's minimum in 6 iterations,
    // and so must LM.
    let Some(path) = common::dataset("2d/ais2klinik.g2o") else {
        return;
    };
    let (mut graph, _) = read_file(&path, &ReadOptions::default()).unwrap();
    let config = SolverConfig {
        relative_decrease: 1e-5,
        ..common::lm_config(LevenbergMarquardtConfig::default().nonmonotonic_steps)
    };
    let s = optimize(&mut graph, config).unwrap();
    let minimum = 172.815579;
    eprintln!(
        "ais2klinik lm: χ² {} after {} it",
        s.final_chi2, s.iterations
    );
    assert!(
        ((s.final_chi2 - minimum) / minimum).abs() <= 1e-6,
        "χ² {} misses the minimum {minimum}",
        s.final_chi2
    );
    assert!(s.iterations <= 8, "{} iterations", s.iterations);
}

#[test]
fn levenberg_marquardt_climbs_out_of_a_poor_start() {
    // input_INTEL_g2o's vertices are far off: Gauss-Newton's first step
    // raises χ² 31× on its way to the minimum (215.830235). A monotone LM
    // refuses that path and damps itself into χ² ≈ 1.3e4; non-monotonic
    // steps (the default) follow it down.
    let Some(path) = common::dataset("2d/input_INTEL_g2o.g2o") else {
        return;
    };
    let solve = |nonmonotonic_steps| {
        let (mut graph, _) = read_file(&path, &ReadOptions::default()).unwrap();
        optimize(&mut graph, common::lm_config(nonmonotonic_steps)).unwrap()
    };
    let s = solve(LevenbergMarquardtConfig::default().nonmonotonic_steps);
    let minimum = 215.830235;
    eprintln!(
        "input_INTEL_g2o lm: χ² {} after {} it",
        s.final_chi2, s.iterations
    );
    assert!(
        ((s.final_chi2 - minimum) / minimum).abs() <= 1e-6,
        "χ² {}",
        s.final_chi2
    );
    assert!(s.termination.converged(), "{:?}", s.termination);
    let monotone = solve(0);
    assert!(
        monotone.final_chi2 > 10.0 * minimum,
        "{}",
        monotone.final_chi2
    );
}

#[test]
fn non_monotonic_lm_converges_on_its_lowest_chi2() {
    // From its poor start, LM on sphere_bignoise_vertex3 can end circling
    // near its lowest χ², with steps that each change χ² by more than the
    // tolerance (760707.7 in 71 iterations under the peers' 1e-5 rule,
    // before the line search and the exponential SE3 update; now 743862.7
    // in 67). Converging when the lowest χ² improves by less than the
    // tolerance stops it there instead of circling until a step fails.
    let Some(path) = common::dataset("3d/sphere_bignoise_vertex3.g2o") else {
        return;
    };
    let (mut graph, _) = read_file(&path, &ReadOptions::default()).unwrap();
    let config = SolverConfig {
        relative_decrease: 1e-5,
        ..common::lm_config(5)
    };
    let s = optimize(&mut graph, config).unwrap();
    let last = s.trace.last().map_or(s.initial_chi2, |t| t.chi2);
    eprintln!(
        "sphere_bignoise lm: χ² {} after {} it, {:?}",
        s.final_chi2, s.iterations, s.termination
    );
    assert_eq!(s.termination, Termination::RelativeDecrease);
    assert_eq!(last, s.final_chi2, "it stopped above its lowest χ²");
    assert!(s.final_chi2 < 7.61e5, "{}", s.final_chi2);
    assert!(s.iterations <= 75, "{} iterations", s.iterations);
}

#[test]
fn gauss_newton_keeps_the_rotation_of_large_se3_steps() {
    // From their files' poor starts, Gauss-Newton proposes thousands of SE3
    // steps whose compact quaternion has norm above one. g2o's update drops
    // their rotation, and its GN stalls: torus3D at χ² 45561, and
    // sphere_bignoise still at 764298 when it reaches the 100-iteration cap
    // (Cairn's, with the same update: 849848). The exponential update keeps
    // them, and GN converges: torus3D to 19973.6 (the minimum LM reaches
    // too), sphere_bignoise to its best-known minimum.
    for (file, below, minimum) in [
        ("3d/torus3D.g2o", 2.0e4, None),
        ("3d/sphere_bignoise_vertex3.g2o", 7.44e5, Some(743862.7209)),
    ] {
        let Some(path) = common::dataset(file) else {
            return;
        };
        let (mut graph, _) = read_file(&path, &ReadOptions::default()).unwrap();
        let config = SolverConfig {
            relative_decrease: 1e-5,
            ..SolverConfig::default()
        };
        let s = optimize(&mut graph, config).unwrap();
        eprintln!("{file} gn: χ² {} after {} it", s.final_chi2, s.iterations);
        assert_eq!(s.termination, Termination::RelativeDecrease, "{file}");
        assert!(s.final_chi2 < below, "{file}: χ² {}", s.final_chi2);
        if let Some(m) = minimum {
            assert!(
                ((s.final_chi2 - m) / m).abs() <= 1e-6,
                "{file}: χ² {}",
                s.final_chi2
            );
        }
    }
}

/// The default start costs one run where Gauss-Newton converges quickly
/// from the file's vertices: no chordal start is solved, and the minimum
/// is the MANIFEST's.
#[test]
fn the_default_start_is_one_run_where_the_file_converges_quickly() {
    use cairn::solvers::{AUTO_TRUSTED_ITERATIONS, Optimizer};
    let cases = [
        ("2d/city10000.g2o", 511.985164),
        ("2d/ais2klinik.g2o", 172.815579),
        ("2d/manhattanOlson3500.g2o", 146.076613),
        ("3d/sphere2500.g2o", 727.149667),
        ("3d/parking-garage.g2o", 1.238691),
    ];
    for (file, minimum) in cases {
        let Some(path) = common::dataset(file) else {
            return;
        };
        let (mut graph, _) = read_file(&path, &ReadOptions::default()).unwrap();
        let mut optimizer = Optimizer::new(&graph, SolverConfig::default()).unwrap();
        let mut iterations = 0;
        let summary = optimizer
            .optimize_with(&mut graph, &mut |s| {
                assert_eq!(s.start, Initialization::File, "{file}");
                iterations += 1;
            })
            .unwrap();
        assert_eq!(summary.init, Initialization::File, "{file}");
        assert_eq!(iterations, summary.iterations, "{file}");
        assert!(summary.iterations <= AUTO_TRUSTED_ITERATIONS, "{file}");
        assert!(
            (summary.final_chi2 - minimum).abs() <= 1e-6 * minimum.max(1.0),
            "{file}: χ² {} vs {minimum}",
            summary.final_chi2
        );
    }
}
