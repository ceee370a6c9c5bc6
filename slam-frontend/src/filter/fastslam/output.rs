//! What FastSLAM reports: the best particle's map, path and associations.

use super::FastSlam;
use crate::files::{Association, StampedPose};
use crate::filter::particle::Step;
use crate::map::Cone;
use cairn_core::SE2;

impl FastSlam {
    /// Confirmed, live landmarks of the best particle, in index order, less
    /// those the whole run judges clutter.
    fn map_rows(&self) -> Vec<usize> {
        let best = self.best();
        let live =
            (0..best.map.len()).filter(|&l| !best.map[l].removed && best.map[l].sighting.confirmed);
        let poses: Vec<(usize, SE2)> = self.steps().map(|s| (s.scan, s.pose.pose)).collect();
        let matched = self.steps().flat_map(|s| {
            s.choices
                .iter()
                .filter_map(move |c| Some((s.scan, (*c)? as usize)))
        });
        let clutter = crate::filter::judged_clutter(
            &self.run.config,
            &poses,
            matched,
            live.clone()
                .map(|l| (l, best.map[l].mean, &best.map[l].sighting)),
        );
        live.filter(|l| !clutter.contains(l)).collect()
    }

    /// The best particle's map: confirmed landmarks with their covariances.
    pub fn map(&self) -> Vec<Cone> {
        let best = self.best();
        self.map_rows()
            .into_iter()
            .map(|l| Cone {
                position: best.map[l].mean,
                color: best.map[l].sighting.color(),
                covariance: best.map[l].cov,
            })
            .collect()
    }

    /// The best particle's path, one pose per scan.
    pub fn trajectory(&self) -> Vec<StampedPose> {
        let mut poses: Vec<StampedPose> = self.steps().map(|s| s.pose).collect();
        poses.reverse();
        poses
    }

    /// The best particle's associations: for every detection, its row in
    /// [`FastSlam::map`] (or none).
    pub fn associations(&self) -> Vec<Association> {
        let best = self.best();
        let mut steps: Vec<&Step> = self.steps().collect();
        steps.reverse();
        let detections = steps.into_iter().flat_map(|s| {
            s.choices
                .iter()
                .enumerate()
                .map(move |(det, c)| (s.scan, det, c.map(|l| l as usize)))
        });
        crate::files::in_map_rows(detections, best.map.len(), &self.map_rows())
    }

    /// The best particle's path, newest first.
    fn steps(&self) -> impl Iterator<Item = &Step> {
        std::iter::successors(self.best().path.as_deref(), |s| s.parent.as_deref())
    }
}
