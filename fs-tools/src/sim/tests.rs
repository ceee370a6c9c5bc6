use super::*;
use rand::SeedableRng;

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
        let x = effects::Noise::gaussian(sigma).sample(&mut rng);
        assert!(!x.is_nan(), "σ {sigma}: {x}");
    }
    assert!(effects::Noise::gaussian(0.0).sample(&mut rng).abs() < 1e-290);
}

#[test]
fn clusters_stand_for_one_cone_each_and_lost_cones_are_counted() {
    use cairn_slam::points::Cluster;
    let cluster = |points: Vec<usize>| Cluster {
        points,
        centroid: nalgebra::Vector3::zeros(),
    };
    // Points 0–5 of cone 3, 6–8 of cone 4, 9–10 noise, 11–12 of cone 5.
    let origin = [
        Some(3),
        Some(3),
        Some(3),
        Some(3),
        Some(3),
        Some(3),
        Some(4),
        Some(4),
        Some(4),
        None,
        None,
        Some(5),
        Some(5),
    ];
    let clusters = [
        // Cone 3 split in two, the second part with cone 4 merged in.
        cluster(vec![0, 1, 2, 3]),
        cluster(vec![4, 5, 6, 7, 8]),
        // Noise with one point of cone 5: noise.
        cluster(vec![9, 10, 11]),
    ];
    let (labels, lost) = scanner::label_clusters(&clusters, &origin);
    // The second cluster is mostly cone 4 (3 of 5).
    assert_eq!(labels, [Some(3), Some(4), None]);
    // Cone 5's points formed no cluster of their own.
    assert_eq!(lost, 1);
    let split = [cluster(vec![0, 1, 2]), cluster(vec![3, 4, 5])];
    let (labels, lost) = scanner::label_clusters(&split, &origin[..6]);
    assert_eq!(labels.iter().flatten().count(), 1, "{labels:?}");
    assert_eq!(lost, 0);
}
