//! Graphs the solver tests share.

use cairn_core::{EdgeSE2, Graph, SE2};
use nalgebra::Matrix3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// A noisy loop of `n` poses with odometry and loop closures.
pub fn noisy_loop(n: i64, seed: u64) -> Graph {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut g = Graph::new();
    let step = SE2::new(1.0, 0.0, 2.0 * std::f64::consts::PI / n as f64);
    let mut truth = SE2::identity();
    for i in 0..n {
        let noise = SE2::new(
            rng.random_range(-0.3..0.3),
            rng.random_range(-0.3..0.3),
            rng.random_range(-0.1..0.1),
        );
        g.add_vertex(i, truth.compose(&noise)).unwrap();
        truth = truth.compose(&step);
    }
    let info = Matrix3::from_diagonal(&nalgebra::Vector3::new(100.0, 100.0, 1000.0));
    for i in 0..n {
        g.add_edge(i, (i + 1) % n, EdgeSE2::new(step), info)
            .unwrap();
        if i + 3 < n {
            g.add_edge(
                i,
                i + 3,
                EdgeSE2::new(step.compose(&step).compose(&step)),
                info,
            )
            .unwrap();
        }
    }
    g
}
