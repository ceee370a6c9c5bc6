//! Robust kernels recover the clean optimum from graphs with random false loop
//! closures: DCS on the loop closures (g2o's -nonSequential), Gauss-Newton from
//! the file's own vertices, trajectory compared with the clean optimum.

mod common;

use cairn::core::{Graph, RobustKernel};
use cairn::g2o::{ReadOptions, read_file};
use cairn::outliers::{add_false_loop_closures, position_rms, set_robust_kernel};
use cairn::solvers::{SolverConfig, optimize};

fn on_loop_closures(graph: &mut Graph, kernel: RobustKernel) {
    set_robust_kernel(graph, kernel, true);
}

fn recovery(file: &str, fractions: &[f64]) -> Vec<(f64, f64, f64)> {
    let Some(path) = common::dataset(file) else {
        return Vec::new();
    };
    let (mut clean, _) = read_file(&path, &ReadOptions::default()).unwrap();
    optimize(&mut clean, SolverConfig::default()).unwrap();
    let mut out = Vec::new();
    for &fraction in fractions {
        let (mut g, _) = read_file(&path, &ReadOptions::default()).unwrap();
        add_false_loop_closures(&mut g, fraction, 10.0, 7).unwrap();
        let (mut plain, _) = read_file(&path, &ReadOptions::default()).unwrap();
        add_false_loop_closures(&mut plain, fraction, 10.0, 7).unwrap();
        on_loop_closures(&mut g, RobustKernel::Dcs(1.0));
        optimize(&mut g, SolverConfig::default()).unwrap();
        // Without a kernel: a few iterations show the damage.
        optimize(
            &mut plain,
            SolverConfig {
                max_iterations: 10,
                ..Default::default()
            },
        )
        .unwrap();
        let (robust, naive) = (
            position_rms(&clean, &g).unwrap(),
            position_rms(&clean, &plain).unwrap(),
        );
        eprintln!(
            "{file} with {:.0}% false loop closures: RMS {robust:.4} m with DCS, {naive:.3} m without",
            100.0 * fraction
        );
        out.push((fraction, robust, naive));
    }
    out
}

#[test]
fn dcs_recovers_manhattan_from_false_loop_closures() {
    for (fraction, robust, naive) in recovery("2d/manhattanOlson3500.g2o", &[0.01, 0.1, 0.5]) {
        assert!(robust < 0.05, "{fraction}: {robust} m");
        assert!(
            naive > 20.0 * robust,
            "{fraction}: the outliers must matter without a kernel"
        );
    }
}

#[test]
fn dcs_recovers_intel_from_false_loop_closures() {
    for (fraction, robust, _) in recovery("2d/intel.g2o", &[0.01, 0.1, 0.5]) {
        assert!(robust < 0.05, "{fraction}: {robust} m");
    }
}

#[test]
fn dcs_recovers_sphere2500_from_false_loop_closures() {
    for (fraction, robust, naive) in recovery("3d/sphere2500.g2o", &[0.1]) {
        assert!(robust < 0.05, "{fraction}: {robust} m");
        assert!(naive > 1.0, "{fraction}: {naive}");
    }
}

#[test]
fn kernels_change_chi2_to_rho_of_the_squared_error() {
    use cairn::core::{EdgeSE2, SE2};
    use nalgebra::Matrix3;
    let mut g = Graph::new();
    g.add_vertex(0, SE2::identity()).unwrap();
    g.add_vertex(1, SE2::new(4.0, 0.0, 0.0)).unwrap();
    g.add_edge(
        0,
        1,
        EdgeSE2::new(SE2::new(1.0, 0.0, 0.0)),
        Matrix3::identity(),
    )
    .unwrap();
    assert_eq!(g.chi2(), 9.0);
    for name in RobustKernel::NAMES {
        let k = RobustKernel::from_name(name, 1.0).unwrap();
        g.set_robust_kernel(0, Some(k));
        assert_eq!(g.chi2(), k.robustify(9.0)[0], "{name}");
        assert_eq!(g.edge(0).kernel(), Some(k));
    }
    g.set_robust_kernel(0, None);
    assert_eq!(g.chi2(), 9.0);
    assert!(!g.set_robust_kernel(5, None));
}
