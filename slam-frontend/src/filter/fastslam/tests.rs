use super::*;

/// The particles' sample covariance of (x, y, θ).
fn spread(slam: &FastSlam) -> Matrix3<f64> {
    let n = slam.particles.len() as f64;
    let mean = slam
        .particles
        .iter()
        .map(|p| p.pose.to_vector())
        .sum::<Vector3<f64>>()
        / n;
    slam.particles
        .iter()
        .map(|p| {
            let d = p.pose.to_vector() - mean;
            d * d.transpose()
        })
        .sum::<Matrix3<f64>>()
        / (n - 1.0)
}

#[test]
fn both_versions_spread_the_particles_as_the_motion_says_without_observations() {
    // With nothing observed, 2.0's proposal is the motion model, so both
    // versions must sample the same spread. (2.0 once scaled its standard
    // normal by the motion's Cholesky factor twice and barely spread.)
    let spreads = [Version::One, Version::Two].map(|version| {
        let settings = ParticleConfig {
            particles: 4000,
            ..ParticleConfig::new(version)
        };
        let mut slam = FastSlam::new(FrontEndConfig::default(), settings);
        slam.process(&Record::Cones {
            t: 0.0,
            cones: Vec::new(),
        });
        for k in 0..=50 {
            slam.process(&Record::Odom {
                t: k as f64 * 0.02,
                v: 5.0,
                yaw_rate: 0.2,
                steer: None,
                vy: None,
            });
        }
        slam.process(&Record::Cones {
            t: 1.0,
            cones: Vec::new(),
        });
        assert_eq!(slam.resamplings(), 0);
        spread(&slam)
    });
    for i in 0..3 {
        let ratio = spreads[1][(i, i)] / spreads[0][(i, i)];
        assert!(
            (0.85..1.15).contains(&ratio),
            "variance {i}: 2.0 / 1.0 = {ratio} ({spreads:?})"
        );
    }
    assert!(spreads[0][(2, 2)] > 1e-6, "{spreads:?}");
}
