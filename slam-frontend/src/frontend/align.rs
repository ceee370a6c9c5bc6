//! Finding where the car is on a known map from one scan: the candidate
//! alignments of [`super::fits`] are weighed against each other and
//! against the drift the pose may have.

use super::fits::{Fit, INLIER, fits};
use crate::color::Color;
use crate::log::Detection;
use cairn_core::SE2;
use nalgebra::Vector2;

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

/// Map cones per scan let pass after a failed try at placing the car.
const CONES_PER_WAITING_SCAN: usize = 200;

/// Placing the car on a given map scan after scan until one fits. A failed
/// try costs time in proportion to the map's pairs of cones, so the next
/// waits a scan per [`CONES_PER_WAITING_SCAN`] cones of the map (a
/// 2,000-cone map that the car is not on: 4 ms per scan instead of 44).
#[derive(Clone, Debug, Default)]
pub struct Placement {
    /// Scans to let pass before the next try.
    wait: usize,
}

impl Placement {
    /// [`place`] on this scan, unless it is one to let pass.
    pub fn try_place(
        &mut self,
        map: &[(Vector2<f64>, Color)],
        detections: &[Detection],
        here: &SE2,
    ) -> Option<SE2> {
        if self.wait > 0 {
            self.wait -= 1;
            return None;
        }
        let found = place(map, detections, here);
        if found.is_none() {
            self.wait = map.len() / CONES_PER_WAITING_SCAN;
        }
        found
    }
}

/// Place recognition at the end of a lap: the pose near `pose` that puts
/// the scan on `old` landmarks (those that left the view long ago), when at
/// least `needed` detections agree. Drift can put
/// returning landmarks outside the association gates; this finds them
/// geometrically.
///
/// A row of evenly spaced cones fits as well shifted by one spacing. So a
/// correction of more than [`Reach::unambiguous`] metres (up to
/// [`Reach::max_shift`]) is taken only when the start line's big orange
/// cones agree with it, and
/// the chosen fit must beat every fit more than half a spacing away by
/// [`MARGIN`] and put as many of those big orange cones on theirs;
/// otherwise the scan is ambiguous and `None` waits for the next one.
///
/// Without the start line, a larger correction that is clearly the best
/// fit anywhere comes back [`Recognised::Unconfirmed`]: a row's shape hides
/// a fit one spacing off only where the row is regular, so the caller takes
/// it once it recurs scan after scan.
pub fn recognise(
    old: &[(Vector2<f64>, Color)],
    detections: &[Detection],
    proposers: &[Detection],
    pose: &SE2,
    needed: usize,
    reach: Reach,
) -> Option<Recognised> {
    if old.len() < needed {
        return None;
    }
    let fits = fits(old, detections, proposers, Some((pose, reach.max_shift)));
    let anchored = |f: &Fit| {
        pose.between(&f.pose).t.norm() <= reach.unambiguous || f.start_line >= START_LINE_INLIERS
    };
    let distinct = 0.5 * spacing(old);
    let clear = |best: &Fit| {
        let elsewhere = || {
            fits.iter()
                .filter(|f| (f.pose.t - best.pose.t).norm() > distinct)
        };
        let rival = elsewhere().map(|f| f.score).max_by(f64::total_cmp);
        // The start line's big orange cones are few: a fit elsewhere that puts
        // more of them on theirs says the best fit is one spacing off, even
        // when clutter and the prior give the best fit more (eufs_rand, `hard`
        // seed 29: 6 detections 0.6 m from the estimate against 3 and two big
        // orange ones 2.5 m away; taken, the loop closed 3.8 m off and the
        // run ended 22 m off).
        let start_line_elsewhere = elsewhere().any(|f| f.start_line > best.start_line);
        rival.is_none_or(|r| best.score - r >= MARGIN)
            && !start_line_elsewhere
            && best.inliers >= needed
    };
    let best_clear = |anchored_only: bool| {
        fits.iter()
            .filter(|f| !anchored_only || anchored(f))
            .max_by(|a, b| a.score.total_cmp(&b.score))
            .filter(|f| clear(f))
    };
    if let Some(best) = best_clear(true) {
        return Some(Recognised::Anchored(best.pose));
    }
    best_clear(false).map(|f| Recognised::Unconfirmed(f.pose))
}

/// A place [`recognise`] found: the car's pose there.
#[derive(Clone, Copy, Debug)]
pub enum Recognised {
    /// Within half a spacing of the estimate, or confirmed by the start
    /// line.
    Anchored(SE2),
    /// Further off, and only the best fit of this scan.
    Unconfirmed(SE2),
}

impl Recognised {
    /// The pose, anchored or not.
    pub fn pose(&self) -> SE2 {
        match self {
            Recognised::Anchored(p) | Recognised::Unconfirmed(p) => *p,
        }
    }

    /// The pose if it is anchored.
    pub fn anchored(&self) -> Option<SE2> {
        match self {
            Recognised::Anchored(p) => Some(*p),
            Recognised::Unconfirmed(_) => None,
        }
    }
}

/// Big orange detections on big orange landmarks that anchor a large
/// correction to the start line.
const START_LINE_INLIERS: usize = 3;

/// How much better (in [`Fit`]'s score: how closely detections fall on
/// map cones, plus log-prior) the chosen fit must be than any fit
/// elsewhere: a cone more, or as many as closely and a drift e times
/// likelier.
pub const MARGIN: f64 = 1.0;

/// The pose that puts detections most closely on map cones of a
/// compatible colour, and how many agree.
pub fn align(map: &[(Vector2<f64>, Color)], detections: &[Detection]) -> Option<(SE2, usize)> {
    fits(map, detections, detections, None)
        .into_iter()
        .max_by(|a, b| a.score.total_cmp(&b.score))
        .map(|f| (f.pose, f.inliers))
}

/// Largest correction place recognition should make on `map` (m). A row
/// of evenly spaced cones fits as well shifted by one spacing, so a
/// correction of half a spacing or more cannot be told from that.
pub fn unambiguous_shift(map: &[(Vector2<f64>, Color)]) -> f64 {
    0.45 * spacing(map)
}

/// Largest correction when the drift may exceed half a cone spacing, at
/// any distance (m).
pub const BASE_SHIFT: f64 = 8.0;

/// Drift a lap may end with, per metre driven since the start: odometry
/// drift grows with the distance. The `hard` preset's 3% speed bias and
/// 0.01 rad/s gyro bias, learnt online, left random-0 (425 m) 9 m off at
/// the end of a lap. A gyro bias that random-walks at 5·10⁻⁴ rad/s/√s
/// (`realistic`), with the estimator told a steady one, turns the heading
/// about 0.2 rad in a lap: over 22 such laps of 250–450 m (seeds 300–301)
/// the first fits found were 0.05–3.1% of the distance off, nine of them
/// over 2.3%, and random-0 seed 101 ended 13 m (3.1%) off and never closed.
const SHIFT_PER_METRE: f64 = 0.05;

/// Largest correction when the drift may exceed half a cone spacing (m),
/// after driving `distance` metres: [`BASE_SHIFT`], or 5% of the distance
/// on a long lap.
pub fn max_shift(distance: f64) -> f64 {
    BASE_SHIFT.max(SHIFT_PER_METRE * distance)
}

/// How far place recognition may move the car (m).
#[derive(Clone, Copy, Debug)]
pub struct Reach {
    /// Corrections up to this need no confirmation by the start line.
    pub unambiguous: f64,
    /// No correction beyond this.
    pub max_shift: f64,
}

impl Reach {
    /// At the end of a lap of `distance` metres, back among the `map`
    /// landmarks of its start: unambiguous within half their spacing, and
    /// as far as that lap's drift may reach ([`max_shift`]).
    pub fn lap_end(map: &[(Vector2<f64>, Color)], distance: f64) -> Self {
        Reach {
            unambiguous: unambiguous_shift(map),
            max_shift: max_shift(distance),
        }
    }
}

/// Median distance from each boundary cone to the nearest one of a
/// compatible colour (m); 5 m, the rules' largest spacing, when there are
/// too few. The start line's orange cones stand closer and would make the
/// track look denser than it is.
fn spacing(map: &[(Vector2<f64>, Color)]) -> f64 {
    let boundary = |c: &Color| !matches!(c, Color::Orange | Color::BigOrange);
    let mut gaps: Vec<f64> = map
        .iter()
        .enumerate()
        .filter(|(_, (_, c))| boundary(c))
        .filter_map(|(i, (p, c))| {
            map.iter()
                .enumerate()
                .filter(|&(j, (_, d))| j != i && boundary(d) && c.compatible(*d))
                .map(|(_, (q, _))| (q - p).norm())
                .min_by(f64::total_cmp)
        })
        .collect();
    if gaps.len() < 3 {
        return 5.0;
    }
    gaps.sort_by(f64::total_cmp);
    gaps[gaps.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two rows of cones 3 m apart along x, blue left and yellow right.
    fn row() -> Vec<(Vector2<f64>, Color)> {
        (0..8)
            .flat_map(|i| {
                let x = 3.0 * i as f64;
                [
                    (Vector2::new(x, 1.5), Color::Blue),
                    (Vector2::new(x, -1.5), Color::Yellow),
                ]
            })
            .collect()
    }

    /// What a car at `pose` sees of `map` within 10 m ahead.
    fn scan(map: &[(Vector2<f64>, Color)], pose: &SE2) -> Vec<Detection> {
        let inverse = pose.inverse();
        map.iter()
            .map(|(p, c)| (inverse.transform_point(p), *c))
            .filter(|(local, _)| local.x > 0.5 && local.norm() < 10.0)
            .map(|(position, color)| Detection {
                position,
                range_bearing: None,
                color,
                id: None,
                covariance: None,
            })
            .collect()
    }

    #[test]
    fn after_a_failed_try_a_large_map_lets_scans_pass() {
        // The row, and far away 400 cones of clutter: a 416-cone map.
        let mut map = row();
        map.extend((0..400).map(|k| (Vector2::new(1e4 + 7.0 * f64::from(k), 50.0), Color::Blue)));
        let truth = SE2::new(1.0, 0.2, 0.05);
        let fits = scan(&map, &truth);
        let mut placement = Placement::default();
        // A scan of nothing on the map fails; the next two scans wait.
        let empty = [];
        assert!(placement.try_place(&map, &empty, &truth).is_none());
        assert!(placement.try_place(&map, &fits, &truth).is_none());
        assert!(placement.try_place(&map, &fits, &truth).is_none());
        let placed = placement.try_place(&map, &fits, &truth).expect("placed");
        assert!(placed.between(&truth).t.norm() < 1e-6);
        // A small map tries every scan.
        let small = row();
        let mut placement = Placement::default();
        assert!(placement.try_place(&small, &empty, &truth).is_none());
        assert!(placement.try_place(&small, &fits, &truth).is_some());
    }

    #[test]
    fn the_spacing_of_a_row_is_its_cone_gap() {
        assert!((spacing(&row()) - 3.0).abs() < 1e-9);
        assert!((unambiguous_shift(&row()) - 1.35).abs() < 1e-9);
        // The start line's orange cones, 1 m apart, do not count.
        assert!((spacing(&row_with_start_line()) - 3.0).abs() < 1e-9);
        assert_eq!(spacing(&row()[..2]), 5.0);
    }

    /// `row()` with the start line: two pairs of big orange cones 1 m
    /// apart between its columns at x = 15 and 18.
    fn row_with_start_line() -> Vec<(Vector2<f64>, Color)> {
        let mut map = row();
        for x in [16.0, 17.0] {
            map.push((Vector2::new(x, 1.5), Color::BigOrange));
            map.push((Vector2::new(x, -1.5), Color::BigOrange));
        }
        map
    }

    /// Recognition of what a car at `truth` sees, from the estimate `drifted`.
    fn recognise_from(
        map: &[(Vector2<f64>, Color)],
        truth: &SE2,
        drifted: &SE2,
        unambiguous: f64,
    ) -> Option<Recognised> {
        let detections = scan(map, truth);
        recognise(
            map,
            &detections,
            &detections,
            drifted,
            4,
            lap_reach(unambiguous),
        )
    }

    /// The reach of a lap short enough for the base shift.
    fn lap_reach(unambiguous: f64) -> Reach {
        Reach {
            unambiguous,
            max_shift: BASE_SHIFT,
        }
    }

    fn assert_same(found: Option<Recognised>, truth: &SE2) {
        let Some(Recognised::Anchored(found)) = found else {
            panic!("not anchored ({found:?}), expected {truth:?}");
        };
        assert!((found.t - truth.t).norm() < 1e-6, "{found:?}");
        assert!((found.theta - truth.theta).abs() < 1e-6, "{found:?}");
    }

    #[test]
    fn recognition_takes_a_correction_under_half_a_spacing() {
        // Near the row's end a fit one spacing ahead loses the last cones
        // and one spacing behind is 3.3 m from the estimate: the truth,
        // 0.3 m away, is clearly best.
        let map = row();
        let truth = SE2::new(12.0, 0.2, 0.02);
        let drifted = SE2::new(12.3, 0.1, 0.0);
        let limit = unambiguous_shift(&map);
        let found = recognise_from(&map, &truth, &drifted, limit);
        assert_same(found, &truth);
    }

    #[test]
    fn recognition_waits_when_a_fit_one_spacing_off_is_as_good() {
        // 1.7 m of drift on a 3 m row: the truth is beyond the unambiguous
        // 1.35 m and the fit one spacing ahead is 1.3 m from the estimate.
        // Neither may be taken.
        let map = row();
        let truth = SE2::new(10.0, 0.2, 0.02);
        let drifted = SE2::new(11.7, 0.2, 0.02);
        let limit = unambiguous_shift(&map);
        assert!(recognise_from(&map, &truth, &drifted, limit).is_none());
    }

    #[test]
    fn a_clear_fit_beyond_half_a_spacing_comes_back_unconfirmed() {
        // Two cones off the row's rhythm single out the truth, 1.7 m from
        // the estimate (the fit one spacing ahead, 1.3 m away, puts 6
        // detections on cones, the truth 8): too far to take at once, it
        // is for the caller to confirm over more scans.
        let mut map = row();
        map.push((Vector2::new(13.5, 1.5), Color::Blue));
        map.push((Vector2::new(16.5, -1.5), Color::Yellow));
        let truth = SE2::new(10.0, 0.2, 0.02);
        let drifted = SE2::new(11.7, 0.2, 0.02);
        let found = recognise_from(&map, &truth, &drifted, unambiguous_shift(&row()));
        let Some(Recognised::Unconfirmed(pose)) = found else {
            panic!("not unconfirmed: {found:?}");
        };
        assert!(pose.between(&truth).t.norm() < 1e-6, "{pose:?}");
    }

    #[test]
    fn the_start_line_confirms_a_correction_over_half_a_spacing() {
        let map = row_with_start_line();
        let truth = SE2::new(10.0, 0.2, 0.02);
        let drifted = SE2::new(11.7, 0.2, 0.02);
        let limit = unambiguous_shift(&row());
        let found = recognise_from(&map, &truth, &drifted, limit);
        assert_same(found, &truth);
        // Seeing one orange pair is not enough to anchor it: one spacing
        // on, it could be the other pair. (Unconfirmed, the front end
        // ignores it where the start line was mapped.)
        let one_pair: Vec<Detection> = scan(&map, &truth)
            .into_iter()
            .filter(|d| d.color != Color::BigOrange || d.position.x < 6.5)
            .collect();
        let reach = lap_reach(limit);
        let found = recognise(&map, &one_pair, &one_pair, &drifted, 4, reach);
        assert!(found.and_then(|r| r.anchored()).is_none(), "{found:?}");
    }

    #[test]
    fn a_fit_elsewhere_that_places_the_start_line_blocks_the_closure() {
        // The car at x = 10 sees one orange pair (x = 16), and seven
        // detections of things beside the track that, one spacing ahead,
        // happen to fall on map cones. The estimate is 0.5 m from that fit
        // and 2.5 m from the truth, which the one pair cannot anchor.
        let mut map = row_with_start_line();
        let truth = SE2::new(10.0, 0.0, 0.0);
        let mut detections: Vec<Detection> = scan(&map, &truth)
            .into_iter()
            .filter(|d| d.color != Color::BigOrange || d.position.x < 6.5)
            .collect();
        for k in 0..7 {
            let x = 22.0 + 1.9 * k as f64;
            map.push((Vector2::new(x, 4.0), Color::Blue));
            let mut beside = detections[0].clone();
            beside.position = truth.inverse().transform_point(&Vector2::new(x - 3.0, 4.0));
            beside.color = Color::Blue;
            detections.push(beside);
        }
        let drifted = SE2::new(12.5, 0.0, 0.0);
        let reach = lap_reach(unambiguous_shift(&row()));
        let found = recognise(&map, &detections, &detections, &drifted, 4, reach);
        assert!(found.is_none(), "{found:?}");
        // Both orange pairs in view (and nothing beside the track) anchor
        // the truth.
        let both = scan(&map, &truth);
        assert_same(recognise(&map, &both, &both, &drifted, 4, reach), &truth);
    }

    #[test]
    fn a_long_lap_may_end_further_off() {
        // 9 m of drift along the row, confirmed by the start line: more
        // than any lap may end with, but 2.25% of a 400 m lap.
        let map = row_with_start_line();
        let truth = SE2::new(10.0, 0.2, 0.02);
        let drifted = SE2::new(19.0, 0.2, 0.02);
        let limit = unambiguous_shift(&row());
        let detections = scan(&map, &truth);
        let after = |distance| {
            let reach = Reach {
                unambiguous: limit,
                max_shift: max_shift(distance),
            };
            recognise(&map, &detections, &detections, &drifted, 4, reach)
        };
        assert!(after(100.0).is_none());
        assert_same(after(400.0), &truth);
        assert_eq!(max_shift(0.0), BASE_SHIFT);
    }
}
