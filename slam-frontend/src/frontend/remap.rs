//! Revisits of landmarks mapped twice. When relocalisation gives up, the
//! landmarks in view are mapped as new ones from a pose that may be metres
//! off; where the car was in fact back among mapped landmarks, these are
//! duplicates, and the gates, trusting the pose, keep matching them instead
//! of the originals. At the end of the run each such batch of landmarks is
//! fitted, as one rigid shape, onto the landmarks mapped before it: a clear
//! fit moves everything mapped since onto the earlier map and merges the
//! duplicates into their originals, so that the final optimisation closes
//! the loop. Like relocalisation, this reads no start line: the map's own
//! geometry recognises the revisit.

use super::GraphSlam;
use super::relocalise::{AGREE, BASELINE, MARGIN};
use crate::points::{rigid_motion, two_point};
use cairn_core::SE2;
use nalgebra::Vector2;

/// Where mapping went on after relocalisation gave up: the first pose and
/// the first landmark made from then on.
#[derive(Clone, Copy, Debug)]
pub(super) struct Remapped {
    pub keyframe: usize,
    pub landmark: usize,
}

/// Bound on the search's work (pairs of earlier landmarks looked at, plus
/// landmark distances computed to count each fit's agreement), far above
/// MRCLAM's batches (a few million): a batch of hundreds of cones on a
/// track must not stall the end of the run.
const MAX_WORK: usize = 30_000_000;

/// Fits turned further apart than this (rad) are different fits.
const DISTINCT_TURN: f64 = 0.2;

impl GraphSlam {
    /// Fits each batch of landmarks mapped after relocalisation gave up onto
    /// the landmarks before it and merges the duplicates ([`Remapped`]).
    /// Returns how many landmarks were merged.
    pub(super) fn merge_remapped(&mut self) -> usize {
        let batches = std::mem::take(&mut self.remapped);
        let mut merged = 0;
        for (i, batch) in batches.iter().enumerate() {
            let end = batches
                .get(i + 1)
                .map_or(self.landmarks.len(), |b| b.landmark);
            let old: Vec<usize> = (0..batch.landmark).filter(|&l| self.in_map(l)).collect();
            let new: Vec<usize> = (batch.landmark..end).filter(|&l| self.in_map(l)).collect();
            let position = |list: &[usize]| -> Vec<Vector2<f64>> {
                list.iter().map(|&l| self.landmarks[l].mean).collect()
            };
            let Some(correction) = fit_shape(&position(&old), &position(&new)) else {
                continue;
            };
            // Everything since moves with the batch.
            let first = batch.keyframe.min(self.poses.len());
            for p in &mut self.poses[first..] {
                p.pose = correction.compose(&p.pose);
            }
            let rotation = correction.rotation();
            for lm in &mut self.landmarks[batch.landmark..] {
                lm.mean = correction.transform_point(&lm.mean);
                lm.cov = rotation * lm.cov * rotation.transpose();
            }
            self.pose = correction.compose(&self.pose);
            merged += self.merge_onto(&old, &new);
        }
        merged
    }

    /// Merges each landmark of `new` into the one landmark of `old` within
    /// [`AGREE`], unless a scan saw both. Where two stand that close (MRCLAM
    /// Dataset 6's tubes 0.15–0.25 m apart), which one it is cannot be told
    /// and it stays: merged into the nearest, robot 3 with JCBB put half of
    /// some landmarks' detections on a neighbour (71 → 58% by majority).
    fn merge_onto(&mut self, old: &[usize], new: &[usize]) -> usize {
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for &n in new {
            let near =
                |o: &&usize| (self.landmarks[n].mean - self.landmarks[**o].mean).norm() < AGREE;
            if old.iter().filter(near).count() != 1 {
                continue;
            }
            for &o in old {
                let d = (self.landmarks[n].mean - self.landmarks[o].mean).norm();
                if d < AGREE
                    && self.landmarks[n]
                        .sighting
                        .color()
                        .compatible(self.landmarks[o].sighting.color())
                {
                    pairs.push((d, n, o));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let candidates: Vec<(usize, usize)> = pairs.iter().map(|&(_, n, o)| (n, o)).collect();
        let scans = self.scans_seeing(&candidates);
        let mut merged = 0;
        for (n, o) in candidates {
            if self.alias[n] != n
                || self.alias[o] != o
                || super::optimise::shares_a_scan(&scans[&n], &scans[&o])
            {
                continue;
            }
            self.absorb(o, n);
            merged += 1;
        }
        merged
    }
}

/// The rigid correction that puts the shape `new` onto landmarks of `old`,
/// if one is clear: it puts at least three of `new` (and half of them)
/// within [`AGREE`] of a landmark, spread at least two [`BASELINE`]s apart
/// so that they fix the turn, and [`MARGIN`] more than any fit elsewhere.
/// No prior weighs the fits: relocalisation gave up because the drift was
/// too large to bound (MRCLAM's commanded velocities overstate spins by up
/// to 16°, beyond the drift the odometry's noise model allows). Refined by
/// least squares on the landmarks that agree.
fn fit_shape(old: &[Vector2<f64>], new: &[Vector2<f64>]) -> Option<SE2> {
    if old.len() < 3 || new.len() < 3 {
        return None;
    }
    let nearest = |w: &Vector2<f64>| {
        old.iter()
            .copied()
            .min_by(|a, b| (a - w).norm().total_cmp(&(b - w).norm()))
            .filter(|m| (m - w).norm() < AGREE)
    };
    let agreeing = |c: &SE2| {
        new.iter()
            .filter(|p| nearest(&c.transform_point(p)).is_some())
            .count()
    };
    let mut fits: Vec<(SE2, usize)> = Vec::new();
    // Past the bound the search gives up rather than take a fit it could
    // not show clear.
    let mut work = 0usize;
    for (i, a) in new.iter().enumerate() {
        for b in &new[i + 1..] {
            let length = (b - a).norm();
            if length < BASELINE {
                continue;
            }
            work += old.len() * old.len();
            for (j, ma) in old.iter().enumerate() {
                for (k, mb) in old.iter().enumerate() {
                    if j == k || ((mb - ma).norm() - length).abs() > 2.0 * AGREE {
                        continue;
                    }
                    let Some(c) = two_point(a, b, ma, mb) else {
                        continue;
                    };
                    work += new.len() * old.len();
                    if work > MAX_WORK {
                        return None;
                    }
                    fits.push((c, agreeing(&c)));
                }
            }
        }
    }
    let &(best, count) = fits.iter().max_by_key(|f| f.1)?;
    // A fit elsewhere moves the shape's centre a baseline from the best's,
    // or turns it by more than DISTINCT_TURN.
    let centre = new.iter().sum::<Vector2<f64>>() / new.len() as f64;
    let same = |c: &SE2| {
        (c.transform_point(&centre) - best.transform_point(&centre)).norm() < BASELINE
            && cairn_core::se2::normalize_angle(c.theta - best.theta).abs() < DISTINCT_TURN
    };
    let rival = fits
        .iter()
        .filter(|f| !same(&f.0))
        .map(|f| f.1)
        .max()
        .unwrap_or(0);
    if count < 3.max(new.len().div_ceil(2)) || (count as f64) < rival as f64 + MARGIN {
        return None;
    }
    let (from, to): (Vec<_>, Vec<_>) = new
        .iter()
        .filter_map(|p| Some((*p, nearest(&best.transform_point(p))?)))
        .unzip();
    let spread = to
        .iter()
        .flat_map(|a| to.iter().map(move |b| (a - b).norm()))
        .fold(0.0, f64::max);
    if spread < 2.0 * BASELINE {
        return None;
    }
    rigid_motion(&from, &to)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points(list: &[(f64, f64)]) -> Vec<Vector2<f64>> {
        list.iter().map(|&(x, y)| Vector2::new(x, y)).collect()
    }

    /// Ten landmarks scattered over a 10 m × 8 m room.
    fn room() -> Vec<Vector2<f64>> {
        points(&[
            (3.2, 1.2),
            (6.5, 0.6),
            (5.4, 2.9),
            (0.6, 4.1),
            (0.7, 0.7),
            (4.2, 6.6),
            (1.2, 1.8),
            (6.3, 7.6),
            (9.8, 0.4),
            (8.6, 2.3),
        ])
    }

    #[test]
    fn a_shape_mapped_again_metres_off_is_fitted_back_onto_the_map() {
        let old = room();
        // Five of them mapped again from a pose 2.5 m and 0.4 rad off, with
        // a few centimetres of noise, and one landmark never mapped before.
        let off = SE2::new(2.0, -1.5, 0.4);
        let noise = [
            (0.03, -0.02),
            (-0.02, 0.01),
            (0.01, 0.03),
            (0.0, -0.03),
            (-0.03, 0.0),
        ];
        let mut new: Vec<Vector2<f64>> = [1, 2, 5, 8, 9]
            .iter()
            .zip(noise)
            .map(|(&i, (dx, dy))| off.transform_point(&old[i]) + Vector2::new(dx, dy))
            .collect();
        new.push(off.transform_point(&Vector2::new(8.0, 5.0)));
        let found = fit_shape(&old, &new).expect("a clear fit");
        let back = found.compose(&off);
        assert!(back.t.norm() < 0.05 && back.theta.abs() < 0.02, "{back:?}");
    }

    #[test]
    fn a_batch_of_hundreds_of_cones_is_not_searched_without_end() {
        // Two rows of 300 cones 1.5 m apart, mapped again 0.7 m along: the
        // search stops at its bound and takes nothing.
        let rows = |shift: f64| -> Vec<Vector2<f64>> {
            (0..600)
                .map(|i| Vector2::new(1.5 * (i / 2) as f64 + shift, 3.0 * (i % 2) as f64))
                .collect()
        };
        assert!(fit_shape(&rows(0.0), &rows(0.7)).is_none());
    }

    #[test]
    fn a_shape_that_fits_nowhere_or_anywhere_is_left_alone() {
        // Nothing like the map.
        let new = points(&[(0.0, 0.0), (0.0, 5.0), (9.0, 0.2)]);
        assert!(fit_shape(&room(), &new).is_none());
        // A regular row fits as well shifted by one spacing.
        let row: Vec<Vector2<f64>> = (0..8).map(|i| Vector2::new(2.0 * i as f64, 0.0)).collect();
        let again: Vec<Vector2<f64>> = (0..4)
            .map(|i| Vector2::new(2.0 * i as f64 + 0.9, 0.4))
            .collect();
        assert!(fit_shape(&row, &again).is_none());
    }
}
