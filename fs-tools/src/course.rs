//! The line a simulated car drives: the centre line of a track, found from
//! its ordered boundaries.

use crate::track::{Track, TrackKind};
use cairn_core::SE2;
use cairn_slam::Color;
use nalgebra::Vector2;

/// A polyline parameterised by arc length, closed for loop tracks.
#[derive(Clone, Debug)]
pub struct Course {
    points: Vec<Vector2<f64>>,
    /// Arc length at each point.
    arc: Vec<f64>,
    closed: bool,
    length: f64,
}

/// Spacing of the resampled centre line (m).
const STEP: f64 = 0.25;

/// Most points a resampled course may have (1,000 km every 10 cm).
const MAX_RESAMPLED: usize = 10_000_000;

/// The longest course the simulator drives (m): an endurance event is 22 km
/// of laps on a course under 2 km.
pub const MAX_LENGTH: f64 = 50_000.0;

/// The shortest (m).
pub const MIN_LENGTH: f64 = 1.0;

impl Course {
    /// A course through `points`; a closed one joins the last point to the first.
    pub fn new(points: Vec<Vector2<f64>>, closed: bool) -> Result<Course, String> {
        if points.len() < 2 {
            return Err("a course needs at least two points".into());
        }
        let mut arc = Vec::with_capacity(points.len());
        let mut s = 0.0;
        for i in 0..points.len() {
            arc.push(s);
            if i + 1 < points.len() {
                s += (points[i + 1] - points[i]).norm();
            }
        }
        let length = if closed {
            s + (points[0] - points[points.len() - 1]).norm()
        } else {
            s
        };
        if !(MIN_LENGTH..=MAX_LENGTH).contains(&length) {
            return Err(format!(
                "the course is {length} m long; the simulator drives courses of {MIN_LENGTH} to {MAX_LENGTH} m"
            ));
        }
        Ok(Course {
            points,
            arc,
            closed,
            length,
        })
    }

    /// The centre line of a track: for a loop, midpoints between the ordered
    /// blue boundary and the nearest point of the yellow one, smoothed; for an
    /// acceleration track, the straight line from the start along its heading.
    pub fn from_track(track: &Track) -> Result<Course, String> {
        match track.kind {
            TrackKind::Skidpad => Err("the simulator does not drive skidpad yet".into()),
            TrackKind::Acceleration => {
                let dir = Vector2::new(track.start.theta.cos(), track.start.theta.sin());
                let end = track
                    .cones
                    .iter()
                    .map(|c| (c.position - track.start.t).dot(&dir))
                    .fold(0.0, f64::max);
                if !(MIN_LENGTH..=MAX_LENGTH).contains(&end) {
                    return Err(format!(
                        "the straight is {end} m long; the simulator drives courses of {MIN_LENGTH} to {MAX_LENGTH} m"
                    ));
                }
                let n = (end / STEP).ceil().max(1.0) as usize;
                let points = (0..=n)
                    .map(|k| track.start.t + dir * (end * k as f64 / n as f64))
                    .collect();
                Course::new(points, false)
            }
            TrackKind::Loop => {
                let side = |color| -> Vec<Vector2<f64>> {
                    track
                        .of_color(color)
                        .iter()
                        .map(|&i| track.cones[i].position)
                        .collect()
                };
                let blue = order_boundary(&side(Color::Blue), &track.start);
                let yellow = order_boundary(&side(Color::Yellow), &track.start);
                if blue.len() < 3 || yellow.len() < 3 {
                    return Err("a loop track needs blue and yellow boundaries".into());
                }
                let blue = Course::new(blue, true)?.resampled(0.5)?;
                let yellow = Course::new(yellow, true)?;
                let mids: Vec<_> = blue
                    .points
                    .iter()
                    .map(|b| 0.5 * (b + yellow.nearest_point(b)))
                    .collect();
                let smooth = smooth_closed(&mids, 1);
                let course = Course::new(smooth, true)?.resampled(STEP)?;
                let cones: Vec<_> = track.cones.iter().map(|c| c.position).collect();
                let clearance = course.clearance(&cones);
                if clearance < 0.7 {
                    return Err(format!(
                        "no centre line found: the best guess passes {clearance:.2} m from a cone \
                         (boundaries too intertwined for the nearest-cone walk)"
                    ));
                }
                Ok(course)
            }
        }
    }

    /// Total length (m).
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Whether the course is a loop.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The points of the polyline.
    pub fn points(&self) -> &[Vector2<f64>] {
        &self.points
    }

    /// The point at arc length `s` (wrapped on a loop, clamped otherwise).
    pub fn point_at(&self, s: f64) -> Vector2<f64> {
        let s = if self.closed {
            s.rem_euclid(self.length)
        } else {
            s.clamp(0.0, self.length)
        };
        let i = match self.arc.binary_search_by(|a| a.total_cmp(&s)) {
            Ok(i) => i,
            Err(i) => i.saturating_sub(1),
        };
        let a = self.points[i];
        let b = if i + 1 < self.points.len() {
            self.points[i + 1]
        } else if self.closed {
            self.points[0]
        } else {
            return a;
        };
        let seg = (b - a).norm();
        if seg <= 0.0 {
            return a;
        }
        a + (b - a) * ((s - self.arc[i]) / seg)
    }

    /// Arc length of the point nearest to `p`, searched within `window`
    /// metres around `hint` (the whole course when `hint` is `None`).
    pub fn project(&self, p: &Vector2<f64>, hint: Option<f64>, window: f64) -> f64 {
        let mut best = (f64::INFINITY, 0.0);
        let n = self.segments();
        for i in 0..n {
            if let Some(h) = hint {
                let mut d = (self.arc[i] - h).abs();
                if self.closed {
                    d = d.min(self.length - d);
                }
                if d > window {
                    continue;
                }
            }
            let (a, b) = self.segment(i);
            let ab = b - a;
            let len2 = ab.norm_squared();
            let u = if len2 > 0.0 {
                ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let d = (a + ab * u - p).norm_squared();
            if d < best.0 {
                best = (d, self.arc[i] + u * len2.sqrt());
            }
        }
        best.1
    }

    fn segments(&self) -> usize {
        if self.closed {
            self.points.len()
        } else {
            self.points.len() - 1
        }
    }

    fn segment(&self, i: usize) -> (Vector2<f64>, Vector2<f64>) {
        (self.points[i], self.points[(i + 1) % self.points.len()])
    }

    fn nearest_point(&self, p: &Vector2<f64>) -> Vector2<f64> {
        self.point_at(self.project(p, None, 0.0))
    }

    /// The same course resampled at about `step` metres; an error if that
    /// is no finite number of points (a course of infinite length, say).
    pub fn resampled(&self, step: f64) -> Result<Course, String> {
        let n = (self.length / step).round().max(2.0);
        if !n.is_finite() || n > MAX_RESAMPLED as f64 {
            return Err(format!(
                "cannot resample a {} m course every {step} m",
                self.length
            ));
        }
        let n = n as usize;
        let count = if self.closed { n } else { n + 1 };
        let points = (0..count)
            .map(|k| self.point_at(self.length * k as f64 / n as f64))
            .collect();
        Course::new(points, self.closed)
    }

    /// The smallest distance from the course to any of `points` (cone clearance).
    pub fn clearance(&self, points: &[Vector2<f64>]) -> f64 {
        points
            .iter()
            .map(|p| (self.nearest_point(p) - p).norm())
            .fold(f64::INFINITY, f64::min)
    }
}

/// Orders the cones of one boundary by walking from the start: each next cone
/// is the near one that best continues the current direction.
pub fn order_boundary(cones: &[Vector2<f64>], start: &SE2) -> Vec<Vector2<f64>> {
    let mut left: Vec<Vector2<f64>> = cones.to_vec();
    let mut ordered = Vec::with_capacity(cones.len());
    let mut dir = Vector2::new(start.theta.cos(), start.theta.sin());
    // First cone: the nearest one that is not behind the start.
    let first = left
        .iter()
        .enumerate()
        .filter(|(_, c)| (*c - start.t).dot(&dir) > -1.0)
        .min_by(|a, b| (a.1 - start.t).norm().total_cmp(&(b.1 - start.t).norm()))
        .map(|(i, _)| i);
    let Some(first) = first else {
        return ordered;
    };
    let mut current = left.swap_remove(first);
    ordered.push(current);
    while !left.is_empty() {
        let next = left
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let d = (c - current).norm();
                let cos = if d > 0.0 {
                    (c - current).dot(&dir) / d
                } else {
                    1.0
                };
                (i, d * (1.0 + 1.5 * (1.0 - cos)), d)
            })
            .filter(|&(_, _, d)| d < 12.0)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((i, _, d)) = next else { break };
        let c = left.swap_remove(i);
        if d > 0.0 {
            dir = (c - current) / d;
        }
        current = c;
        ordered.push(c);
    }
    ordered
}

fn smooth_closed(points: &[Vector2<f64>], half_window: usize) -> Vec<Vector2<f64>> {
    let n = points.len();
    (0..n)
        .map(|i| {
            let mut sum = Vector2::zeros();
            for k in 0..=2 * half_window {
                sum += points[(i + n + k - half_window) % n];
            }
            sum / (2 * half_window + 1) as f64
        })
        .collect()
}

/// The pose on the start line of `track` (between its big orange cones,
/// facing along `course`): where a car that starts on the line stands.
/// `None` for a track without big orange cones.
pub fn start_on_line(track: &Track, course: &Course) -> Option<SE2> {
    let line = track.of_color(Color::BigOrange);
    if line.is_empty() {
        return None;
    }
    let centre = line
        .iter()
        .map(|&i| track.cones[i].position)
        .sum::<Vector2<f64>>()
        / line.len() as f64;
    let s = course.project(&centre, None, 0.0);
    let (on, ahead) = (course.point_at(s), course.point_at(s + 1.0));
    Some(SE2::new(on.x, on.y, (ahead - on).y.atan2((ahead - on).x)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resampling_keeps_the_length_and_refuses_an_endless_course() {
        let square: Vec<Vector2<f64>> = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
            .iter()
            .map(|&(x, y)| Vector2::new(x, y))
            .collect();
        let course = Course::new(square, true).unwrap();
        let fine = course.resampled(0.5).unwrap();
        assert!((fine.length() - 40.0).abs() < 1e-9, "{}", fine.length());
        assert!(fine.resampled(1e-9).is_err(), "10¹⁰ points");
        let huge = vec![Vector2::new(-1e308, 0.0), Vector2::new(1e308, 0.0)];
        assert!(Course::new(huge, false).is_err());
        let point = vec![Vector2::new(3.0, 4.0); 6];
        assert!(Course::new(point, true).is_err(), "a course of zero length");
    }

    #[test]
    fn the_start_line_pose_stands_between_the_big_orange_cones() {
        let (mut track, course) = crate::trackgen::random_track(1, &Default::default());
        let start = start_on_line(&track, &course).expect("random tracks have a start line");
        let line = track.of_color(Color::BigOrange);
        let centre = line
            .iter()
            .map(|&i| track.cones[i].position)
            .sum::<Vector2<f64>>()
            / line.len() as f64;
        assert!((start.t - centre).norm() < 0.5, "{start:?} vs {centre}");
        // Facing along the course, as the file's start does.
        let d = cairn_core::se2::normalize_angle(start.theta - track.start.theta);
        assert!(d.abs() < 0.3, "{start:?} vs {:?}", track.start);
        track.cones.retain(|c| c.color != Color::BigOrange);
        assert!(start_on_line(&track, &course).is_none());
    }
}
