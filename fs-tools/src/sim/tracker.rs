//! The tracker ids a simulated detector writes: an oracle keyed on the
//! true object, or a gated nearest-neighbour tracker on the noisy
//! detections, as a car's perception stack has.

use super::Source;
use cairn_core::SE2;
use nalgebra::Vector2;
use rand::Rng;
use std::collections::{BTreeSet, HashMap};

/// How the simulated detector gives its tracker ids.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TrackerModel {
    /// Keyed on the true object: an id lasts while the object is seen
    /// within 3 scans, and the ids of two objects less than 3 m apart swap
    /// with the sensor's `id_swap` probability per scan. Close to an oracle.
    Oracle,
    /// Gated nearest neighbour on the noisy detections, each track moved by
    /// the odometry since the last scan: closest pairs within `gate` (m)
    /// first, each track and detection once; a detection left over starts a
    /// track; a track missed more than `max_misses` scans in a row ends, and
    /// its id is free again (the smallest free id is taken first). Ids
    /// switch between cones closer than the gate, fragment after misses and
    /// come back on other cones.
    NearestNeighbour {
        /// Largest distance (m) between a track and its next detection.
        gate: f64,
        /// Scans a track survives without a detection.
        max_misses: usize,
    },
}

/// The state of either tracker.
pub(super) enum Tracker {
    Oracle(OracleTracker),
    Nearest(NearestTracker),
}

impl Tracker {
    pub(super) fn new(model: TrackerModel) -> Self {
        match model {
            TrackerModel::Oracle => Tracker::Oracle(OracleTracker::default()),
            TrackerModel::NearestNeighbour { gate, max_misses } => {
                Tracker::Nearest(NearestTracker {
                    gate,
                    max_misses,
                    tracks: Vec::new(),
                    free: BTreeSet::new(),
                    next: 0,
                })
            }
        }
    }
}

/// Ids keyed on the true object.
#[derive(Default)]
pub(super) struct OracleTracker {
    ids: HashMap<Source, (u64, usize)>,
    next: u64,
    scan: usize,
}

impl OracleTracker {
    /// The ids of one scan's objects; with probability `id_swap`, two
    /// tracked objects less than 3 m apart swap theirs.
    pub(super) fn ids<T>(
        &mut self,
        found: &[(Source, Vector2<f64>, T)],
        id_swap: f64,
        rng: &mut impl Rng,
    ) -> Vec<u64> {
        self.scan += 1;
        let mut ids: Vec<u64> = found.iter().map(|(s, _, _)| self.id(*s)).collect();
        if found.len() >= 2 && rng.random::<f64>() < id_swap {
            let i = rng.random_range(0..found.len());
            let near = (0..found.len()).find(|&j| {
                j != i
                    && found[j].0 != Source::FalsePositive
                    && found[i].0 != Source::FalsePositive
                    && (found[j].1 - found[i].1).norm() < 3.0
            });
            if let Some(j) = near {
                ids.swap(i, j);
                for k in [i, j] {
                    if let Some(entry) = self.ids.get_mut(&found[k].0) {
                        entry.0 = ids[k];
                    }
                }
            }
        }
        ids
    }

    fn id(&mut self, source: Source) -> u64 {
        let scan = self.scan;
        if source == Source::FalsePositive {
            self.next += 1;
            return self.next;
        }
        match self.ids.get_mut(&source) {
            Some((id, last)) if scan <= *last + 3 => {
                *last = scan;
                *id
            }
            _ => {
                self.next += 1;
                self.ids.insert(source, (self.next, scan));
                self.next
            }
        }
    }
}

/// One track: its id, where it was last seen (vehicle frame of the last
/// scan) and the scans it has been missed in a row.
struct Track {
    id: u64,
    position: Vector2<f64>,
    misses: usize,
}

/// Gated nearest-neighbour tracks.
pub(super) struct NearestTracker {
    gate: f64,
    max_misses: usize,
    tracks: Vec<Track>,
    free: BTreeSet<u64>,
    next: u64,
}

impl NearestTracker {
    /// The ids of one scan's detections (vehicle frame), the vehicle
    /// having moved by `motion` (as the odometry measured it) since the
    /// last scan.
    pub(super) fn ids(&mut self, detections: &[Vector2<f64>], motion: &SE2) -> Vec<u64> {
        let back = motion.inverse();
        for track in &mut self.tracks {
            track.position = back.transform_point(&track.position);
        }
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (t, track) in self.tracks.iter().enumerate() {
            for (d, p) in detections.iter().enumerate() {
                let distance = (p - track.position).norm();
                if distance <= self.gate {
                    pairs.push((distance, t, d));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut ids: Vec<Option<u64>> = vec![None; detections.len()];
        let mut seen = vec![false; self.tracks.len()];
        for (_, t, d) in pairs {
            if !seen[t] && ids[d].is_none() {
                seen[t] = true;
                ids[d] = Some(self.tracks[t].id);
                self.tracks[t].position = detections[d];
                self.tracks[t].misses = 0;
            }
        }
        for (track, seen) in self.tracks.iter_mut().zip(&seen) {
            if !seen {
                track.misses += 1;
            }
        }
        let max_misses = self.max_misses;
        let free = &mut self.free;
        self.tracks.retain(|track| {
            let alive = track.misses <= max_misses;
            if !alive {
                free.insert(track.id);
            }
            alive
        });
        ids.iter()
            .zip(detections)
            .map(|(id, p)| match id {
                Some(id) => *id,
                None => {
                    let id = self.free.pop_first().unwrap_or_else(|| {
                        self.next += 1;
                        self.next
                    });
                    self.tracks.push(Track {
                        id,
                        position: *p,
                        misses: 0,
                    });
                    id
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tracker(gate: f64, max_misses: usize) -> NearestTracker {
        match Tracker::new(TrackerModel::NearestNeighbour { gate, max_misses }) {
            Tracker::Nearest(t) => t,
            Tracker::Oracle(_) => unreachable!(),
        }
    }

    #[test]
    fn a_track_follows_its_cone_as_the_car_moves() {
        let mut t = tracker(0.5, 1);
        let first = t.ids(
            &[Vector2::new(10.0, 1.0), Vector2::new(10.0, -1.0)],
            &SE2::identity(),
        );
        // The car moved 1 m forward: the cones are 1 m nearer.
        let second = t.ids(
            &[Vector2::new(9.0, -1.0), Vector2::new(9.0, 1.0)],
            &SE2::new(1.0, 0.0, 0.0),
        );
        assert_eq!(second, [first[1], first[0]]);
    }

    #[test]
    fn ids_fragment_after_misses_and_are_reused() {
        let mut t = tracker(0.5, 1);
        let a = t.ids(&[Vector2::new(5.0, 0.0)], &SE2::identity())[0];
        // Missed twice: the track ends and its id is free.
        t.ids(&[], &SE2::identity());
        t.ids(&[], &SE2::identity());
        // The same cone again gets the freed id back; another cone elsewhere
        // a new one.
        let again = t.ids(
            &[Vector2::new(20.0, 0.0), Vector2::new(5.0, 0.0)],
            &SE2::identity(),
        );
        assert_eq!(again[0], a, "the smallest free id is reused");
        assert_ne!(again[1], a);
    }

    #[test]
    fn cones_closer_than_the_gate_can_swap_ids() {
        let mut t = tracker(1.0, 0);
        let ids = t.ids(
            &[Vector2::new(5.0, 0.0), Vector2::new(5.0, 0.6)],
            &SE2::identity(),
        );
        // Both detections moved 0.5 m towards the other's old place.
        let next = t.ids(
            &[Vector2::new(5.0, 0.5), Vector2::new(5.0, 0.1)],
            &SE2::identity(),
        );
        assert_eq!(
            next,
            [ids[1], ids[0]],
            "the first detection took the second cone's id"
        );
    }
}
