//! The yaw-rate bias and the scan latency in the full optimisation: a pose
//! that carries the gyro's bias and how late the scans are stamped,
//! odometry that takes the bias out of its turn, sightings taken where the
//! car was when the scan was measured, and the prior on the first pose.

use super::edges::OdometryEdge;
use crate::motion::with_heading_variance;
use cairn_core::edge::Linearized;
use cairn_core::{BinaryEdge, EdgeSE2, EdgeSE2XY, SE2, UnaryEdge, Variable};
use nalgebra::{Matrix2, Matrix3, Matrix5, SMatrix, SVector, Vector2, Vector3, Vector5};

/// A pose, the yaw-rate bias at that time (rad/s) and how much older than
/// the config's `scan_latency` the scans are (s). A lap's odometry pins the
/// bias only together with the landmarks: the heading a loop closure
/// corrects is the bias times the lap's duration, so the full optimisation
/// can weigh the integrated yaw rate by its white noise alone instead of a
/// σ wide enough to cover an unknown bias. The latency shows where the car
/// changes speed or turns: a cone seen at 3 and at 8 m/s from poses 50 ms
/// off lands 0.25 m apart.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PoseBias {
    pub(crate) pose: SE2,
    pub(crate) bias: f64,
    pub(crate) latency: f64,
}

impl Variable<5> for PoseBias {
    const PARAMS: usize = 5;
    const NAME: &'static str = "SE2_YAW_BIAS_LATENCY";
    const IS_POSE: bool = true;

    fn from_params(p: &[f64]) -> Self {
        Self {
            pose: SE2::new(p[0], p[1], p[2]),
            bias: p[3],
            latency: p[4],
        }
    }
    fn write_params(&self, out: &mut [f64]) {
        self.pose.write_params(out);
        out[3] = self.bias;
        out[4] = self.latency;
    }
    fn oplus(&self, d: &Vector5<f64>) -> Self {
        Self {
            pose: self.pose.oplus(&d.fixed_rows::<3>(0).into_owned()),
            bias: self.bias + d[3],
            latency: self.latency + d[4],
        }
    }
}

/// How far the scan latency may wander (s/√s): next to not at all (a
/// pipeline's delay is a constant of it), yet each pose keeps its own so
/// that the graph stays a chain.
const LATENCY_WALK: f64 = 1e-4;

/// Odometry between two keyframes with the bias taken out: the measured
/// heading change less (bias − the bias the integration assumed)·dt, the
/// bias's random walk and the latency's.
#[derive(Clone, Debug)]
pub(crate) struct OdometryBias {
    delta: SE2,
    dt: f64,
    bias_used: f64,
}

impl OdometryBias {
    /// The edge of `o` and its information: the smoother's for position,
    /// the yaw rate's white noise for heading (the position–heading
    /// correlation kept), the bias's random walk of `walk` rad/s/√s and
    /// the latency's of [`LATENCY_WALK`].
    pub(crate) fn new(o: &OdometryEdge, walk: f64) -> (Self, Matrix5<f64>) {
        let cov: Matrix3<f64> = o.information.try_inverse().unwrap_or_else(Matrix3::zeros);
        let cov = with_heading_variance(&cov, o.heading_variance);
        let info3 = cov.try_inverse().unwrap_or(o.information);
        let mut info = Matrix5::zeros();
        info.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(0.5 * (info3 + info3.transpose())));
        info[(3, 3)] = 1.0 / (walk * walk * o.dt.max(1e-3)).max(1e-30);
        info[(4, 4)] = 1.0 / (LATENCY_WALK * LATENCY_WALK * o.dt.max(1e-3));
        (Self::edge(o), info)
    }

    /// The edge of `o` alone.
    pub(crate) fn edge(o: &OdometryEdge) -> Self {
        Self {
            delta: o.delta,
            dt: o.dt,
            bias_used: o.yaw_rate_bias,
        }
    }
}

impl BinaryEdge<5, 5, 5> for OdometryBias {
    type V1 = PoseBias;
    type V2 = PoseBias;
    const NAME: &'static str = "EDGE_SE2_YAW_BIAS";

    fn error(&self, a: &PoseBias, b: &PoseBias) -> Vector5<f64> {
        let e = EdgeSE2::new(self.corrected(a)).error(&a.pose, &b.pose);
        Vector5::new(e.x, e.y, e.z, b.bias - a.bias, b.latency - a.latency)
    }

    fn jacobians(&self, a: &PoseBias, b: &PoseBias) -> (Matrix5<f64>, Matrix5<f64>) {
        let delta = self.corrected(a);
        let (ji, jj) = EdgeSE2::new(delta).jacobians(&a.pose, &b.pose);
        // e = (R(turn)ᵀ (Rₐᵀ(t_b − t_a) − Δt), θ_b − θ_a − turn) and
        // turn = Δθ + (bias_used − bias_a)·dt.
        let p = a.pose.rotation().transpose() * (b.pose.t - a.pose.t) - delta.t;
        let (s, c) = delta.theta.sin_cos();
        let d_rt = Matrix2::new(-s, c, -c, -s);
        let de_dturn = d_rt * p;
        let mut j1 = Matrix5::zeros();
        j1.fixed_view_mut::<3, 3>(0, 0).copy_from(&ji);
        j1[(0, 3)] = -self.dt * de_dturn.x;
        j1[(1, 3)] = -self.dt * de_dturn.y;
        j1[(2, 3)] = self.dt;
        j1[(3, 3)] = -1.0;
        j1[(4, 4)] = -1.0;
        let mut j2 = Matrix5::zeros();
        j2.fixed_view_mut::<3, 3>(0, 0).copy_from(&jj);
        j2[(3, 3)] = 1.0;
        j2[(4, 4)] = 1.0;
        (j1, j2)
    }
}

impl OdometryBias {
    /// ∂ of the error's pose part with respect to the sideslip, from `a`,
    /// where `slip_jacobian` is that of the measured motion's translation:
    /// the error subtracts the motion, turned back by the corrected turn.
    pub(crate) fn sideslip_jacobian(
        &self,
        a: &PoseBias,
        slip_jacobian: &Vector2<f64>,
    ) -> Vector3<f64> {
        let back = self.corrected(a).rotation().transpose() * slip_jacobian;
        Vector3::new(-back.x, -back.y, 0.0)
    }

    /// The measured motion with the bias of `a` taken out of its turn.
    fn corrected(&self, a: &PoseBias) -> SE2 {
        let turn = self.delta.theta + (self.bias_used - a.bias) * self.dt;
        SE2::new(self.delta.t.x, self.delta.t.y, turn)
    }
}

/// A landmark sighting from a [`PoseBias`], taken `latency` seconds before
/// the pose, while the car moved at `speed` (m/s) and turned at `yaw_rate`
/// (rad/s); the bias plays no part. Zero speeds leave the latency out.
#[derive(Clone, Debug)]
pub(crate) struct SightingBias {
    pub(crate) sighting: EdgeSE2XY,
    pub(crate) speed: f64,
    pub(crate) yaw_rate: f64,
}

impl BinaryEdge<2, 5, 2> for SightingBias {
    type V1 = PoseBias;
    type V2 = Vector2<f64>;
    const NAME: &'static str = "EDGE_SE2_YAW_BIAS_LATENCY_XY";

    fn error(&self, x: &PoseBias, l: &Vector2<f64>) -> Vector2<f64> {
        self.linearize(x, l).0
    }

    fn jacobians(&self, x: &PoseBias, l: &Vector2<f64>) -> (SMatrix<f64, 2, 5>, Matrix2<f64>) {
        let (_, jx, jl) = self.linearize(x, l);
        (jx, jl)
    }

    /// The landmark q in the pose's frame, as the car saw it τ earlier,
    /// from (−vτ, 0) turned by −ωτ: R(ωτ)·(q + (vτ, 0)).
    fn linearize(&self, x: &PoseBias, l: &Vector2<f64>) -> Linearized<2, 5, 2> {
        let z = *self.sighting.measurement();
        let (e, jx, jl) = self.sighting.linearize(&x.pose, l);
        let turn = SE2::new(0.0, 0.0, self.yaw_rate * x.latency).rotation();
        let moved = e + z + Vector2::new(self.speed * x.latency, 0.0);
        let mut j = SMatrix::<f64, 2, 5>::zeros();
        j.fixed_view_mut::<2, 3>(0, 0).copy_from(&(turn * jx));
        // d/dτ: the turn's derivative ω·S·R (S the quarter turn) and the
        // travel's R·(v, 0).
        let quarter = Matrix2::new(0.0, -1.0, 1.0, 0.0);
        let d = self.yaw_rate * quarter * turn * moved + turn * Vector2::new(self.speed, 0.0);
        j.set_column(4, &d);
        (turn * moved - z, j, turn * jl)
    }
}

/// The first pose where the log started it, and weak priors on its bias
/// (the lap decides the bias) and on the scans being no later than the
/// config says ([`LATENCY_PRIOR`]).
#[derive(Clone, Debug)]
pub(crate) struct StartPrior(pub(crate) PoseBias);

impl StartPrior {
    pub(crate) fn information() -> Matrix5<f64> {
        let latency = 1.0 / (LATENCY_PRIOR * LATENCY_PRIOR);
        Matrix5::from_diagonal(&Vector5::new(1e8, 1e8, 1e8, 1e2, latency))
    }
}

/// σ of the prior on the extra scan latency (s): a detector pipeline is
/// typically 20–100 ms late, so this leaves such values to the data.
const LATENCY_PRIOR: f64 = 0.1;

impl UnaryEdge<5, 5> for StartPrior {
    type V = PoseBias;
    const NAME: &'static str = "EDGE_PRIOR_SE2_YAW_BIAS";

    fn error(&self, x: &PoseBias) -> SVector<f64, 5> {
        let d = x.pose.t - self.0.pose.t;
        let turn = cairn_core::se2::normalize_angle(x.pose.theta - self.0.pose.theta);
        let late = x.latency - self.0.latency;
        Vector5::new(d.x, d.y, turn, x.bias - self.0.bias, late)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cairn_core::edge::numeric_binary;
    use rand::{Rng, SeedableRng, rngs::StdRng};

    fn random_pose(rng: &mut StdRng) -> PoseBias {
        PoseBias {
            pose: SE2::new(
                rng.random_range(-20.0..20.0),
                rng.random_range(-20.0..20.0),
                rng.random_range(-3.0..3.0),
            ),
            bias: rng.random_range(-0.01..0.01),
            latency: rng.random_range(-0.1..0.1),
        }
    }

    #[test]
    fn the_sighting_jacobian_matches_central_differences_and_ignores_the_bias() {
        let mut rng = StdRng::seed_from_u64(7);
        for _ in 0..200 {
            let x = random_pose(&mut rng);
            let l = Vector2::new(rng.random_range(-20.0..20.0), rng.random_range(-20.0..20.0));
            let edge = SightingBias {
                sighting: EdgeSE2XY::new(Vector2::new(
                    rng.random_range(0.0..15.0),
                    rng.random_range(-5.0..5.0),
                )),
                speed: rng.random_range(0.0..10.0),
                yaw_rate: rng.random_range(-1.0..1.0),
            };
            let (jx, jl) = edge.jacobians(&x, &l);
            let (nx, nl) = numeric_binary(&edge, &x, &l);
            assert!((jx - nx).amax() < 1e-6, "{jx} vs {nx}");
            assert!((jl - nl).amax() < 1e-6, "{jl} vs {nl}");
            assert_eq!(jx.column(3).amax(), 0.0);
        }
    }

    #[test]
    fn a_late_sighting_is_taken_where_the_car_was_when_it_was_measured() {
        // The car drives at 6 m/s turning at 0.5 rad/s; the scan stamped at
        // pose x was measured 0.05 s before, at the pose the motion then
        // leads back to.
        let (speed, yaw_rate, late) = (6.0, 0.5, 0.05);
        let x = SE2::new(3.0, -1.0, 0.7);
        let earlier = x.compose(&crate::motion::integrate(
            &SE2::identity(),
            -speed,
            -yaw_rate,
            late,
        ));
        let landmark = Vector2::new(10.0, 4.0);
        let z = earlier.inverse().transform_point(&landmark);
        let edge = SightingBias {
            sighting: EdgeSE2XY::new(z),
            speed,
            yaw_rate,
        };
        let at = |latency| PoseBias {
            pose: x,
            bias: 0.0,
            latency,
        };
        // Exact but for the arc's sideways part, vωτ²/2 (4 mm).
        let e = edge.error(&at(late), &landmark).norm();
        assert!(e < 5e-3, "{e}");
        assert!(edge.error(&at(0.0), &landmark).norm() > 0.25);
        // Standing still, the latency plays no part.
        let still = SightingBias {
            sighting: EdgeSE2XY::new(x.inverse().transform_point(&landmark)),
            speed: 0.0,
            yaw_rate: 0.0,
        };
        assert!(still.error(&at(late), &landmark).norm() < 1e-12);
    }

    #[test]
    fn the_odometry_jacobians_match_central_differences() {
        let mut rng = StdRng::seed_from_u64(8);
        for _ in 0..200 {
            let a = random_pose(&mut rng);
            let b = random_pose(&mut rng);
            let edge = OdometryBias {
                delta: SE2::new(
                    rng.random_range(0.0..1.0),
                    rng.random_range(-0.1..0.1),
                    rng.random_range(-0.3..0.3),
                ),
                dt: rng.random_range(0.05..0.2),
                bias_used: rng.random_range(-0.01..0.01),
            };
            let (j1, j2) = edge.jacobians(&a, &b);
            let (n1, n2) = numeric_binary(&edge, &a, &b);
            assert!((j1 - n1).amax() < 1e-6, "{j1} vs {n1}");
            assert!((j2 - n2).amax() < 1e-6, "{j2} vs {n2}");
        }
    }

    #[test]
    fn the_sideslip_jacobian_is_the_errors_derivative() {
        let mut rng = StdRng::seed_from_u64(9);
        for _ in 0..20 {
            let slip_jacobian =
                Vector2::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
            let o = OdometryEdge {
                delta: SE2::new(0.5, 0.02, rng.random_range(-0.2..0.2)),
                information: Matrix3::identity(),
                dt: 0.1,
                yaw_rate_bias: 0.001,
                heading_variance: 1e-8,
                slip_jacobian,
                slip_made: slip_jacobian * 0.004,
            };
            let a = PoseBias {
                pose: SE2::new(1.0, -2.0, rng.random_range(-3.0..3.0)),
                bias: 0.003,
                latency: 0.0,
            };
            let b = PoseBias {
                pose: a.pose.compose(&SE2::new(0.45, 0.05, 0.1)),
                ..a
            };
            let error = |slip: f64| {
                let delta = o.with_sideslip(slip);
                OdometryBias::edge(&OdometryEdge { delta, ..o }).error(&a, &b)
            };
            let (slip, h) = (0.01, 1e-6);
            let numeric = (error(slip + h) - error(slip - h)) / (2.0 * h);
            let edge = OdometryBias::edge(&OdometryEdge {
                delta: o.with_sideslip(slip),
                ..o
            });
            let analytic = edge.sideslip_jacobian(&a, &slip_jacobian);
            assert!(
                (analytic - numeric.fixed_rows::<3>(0)).amax() < 1e-6,
                "{analytic} vs {numeric}"
            );
            assert_eq!(numeric[3], 0.0);
        }
        // With the sideslip it was integrated with, the motion is as measured.
        let o = OdometryEdge {
            delta: SE2::new(0.5, 0.0, 0.1),
            information: Matrix3::identity(),
            dt: 0.1,
            yaw_rate_bias: 0.0,
            heading_variance: 1e-8,
            slip_jacobian: Vector2::new(0.0, 2.0),
            slip_made: Vector2::new(0.0, 0.02),
        };
        assert!((o.with_sideslip(0.01).t - o.delta.t).norm() < 1e-12);
    }

    #[test]
    fn odometry_takes_the_bias_out_of_the_heading() {
        let delta = SE2::new(0.5, 0.01, 0.05);
        let o = OdometryEdge {
            delta,
            information: Matrix3::identity() * 1e4,
            dt: 0.1,
            yaw_rate_bias: 0.001,
            heading_variance: 1e-8,
            slip_jacobian: Vector2::zeros(),
            slip_made: Vector2::zeros(),
        };
        let (edge, info) = OdometryBias::new(&o, 1e-5);
        let a = PoseBias {
            pose: SE2::new(1.0, 2.0, 0.3),
            bias: 0.003,
            latency: 0.0,
        };
        // The true turn is the measured one less (0.003 − 0.001)·0.1.
        let turned = SE2::new(delta.t.x, delta.t.y, delta.theta - 0.0002);
        let b = PoseBias {
            pose: a.pose.compose(&turned),
            bias: 0.003,
            latency: 0.0,
        };
        assert!(edge.error(&a, &b).amax() < 1e-12, "{}", edge.error(&a, &b));
        let drifted = PoseBias { bias: 0.004, ..b };
        assert!((edge.error(&a, &drifted)[3] - 0.001).abs() < 1e-12);
        // Heading weighed by the white noise, far tighter than the smoother's.
        let heading_sigma = 1.0 / info[(2, 2)].sqrt();
        assert!(heading_sigma < 2e-4, "{heading_sigma}");
        assert!(info.symmetric_eigen().eigenvalues.min() > 0.0);
    }

    #[test]
    fn chained_odometry_turns_like_its_edges_for_any_bias() {
        let mut rng = StdRng::seed_from_u64(4);
        for _ in 0..50 {
            let edges: Vec<OdometryEdge> = (0..4)
                .map(|_| OdometryEdge {
                    delta: SE2::new(
                        rng.random_range(0.3..0.7),
                        rng.random_range(-0.01..0.01),
                        rng.random_range(-0.2..0.2),
                    ),
                    information: Matrix3::from_diagonal(&nalgebra::Vector3::new(1e4, 1e6, 1e3)),
                    dt: rng.random_range(0.08..0.12),
                    yaw_rate_bias: rng.random_range(-0.003..0.003),
                    heading_variance: rng.random_range(1e-9..1e-8),
                    slip_jacobian: Vector2::zeros(),
                    slip_made: Vector2::zeros(),
                })
                .collect();
            let chain = OdometryEdge::chain(&edges);
            let dt: f64 = edges.iter().map(|e| e.dt).sum();
            assert!((chain.dt - dt).abs() < 1e-12);
            let var: f64 = edges.iter().map(|e| e.heading_variance).sum();
            assert!((chain.heading_variance - var).abs() < 1e-18);
            // Poses that follow every edge with its bias taken out.
            let bias = rng.random_range(-0.005..0.005);
            let mut pose = PoseBias {
                pose: SE2::new(1.0, -2.0, 0.4),
                bias,
                latency: 0.0,
            };
            let start = pose;
            for e in &edges {
                let (edge, _) = OdometryBias::new(e, 1e-5);
                pose.pose = pose.pose.compose(&edge.corrected(&pose));
            }
            let (edge, info) = OdometryBias::new(&chain, 1e-5);
            let error = edge.error(&start, &pose);
            // The turn exactly. The position to within the bias's turn times
            // the distance: single edges correct only the turn too.
            assert!(error[2].abs() < 1e-12, "{error}");
            let turn: f64 = edges
                .iter()
                .map(|e| (e.yaw_rate_bias - bias).abs() * e.dt)
                .sum();
            assert!(error.fixed_rows::<2>(0).norm() < turn * 2.8, "{error}");
            // Four edges' uncertainty: weaker than one edge, still positive.
            let cov = info.try_inverse().expect("positive definite");
            let one = OdometryBias::new(&edges[0], 1e-5)
                .1
                .try_inverse()
                .expect("positive definite");
            assert!((0..3).all(|i| cov[(i, i)] > one[(i, i)]), "{cov} vs {one}");
            assert!(info.symmetric_eigen().eigenvalues.min() > 0.0);
        }
        let single = OdometryEdge::chain(&[OdometryEdge {
            delta: SE2::new(0.5, 0.0, 0.1),
            information: Matrix3::identity(),
            dt: 0.1,
            yaw_rate_bias: 0.002,
            heading_variance: 1e-8,
            slip_jacobian: Vector2::zeros(),
            slip_made: Vector2::zeros(),
        }]);
        assert_eq!(single.information, Matrix3::identity());
    }
}
