//! Random tracks that follow the Formula Student rules: a closed loop of
//! 200–500 m, boundary cones at most 5 m apart, at least 3 m wide.

use crate::course::Course;
use crate::track::{Track, TrackKind};
use cairn_core::SE2;
use cairn_slam::Color;
use cairn_slam::Cone;
use nalgebra::Vector2;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::f64::consts::TAU;

/// Limits of a generated track.
#[derive(Clone, Debug)]
pub struct TrackRules {
    /// Lap length range (m).
    pub length: (f64, f64),
    /// Track width range (m).
    pub width: (f64, f64),
    /// Cone spacing along a boundary, range (m); the upper end is the rule's
    /// 5 m. Equal ends give that spacing.
    pub spacing: (f64, f64),
    /// Smallest radius of the centre line's curvature (m).
    pub min_radius: f64,
}

impl Default for TrackRules {
    fn default() -> Self {
        Self {
            length: (200.0, 500.0),
            width: (3.5, 4.5),
            spacing: (3.0, 5.0),
            min_radius: 9.0,
        }
    }
}

/// A random closed track and its centre line; the car starts at the origin
/// facing +x, on the centre line, and drives counter-clockwise (blue inside).
pub fn random_track(seed: u64, rules: &TrackRules) -> (Track, Course) {
    let mut rng = StdRng::seed_from_u64(seed);
    loop {
        if let Some(result) = attempt(&mut rng, seed, rules) {
            return result;
        }
    }
}

fn attempt(rng: &mut StdRng, seed: u64, rules: &TrackRules) -> Option<(Track, Course)> {
    // A star-shaped curve r(θ) = 1 + Σ aₖ cos(kθ + φₖ) is simple when r > 0.
    let harmonics: Vec<(f64, f64, f64)> = (2..=5)
        .map(|k| {
            let k = k as f64;
            (
                k,
                rng.random_range(0.0..0.3 / k),
                rng.random_range(0.0..TAU),
            )
        })
        .collect();
    let n = 2000;
    let raw: Vec<Vector2<f64>> = (0..n)
        .map(|i| {
            let th = TAU * i as f64 / n as f64;
            let r = 1.0
                + harmonics
                    .iter()
                    .map(|(k, a, p)| a * (k * th + p).cos())
                    .sum::<f64>();
            Vector2::new(r * th.cos(), r * th.sin())
        })
        .collect();
    let unit = Course::new(raw.clone(), true).ok()?;
    let length = rng.random_range(rules.length.0..rules.length.1);
    let scale = length / unit.length();
    let width = rng.random_range(rules.width.0..rules.width.1);
    // Move the start to the origin, facing +x.
    let p0 = raw[0] * scale;
    let heading = (raw[1] - raw[0]).y.atan2((raw[1] - raw[0]).x);
    let to_start = SE2::new(p0.x, p0.y, heading).inverse();
    let centre: Vec<Vector2<f64>> = raw
        .iter()
        .map(|p| to_start.transform_point(&(p * scale)))
        .collect();
    let course = Course::new(centre, true).ok()?.resampled(0.25).ok()?;
    let pts = course.points();
    let m = pts.len();
    // Curvature radius from three points 2 m apart; necks narrower than the track.
    let k = 8;
    for i in 0..m {
        let (a, b, c) = (pts[(i + m - k) % m], pts[i], pts[(i + k) % m]);
        let cross = (b - a).perp(&(c - b));
        let radius =
            (b - a).norm() * (c - b).norm() * (c - a).norm() / (2.0 * cross.abs()).max(1e-12);
        if radius < rules.min_radius {
            return None;
        }
    }
    let apart = (20.0 / 0.25) as usize;
    for i in (0..m).step_by(4) {
        for j in (0..m).step_by(4) {
            let gap = (i as isize - j as isize).unsigned_abs();
            if gap.min(m - gap) > apart && (pts[i] - pts[j]).norm() < width + 3.0 {
                return None;
            }
        }
    }
    let (low, high) = rules.spacing;
    let spacing = if low < high {
        rng.random_range(low..high)
    } else {
        low
    };
    let mut cones = Vec::new();
    for (color, side) in [(Color::Blue, 1.0), (Color::Yellow, -1.0)] {
        let offset: Vec<Vector2<f64>> = (0..m)
            .map(|i| {
                let t = (pts[(i + 1) % m] - pts[(i + m - 1) % m]).normalize();
                pts[i] + Vector2::new(-t.y, t.x) * (side * width / 2.0)
            })
            .collect();
        let boundary = Course::new(offset, true).ok()?;
        let count = (boundary.length() / spacing).ceil() as usize;
        for j in 0..count {
            let p = boundary.point_at(boundary.length() * j as f64 / count as f64 + 1.0);
            cones.push(Cone::new(p.x, p.y, color));
        }
    }
    // Start line 6 m ahead: two big orange cones on each side.
    let line = course.point_at(6.0);
    let t = (course.point_at(6.5) - course.point_at(5.5)).normalize();
    let normal = Vector2::new(-t.y, t.x);
    let mut big = Vec::new();
    for along in [-0.5, 0.5] {
        for side in [1.0, -1.0] {
            big.push(line + t * along + normal * (side * (width / 2.0 + 0.2)));
        }
    }
    cones.retain(|c| big.iter().all(|b| (c.position - b).norm() > 1.2));
    cones.extend(big.iter().map(|b| Cone::new(b.x, b.y, Color::BigOrange)));
    let track = Track {
        name: format!("random-{seed}"),
        cones,
        clutter: Vec::new(),
        start: SE2::identity(),
        kind: TrackKind::Loop,
    };
    Some((track, course))
}
