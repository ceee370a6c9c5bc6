//! Property tests: the estimate does not depend on the scale of the
//! information, nor on the vertices' ids or the order they were added in.

use cairn_core::nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use cairn_core::{EdgeSE2, EdgeSE2XY, Graph, SE2};
use cairn_solvers::{Algorithm, Initialization, SolverConfig, optimize};
use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};

/// A pose graph with landmarks in plain arrays: vertex k is pose k below
/// `poses.len()`, landmark k − `poses.len()` above.
struct Problem {
    poses: Vec<SE2>,
    landmarks: Vec<Vector2<f64>>,
    odometry: Vec<(usize, usize, SE2, Matrix3<f64>)>,
    sightings: Vec<(usize, usize, Vector2<f64>, Matrix2<f64>)>,
}

/// An information matrix with these σ and a random correlation.
fn information3(rng: &mut StdRng, sigma: Vector3<f64>) -> Matrix3<f64> {
    let rho = rng.random_range(-0.5..0.5);
    let mut cov = Matrix3::from_diagonal(&sigma.component_mul(&sigma));
    cov[(0, 1)] = rho * sigma.x * sigma.y;
    cov[(1, 0)] = cov[(0, 1)];
    cov.try_inverse().unwrap()
}

/// A robot driving a noisy loop, seeing landmarks, closing loops; the
/// initial estimate integrates its noisy odometry.
fn problem(seed: u64, poses: usize, landmarks: usize) -> Problem {
    let mut rng = StdRng::seed_from_u64(seed);
    let step = SE2::new(1.0, 0.0, 2.0 * std::f64::consts::PI / poses as f64);
    let sigma = Vector3::new(0.05, 0.03, 0.02);
    let noisy = |rng: &mut StdRng, z: SE2| {
        z.compose(&SE2::new(
            rng.random_range(-2.0..2.0) * sigma.x,
            rng.random_range(-2.0..2.0) * sigma.y,
            rng.random_range(-2.0..2.0) * sigma.z,
        ))
    };
    let truth: Vec<SE2> = (0..poses)
        .scan(SE2::identity(), |pose, _| {
            let here = *pose;
            *pose = pose.compose(&step);
            Some(here)
        })
        .collect();
    let marks: Vec<Vector2<f64>> = (0..landmarks)
        .map(|_| Vector2::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)))
        .collect();
    let mut p = Problem {
        poses: vec![SE2::identity()],
        landmarks: vec![Vector2::zeros(); landmarks],
        odometry: Vec::new(),
        sightings: Vec::new(),
    };
    let link = |rng: &mut StdRng, p: &mut Problem, i: usize, j: usize| {
        let z = noisy(rng, truth[i].inverse().compose(&truth[j]));
        p.odometry.push((i, j, z, information3(rng, sigma)));
        z
    };
    for i in 1..poses {
        let z = link(&mut rng, &mut p, i - 1, i);
        let previous = p.poses[i - 1];
        p.poses.push(previous.compose(&z));
    }
    for _ in 0..poses / 4 {
        let (i, j) = (rng.random_range(0..poses), rng.random_range(0..poses));
        if i != j {
            link(&mut rng, &mut p, i, j);
        }
    }
    for (l, mark) in marks.iter().enumerate() {
        for _ in 0..3 {
            let i = rng.random_range(0..poses);
            let local = truth[i].inverse().transform_point(mark);
            let z =
                local + Vector2::new(rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05));
            p.sightings.push((i, l, z, Matrix2::identity() * 400.0));
            p.landmarks[l] = p.poses[i].transform_point(&z);
        }
    }
    p
}

/// The problem as a graph: vertex k gets id `ids[k]`, vertices are added
/// in `order`, all information is × `scale`, and pose 0 is held.
fn graph(p: &Problem, ids: &[i64], order: &[usize], scale: f64) -> Graph {
    let mut g = Graph::new();
    for &k in order {
        if k < p.poses.len() {
            g.add_vertex(ids[k], p.poses[k]).unwrap();
        } else {
            g.add_vertex(ids[k], p.landmarks[k - p.poses.len()])
                .unwrap();
        }
    }
    for &(i, j, z, info) in &p.odometry {
        g.add_edge(ids[i], ids[j], EdgeSE2::new(z), info * scale)
            .unwrap();
    }
    for &(i, l, z, info) in &p.sightings {
        let l = ids[p.poses.len() + l];
        g.add_edge(ids[i], l, EdgeSE2XY::new(z), info * scale)
            .unwrap();
    }
    g.set_fixed(ids[0], true).unwrap();
    g
}

/// Solves and returns χ² and the estimate in the problem's vertex order.
fn solve(
    p: &Problem,
    g: &mut Graph,
    ids: &[i64],
    algorithm: Algorithm,
    init: Initialization,
) -> (f64, Vec<f64>) {
    let config = SolverConfig {
        algorithm,
        init,
        ..Default::default()
    };
    let summary = optimize(g, config).unwrap();
    let mut estimate = Vec::new();
    for (k, &id) in ids.iter().enumerate() {
        if k < p.poses.len() {
            let x: SE2 = g.value(id).unwrap();
            estimate.extend([x.t.x, x.t.y, x.theta]);
        } else {
            let l: Vector2<f64> = g.value(id).unwrap();
            estimate.extend([l.x, l.y]);
        }
    }
    (summary.final_chi2, estimate)
}

fn assert_same(a: &(f64, Vec<f64>), b: &(f64, Vec<f64>), scale: f64) {
    let (chi2_a, chi2_b) = (a.0, b.0 / scale);
    assert!(
        (chi2_a - chi2_b).abs() <= 1e-6 * chi2_a.max(1e-12),
        "χ² {chi2_a} against {chi2_b} (rescaled)"
    );
    for (k, (x, y)) in a.1.iter().zip(&b.1).enumerate() {
        assert!(
            (x - y).abs() <= 1e-6 * (1.0 + x.abs()),
            "unknown {k}: {x} against {y}"
        );
    }
}

const ALGORITHMS: [Algorithm; 3] = [
    Algorithm::GaussNewton,
    Algorithm::LevenbergMarquardt,
    Algorithm::Dogleg,
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// All information × 10^k, k in [−12, 12]: the same estimate, χ² × 10^k,
    /// from the file and from the default starts.
    #[test]
    fn information_scale_does_not_change_the_estimate(
        seed in any::<u64>(),
        poses in 6usize..40,
        landmarks in 0usize..8,
        exponent in -12i32..=12,
    ) {
        let p = problem(seed, poses, landmarks);
        let n = poses + landmarks;
        let ids: Vec<i64> = (0..n as i64).collect();
        let order: Vec<usize> = (0..n).collect();
        let scale = 10f64.powi(exponent);
        for algorithm in ALGORITHMS {
            for init in [Initialization::File, Initialization::Auto] {
                let plain = solve(&p, &mut graph(&p, &ids, &order, 1.0), &ids, algorithm, init);
                let scaled = solve(&p, &mut graph(&p, &ids, &order, scale), &ids, algorithm, init);
                assert_same(&plain, &scaled, scale);
            }
        }
    }

    /// The vertices renamed by a random permutation of sparse ids and added
    /// in a random order: the same estimate.
    #[test]
    fn ids_and_order_do_not_change_the_estimate(
        seed in any::<u64>(),
        poses in 6usize..40,
        landmarks in 0usize..8,
    ) {
        let p = problem(seed, poses, landmarks);
        let n = poses + landmarks;
        let ids: Vec<i64> = (0..n as i64).collect();
        let order: Vec<usize> = (0..n).collect();
        let mut rng = StdRng::seed_from_u64(seed ^ 0x5eed);
        let mut renamed: Vec<i64> = (0..n as i64).map(|k| 7 * k + 3).collect();
        renamed.shuffle(&mut rng);
        let mut shuffled = order.clone();
        shuffled.shuffle(&mut rng);
        for algorithm in ALGORITHMS {
            let plain = solve(&p, &mut graph(&p, &ids, &order, 1.0), &ids, algorithm, Initialization::File);
            let permuted = solve(&p, &mut graph(&p, &renamed, &shuffled, 1.0), &renamed, algorithm, Initialization::File);
            assert_same(&plain, &permuted, 1.0);
        }
    }
}
