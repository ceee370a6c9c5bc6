use super::*;

fn cone_at(x: f64, y: f64) -> Cone {
    Cone {
        position: Vector2::new(x, y),
        color: Color::Yellow,
        covariance: nalgebra::Matrix2::zeros(),
    }
}

#[test]
fn only_the_later_of_overlapping_cones_is_hidden() {
    let cones = [
        cone_at(0.0, 0.0),
        cone_at(0.1, 0.0),
        cone_at(5.0, 0.0),
        cone_at(5.28, 0.0),
    ];
    // 0.28 m apart, like the big orange pairs: two cones.
    assert_eq!(hidden_by_overlap(&cones), [false, true, false, false]);
}

#[test]
fn a_cone_listed_twice_is_detected_as_one() {
    let (mut track, course) =
        crate::trackgen::random_track(3, &crate::trackgen::TrackRules::default());
    let original = track.cones[5].clone();
    let twin = track.cones.len();
    track.cones.push(Cone {
        position: original.position + Vector2::new(0.1, 0.0),
        ..original
    });
    let sim = simulate(&track, &course, &SimConfig::default());
    let sources: Vec<usize> = sim
        .truth_associations
        .iter()
        .filter_map(|a| a.landmark)
        .collect();
    assert!(sources.contains(&5), "the first of the pair is seen");
    assert!(!sources.contains(&twin), "the second is not");
    assert_eq!(sim.truth_map.len(), twin + 1, "the truth map keeps both");
}

#[test]
fn noise_of_any_sigma_can_be_drawn() {
    let mut rng = StdRng::seed_from_u64(1);
    for sigma in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-320, 0.05] {
        let x = gaussian(sigma).sample(&mut rng);
        assert!(!x.is_nan(), "σ {sigma}: {x}");
    }
    assert!(gaussian(0.0).sample(&mut rng).abs() < 1e-290);
}
