//! Matching in hindsight without tracker ids: each scan's most likely
//! assignment of landmarks (or clutter) to its detections.

use super::Link;
use cairn_core::DisjointSets;
use pathfinding::prelude::{Matrix, kuhn_munkres_min};
use std::collections::HashMap;

/// Chains of one link (no tracker ids): each scan's most likely
/// assignment, every landmark taken at most once. Settling claims one by
/// one, the cheaper claim first, gets a close pair of cones the wrong way
/// round whenever the other detection fits its own cone better still; the
/// assignment weighs both.
pub(super) fn assignments(
    chains: &[Vec<Link>],
    by_scan: &[Vec<(usize, usize)>],
) -> Vec<Vec<Option<usize>>> {
    let mut paths = vec![Vec::new(); chains.len()];
    for links in by_scan {
        let scan: Vec<&Link> = links.iter().map(|&(c, t)| &chains[c][t]).collect();
        for group in sharing_landmarks(&scan) {
            let members: Vec<&Link> = group.iter().map(|&i| scan[i]).collect();
            for (&i, l) in group.iter().zip(most_likely_assignment(&members)) {
                paths[links[i].0] = vec![l];
            }
        }
    }
    paths
}

/// The scan's detections in groups that share no candidate landmark with
/// one another: each group is assigned on its own (most are one detection).
fn sharing_landmarks(scan: &[&Link]) -> Vec<Vec<usize>> {
    let mut sets = DisjointSets::new(scan.len());
    let mut first_to_claim: HashMap<usize, usize> = HashMap::new();
    for (i, link) in scan.iter().enumerate() {
        for &(l, _) in &link.landmarks {
            sets.union(i, *first_to_claim.entry(l).or_insert(i));
        }
    }
    sets.groups()
}

/// The landmark (or clutter) for each of one scan's detections that
/// minimises the summed cost, no landmark taken twice: the Hungarian
/// method on costs rounded to 10⁻⁶, far below what tells cones apart. More
/// than [`MAX_JOINT`] detections take the cheapest claims first instead.
fn most_likely_assignment(scan: &[&Link]) -> Vec<Option<usize>> {
    if scan.len() > MAX_JOINT {
        return cheapest_claims_first(scan);
    }
    let mut landmarks: Vec<usize> = scan
        .iter()
        .flat_map(|link| link.landmarks.iter().map(|p| p.0))
        .collect();
    landmarks.sort_unstable();
    landmarks.dedup();
    // |cost| ≤ 10⁴ (−2 ln of a likelihood), scaled by 10⁶: a pair outside
    // the gate costs more than any assignment without it, and the sums
    // stay far from overflowing.
    let scaled = |cost: f64| (cost.clamp(-1e4, 1e4) * 1e6).round() as i64;
    let forbidden = 2 * 10i64.pow(10) * (scan.len() as i64 + 1);
    // Columns: the landmarks, then each detection's own clutter.
    let columns = landmarks.len() + scan.len();
    let weights = Matrix::from_fn(scan.len(), columns, |(i, j)| match landmarks.get(j) {
        Some(&l) => scan[i]
            .landmarks
            .iter()
            .find(|p| p.0 == l)
            .map_or(forbidden, |p| scaled(p.1)),
        None if j - landmarks.len() == i => scaled(scan[i].clutter),
        None => forbidden,
    });
    let (_, chosen) = kuhn_munkres_min(&weights);
    chosen
        .into_iter()
        .map(|j| landmarks.get(j).copied())
        .collect()
}

/// Groups of detections that share candidates larger than this (cones
/// crowd a few metres at most; this bounds the cubic time) are assigned
/// cheapest claim first.
const MAX_JOINT: usize = 1000;

/// Each detection's cheapest option among the landmarks still free and
/// clutter, the cheapest claims settled first.
fn cheapest_claims_first(scan: &[&Link]) -> Vec<Option<usize>> {
    let mut claims: Vec<(f64, usize, Option<usize>)> = scan
        .iter()
        .enumerate()
        .flat_map(|(i, link)| {
            let landmarks = link.landmarks.iter().map(move |p| (p.1, i, Some(p.0)));
            landmarks.chain(std::iter::once((link.clutter, i, None)))
        })
        .collect();
    claims.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut chosen = vec![None; scan.len()];
    let mut decided = vec![false; scan.len()];
    let mut taken = std::collections::HashSet::new();
    for (_, i, l) in claims {
        if !decided[i] && l.is_none_or(|l| taken.insert(l)) {
            chosen[i] = l;
            decided[i] = true;
        }
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::super::tests::link;
    use super::*;

    /// How many landmarks `chosen` takes, if it takes none twice.
    fn landmarks_taken_once(chosen: &[Option<usize>]) -> Option<usize> {
        let mut taken: Vec<usize> = chosen.iter().flatten().copied().collect();
        let n = taken.len();
        taken.sort_unstable();
        taken.dedup();
        (taken.len() == n).then_some(n)
    }

    fn total(scan: &[&Link], chosen: &[Option<usize>]) -> f64 {
        scan.iter().zip(chosen).map(|(link, &l)| link.cost(l)).sum()
    }

    /// Every choice of landmark or clutter per detection, each landmark at
    /// most once: the least total cost by brute force.
    fn least_total(scan: &[&Link]) -> f64 {
        fn go(scan: &[&Link], used: &mut Vec<usize>) -> f64 {
            let Some((link, rest)) = scan.split_first() else {
                return 0.0;
            };
            let mut best = link.clutter + go(rest, used);
            for &(l, cost) in &link.landmarks {
                if !used.contains(&l) {
                    used.push(l);
                    best = best.min(cost + go(rest, used));
                    used.pop();
                }
            }
            best
        }
        go(scan, &mut Vec::new())
    }

    #[test]
    fn detections_that_share_no_candidate_are_assigned_apart() {
        let links = [
            link(0, &[(1, 0.0), (2, 1.0)]),
            link(0, &[(5, 0.0)]),
            link(0, &[(2, 0.5), (3, 9.0)]),
            link(0, &[]),
            link(0, &[(3, 1.0)]),
        ];
        let scan: Vec<&Link> = links.iter().collect();
        assert_eq!(
            sharing_landmarks(&scan),
            vec![vec![0, 2, 4], vec![1], vec![3]]
        );
    }

    #[test]
    fn a_scan_is_assigned_as_a_whole() {
        // Cheapest claim first, 0 takes landmark 1 and 1 is left with
        // clutter (8.0): 8.0 in all; together 1.5.
        let links = [
            link(0, &[(1, 0.0), (2, 1.0)]),
            link(0, &[(1, 0.5), (2, 9.0)]),
        ];
        let scan: Vec<&Link> = links.iter().collect();
        assert_eq!(cheapest_claims_first(&scan), vec![Some(1), None]);
        assert_eq!(most_likely_assignment(&scan), vec![Some(2), Some(1)]);
    }

    #[test]
    fn a_poor_fit_is_left_to_clutter_in_a_scan() {
        let links = [link(0, &[(3, -2.0)]), link(0, &[(3, 1.0), (4, 8.5)])];
        let scan: Vec<&Link> = links.iter().collect();
        assert_eq!(most_likely_assignment(&scan), vec![Some(3), None]);
    }

    #[test]
    fn a_scan_too_large_to_assign_jointly_still_takes_each_landmark_once() {
        let links: Vec<Link> = (0..MAX_JOINT + 1)
            .map(|i| link(0, &[(i % 7, (i % 5) as f64), (i % 11, 1.0)]))
            .collect();
        let scan: Vec<&Link> = links.iter().collect();
        assert_eq!(
            landmarks_taken_once(&most_likely_assignment(&scan)),
            Some(11)
        );
    }

    proptest::proptest! {
        #[test]
        fn the_scan_assignment_is_the_least_total_cost(
            costs in proptest::collection::vec(
                proptest::collection::vec(proptest::option::weighted(0.3, -10.0f64..20.0), 8),
                1..7,
            ),
        ) {
            let chains: Vec<Vec<Link>> = costs
                .iter()
                .map(|row| {
                    let pairs: Vec<(usize, f64)> =
                        row.iter().enumerate().filter_map(|(l, c)| c.map(|c| (l, c))).collect();
                    vec![link(0, &pairs)]
                })
                .collect();
            let scan: Vec<&Link> = chains.iter().map(|c| &c[0]).collect();
            let least = least_total(&scan);
            let chosen = most_likely_assignment(&scan);
            proptest::prop_assert!(landmarks_taken_once(&chosen).is_some());
            let cost = total(&scan, &chosen);
            proptest::prop_assert!(cost.is_finite());
            proptest::prop_assert!((cost - least).abs() < 1e-5);
            proptest::prop_assert!(cost <= total(&scan, &cheapest_claims_first(&scan)) + 1e-5);
            // Group by group, as the scans are assigned, the same least total.
            let by_scan = vec![(0..chains.len()).map(|c| (c, 0)).collect()];
            let grouped: Vec<Option<usize>> =
                assignments(&chains, &by_scan).into_iter().map(|p| p[0]).collect();
            proptest::prop_assert!(landmarks_taken_once(&grouped).is_some());
            proptest::prop_assert!((total(&scan, &grouped) - least).abs() < 1e-5);
        }
    }
}
