//! What makes a simulated run realistic beyond Gaussian noise: heavy-tailed
//! noise, occlusion, speed profiles and sideslip.

use cairn_core::SE2;
use cairn_core::se2::normalize_angle;
use cairn_slam::motion::integrate;
use nalgebra::Vector2;
use rand::Rng;
use rand_distr::{ChiSquared, Distribution, StandardNormal};

/// Zero-mean noise of standard deviation σ: Gaussian, or Student-t with
/// `dof` degrees of freedom scaled to the same σ (heavy tails: at 3 dof, 1
/// draw in 72 lies beyond 3σ where a Gaussian has 1 in 370).
pub(super) struct Noise {
    sigma: f64,
    chi_squared: Option<(f64, ChiSquared<f64>)>,
}

impl Noise {
    /// σ clamped to [1e-300, f64::MAX] (a noise-free sensor or a bad σ still
    /// draws finite noise); `dof` (above 2) selects Student-t.
    pub(super) fn new(sigma: f64, dof: Option<f64>) -> Self {
        let sigma = if sigma.is_nan() {
            1e-300
        } else {
            sigma.clamp(1e-300, f64::MAX)
        };
        let chi_squared = dof
            .filter(|d| *d > 2.0 && d.is_finite())
            .and_then(|d| ChiSquared::new(d).ok().map(|c| (d, c)));
        Self { sigma, chi_squared }
    }

    /// Gaussian noise of σ (the same draws as `rand_distr::Normal`).
    pub(super) fn gaussian(sigma: f64) -> Self {
        Self::new(sigma, None)
    }
}

impl Distribution<f64> for Noise {
    fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        let z: f64 = rng.sample(StandardNormal);
        match &self.chi_squared {
            None => self.sigma * z,
            Some((dof, chi_squared)) => {
                // t = z / √(χ²/ν) has variance ν/(ν−2).
                let scale = ((dof - 2.0) / dof).sqrt();
                self.sigma * scale * z / (chi_squared.sample(rng) / dof).sqrt()
            }
        }
    }
}

/// A cone's base radius (m): what hides the objects behind it.
const CONE_RADIUS: f64 = 0.114;

/// Whether one of `others` (vehicle frame) stands nearer than `p` and in
/// front of its centre: `p`'s bearing within that cone's angular half-width.
pub(super) fn behind(p: &Vector2<f64>, others: &[Vector2<f64>]) -> bool {
    let (r, b) = (p.norm(), p.y.atan2(p.x));
    others.iter().any(|q| {
        let rq = q.norm();
        let db = normalize_angle(q.y.atan2(q.x) - b);
        rq < r && db.abs() < (CONE_RADIUS / rq.max(CONE_RADIUS)).atan()
    })
}

/// How fast the simulated car drives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpeedProfile {
    /// The configured speed throughout.
    Constant,
    /// As fast as the configured speed allows without exceeding the
    /// lateral acceleration on the path's curvature, braking and
    /// accelerating at most `longitudinal_acceleration`: slow in hairpins,
    /// fast on straights.
    Corners {
        /// Largest lateral acceleration (m/s²).
        lateral_acceleration: f64,
        /// Largest change of speed (m/s²).
        longitudinal_acceleration: f64,
    },
}

impl SpeedProfile {
    /// The speed after a step of `dt` from `speed`, with `top` the
    /// configured speed and `curvature` (1/m) the path's ahead.
    pub(super) fn next(&self, speed: f64, top: f64, curvature: f64, dt: f64) -> f64 {
        match *self {
            SpeedProfile::Constant => top,
            SpeedProfile::Corners {
                lateral_acceleration,
                longitudinal_acceleration,
            } => {
                let target = (lateral_acceleration / curvature.abs().max(1e-9))
                    .sqrt()
                    .min(top);
                let step = longitudinal_acceleration * dt;
                (speed + (target - speed).clamp(-step, step)).max(0.5_f64.min(top))
            }
        }
    }
}

/// The pose after `dt` at speed `v` and yaw rate `yaw_rate` with the
/// velocity `sideslip` (rad) off the heading: an arc of the same length,
/// turned by the sideslip.
pub(super) fn integrate_with_sideslip(
    pose: &SE2,
    v: f64,
    yaw_rate: f64,
    sideslip: f64,
    dt: f64,
) -> SE2 {
    if sideslip == 0.0 {
        return integrate(pose, v, yaw_rate, dt);
    }
    let turn = SE2::new(0.0, 0.0, sideslip);
    pose.compose(&turn)
        .compose(&integrate(&SE2::identity(), v, yaw_rate, dt))
        .compose(&turn.inverse())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::StdRng;

    #[test]
    fn student_t_noise_has_its_sigma_and_heavy_tails() {
        let mut rng = StdRng::seed_from_u64(1);
        let n = 400_000;
        let (gauss, t3) = (Noise::gaussian(0.1), Noise::new(0.1, Some(3.0)));
        let tail = |noise: &Noise, rng: &mut StdRng| {
            let draws: Vec<f64> = (0..n).map(|_| noise.sample(rng)).collect();
            let beyond = draws.iter().filter(|x| x.abs() > 0.3).count() as f64 / n as f64;
            let median_abs = {
                let mut a: Vec<f64> = draws.iter().map(|x| x.abs()).collect();
                a.sort_by(f64::total_cmp);
                a[n / 2]
            };
            (beyond, median_abs)
        };
        let (g_tail, g_median) = tail(&gauss, &mut rng);
        let (t_tail, t_median) = tail(&t3, &mut rng);
        // Gaussian: P(|x| > 3σ) = 0.27%, median |x| = 0.674σ. Student-t(3)
        // scaled to σ: P(|t| > 3√3) = 1.39%, median |x| = 0.765/√3 σ.
        assert!((g_tail - 0.0027).abs() < 0.0005, "{g_tail}");
        assert!((g_median - 0.0674).abs() < 0.001, "{g_median}");
        assert!((t_tail - 0.0139).abs() < 0.0015, "{t_tail}");
        assert!((t_median - 0.0442).abs() < 0.001, "{t_median}");
    }

    #[test]
    fn a_cone_behind_another_is_occluded() {
        let objects = [
            Vector2::new(5.0, 0.0),
            Vector2::new(10.0, 0.05),
            Vector2::new(10.0, 1.0),
        ];
        let hidden: Vec<bool> = objects.iter().map(|p| behind(p, &objects)).collect();
        assert_eq!(hidden, [false, true, false]);
    }

    #[test]
    fn the_corner_profile_slows_for_curves_and_keeps_its_acceleration() {
        let profile = SpeedProfile::Corners {
            lateral_acceleration: 4.0,
            longitudinal_acceleration: 2.0,
        };
        // A 4 m radius: at most 4 m/s; from 10 m/s braking 2 m/s² over 0.1 s.
        assert!((profile.next(10.0, 12.0, 0.25, 0.1) - 9.8).abs() < 1e-12);
        assert!((profile.next(4.05, 12.0, 0.25, 0.1) - 4.0).abs() < 1e-12);
        // A straight: up to the top speed.
        assert!((profile.next(11.9, 12.0, 0.0, 0.1) - 12.0).abs() < 1e-12);
        assert_eq!(SpeedProfile::Constant.next(3.0, 5.0, 1.0, 0.1), 5.0);
    }

    #[test]
    fn sideslip_turns_the_velocity_not_the_heading() {
        let pose = integrate_with_sideslip(&SE2::identity(), 2.0, 0.0, 0.1, 1.0);
        assert!((pose.theta).abs() < 1e-12);
        assert!((pose.t - Vector2::new(2.0 * 0.1f64.cos(), 2.0 * 0.1f64.sin())).norm() < 1e-12);
        let turning = integrate_with_sideslip(&SE2::identity(), 2.0, 0.5, 0.0, 1.0);
        assert_eq!(turning, integrate(&SE2::identity(), 2.0, 0.5, 1.0));
    }
}
