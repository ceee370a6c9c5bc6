//! Finding where the car is on a known map from one scan: two detections
//! and two map cones of the same colours and spacing fix a rigid transform;
//! the one most detections agree with wins.

use crate::color::Color;
use crate::log::Detection;
use cairn_core::SE2;
use nalgebra::Vector2;

/// Detections within this distance of a map cone count as agreeing (m).
const INLIER: f64 = 0.5;

/// Where the car stands on `map`: at `here` if most detections fall on map
/// cones there, else at the best two-point alignment. Needs three agreeing
/// detections (or half the scan, if more).
pub fn place(map: &[(Vector2<f64>, Color)], detections: &[Detection], here: &SE2) -> Option<SE2> {
    let agree = detections
        .iter()
        .filter(|d| {
            let w = here.transform_point(&d.position);
            map.iter().any(|(m, _)| (m - w).norm() < INLIER)
        })
        .count();
    let needed = 3.max(detections.len() / 2);
    if agree >= needed {
        return Some(*here);
    }
    align(map, detections)
        .filter(|(_, n)| *n >= needed)
        .map(|(p, _)| p)
}

/// Place recognition at the end of a lap: the pose near `pose` that puts
/// the scan on `old` landmarks (those that left the view long ago), when at
/// least `min_inliers` detections (and half the scan) agree. Drift can put
/// returning landmarks outside the association gates; this finds them
/// geometrically.
pub fn recognise(
    old: &[(Vector2<f64>, Color)],
    detections: &[Detection],
    pose: &SE2,
    min_inliers: usize,
) -> Option<SE2> {
    if old.len() < min_inliers {
        return None;
    }
    let (aligned, inliers) = align(old, detections)?;
    let shift = pose.between(&aligned);
    (inliers >= min_inliers.max(detections.len() / 2)
        && shift.t.norm() <= 8.0
        && shift.theta.abs() <= 0.4)
        .then_some(aligned)
}

/// The pose that puts most detections on map cones of a compatible colour,
/// and how many agree.
pub fn align(map: &[(Vector2<f64>, Color)], detections: &[Detection]) -> Option<(SE2, usize)> {
    let count = |pose: &SE2| {
        detections
            .iter()
            .filter(|d| {
                let w = pose.transform_point(&d.position);
                map.iter()
                    .any(|(m, c)| c.compatible(d.color) && (m - w).norm() < INLIER)
            })
            .count()
    };
    // The nearest detections are the most precise.
    let mut near: Vec<&Detection> = detections.iter().collect();
    near.sort_by(|a, b| a.position.norm().total_cmp(&b.position.norm()));
    near.truncate(8);
    let mut best: Option<(SE2, usize)> = None;
    for i in 0..near.len() {
        for j in i + 1..near.len() {
            let (a, b) = (near[i], near[j]);
            let dab = (b.position - a.position).norm();
            if dab < 1.0 {
                continue;
            }
            for (p, cp) in map {
                if !cp.compatible(a.color) {
                    continue;
                }
                for (q, cq) in map {
                    if !cq.compatible(b.color) || ((q - p).norm() - dab).abs() > 0.3 {
                        continue;
                    }
                    let pose = from_two(a.position, b.position, *p, *q);
                    let n = count(&pose);
                    if best.as_ref().is_none_or(|(_, m)| n > *m) {
                        best = Some((pose, n));
                    }
                }
            }
        }
    }
    best
}

/// The rigid transform taking vehicle points a, b onto world points p, q.
fn from_two(a: Vector2<f64>, b: Vector2<f64>, p: Vector2<f64>, q: Vector2<f64>) -> SE2 {
    let (u, v) = (b - a, q - p);
    let theta = v.y.atan2(v.x) - u.y.atan2(u.x);
    let rot = cairn_core::se2::rotation2(theta);
    let mid_local = 0.5 * (a + b);
    let mid_world = 0.5 * (p + q);
    let t = mid_world - rot * mid_local;
    SE2::new(t.x, t.y, theta)
}
