//! Where a filter's lap ends: back near its first pose, among the landmarks
//! it left the start area with, as place recognition finds them or as the
//! gates match them.

use super::Run;
use crate::color::Color;
use crate::frontend::{Mode, align};
use crate::log::Detection;
use crate::sighting::{START_AREA, Sighting, View, near_start, near_start_within};
use cairn_core::SE2;
use nalgebra::Vector2;

impl Run {
    /// Which landmarks, seen from `pose`, mark the start area and wait for
    /// the first lap to close. As in the graph, the gates leave them alone
    /// from when the car, mapping, comes within the sensor's reach of the
    /// start (aside at most [`NEAR_START_ASIDE`](crate::sighting::NEAR_START_ASIDE)):
    /// they assume the pose and the landmark known to a few centimetres of
    /// each other, and a lap's drift near a cone spacing matches the start
    /// area's cones one cone off (FastSLAM 2.0 on
    /// epfl_fsds_competition_1_cones, `standard` seed 0: gated 2.2 m off,
    /// the loop closed there and the run ended 12 m off). A stretch of
    /// track that passes further aside keeps them in the gates.
    pub(super) fn awaiting_closure(&self, pose: &SE2) -> impl Fn(&Sighting) -> bool {
        let approaching = self.approaching(pose);
        let (distance, heading) = (self.motion.distance(), pose.theta);
        move |sighting| {
            approaching && sighting.view == View::Left && sighting.is_start_area(distance, heading)
        }
    }

    /// Whether the car at `pose`, mapping its first lap, is within the
    /// sensor's reach of the start ([`Self::awaiting_closure`]).
    fn approaching(&self, pose: &SE2) -> bool {
        let reach = align::max_shift(self.motion.distance()) + self.config.max_range;
        self.mode == Mode::Mapping
            && self.loop_closures == 0
            && self
                .first_pose
                .is_some_and(|f| near_start_within(&f, pose, reach))
    }

    /// Follows the car's approach to the start: the first scan of the
    /// approach `pose` at `scan` is on, if it is on one.
    pub(super) fn approach(&mut self, pose: &SE2, scan: usize) -> Option<usize> {
        if self.approaching(pose) {
            Some(*self.approach_scan.get_or_insert(scan))
        } else {
            self.approach_scan = None;
            None
        }
    }

    /// Whether `pose` is back where the run began, while mapping. Away from
    /// there the votes for a place are forgotten.
    pub(super) fn back_at_start(&mut self, pose: &SE2) -> bool {
        let back =
            self.mode == Mode::Mapping && self.first_pose.is_some_and(|f| near_start(&f, pose));
        if !back {
            self.place_votes.clear();
        }
        back
    }

    /// The confirmed start-area landmarks near `pose` among `landmarks`
    /// (mean and sighting), those place recognition fits a scan to, and
    /// whether the start line's big orange cones are mapped.
    fn start_area<'a>(
        &self,
        pose: &SE2,
        landmarks: impl Iterator<Item = (Vector2<f64>, &'a Sighting)>,
    ) -> (Vec<(Vector2<f64>, Color)>, bool) {
        let distance = self.motion.distance();
        let reach = self.config.max_range + 5.0;
        let confirmed: Vec<_> = landmarks.filter(|(_, s)| s.confirmed).collect();
        let start_line = confirmed
            .iter()
            .any(|(_, s)| s.created_distance < START_AREA && s.color() == Color::BigOrange);
        let old = confirmed
            .iter()
            .filter(|(mean, sighting)| {
                sighting.view == View::Left
                    && sighting.is_start_area(distance, pose.theta)
                    && (mean - pose.t).norm() < reach
            })
            .map(|(mean, sighting)| (*mean, sighting.color()))
            .collect();
        (old, start_line)
    }

    /// Place recognition back at the start, for EKF-SLAM, whose drift can
    /// hide the start landmarks from the gates and which fuses the place as
    /// a measurement of its pose: where `cones` put the car among the
    /// `landmarks` (mean and sighting) it left the start area with, in one
    /// scan, anchored within [`align::BASE_SHIFT`]. (Confirmed over scans,
    /// as FastSLAM's, the second fit fused on eufs_rand `standard` seed 22
    /// was the worse of two: 0.110 → 0.229 m.)
    pub(super) fn recognise_once<'a>(
        &self,
        pose: &SE2,
        cones: &[Detection],
        landmarks: impl Iterator<Item = (Vector2<f64>, &'a Sighting)>,
    ) -> Option<SE2> {
        let (old, _) = self.start_area(pose, landmarks);
        let needed = self.config.loop_min_returned.max(cones.len() / 2);
        let reach = align::Reach {
            unambiguous: align::unambiguous_shift(&old),
            max_shift: align::BASE_SHIFT,
        };
        align::recognise(&old, cones, cones, pose, needed, reach)?.anchored()
    }

    /// Place recognition back at the start, for FastSLAM, which moves its
    /// map to the place and ties the start area's detections to it: where
    /// `cones` put the car among the `landmarks` (mean and sighting) it left
    /// the start area with, once the scans agree on it ([`PlaceVotes`]).
    /// As in the graph, beyond half a cone spacing a fit one spacing along a
    /// regular row can score best, so a larger correction needs the start
    /// line's big orange cones (where they are mapped), or more scans that
    /// agree, to confirm it; and the drift allowed grows with the lap.
    ///
    /// [`PlaceVotes`]: crate::frontend::place_votes::PlaceVotes
    pub(super) fn recognise<'a>(
        &mut self,
        pose: &SE2,
        cones: &[Detection],
        landmarks: impl Iterator<Item = (Vector2<f64>, &'a Sighting)>,
    ) -> Option<SE2> {
        let (old, start_line) = self.start_area(pose, landmarks);
        let needed = self
            .config
            .loop_min_returned
            .max(cones.len().min(old.len()) / 2);
        let reach = align::Reach::lap_end(&old, self.motion.distance());
        let found = align::recognise(&old, cones, cones, pose, needed, reach)?;
        if start_line && found.anchored().is_none() {
            return None;
        }
        self.place_votes.confirm(pose, found)
    }

    /// Whether a lap ends at `pose` with `returned` landmarks back in view.
    pub(super) fn lap_closed(&mut self, pose: &SE2, returned: usize) -> bool {
        let first = *self.first_pose.get_or_insert(*pose);
        self.mode == Mode::Mapping
            && returned >= self.config.loop_min_returned
            && near_start(&first, pose)
    }
}
