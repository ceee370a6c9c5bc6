//! What every estimator remembers about a landmark besides its position:
//! colour votes, sightings and misses (to confirm or drop it), and whether
//! it left the view and came back at the start of a lap (loop closure).

use crate::color::Color;
use crate::frontend::FrontEndConfig;
use cairn_core::SE2;
use cairn_core::se2::normalize_angle;
use nalgebra::Vector2;

/// Landmarks created within this distance from the start mark the start area (m).
pub const START_AREA: f64 = 30.0;
/// The car counts as back at the start within this distance of its first pose (m).
pub const NEAR_START: f64 = 12.0;
/// ... and at most this far to the side of its first heading (m). A
/// straight driven the same way beside the start stands two lanes off or
/// more (eufs_comp_2021's third straight: 12 m), while a lap may end a
/// few metres aside (`realistic`, random track 19 seed 203: 5.9 m).
pub const NEAR_START_ASIDE: f64 = 8.0;
/// The shortest loop (m).
pub const MIN_LOOP: f64 = 60.0;

/// Sightings before a landmark's colours can call it clutter, and that a
/// landmark needs to stay in the map once every detection of the run has
/// been matched again: a cone passed in two laps is seen 30–60 times, while
/// on eufs_rand a clutter object seen only from 13–15 m off the track was
/// matched 3–5 times, too few for its colours or misses to judge it.
pub const JUDGE_AFTER: u32 = 6;

/// Log odds from which a landmark's colours call it clutter (400 : 1).
const CLUTTER_LOG_ODDS: f64 = 6.0;

/// How often an object that is not a cone is detected while well in view:
/// about as often as not, against a cone's `detection_probability` (the
/// simulator detects its clutter objects in 30% of the scans).
const CLUTTER_DETECTION: f64 = 0.5;

/// Where a landmark stands relative to the car's view.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    /// In view, or left only recently.
    Visible,
    /// Out of view for a while.
    Left,
    /// Seen again at the start of a new lap.
    Returned,
}

/// Per-landmark bookkeeping shared by the estimators.
#[derive(Clone, Debug, PartialEq)]
pub struct Sighting {
    /// Colour votes, by [`Color::index`].
    pub votes: [u32; 5],
    /// Times associated.
    pub seen: u32,
    /// Times in view but not associated.
    pub missed: u32,
    /// Seen often enough to be part of the map.
    pub confirmed: bool,
    /// See [`View`].
    pub view: View,
    /// Scan and distance driven when last seen.
    pub last_seen: usize,
    /// See `last_seen`.
    pub last_seen_distance: f64,
    /// Distance driven and heading when the landmark was created.
    pub created_distance: f64,
    /// See `created_distance`.
    pub created_heading: f64,
}

impl Sighting {
    /// A landmark first detected with `color` in `scan`, after driving
    /// `distance`, heading `heading`. It is not counted as seen yet.
    pub fn new(color: Color, scan: usize, distance: f64, heading: f64) -> Self {
        let mut votes = [0; 5];
        votes[color.index()] += 1;
        Self {
            votes,
            seen: 0,
            missed: 0,
            confirmed: false,
            view: View::Visible,
            last_seen: scan,
            last_seen_distance: distance,
            created_distance: distance,
            created_heading: heading,
        }
    }

    /// A landmark of a given map: confirmed, with a settled colour.
    pub fn known(color: Color) -> Self {
        let mut s = Self::new(Color::Unknown, 0, 0.0, 0.0);
        s.votes = [0; 5];
        s.votes[color.index()] = 100;
        s.seen = 100;
        s.confirmed = true;
        s
    }

    /// The colour most votes went to.
    pub fn color(&self) -> Color {
        Color::KNOWN
            .into_iter()
            .max_by_key(|c| self.votes[c.index()])
            .filter(|c| self.votes[c.index()] > 0)
            .unwrap_or(Color::Unknown)
    }

    /// Whether `color` contradicts a clear majority of the votes.
    pub fn contradicts(&self, color: Color) -> bool {
        if color == Color::Unknown {
            return false;
        }
        let known: u32 = Color::KNOWN.iter().map(|c| self.votes[c.index()]).sum();
        known > 0 && 2 * self.votes[color.index()] < known
    }

    /// Counts a sighting with `color`; confirms after `confirm_after`.
    pub fn count(&mut self, color: Color, confirm_after: u32) {
        self.votes[color.index()] += 1;
        self.seen += 1;
        if self.seen >= confirm_after {
            self.confirmed = true;
        }
    }

    /// Takes in the sightings of `duplicate`, a second landmark of the
    /// same cone: its colour votes and sightings, whether it was confirmed
    /// and when it was last seen.
    pub fn absorb(&mut self, duplicate: &Sighting) {
        for (votes, more) in self.votes.iter_mut().zip(duplicate.votes) {
            *votes += more;
        }
        self.seen += duplicate.seen;
        self.confirmed |= duplicate.confirmed;
        if duplicate.last_seen > self.last_seen {
            self.last_seen = duplicate.last_seen;
            self.last_seen_distance = duplicate.last_seen_distance;
        }
    }

    /// Whether the landmark marks the start of the lap: created in the first
    /// [`START_AREA`] metres and seen again after driving at least
    /// [`MIN_LOOP`] metres, heading the same way. Adjacent parts of a track
    /// driven the other way then cannot fake a closure.
    pub fn is_start_area(&self, distance: f64, heading: f64) -> bool {
        self.created_distance < START_AREA
            && distance > self.created_distance + MIN_LOOP
            && normalize_angle(heading - self.created_heading).abs() < 0.8
    }

    /// Records that the landmark was associated in `scan`; returns whether
    /// it counts as returned at the start of a new lap.
    pub fn revisit(&mut self, scan: usize, distance: f64, heading: f64) -> bool {
        let start_area = self.is_start_area(distance, heading);
        let returned = match self.view {
            View::Left if start_area => {
                self.view = View::Returned;
                true
            }
            View::Left => {
                self.view = View::Visible;
                false
            }
            View::Returned => true,
            View::Visible => false,
        };
        self.last_seen = scan;
        self.last_seen_distance = distance;
        returned
    }

    /// After a loop closure: a returned landmark counts as in view again,
    /// so the next lap must return it anew.
    pub fn settle(&mut self) {
        if self.view == View::Returned {
            self.view = View::Visible;
        }
    }

    /// Log odds that this is clutter rather than a cone, from its colour
    /// votes. A cone is read as its own colour but for `color_wrong` (one
    /// other colour) and `color_unknown` of the time; an object that is not
    /// a cone (a sign, a person, a traffic barrel) is read as blue, yellow
    /// or unknown about equally often.
    pub fn clutter_log_odds(&self, config: &FrontEndConfig) -> f64 {
        let top = Color::KNOWN
            .into_iter()
            .max_by_key(|c| self.votes[c.index()])
            .unwrap_or(Color::Blue);
        let wrong = config.color_wrong.clamp(1e-3, 0.3);
        let unknown = config.color_unknown.clamp(1e-3, 1.0);
        let cone = |c: Color| match c {
            Color::Unknown => unknown,
            c if c == top => (1.0 - wrong - unknown).max(1e-3),
            _ => wrong,
        };
        let clutter = |c: Color| match c {
            Color::Blue | Color::Yellow | Color::Unknown => CLUTTER_UNKNOWN,
            Color::Orange | Color::BigOrange => 1e-3,
        };
        [
            Color::Blue,
            Color::Yellow,
            Color::Orange,
            Color::BigOrange,
            Color::Unknown,
        ]
        .into_iter()
        .map(|c| self.votes[c.index()] as f64 * (clutter(c) / cone(c)).ln())
        .sum()
    }

    /// Whether the colour votes say clutter: `CLUTTER_LOG_ODDS` or more,
    /// after `JUDGE_AFTER` sightings.
    pub fn looks_like_clutter(&self, config: &FrontEndConfig) -> bool {
        self.seen >= JUDGE_AFTER && self.clutter_log_odds(config) >= CLUTTER_LOG_ODDS
    }

    /// Whether colours and detections together say clutter, for a
    /// judgement on the whole run when the poses are final: the colours
    /// lean to clutter, and their log odds plus those of being detected in
    /// `hits` and missed in `misses` of the scans that had it well in view
    /// reach `CLUTTER_LOG_ODDS`. Misses alone never decide: a cone mapped
    /// twice shares its detections between the two (the hairpins track,
    /// 40 of 110 scans each), and a real detector misses occluded cones.
    pub fn is_clutter(&self, hits: u32, misses: u32, config: &FrontEndConfig) -> bool {
        let colour = self.clutter_log_odds(config);
        let p = config.detection_probability.clamp(0.6, 0.999);
        let q = CLUTTER_DETECTION;
        let detection =
            f64::from(hits) * (q / p).ln() + f64::from(misses) * ((1.0 - q) / (1.0 - p)).ln();
        colour > 0.0 && colour + detection >= CLUTTER_LOG_ODDS
    }

    /// Updates the counts and the view after a scan: `visible` says whether
    /// the landmark should have been seen, `associated` whether it was.
    /// Returns whether it should be dropped while mapping: missed more often
    /// than seen, or [clutter by its colours](Self::looks_like_clutter).
    pub fn after_scan(
        &mut self,
        config: &FrontEndConfig,
        visible: bool,
        associated: bool,
        mapping: bool,
        scan: usize,
        distance: f64,
    ) -> bool {
        let mut drop = mapping && self.looks_like_clutter(config);
        if visible && !associated && mapping {
            self.missed += 1;
            drop |= self.missed > self.seen + 1 && !(self.confirmed && self.seen >= 10);
        }
        if !visible && scan > self.last_seen + 10 && distance > self.last_seen_distance + 20.0 {
            self.view = View::Left;
        }
        drop
    }
}

/// How often clutter reads as each of blue, yellow and unknown.
const CLUTTER_UNKNOWN: f64 = 1.0 / 3.0;

/// Detections before the detector's rate of colourless readings is learnt.
const COLOR_RATE_AFTER: u64 = 50;

/// The detector's rate of `unknown` colours on cones, as the log shows it.
/// A detector that gives no colour (a lidar, a camera that reads barcodes)
/// says `unknown` of every object; colour is evidence, so such a reading
/// must not count against a landmark. [`ColorRate::learn`] raises the
/// assumed `color_unknown` to the rate the log shows where that is well above
/// it (never lowers it), which takes the weight out of `unknown` readings
/// where they are the rule.
/// The log's rate mixes cones and clutter, which reads `unknown` a third of
/// the time ([`Sighting::clutter_log_odds`]); the assumed false positives
/// per scan say how much of it is clutter.
#[derive(Clone, Copy, Debug)]
pub struct ColorRate {
    assumed: f64,
    scans: u64,
    detections: u64,
    unknown: u64,
}

impl ColorRate {
    /// Starts from the assumed rate of `config`.
    pub fn new(config: &FrontEndConfig) -> Self {
        Self {
            assumed: config.color_unknown,
            scans: 0,
            detections: 0,
            unknown: 0,
        }
    }

    /// Counts a scan's detections and sets `config.color_unknown` to the
    /// cones' rate seen so far where it is more than twice the assumed one.
    pub fn learn(&mut self, cones: &[crate::log::Detection], config: &mut FrontEndConfig) {
        self.scans += 1;
        self.detections += cones.len() as u64;
        self.unknown += cones.iter().filter(|d| d.color == Color::Unknown).count() as u64;
        if self.detections >= COLOR_RATE_AFTER {
            let n = self.detections as f64;
            let clutter = (config.false_positives * self.scans as f64 / n).min(0.9);
            let seen = self.unknown as f64 / n;
            let cones = ((seen - clutter * CLUTTER_UNKNOWN) / (1.0 - clutter)).clamp(0.0, 1.0);
            // Clutter objects beside a track also read `unknown` often,
            // and the false positives do not count them: within twice the
            // assumed rate the log does not contradict the assumption.
            config.color_unknown = if cones > 2.0 * self.assumed {
                cones
            } else {
                self.assumed
            };
        }
    }
}

/// Whether a world point lies well inside the assumed field of view.
pub fn in_view(config: &FrontEndConfig, pose_inverse: &SE2, point: &Vector2<f64>) -> bool {
    in_view_within(config, pose_inverse, point, ViewMargin::WHILE_MAPPING)
}

/// In how many of the scans whose poses are given (scan index and inverse
/// pose) `point` lay in view ([`ViewMargin::FINAL`]), split into those in
/// `seen` (sorted scan indices: the scans that detected it) and the rest:
/// the hits and misses [`Sighting::is_clutter`] weighs.
pub fn hits_and_misses<'a>(
    config: &FrontEndConfig,
    inverses: impl IntoIterator<Item = (usize, &'a SE2)>,
    point: &Vector2<f64>,
    seen: &[usize],
) -> (u32, u32) {
    let (mut hits, mut misses) = (0, 0);
    for (k, inverse) in inverses {
        if in_view_within(config, inverse, point, ViewMargin::FINAL) {
            if seen.binary_search(&k).is_ok() {
                hits += 1;
            } else {
                misses += 1;
            }
        }
    }
    (hits, misses)
}

/// How far inside the field of view a landmark must lie to count as in
/// view: the margin covers the errors of the pose and the landmark.
#[derive(Clone, Copy, Debug)]
pub struct ViewMargin {
    /// Short of the range limit (m).
    pub range: f64,
    /// Inside the edge of the field of view (rad).
    pub bearing: f64,
}

impl ViewMargin {
    /// While mapping, when poses and landmarks may be off by decimetres.
    pub const WHILE_MAPPING: Self = Self {
        range: 1.0,
        bearing: 0.1,
    };
    /// With the final poses and map, good to a few centimetres and a tenth
    /// of a degree. On eufs_rand the margin of the mapping kept clutter
    /// objects 13–15 m off the track in view for 3–5 scans a run, too few to
    /// judge them (`standard`, 30 seeds: 1.0 of them per run stayed in the
    /// map; with this margin 0.3).
    pub const FINAL: Self = Self {
        range: 0.1,
        bearing: 0.01,
    };
}

/// Whether a world point lies inside the assumed field of view by `margin`.
pub fn in_view_within(
    config: &FrontEndConfig,
    pose_inverse: &SE2,
    point: &Vector2<f64>,
    margin: ViewMargin,
) -> bool {
    let local = pose_inverse.transform_point(point);
    let fov = config.fov / 2.0 - margin.bearing;
    let range = config.max_range - margin.range;
    local.norm() < range && local.norm() > 1.0 && local.y.atan2(local.x).abs() < fov
}

/// Whether `pose` is back where the run began: near it, not far to its
/// side, heading the same way.
pub fn near_start(first: &SE2, pose: &SE2) -> bool {
    near_start_within(first, pose, NEAR_START)
}

/// [`near_start`], where the estimate may be up to `reach` metres (at least
/// [`NEAR_START`]) ahead of or behind the start: after a long lap's drift the
/// car reaches the start cones only once its estimate has passed them.
pub fn near_start_within(first: &SE2, pose: &SE2, reach: f64) -> bool {
    let offset = first.inverse().transform_point(&pose.t);
    offset.norm() < reach.max(NEAR_START)
        && offset.y.abs() < NEAR_START_ASIDE
        && normalize_angle(first.theta - pose.theta).abs() < 0.8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cone_misread_now_and_then_is_not_clutter_but_a_colour_flipping_object_is() {
        let config = FrontEndConfig::default();
        let mut cone = Sighting::new(Color::Blue, 0, 0.0, 0.0);
        let mut clutter = cone.clone();
        for k in 0..20 {
            let read = match k {
                7 => Color::Yellow,
                12 => Color::Unknown,
                _ => Color::Blue,
            };
            cone.count(read, 3);
            clutter.count([Color::Blue, Color::Yellow, Color::Unknown][k % 3], 3);
            assert!(!cone.looks_like_clutter(&config), "after {k}: {cone:?}");
        }
        assert!(clutter.looks_like_clutter(&config), "{clutter:?}");
        // Six sightings of a clutter object: already clear.
        let mut few = Sighting::new(Color::Blue, 0, 0.0, 0.0);
        for read in [Color::Yellow, Color::Unknown, Color::Yellow, Color::Blue] {
            few.count(read, 3);
            assert!(!few.looks_like_clutter(&config), "judged early: {few:?}");
        }
        for read in [Color::Unknown, Color::Yellow] {
            few.count(read, 3);
        }
        assert!(few.looks_like_clutter(&config), "{few:?}");
        // A young cone read as unknown twice is not judged yet.
        let mut young = Sighting::new(Color::Unknown, 0, 0.0, 0.0);
        young.count(Color::Unknown, 3);
        young.count(Color::Unknown, 3);
        assert!(!young.looks_like_clutter(&config));
        // Dropped only while mapping.
        assert!(clutter.after_scan(&config, false, false, true, 30, 0.0));
        assert!(!clutter.after_scan(&config, false, false, false, 31, 0.0));
    }

    #[test]
    fn the_final_margin_counts_what_lies_just_inside_the_sensor_view() {
        let config = FrontEndConfig::default();
        let car = SE2::new(2.0, 1.0, 0.5).inverse();
        let from_car = |range: f64, bearing: f64| {
            SE2::new(2.0, 1.0, 0.5)
                .transform_point(&Vector2::new(range * bearing.cos(), range * bearing.sin()))
        };
        let edge = config.fov / 2.0;
        let view = |p: Vector2<f64>| {
            (
                in_view(&config, &car, &p),
                in_view_within(&config, &car, &p, ViewMargin::FINAL),
            )
        };
        assert_eq!(view(from_car(10.0, 0.3)), (true, true));
        // 0.5 m short of the range limit, or 0.05 rad inside the edge.
        assert_eq!(view(from_car(config.max_range - 0.5, 0.0)), (false, true));
        assert_eq!(view(from_car(8.0, edge - 0.05)), (false, true));
        // Beyond the sensor's reach, or too close to call.
        assert_eq!(view(from_car(config.max_range - 0.05, 0.0)), (false, false));
        assert_eq!(view(from_car(8.0, edge - 0.005)), (false, false));
        assert_eq!(view(from_car(0.8, 0.0)), (false, false));
    }

    #[test]
    fn misses_tip_a_landmark_whose_colours_lean_to_clutter_but_never_decide_alone() {
        let config = FrontEndConfig::default();
        let mut rare = Sighting::new(Color::Blue, 0, 0.0, 0.0);
        for read in [Color::Blue, Color::Unknown, Color::Yellow, Color::Blue] {
            rare.count(read, 3);
        }
        // Too few sightings for the colours alone, and they alone are not enough.
        assert!(!rare.looks_like_clutter(&config));
        assert!(!rare.is_clutter(4, 0, &config));
        // Seen in 4 of the 14 scans that had it in view: clutter.
        assert!(rare.is_clutter(4, 10, &config));
        // A cone mapped twice sees half its detections go to the twin; a
        // cone seen rarely but always in its colour stays too.
        let mut cone = Sighting::new(Color::Yellow, 0, 0.0, 0.0);
        for k in 0..40 {
            cone.count(
                if k % 10 == 3 {
                    Color::Unknown
                } else {
                    Color::Yellow
                },
                3,
            );
        }
        assert!(!cone.is_clutter(40, 70, &config));
        let mut faint = Sighting::new(Color::Blue, 0, 0.0, 0.0);
        for _ in 0..4 {
            faint.count(Color::Blue, 3);
        }
        assert!(!faint.is_clutter(4, 30, &config));
    }

    #[test]
    fn back_at_the_start_means_behind_or_past_it_not_beside_it() {
        let first = SE2::new(20.0, -14.0, std::f64::consts::PI);
        let at = |x, y, theta| near_start(&first, &SE2::new(x, y, theta));
        // Coming back along the start's line, before or past the start.
        assert!(at(31.0, -14.5, 3.0));
        assert!(at(10.0, -13.0, 3.1));
        // Metres of drift to the side.
        assert!(at(22.0, -10.0, 3.1));
        assert!(at(18.0, -21.0, 3.1));
        // A parallel straight 11 m away, heading the same way.
        assert!(!at(20.0, -3.0, 3.1));
        // The right place, the wrong way.
        assert!(!at(20.0, -14.0, 0.0));
        // Too far back.
        assert!(!at(33.0, -14.0, 3.1));
        // Unless the drift may be that large; still not beside the start.
        let within = |x, y, theta| near_start_within(&first, &SE2::new(x, y, theta), 20.0);
        assert!(within(33.0, -14.0, 3.1));
        assert!(within(2.0, -15.0, 3.1));
        assert!(!within(20.0, -3.0, 3.1));
        assert!(!within(41.0, -14.0, 3.1));
    }
}
