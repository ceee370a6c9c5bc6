//! The scanner variant of a simulated run: the points a 3D scanner would
//! return instead of cone detections.

use super::effects::Noise;
use super::*;
use rand::Rng;
use std::collections::HashMap;

/// Base radius and height of a big orange cone (m).
const BIG_CONE: (f64, f64) = (0.142, 0.505);

/// The same run seen by a scanner instead of a cone detector: every `cones`
/// record becomes a `points` record holding the points the scanner would
/// return from the same objects (the true cones' visible surfaces, a small
/// blob per false positive), plus points on the vehicle's own nose and far
/// beyond the cones, which the point front end must remove. The truth
/// associations refer to the clusters the estimator makes with `points`
/// ([`cairn_slam::points::extract`], in its order), each labelled by the
/// cone its points came from, one cluster per cone and scan: the cluster
/// with most of the cone's points. A second cluster of one cone is a false
/// positive, and a cone whose points went to another cone's cluster (or to
/// none) is a lost sighting ([`Simulation::lost_sightings`]), so clustering
/// errors count against the association.
pub fn point_clouds(
    sim: &Simulation,
    points: &cairn_slam::points::PointCloudConfig,
    seed: u64,
) -> Simulation {
    let mut rng = StdRng::seed_from_u64(seed);
    let noise = Noise::gaussian(0.01);
    let truth_at: HashMap<u64, SE2> = sim.truth.iter().map(|p| (p.t.to_bits(), p.pose)).collect();
    let mut sources = sim.truth_associations.iter().peekable();
    let mut log = Vec::with_capacity(sim.log.len());
    let mut truth_associations = Vec::new();
    let mut lost_sightings = 0;
    let mut scan = 0;
    for record in &sim.log {
        let Record::Cones { t, cones } = record else {
            log.push(record.clone());
            continue;
        };
        let pose = truth_at
            .get(&t.to_bits())
            .copied()
            .unwrap_or(SE2::identity());
        let inverse = pose.inverse();
        let mut cloud: Vec<[f64; 3]> = Vec::new();
        let mut origin: Vec<Option<usize>> = Vec::new();
        for (det, d) in cones.iter().enumerate() {
            let source = match sources.peek() {
                Some(a) if a.scan == scan && a.det == det => {
                    sources.next().and_then(|a| a.landmark)
                }
                _ => None,
            };
            match source.and_then(|i| sim.truth_map.get(i).map(|c| (i, c))) {
                Some((i, cone)) => {
                    let centre = inverse.transform_point(&cone.position);
                    for p in cone_surface(&centre, cone.color, &mut rng, &noise) {
                        cloud.push(p);
                        origin.push(Some(i));
                    }
                }
                None => {
                    for _ in 0..4 {
                        let p = d.position
                            + Vector2::new(noise.sample(&mut rng), noise.sample(&mut rng)) * 4.0;
                        cloud.push([p.x, p.y, 0.1]);
                        origin.push(None);
                    }
                }
            }
        }
        // The vehicle's own nose, and a wall far beyond the cones.
        for _ in 0..8 {
            cloud.push([
                rng.random_range(-1.0..0.3),
                rng.random_range(-0.5..0.5),
                0.2,
            ]);
            origin.push(None);
        }
        let wall = rng.random_range(-1.5..1.5f64);
        for k in 0..10 {
            let (s, c) = (wall + 0.01 * k as f64).sin_cos();
            cloud.push([30.0 * c, 30.0 * s, 0.5]);
            origin.push(None);
        }
        let clusters = cairn_slam::points::extract(&cloud, points);
        let (labels, lost) = label_clusters(&clusters, &origin);
        lost_sightings += lost;
        for (det, landmark) in labels.into_iter().enumerate() {
            truth_associations.push(Association {
                scan,
                det,
                landmark,
            });
        }
        log.push(Record::Points {
            t: *t,
            points: cloud,
        });
        scan += 1;
    }
    Simulation {
        log,
        truth: sim.truth.clone(),
        truth_associations,
        truth_map: sim.truth_map.clone(),
        lost_sightings,
    }
}

/// Each cluster's cone: the origin of most of its points, one cluster per
/// cone (the one with most of its points; another is a false positive);
/// and the cones with points in the cloud that no cluster stands for.
pub(super) fn label_clusters(
    clusters: &[cairn_slam::points::Cluster],
    origin: &[Option<usize>],
) -> (Vec<Option<usize>>, usize) {
    let links: Vec<Vec<(usize, i64)>> = clusters
        .iter()
        .map(|cluster| {
            let mut counts: HashMap<Option<usize>, i64> = HashMap::new();
            for &i in &cluster.points {
                *counts.entry(origin[i]).or_default() += 1;
            }
            let most = counts.into_iter().max_by_key(|(o, n)| (*n, *o));
            most.and_then(|(cone, n)| Some((cone?, n)))
                .into_iter()
                .collect()
        })
        .collect();
    let cones = origin.iter().flatten().map(|c| c + 1).max().unwrap_or(0);
    let labels = crate::matching::assign(&links, cones);
    let seen: std::collections::HashSet<usize> = origin.iter().flatten().copied().collect();
    let lost = seen.len() - labels.iter().flatten().count();
    (labels, lost)
}

/// Points a scanner with 0.2° bearing and 1° elevation steps returns from
/// the visible half of a cone standing at `centre` (vehicle frame).
fn cone_surface(
    centre: &Vector2<f64>,
    color: Color,
    rng: &mut StdRng,
    noise: &Noise,
) -> Vec<[f64; 3]> {
    let (base, height) = if color == Color::BigOrange {
        BIG_CONE
    } else {
        (
            cairn_slam::points::CONE_RADIUS,
            cairn_slam::points::CONE_HEIGHT,
        )
    };
    let range = centre.norm().max(0.5);
    let sight = centre / range;
    let across = Vector2::new(-sight.y, sight.x);
    let ring_step = (range * 1f64.to_radians()).max(0.04);
    let lateral_step = range * 0.2f64.to_radians();
    let mut out = Vec::new();
    let mut h = 0.5 * ring_step;
    while h < 0.9 * height {
        let rho = base * (1.0 - h / height);
        let mut u = -rho + rng.random_range(0.0..lateral_step.min(2.0 * rho));
        while u <= rho {
            let depth = (rho * rho - u * u).max(0.0).sqrt();
            let p = centre - sight * depth + across * u;
            out.push([
                p.x + noise.sample(rng),
                p.y + noise.sample(rng),
                h + noise.sample(rng),
            ]);
            u += lateral_step;
        }
        h += ring_step;
    }
    out
}
