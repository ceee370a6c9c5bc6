//! Synthetic pose graphs with known structure: a 2D Manhattan world and a 3D
//! sphere, like the classic benchmark files. Measurements are the true relative
//! poses plus Gaussian noise; the initial estimate chains the noisy odometry,
//! as a robot's dead reckoning would.

use cairn_core::se3::quaternion_from_vector;
use cairn_core::{EdgeSE2, EdgeSE3, Graph, GraphError, SE2, SE3};
use nalgebra::{Matrix3, Matrix6, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI};

/// Options of [`manhattan`].
#[derive(Clone, Debug, PartialEq)]
pub struct ManhattanOptions {
    /// Number of poses.
    pub poses: usize,
    /// Side of the square world in grid steps of 1 m.
    pub size: i64,
    /// Chance of turning at each step.
    pub turn_probability: f64,
    /// Chance that revisiting a grid point adds a loop closure.
    pub loop_probability: f64,
    /// Translation noise σ (m).
    pub sigma_translation: f64,
    /// Rotation noise σ (rad).
    pub sigma_rotation: f64,
    /// Random seed.
    pub seed: u64,
}

impl Default for ManhattanOptions {
    fn default() -> Self {
        Self {
            poses: 500,
            size: 20,
            turn_probability: 0.2,
            loop_probability: 0.5,
            sigma_translation: 0.05,
            sigma_rotation: 0.01,
            seed: 1,
        }
    }
}

/// A zero-mean Gaussian sample with standard deviation `sigma`.
fn gauss(rng: &mut StdRng, sigma: f64) -> f64 {
    let n: f64 = rng.sample(StandardNormal);
    n * sigma
}

fn noisy_se2(rng: &mut StdRng, truth: &SE2, st: f64, sr: f64) -> SE2 {
    SE2::new(
        truth.t.x + gauss(rng, st),
        truth.t.y + gauss(rng, st),
        truth.theta + gauss(rng, sr),
    )
}

/// A robot driving a grid of 1 m streets, turning at random and closing loops
/// where it passes a point it visited before.
/// Fails only for noise σ ≤ 0 (the information matrix would not be finite).
pub fn manhattan(o: &ManhattanOptions) -> Result<Graph, GraphError> {
    let mut rng = StdRng::seed_from_u64(o.seed);
    let info = Matrix3::from_diagonal(&Vector3::new(
        1.0 / o.sigma_translation.powi(2),
        1.0 / o.sigma_translation.powi(2),
        1.0 / o.sigma_rotation.powi(2),
    ));
    let mut truth = vec![SE2::identity()];
    let (mut x, mut y, mut heading) = (0i64, 0i64, 0i64); // heading in quarter turns
    let mut visits: HashMap<(i64, i64), Vec<usize>> = HashMap::from([((0, 0), vec![0])]);
    let mut odometry = Vec::new();
    let mut closures = Vec::new();
    let half = o.size.max(2) / 2;
    while truth.len() < o.poses.max(1) {
        let mut turn = 0;
        if rng.random_bool(o.turn_probability.clamp(0.0, 1.0)) {
            turn = if rng.random_bool(0.5) { 1 } else { -1 };
        }
        let (dx, dy) = [(1, 0), (0, 1), (-1, 0), (0, -1)][(heading + turn).rem_euclid(4) as usize];
        if (x + dx).abs() > half || (y + dy).abs() > half {
            turn = if turn == 0 { 1 } else { -turn };
        }
        let new_heading = (heading + turn).rem_euclid(4);
        let (dx, dy) = [(1, 0), (0, 1), (-1, 0), (0, -1)][new_heading as usize];
        if (x + dx).abs() > half || (y + dy).abs() > half {
            heading = (heading + 2).rem_euclid(4); // dead end: turn around on the spot
            let prev = *truth.last().unwrap_or(&SE2::identity());
            truth.push(SE2::new(prev.t.x, prev.t.y, heading as f64 * FRAC_PI_2));
        } else {
            heading = new_heading;
            x += dx;
            y += dy;
            truth.push(SE2::new(x as f64, y as f64, heading as f64 * FRAC_PI_2));
        }
        let k = truth.len() - 1;
        odometry.push((k - 1, k));
        let seen = visits.entry((x, y)).or_default();
        if let Some(&earlier) = seen.first()
            && earlier + 2 < k
            && rng.random_bool(o.loop_probability.clamp(0.0, 1.0))
        {
            closures.push((earlier, k));
        }
        seen.push(k);
    }
    let mut graph = Graph::new();
    let mut estimate = SE2::identity();
    let measured: Vec<(usize, usize, SE2)> = odometry
        .iter()
        .chain(&closures)
        .map(|&(a, b)| {
            (
                a,
                b,
                noisy_se2(
                    &mut rng,
                    &truth[a].between(&truth[b]),
                    o.sigma_translation,
                    o.sigma_rotation,
                ),
            )
        })
        .collect();
    for k in 0..truth.len() {
        if k > 0 {
            estimate = estimate.compose(&measured[k - 1].2);
        }
        graph.add_vertex(k as i64, estimate)?;
    }
    for (a, b, z) in measured {
        graph.add_edge(a as i64, b as i64, EdgeSE2::new(z), info)?;
    }
    Ok(graph)
}

/// Options of [`sphere`].
#[derive(Clone, Debug, PartialEq)]
pub struct SphereOptions {
    /// Number of rings (latitudes).
    pub rings: usize,
    /// Poses per ring.
    pub poses_per_ring: usize,
    /// Radius (m).
    pub radius: f64,
    /// Translation noise σ (m).
    pub sigma_translation: f64,
    /// Rotation noise σ (rad).
    pub sigma_rotation: f64,
    /// Random seed.
    pub seed: u64,
}

impl Default for SphereOptions {
    fn default() -> Self {
        Self {
            rings: 20,
            poses_per_ring: 20,
            radius: 50.0,
            sigma_translation: 0.05,
            sigma_rotation: 0.01,
            seed: 1,
        }
    }
}

fn noisy_se3(rng: &mut StdRng, truth: &SE3, st: f64, sr: f64) -> SE3 {
    let dt = Vector3::new(gauss(rng, st), gauss(rng, st), gauss(rng, st));
    // g2o's quaternion-vector update has ‖v‖ ≈ θ/2.
    let dq = quaternion_from_vector(
        &(Vector3::new(gauss(rng, sr), gauss(rng, sr), gauss(rng, sr)) * 0.5),
    );
    truth.compose(&SE3::new(dt, dq))
}

/// A robot spiralling over a sphere ring by ring (like `sphere2500.g2o`), with
/// loop closures to the pose straight below on the previous ring.
/// Fails only for noise σ ≤ 0 (the information matrix would not be finite).
pub fn sphere(o: &SphereOptions) -> Result<Graph, GraphError> {
    let mut rng = StdRng::seed_from_u64(o.seed);
    let (rings, per) = (o.rings.max(1), o.poses_per_ring.max(1));
    let mut truth = Vec::with_capacity(rings * per);
    for r in 0..rings {
        let elevation = -FRAC_PI_2 + PI * (r as f64 + 1.0) / (rings as f64 + 1.0);
        for k in 0..per {
            let azimuth = 2.0 * PI * k as f64 / per as f64;
            let t = Vector3::new(
                azimuth.cos() * elevation.cos(),
                azimuth.sin() * elevation.cos(),
                elevation.sin(),
            ) * o.radius;
            let q = UnitQuaternion::from_euler_angles(0.0, -elevation, azimuth + FRAC_PI_2);
            truth.push(SE3::new(t, q));
        }
    }
    let mut info = Matrix6::identity() / o.sigma_translation.powi(2);
    for d in 3..6 {
        // Information on the quaternion vector part (≈ θ/2).
        info[(d, d)] = 4.0 / o.sigma_rotation.powi(2);
    }
    let mut pairs: Vec<(usize, usize)> = (1..truth.len()).map(|k| (k - 1, k)).collect();
    pairs.extend((per..truth.len()).map(|k| (k - per, k)));
    let measured: Vec<(usize, usize, SE3)> = pairs
        .into_iter()
        .map(|(a, b)| {
            (
                a,
                b,
                noisy_se3(
                    &mut rng,
                    &truth[a].between(&truth[b]),
                    o.sigma_translation,
                    o.sigma_rotation,
                ),
            )
        })
        .collect();
    let mut graph = Graph::new();
    let mut estimate = truth[0];
    for k in 0..truth.len() {
        if k > 0 {
            estimate = estimate.compose(&measured[k - 1].2);
        }
        graph.add_vertex(k as i64, estimate)?;
    }
    for (a, b, z) in measured {
        graph.add_edge(a as i64, b as i64, EdgeSE3::new(z), info)?;
    }
    Ok(graph)
}
