//! Association in hindsight: at the end of the run, every detection is
//! matched again from the optimised poses and map, along its tracker id's
//! chain of sightings (tracking association) or scan by scan (the other
//! methods, which have no ids).
//!
//! The `hard` preset's noise at 10–15 m (0.3–0.4 m) is larger than the gaps
//! between the EUFS tracks' cones (1–2 m; the start's big orange pairs
//! 0.28 m). Even from the true poses and map, each scan's most likely
//! assignment gets only 97.1–97.7% of the detections right on
//! eufs_boa_constrictor, comp_2021, hairpins and peanut (eufs_rand 98.0%,
//! the other tracks 99.1–99.4%; 5 seeds, `scripts/association_limit.py`),
//! and matching each detection alone 95.4–96.3%. The tracker follows a cone
//! from far to near, so its id ties the ambiguous far sightings to the
//! clear near ones: the most likely landmark sequence of each chain
//! (Viterbi), where the id moves to another object only rarely, gets 99.2%
//! of eufs_boa_constrictor's from the true poses and map.
//!
//! Scan by scan, a detection still gains from hindsight: the poses and map
//! it is matched against are the final optimisation's rather than those of
//! the moment it was seen, and clutter is an alternative to every landmark
//! (15 tracks × 10 seeds, `hard`: maximum likelihood 97.99 → 98.40%, SCNN
//! 97.20 → 98.23%, JCBB 97.27 → 97.99%, the EUFS tracks by 1–3 points;
//! `standard` 99.73–99.82 → 99.82–99.83%). Assigning each scan as a whole
//! rather than claim by claim weighs both detections of a close pair
//! (15 tracks × 5 seeds: `standard` 99.88 → 99.92%, eufs_boa_constrictor
//! 99.49 → 99.68%; `hard` 98.32–98.44 → 98.46–98.60%).
//!
//! A detector's noise is rarely Gaussian to the last percent: a cone's
//! likelihood has a tail four times as wide whose weight, and the clutter
//! rate beside it, are learnt from the detections themselves
//! (`hindsight/tail.rs`). On Student-t noise of the assumed σ this kept
//! the 1–2% of detections beyond the Gaussian's gate with their cones
//! (random track 11, seed 11: 99.03 → 99.86%); on Gaussian logs the
//! weight stays near 0.

mod scan;
mod tail;
mod unmatched;

use super::GraphSlam;
use super::Observation;
use super::OptimiseError;
use super::association::{AssociationMethod, Candidates};
use super::edges::nearest_information;
use super::loop_closure::PendingScan;
use super::optimise::Batch;
use crate::sighting::JUDGE_AFTER;
use std::collections::HashMap;
use tail::{SPREAD, Tail};

/// How likely a tracker id moves to another object between two sightings,
/// before the chains say (the simulator's `hard` preset swaps two of ~20
/// ids in 3% of scans); [`chain_paths`] learns it.
const ID_SWITCH: f64 = 0.003;

/// Times, at most, the switch rate is learnt again and the paths found
/// with it; it stops once the rate changes by less than a factor 2.
const SWITCH_ROUNDS: usize = 3;

/// An id unseen for more scans than this starts a new chain (trackers may
/// reuse ids).
const CHAIN_GAP: usize = 10;

/// Rounds of settling two detections of one scan that claim one landmark.
const ROUNDS: usize = 10;

/// One detection of a chain: its slot in [`GraphSlam::detections`], its
/// scan, and the cost (−2 log likelihood) of each landmark and of clutter.
#[derive(Clone)]
struct Link {
    slot: usize,
    scan: usize,
    landmarks: Vec<(usize, f64)>,
    clutter: f64,
}

impl Link {
    fn cost(&self, state: Option<usize>) -> f64 {
        match state {
            None => self.clutter,
            Some(l) => self
                .landmarks
                .iter()
                .find(|p| p.0 == l)
                .map_or(f64::INFINITY, |p| p.1),
        }
    }
}

impl GraphSlam {
    /// Whether [`GraphSlam::finish`] matches every detection again.
    pub(super) fn matches_in_hindsight(&self) -> bool {
        self.config.hindsight
    }

    /// Matches every detection of `scans` again from the poses and map as
    /// they stand, chain by chain, one landmark per detection per scan, and
    /// rebuilds the sightings from the result. Detections left unexplained
    /// that gather on one spot found a landmark
    /// ([`GraphSlam::map_unmatched_clusters`]); landmarks left without a
    /// sighting leave the map. With `learn_tail`, a cone's likelihood has
    /// the detector's tail and clutter its rate, both learnt from these
    /// detections (`hindsight/tail.rs`). Returns the matches changed and
    /// the tail.
    fn associate_in_hindsight(
        &mut self,
        scans: &[PendingScan],
        gate: f64,
        learn_tail: bool,
    ) -> (usize, Tail) {
        let sector = 0.5 * self.config.fov * self.config.max_range.powi(2);
        // Out to where the detector's tail could reach, for the tail to be
        // learnt from and to explain.
        let reach = if learn_tail {
            gate * SPREAD * SPREAD
        } else {
            gate
        };
        let candidates: Vec<Candidates> = scans
            .iter()
            .map(|s| self.candidates_again(s, reach).0)
            .collect();
        let assumed = self.config.false_positives;
        let tail = if learn_tail {
            let nearest: Vec<_> = candidates.iter().flatten().map(|p| p.first()).collect();
            Tail::learn(&nearest, scans.len(), sector, assumed)
        } else {
            Tail::none(assumed, sector)
        };
        let chains = self.chains(scans, candidates, &tail, gate);
        let by_scan = links_by_scan(&chains);
        let paths = if self.config.association == AssociationMethod::Tracking {
            chain_paths(&chains, &by_scan)
        } else {
            scan::assignments(&chains, &by_scan)
        };
        let mut changed = 0;
        for (chain, path) in chains.iter().zip(&paths) {
            for (link, &l) in chain.iter().zip(path) {
                let before = self.detections[link.slot].2.map(|x| self.resolve(x));
                changed += usize::from(before != l.map(|x| self.resolve(x)));
                self.detections[link.slot].2 = l;
            }
        }
        self.map_unmatched_clusters(scans);
        self.rebuild_sightings(scans);
        (changed, tail)
    }

    /// Matches every detection again and optimises, for the config's
    /// `hindsight_rounds` or until a round changes no match. On MRCLAM
    /// Dataset 6, whose tubes stand 0.15–0.25 m apart, each round moves
    /// 0.5–7% of the matches and the map with them: five rounds took
    /// maximum-likelihood association from 73.8 to 79.9% over the five
    /// robots (SCNN 77.4 → 84.9%, JCBB 79.9 → 84.4%). Before them, with
    /// `hindsight_anneal` above 1, rounds at a wider σ ([`anneal`]).
    pub(super) fn settle_in_hindsight(
        &mut self,
        scans: &[PendingScan],
        gate: f64,
    ) -> Result<(), OptimiseError> {
        let sigma = self.config.detector_sigma();
        let widened = anneal(self.config.hindsight_anneal).try_for_each(|k| {
            self.config.set_detector_sigma(sigma.map(|s| s * k));
            self.associate_in_hindsight(scans, gate, false);
            self.optimise(Batch::last(true))
        });
        self.config.set_detector_sigma(sigma);
        widened?;
        let (_, mut tail) = self.associate_in_hindsight(scans, gate, true);
        self.optimise(Batch::last(true))?;
        for _ in 1..self.config.hindsight_rounds {
            let (changed, learnt) = self.associate_in_hindsight(scans, gate, true);
            tail = learnt;
            if changed == 0 {
                break;
            }
            self.optimise(Batch::last(true))?;
        }
        self.report_tail(&tail);
        Ok(())
    }

    /// The chains of sightings: one per tracker id (split where it went
    /// unseen for long), one per detection without an id; each detection
    /// of `scans` with its `candidates` (within the χ² `gate`, or beyond it
    /// where the detector's `tail` explains them) and clutter.
    fn chains(
        &self,
        scans: &[PendingScan],
        candidates: Vec<Candidates>,
        tail: &Tail,
        gate: f64,
    ) -> Vec<Vec<Link>> {
        let mut chains: Vec<Vec<Link>> = Vec::new();
        let mut open: HashMap<u64, (usize, usize)> = HashMap::new();
        for (s, candidates) in scans.iter().zip(candidates) {
            for (i, (d, pairs)) in s.cones.iter().zip(candidates).enumerate() {
                let slot = s.first + i;
                let scan = self.detections[slot].0;
                let link = Link {
                    slot,
                    scan,
                    landmarks: pairs
                        .iter()
                        .filter(|p| tail.admits(p, gate))
                        .map(|p| (p.landmark, tail.cost(p)))
                        .collect(),
                    clutter: tail.clutter,
                };
                // Without tracking association every detection is a chain of its own.
                let id =
                    d.id.filter(|_| self.config.association == AssociationMethod::Tracking);
                let chain = match id.and_then(|id| open.get(&id).map(|&o| (id, o))) {
                    Some((id, (last, c))) if scan <= last + CHAIN_GAP => {
                        open.insert(id, (scan, c));
                        c
                    }
                    _ => {
                        chains.push(Vec::new());
                        if let Some(id) = id {
                            open.insert(id, (scan, chains.len() - 1));
                        }
                        chains.len() - 1
                    }
                };
                chains[chain].push(link);
            }
        }
        chains
    }

    /// The sightings and each landmark's colour votes again, from the
    /// detections of `scans` as now matched. Landmarks matched fewer than
    /// [`JUDGE_AFTER`] times (or than a tentative one needs to be confirmed)
    /// leave the map: typically a cone's second landmark, whose detections
    /// the chains gave to the first, left with a false positive or two that
    /// would pull it off the cone, or a clutter object seen only from afar.
    fn rebuild_sightings(&mut self, scans: &[PendingScan]) {
        let mut votes = vec![[0u32; 5]; self.landmarks.len()];
        for s in scans {
            for (i, d) in s.cones.iter().enumerate() {
                if let Some(l) = self.detections[s.first + i].2 {
                    votes[l][d.color.index()] += 1;
                }
            }
        }
        for l in self.map_rows() {
            let seen: u32 = votes[l].iter().sum();
            let sighting = &mut self.landmarks[l].sighting;
            sighting.votes = votes[l];
            sighting.seen = seen;
            if seen < self.config.confirm_after.max(JUDGE_AFTER) {
                self.landmarks[l].removed = true;
            }
        }
        self.observations.clear();
        for s in scans {
            for (i, d) in s.cones.iter().enumerate() {
                let slot = &mut self.detections[s.first + i].2;
                let Some(l) = *slot else {
                    continue;
                };
                if self.landmarks[l].removed {
                    *slot = None;
                    continue;
                }
                self.observations.push(Observation {
                    pose: s.keyframe,
                    landmark: l,
                    z: d.position,
                    information: nearest_information(&self.config.detection_cov(d)),
                });
            }
        }
        self.refold();
    }
}

/// The σ factors of the annealing rounds that begin at `start`: the
/// variance halves each round, down to the last factor above 1 (none for
/// `start` ≤ 1). On MRCLAM Dataset 6, beginning at 8 (σ × 8, 5.7, 4, 2.8,
/// 2, 1.4, then the rounds at σ) took maximum-likelihood association over
/// the five robots from 79.9 to 85.6% (SCNN 84.9 → 87.6%, JCBB 84.4 →
/// 87.1%), and robot 1 from 13 landmarks of 15 to 14.
fn anneal(start: f64) -> impl Iterator<Item = f64> {
    let rounds = if start > 1.0 {
        (2.0 * start.log2()).ceil() as i32
    } else {
        0
    };
    (0..rounds).map(move |i| start * 0.5f64.powf(0.5 * f64::from(i)))
}

/// Each scan's links, as (chain, position in the chain).
fn links_by_scan(chains: &[Vec<Link>]) -> Vec<Vec<(usize, usize)>> {
    let mut by_scan: Vec<Vec<(usize, usize)>> = Vec::new();
    for (c, chain) in chains.iter().enumerate() {
        for (t, link) in chain.iter().enumerate() {
            if by_scan.len() <= link.scan {
                by_scan.resize_with(link.scan + 1, Vec::new);
            }
            by_scan[link.scan].push((c, t));
        }
    }
    by_scan
}

/// Each chain's most likely landmark sequence, one landmark per detection
/// per scan. How often the tracker's ids switch is learnt from the paths
/// (hard EM): a tracker that switches more than assumed lets its chains
/// follow weaker evidence from cone to cone, one that never does holds
/// them. On the `realistic` preset's nearest-neighbour tracker it came out
/// at about 0.08 per sighting, on the `hard` preset's 0.0005–0.001 (random
/// tracks 0 and 3, seed 100).
fn chain_paths(chains: &[Vec<Link>], by_scan: &[Vec<(usize, usize)>]) -> Vec<Vec<Option<usize>>> {
    let mut rate = ID_SWITCH;
    let mut paths = settled_paths(chains, by_scan, rate);
    for _ in 0..SWITCH_ROUNDS {
        let learnt = switch_rate(&paths);
        if (learnt / rate).ln().abs() < 2f64.ln() {
            break;
        }
        rate = learnt;
        paths = settled_paths(chains, by_scan, rate);
    }
    paths
}

/// The id switches per step of `paths`, with [`ID_SWITCH`] as a prior
/// worth one switch.
fn switch_rate(paths: &[Vec<Option<usize>>]) -> f64 {
    let (switches, steps) = paths.iter().fold((0, 0), |(s, n), p| {
        let switched = p.windows(2).filter(|w| w[0] != w[1]).count();
        (s + switched, n + p.len().saturating_sub(1))
    });
    (switches as f64 + 1.0) / (steps as f64 + 1.0 / ID_SWITCH)
}

/// [`best_path`] for every chain with ids switching at `rate` per step,
/// two detections of a scan never on one landmark.
fn settled_paths(
    chains: &[Vec<Link>],
    by_scan: &[Vec<(usize, usize)>],
    rate: f64,
) -> Vec<Vec<Option<usize>>> {
    let mut chains = chains.to_vec();
    let switch = -2.0 * rate.ln();
    let mut paths: Vec<Vec<Option<usize>>> = chains.iter().map(|c| best_path(c, switch)).collect();
    for _ in 0..ROUNDS {
        let redo = settle_claims(&mut chains, &paths, by_scan);
        if redo.is_empty() {
            break;
        }
        for c in redo {
            paths[c] = best_path(&chains[c], switch);
        }
    }
    paths
}

/// The chain's most likely landmark sequence: each link's cost plus
/// `switch` wherever the state changes (Viterbi).
fn best_path(chain: &[Link], switch: f64) -> Vec<Option<usize>> {
    let mut states: Vec<Option<usize>> = chain
        .iter()
        .flat_map(|link| link.landmarks.iter().map(|p| Some(p.0)))
        .collect();
    states.push(None);
    states.sort_unstable();
    states.dedup();
    let k = states.len();
    let mut cost: Vec<f64> = states.iter().map(|&s| chain[0].cost(s)).collect();
    let mut back = vec![0usize; chain.len() * k];
    let mut next = vec![0.0; k];
    for (t, link) in chain.iter().enumerate().skip(1) {
        let (best, lowest) = argmin(&cost);
        for (j, &s) in states.iter().enumerate() {
            let (from, c) = if cost[j] <= lowest + switch {
                (j, cost[j])
            } else {
                (best, lowest + switch)
            };
            back[t * k + j] = from;
            next[j] = c + link.cost(s);
        }
        std::mem::swap(&mut cost, &mut next);
    }
    let mut j = argmin(&cost).0;
    let mut path = vec![None; chain.len()];
    for t in (0..chain.len()).rev() {
        path[t] = states[j];
        j = back[t * k + j];
    }
    path
}

fn argmin(values: &[f64]) -> (usize, f64) {
    values.iter().copied().enumerate().fold(
        (0, f64::INFINITY),
        |a, (i, v)| if v < a.1 { (i, v) } else { a },
    )
}

/// Where two detections of one scan claim one landmark, the chain that
/// holds it longer (then the likelier detection) keeps it, and the others
/// lose it as a candidate while the keeper holds it: two objects tracked
/// at once are not one cone (a clutter object beside a cone, seen a third
/// as often, took the cone's landmark whenever the cone went undetected).
/// `by_scan` lists each scan's links as (chain, position). Returns the
/// chains to redo.
fn settle_claims(
    chains: &mut [Vec<Link>],
    paths: &[Vec<Option<usize>>],
    by_scan: &[Vec<(usize, usize)>],
) -> Vec<usize> {
    let mut redo = Vec::new();
    let mut claims: Vec<(usize, Holding, f64, usize, usize)> = Vec::new();
    for links in by_scan {
        claims.clear();
        for &(c, t) in links {
            if let Some(l) = paths[c][t] {
                let holding = Holding::of(&chains[c], &paths[c], l);
                claims.push((l, holding, chains[c][t].cost(Some(l)), c, t));
            }
        }
        claims.sort_unstable_by(|a, b| {
            (a.0.cmp(&b.0))
                .then(b.1.links.cmp(&a.1.links))
                .then(a.2.total_cmp(&b.2))
                .then(a.3.cmp(&b.3))
        });
        for pair in claims.windows(2) {
            let (l, _, _, c, _) = pair[1];
            if pair[0].0 != l {
                continue;
            }
            let keeper = pair[0].1;
            for link in &mut chains[c] {
                if (keeper.first..=keeper.last).contains(&link.scan) {
                    link.landmarks.retain(|p| p.0 != l);
                }
            }
            redo.push(c);
        }
    }
    redo.sort_unstable();
    redo.dedup();
    redo
}

/// How a chain holds a landmark: its links on it, and the first and last
/// of their scans.
#[derive(Clone, Copy)]
struct Holding {
    links: usize,
    first: usize,
    last: usize,
}

impl Holding {
    fn of(chain: &[Link], path: &[Option<usize>], l: usize) -> Holding {
        let mut h = Holding {
            links: 0,
            first: usize::MAX,
            last: 0,
        };
        for (link, &state) in chain.iter().zip(path) {
            if state == Some(l) {
                h.links += 1;
                h.first = h.first.min(link.scan);
                h.last = h.last.max(link.scan);
            }
        }
        h
    }
}

#[cfg(test)]
mod tests;
