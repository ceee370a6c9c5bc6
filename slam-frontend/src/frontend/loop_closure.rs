//! Loop closure: start-area landmarks that return after a lap, place
//! recognition when drift hides them from the gates, the full optimisation
//! that follows, and placing the car on a given map.

use super::association::{AssociationMethod, Candidates, Correlation, associate};
use super::{GraphSlam, Mode, Observation, align, chi2_99, nearest_information};
use crate::color::Color;
use crate::log::Detection;
use crate::sighting::{START_AREA, View, near_start_within};
use cairn_core::SE2;
use nalgebra::{Matrix2, Matrix3, Vector2};

/// How far back the landmarks of [`GraphSlam::recent_submap`] were made (m).
const RECENT: f64 = 40.0;

/// A scan kept to be matched again later (near the start until the loop
/// closes, every scan until the end of the run, scans waiting for
/// relocalisation).
#[derive(Clone, Debug)]
pub(super) struct PendingScan {
    /// Its pose.
    pub keyframe: usize,
    /// Its first detection in [`GraphSlam::detections`].
    pub first: usize,
    /// Its detections.
    pub cones: Vec<Detection>,
}

impl GraphSlam {
    /// Whether landmark `l` marks the start of the lap ([`crate::sighting::Sighting::is_start_area`]).
    pub(super) fn is_start_area(&self, l: usize) -> bool {
        self.landmarks[l]
            .sighting
            .is_start_area(self.motion.distance(), self.pose.theta)
    }

    /// Whether `pose` is back where the run began, within the drift place
    /// recognition allows for the distance driven.
    pub(super) fn back_at_start(&self, pose: &SE2) -> bool {
        let reach = align::max_shift(self.motion.distance());
        self.poses
            .first()
            .is_some_and(|p| near_start_within(&p.pose, pose, reach))
    }

    /// Whether landmark `l` is a start-area landmark waiting for the lap to
    /// close. The gates assume the pose and the landmark are known to a few
    /// centimetres of each other, which a lap of drift breaks: near a cone
    /// spacing they match the wrong cones and bend the whole loop. So these
    /// landmarks are left out of the gates ([`Self::candidates`]) and
    /// matched only through place recognition, not only once the car is
    /// back near the start but on the way there, when the sensor first
    /// reaches them: on random tracks with cones 1.5–2 m apart, `hard`
    /// drift is a spacing, and far detections gated there onto the start
    /// area closed 5 runs of 20 one cone off (association 54%). Once the
    /// loop has closed, the map holds together and later laps (when mapping
    /// goes on) are matched by the gates.
    pub(super) fn awaits_loop_closure(&self, l: usize) -> bool {
        self.mode == Mode::Mapping
            && self.closed_at.is_none()
            && self.landmarks[l].sighting.view == View::Left
            && self.is_start_area(l)
    }

    /// Whether the start area has big orange cones in the map.
    pub(super) fn start_line_mapped(&self) -> bool {
        (0..self.landmarks.len()).any(|l| {
            self.in_map(l)
                && self.landmarks[l].sighting.created_distance < START_AREA
                && self.landmarks[l].sighting.color() == Color::BigOrange
        })
    }

    /// Whether a start-area landmark waiting for the loop to close is
    /// within the sensor's reach.
    pub(super) fn start_area_in_reach(&self) -> bool {
        let reach = self.config.max_range + 5.0;
        (0..self.landmarks.len()).any(|l| {
            self.in_map(l)
                && self.awaits_loop_closure(l)
                && (self.landmarks[l].mean - self.pose.t).norm() < reach
        })
    }

    /// Drift can put returning landmarks outside the association gates, so
    /// the place is also recognised geometrically: the scan is aligned to
    /// the landmarks that left the view long ago, near the current pose.
    /// When enough detections agree, they are tied to those landmarks,
    /// which closes the loop in the graph.
    pub(super) fn recognise_place(
        &mut self,
        cones: &[Detection],
        covs: &[Matrix2<f64>],
        keyframe: usize,
    ) -> bool {
        let reach = self.config.max_range + 5.0;
        // Where the start line was mapped, it anchors the large corrections.
        let start_line = self.start_line_mapped();
        let usable = |r: align::Recognised| (!start_line || r.anchored().is_some()).then_some(r);
        let old: Vec<usize> = (0..self.landmarks.len())
            .filter(|&l| {
                self.in_map(l)
                    && self.awaits_loop_closure(l)
                    && (self.landmarks[l].mean - self.pose.t).norm() < reach
            })
            .collect();
        let map: Vec<(Vector2<f64>, Color)> = old
            .iter()
            .map(|&l| (self.landmarks[l].mean, self.landmarks[l].sighting.color()))
            .collect();
        // Near the start the gates leave the old landmarks alone, so the
        // detections they matched to confirmed landmarks belong to the
        // lap's end. The rest (unmatched, or on tentative landmarks the
        // drift made) propose the alignments, and at least half of them
        // (or of the old landmarks near) must agree. So do the start
        // line's big orange cones, which anchor a large correction even
        // when the gates have matched them to the lap's end's duplicates.
        let first = self.detections.len() - cones.len();
        let unexplained: Vec<Detection> = cones
            .iter()
            .zip(&self.detections[first..])
            .filter(|(c, d)| {
                c.color == Color::BigOrange
                    || d.2.is_none_or(|l| !self.landmarks[l].sighting.confirmed)
            })
            .map(|(c, _)| c.clone())
            .collect();
        let needed = self
            .config
            .loop_min_returned
            .max(unexplained.len().min(old.len()) / 2);
        // A correction of half a cone spacing or more could as well be one
        // spacing off; the start line's orange cones must confirm it.
        let reach = align::Reach::lap_end(&map, self.motion.distance());
        // Where drift put the car's estimate more than a gate away, the
        // lap's end has mapped the start area again: its landmarks, each
        // placed by many sightings, are aligned when the scan alone is not.
        // Their covariances weigh them in the fit: far ones are the noisiest.
        let weighed: Vec<Detection> = cones
            .iter()
            .zip(covs)
            .map(|(c, cov)| Detection {
                covariance: Some(*cov),
                ..c.clone()
            })
            .collect();
        let found = align::recognise(&map, &weighed, &unexplained, &self.pose, needed, reach)
            .and_then(usable)
            .or_else(|| {
                let recent = self.recent_submap(start_line);
                let needed = self
                    .config
                    .loop_min_returned
                    .max(recent.len().min(old.len()) / 2);
                align::recognise(&map, &recent, &recent, &self.pose, needed, reach).and_then(usable)
            });
        let Some(found) = found else {
            return false;
        };
        let Some(aligned) = self.place_votes.confirm(&self.pose, found) else {
            return false;
        };
        for (i, d) in cones.iter().enumerate() {
            let w = aligned.transform_point(&d.position);
            let nearest = old
                .iter()
                .map(|&l| (l, (self.landmarks[l].mean - w).norm()))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((l, dist)) = nearest
                && dist < 0.6
            {
                // A detection the gates matched to the lap's end keeps its
                // one sighting, now of the old landmark (pushed again, it
                // counted twice once the two landmarks merged).
                let matched = self.detections[first + i].2.and_then(|_| {
                    self.observations
                        .iter()
                        .rposition(|o| o.pose == keyframe && o.z == d.position)
                });
                match matched {
                    Some(o) => self.observations[o].landmark = l,
                    None => self.observations.push(Observation {
                        pose: keyframe,
                        landmark: l,
                        z: d.position,
                        information: nearest_information(&covs[i]),
                    }),
                }
                self.detections[first + i].2 = Some(l);
                self.landmarks[l].sighting.view = View::Returned;
            }
        }
        true
    }

    /// The landmarks mapped in the last [`RECENT`] metres of this lap near
    /// the car, as the car sees them. Without a `start_line` mapped, only
    /// those since the car came back near the start: those of the lap's end
    /// before it stand where no old landmark is, and counted, they favour
    /// fits that shift the car along the start row. (With it, they help:
    /// epfl_track_3_cones, `hard` seed 0, closed 3.2 m off without them.)
    fn recent_submap(&self, start_line: bool) -> Vec<Detection> {
        let reach = self.config.max_range + 5.0;
        let distance = self.motion.distance();
        let inverse = self.pose.inverse();
        (0..self.landmarks.len())
            .filter(|&l| {
                let lm = &self.landmarks[l];
                self.in_map(l)
                    && lm.sighting.created_distance >= START_AREA
                    && (start_line
                        || self
                            .returned_at
                            .is_some_and(|d| lm.sighting.created_distance >= d))
                    && distance - lm.sighting.created_distance < RECENT
                    && (lm.mean - self.pose.t).norm() < reach
            })
            .map(|l| Detection {
                position: inverse.transform_point(&self.landmarks[l].mean),
                range_bearing: None,
                color: self.landmarks[l].sighting.color(),
                id: None,
                covariance: None,
            })
            .collect()
    }

    /// Places the car on the given map, if this scan may try
    /// ([`align::Placement`]).
    pub(super) fn align_to_map(&mut self, cones: &[Detection]) -> bool {
        let map: Vec<(Vector2<f64>, Color)> = self
            .landmarks
            .iter()
            .map(|l| (l.mean, l.sighting.color()))
            .collect();
        let here = self.pose.compose(&self.motion.pending());
        let found = self.placement.try_place(&map, cones, &here);
        let Some(pose) = found else { return false };
        self.pose = pose;
        self.pose_cov = Matrix3::from_diagonal(&nalgebra::Vector3::new(0.25, 0.25, 0.05));
        self.motion.take();
        self.aligned = true;
        true
    }

    /// Matches again what the scans near the start left unmatched before the
    /// loop closed. Until then the gates leave the start area's landmarks to
    /// place recognition ([`Self::awaits_loop_closure`]), which ties only
    /// the scan it recognises: the detections of the scans before it stayed
    /// unmatched (40–60 per run on the 90 m eufs_boa_constrictor). Now the
    /// optimised poses place them, maximum likelihood matches them to the
    /// landmarks their scan left free, and their sightings join the final
    /// optimisation.
    pub(super) fn match_near_start_scans(&mut self) {
        let scans = std::mem::take(&mut self.near_start_scans);
        self.match_again(&scans, self.config.gate);
    }

    /// The candidates of a logged scan's detections within the χ² `gate`
    /// from its pose as it now stands, and the detections' covariances.
    pub(super) fn candidates_again(
        &self,
        scan: &PendingScan,
        gate: f64,
    ) -> (Candidates, Vec<Matrix2<f64>>) {
        let pose = self.poses[scan.keyframe].pose;
        let covs: Vec<Matrix2<f64>> = scan
            .cones
            .iter()
            .map(|d| self.config.detection_cov(d))
            .collect();
        let (candidates, _) = self.candidates(&pose, &self.pose_cov, &scan.cones, &covs, gate);
        (candidates, covs)
    }

    /// Matches the unmatched detections of `scans` from their poses as
    /// they now stand, by maximum likelihood within the χ² `gate` among the
    /// landmarks each scan left free, each match a sighting.
    pub(super) fn match_again(&mut self, scans: &[PendingScan], gate: f64) {
        let pose_cov = self.pose_cov;
        for scan in scans {
            let slots = scan.first..scan.first + scan.cones.len();
            let matched: Vec<Option<usize>> = self.detections[slots]
                .iter()
                .map(|d| {
                    d.2.map(|l| self.resolve(l)).filter(|&l| {
                        self.landmarks[l].sighting.confirmed && !self.landmarks[l].removed
                    })
                })
                .collect();
            if matched.iter().all(Option::is_some) {
                continue;
            }
            let (mut candidates, covs) = self.candidates_again(scan, gate);
            for (i, pairs) in candidates.iter_mut().enumerate() {
                if matched[i].is_some() {
                    pairs.clear();
                } else {
                    pairs.retain(|p| !matched.contains(&Some(p.landmark)));
                }
            }
            let assigned = associate(
                AssociationMethod::MaximumLikelihood,
                &candidates,
                &vec![None; candidates.len()],
                |pairs| chi2_99(2 * pairs),
                Correlation::ThroughPose(&pose_cov),
            );
            for (i, l) in assigned.iter().enumerate() {
                let Some(l) = *l else { continue };
                let confirm = self.config.confirm_after;
                self.landmarks[l]
                    .sighting
                    .count(scan.cones[i].color, confirm);
                self.detections[scan.first + i].2 = Some(l);
                self.observations.push(Observation {
                    pose: scan.keyframe,
                    landmark: l,
                    z: scan.cones[i].position,
                    information: nearest_information(&covs[i]),
                });
            }
        }
        // The smoothing window folds sightings in pose order.
        self.observations.sort_by_key(|o| o.pose);
        self.refold();
    }

    /// Optimises every pose and confirmed landmark, merges duplicates,
    /// matches the scans near the start again, and switches to
    /// localisation if configured.
    pub(super) fn close_loop(&mut self) {
        self.loop_closures += 1;
        self.closed_at = Some(self.motion.distance());
        self.place_votes.clear();
        if let Err(e) = self.optimise(super::optimise::Batch::loop_closure(
            self.matches_in_hindsight(),
        )) {
            self.warnings.push(format!(
                "loop closure {}: the optimisation failed ({e}); kept the estimate",
                self.loop_closures
            ));
        }
        for lm in &mut self.landmarks {
            lm.sighting.settle();
        }
        // Before localisation, which matches confirmed landmarks only: the
        // start area's tentative ones (cones seen once at the edge of the
        // view as the run began, which the gates used to confirm on the
        // way back) are confirmed by these scans.
        self.match_near_start_scans();
        if self.config.localise_after_loop {
            self.mode = Mode::Localising;
        }
    }
}
