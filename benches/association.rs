//! Micro-benchmarks of data association on a dense synthetic scan (no files
//! needed): 40 cones in view, 1.5 m apart along both boundaries and a
//! stretch of track beside them as on the EUFS tracks, seen through a pose
//! 0.3 m and 1° off. Each method chooses
//! among the same candidates; JCBB runs on both of its joint tests, the
//! rank-3 one graph SLAM uses and the general one EKF-SLAM uses.
//! `cargo bench --bench association`.

use cairn::slam::frontend::association::{
    AssociationMethod, Candidates, Correlation, Pair, associate,
};
use cairn::slam::frontend::chi2_99;
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Matrix2, Matrix3, SMatrix, Vector2, Vector3};
use rand::{Rng, SeedableRng, rngs::StdRng};
use std::hint::black_box;

/// The candidates of a dense scan and the pose covariance that correlates them.
fn dense_scan() -> (Candidates, Matrix3<f64>) {
    let mut rng = StdRng::seed_from_u64(1);
    let pose_cov = Matrix3::from_diagonal(&Vector3::new(0.09, 0.09, 3e-4));
    // The car's frame: boundaries 1.5 m either side and the next stretch's
    // 6 m away, cones every 1.5 m up to 15 m ahead.
    let landmarks: Vec<Vector2<f64>> = (1..=10)
        .flat_map(|k| {
            let x = 1.5 * f64::from(k);
            [-6.0, -1.5, 1.5, 6.0].map(|y| Vector2::new(x, y))
        })
        .collect();
    let (error, turn) = (Vector2::new(0.2, -0.2), 1f64.to_radians());
    let rotation = nalgebra::Rotation2::new(turn);
    let landmark_cov = Matrix2::identity() * 0.01;
    let candidates = landmarks
        .iter()
        .map(|m| {
            let r = Matrix2::identity() * (0.05 + 0.01 * m.norm()).powi(2);
            let seen = rotation * m
                + error
                + Vector2::new(rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05));
            let mut pairs: Vec<Pair> = landmarks
                .iter()
                .enumerate()
                .filter_map(|(l, other)| {
                    let h_pose = SMatrix::<f64, 2, 3>::new(
                        -1.0, 0.0, other.y, //
                        0.0, -1.0, -other.x,
                    );
                    Pair::new(
                        l,
                        seen - other,
                        h_pose,
                        &r,
                        &landmark_cov,
                        &pose_cov,
                        0.0,
                        25.0,
                    )
                })
                .filter(|p| p.d2 <= 13.8)
                .collect();
            pairs.sort_by(|a, b| a.d2.total_cmp(&b.d2));
            pairs
        })
        .collect();
    (candidates, pose_cov)
}

fn methods(c: &mut Criterion) {
    let (candidates, pose_cov) = dense_scan();
    let tracked = vec![None; candidates.len()];
    let gate = |pairs: usize| chi2_99(2 * pairs);
    let through = |a: &Pair, b: &Pair| a.h_pose * pose_cov * b.h_pose.transpose();
    let mut group = c.benchmark_group("dense-scan-40");
    for method in AssociationMethod::ALL {
        group.bench_function(method.name(), |b| {
            b.iter(|| {
                associate(
                    method,
                    black_box(&candidates),
                    &tracked,
                    gate,
                    Correlation::ThroughPose(&pose_cov),
                )
            })
        });
    }
    group.bench_function("jcbb-general", |b| {
        b.iter(|| {
            associate(
                AssociationMethod::Jcbb,
                black_box(&candidates),
                &tracked,
                gate,
                Correlation::General(&through),
            )
        })
    });
    group.finish();
}

criterion_group!(benches, methods);
criterion_main!(benches);
