//! How much of a simulated log's association any matcher could get right:
//! each scan matched knowing what no estimator knows, the car's true pose,
//! the true cones and the detector's true noise. Where two cones stand
//! closer than the noise separates (the big orange pairs 0.28 m apart at the
//! start line), even this matcher swaps them, so an estimator's accuracy is
//! read against it rather than against 100%. It is a reference, not a
//! strict bound: a matcher with tracker ids can pass it, and so, by a
//! little, can one that weighs the scans differently, since the most likely
//! assignment of a scan is not the one with the most detections right.

use crate::eval::pose_at;
use crate::matching::assign;
use crate::sim::{SensorModel, Simulation, read_probability};
use cairn_core::se2::normalize_angle;
use cairn_slam::log::Record;
use std::collections::HashMap;

/// Farthest from its cone, placed by the true pose, a detection is paired
/// with it (m): beyond any σ the presets give a cone in range.
const REACH: f64 = 3.0;

/// The share of the log's detections that maximum likelihood gets right,
/// scan by scan, given the true poses, cones and noise (`sensor`: the
/// simulator's detector, σ_r = `range_sigma` + `range_sigma_relative`·r,
/// σ_b = `bearing_sigma`). Each scan's detections are assigned one-to-one
/// to cones, as many as can be and then the smallest summed χ² (Gaussian,
/// whatever tails the noise has) with −2 ln of the chance of each colour
/// read (the simulator's misreading law). False positives count as right,
/// as if known, and sightings the point clustering lost as wrong, as the
/// evaluation counts them. Scans measured before or after the truth's
/// poses are left out. `None` for a log without detections.
pub fn association_ceiling(sim: &Simulation, sensor: &SensorModel) -> Option<f64> {
    let truth: HashMap<(usize, usize), Option<usize>> = sim
        .truth_associations
        .iter()
        .map(|a| ((a.scan, a.det), a.landmark))
        .collect();
    let cones = &sim.truth_map;
    let (mut right, mut total) = (0usize, 0usize);
    let scans = sim.log.iter().filter_map(|r| match r {
        Record::Cones { t, cones } => Some((*t, cones)),
        _ => None,
    });
    for (scan, (t, detections)) in scans.enumerate() {
        let Some(pose) = pose_at(&sim.truth, t - sensor.latency) else {
            continue;
        };
        total += detections.len();
        // Links of each detection of a true cone: (cone, benefit). A pair is
        // worth more than any saving of χ² (counted in millionths, at most
        // 10⁵), so that as many detections as can be are paired first.
        let pair = 1_000_000_000_000_i64;
        let links: Vec<Vec<(usize, i64)>> = (0..detections.len())
            .map(|i| {
                if truth.get(&(scan, i)).copied().flatten().is_none() {
                    return Vec::new();
                }
                let z = &detections[i];
                let (range, bearing) = z
                    .range_bearing
                    .unwrap_or((z.position.norm(), z.position.y.atan2(z.position.x)));
                let world = pose.transform_point(&z.position);
                cones
                    .iter()
                    .enumerate()
                    .filter(|(_, c)| (c.position - world).norm() < REACH)
                    .filter_map(|(j, c)| {
                        let read = read_probability(c.color, z.color, sensor);
                        let local = pose.inverse().transform_point(&c.position);
                        let r = local.norm();
                        let sigma_r = sensor.range_sigma + sensor.range_sigma_relative * r;
                        let db = normalize_angle(bearing - local.y.atan2(local.x));
                        let d2 = ((range - r) / sigma_r).powi(2)
                            + (db / sensor.bearing_sigma).powi(2)
                            - 2.0 * read.ln();
                        (read > 0.0).then(|| (j, pair - (d2.min(1e5) * 1e6).round() as i64))
                    })
                    .collect()
            })
            .collect();
        let chosen = assign(&links, cones.len());
        right += (0..detections.len())
            .filter(|&i| match truth.get(&(scan, i)).copied().flatten() {
                Some(cone) => chosen[i] == Some(cone),
                None => true,
            })
            .count();
    }
    let total = total + sim.lost_sightings;
    (total > 0).then(|| right as f64 / total as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{Preset, simulate_preset};
    use crate::trackgen::{TrackRules, random_track};

    fn ceiling(scale: f64) -> f64 {
        let (track, course) = random_track(3, &TrackRules::default());
        let mut preset = Preset::standard();
        preset.sensor.scale_noise(scale);
        let sensor = preset.sensor.clone();
        let sim = simulate_preset(&track, &course, preset, 5);
        association_ceiling(&sim, &sensor).expect("detections")
    }

    #[test]
    fn a_noisier_detector_lowers_the_ceiling_and_a_precise_one_reaches_all() {
        let (precise, standard, noisy) = (ceiling(0.01), ceiling(1.0), ceiling(4.0));
        println!("{precise} {standard} {noisy}");
        assert!(precise > 0.9999, "{precise}");
        assert!(standard > 0.99 && standard <= precise, "{standard}");
        assert!(noisy < standard - 0.002, "{noisy} against {standard}");
    }
}
