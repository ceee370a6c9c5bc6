//! The rigid placement of an estimated map on the true one that matches the
//! most landmarks, found from the positions alone (no associations): a map
//! whose frame turned early in the run is still scored on its shape.

use crate::matching::one_to_one;
use cairn_core::SE2;
use cairn_slam::frontend::grid::Grid;
use cairn_slam::points::{rigid_motion, two_point};
use nalgebra::Vector2;

/// Above this many candidate placements (estimated pairs × true pairs) only
/// the estimate's own frame is refined: an FS track's 300 cones would give
/// billions, and there the start line fixes the frame anyway. MRCLAM's
/// 15 tubes against a map of up to 60 landmarks give under 200,000.
const MAX_HYPOTHESES: usize = 2_000_000;

/// Placements refined after the quick count.
const REFINED: usize = 20;

/// Refinement rounds per placement (each re-matches and re-aligns).
const ROUNDS: usize = 20;

/// The rigid placement of `estimate` on `truth` with the most points matched
/// one-to-one within `radius` ([`one_to_one`]), then the smallest summed
/// distance. Candidates are the estimate's own frame and every placement
/// that lays a pair of estimated points at least `radius` apart onto a true
/// pair as far apart; the best 20 by a quick count are refined by
/// re-matching and re-aligning (least squares on the matched pairs) until
/// the matches stop changing. Only where the pairs of the two maps give at
/// most 2·10⁶ candidates (a few dozen points each); a larger map is refined
/// from its own frame alone.
pub fn best_placement(estimate: &[Vector2<f64>], truth: &[Vector2<f64>], radius: f64) -> SE2 {
    let identity = SE2::identity();
    if estimate.is_empty() || truth.is_empty() || !(radius > 0.0 && radius.is_finite()) {
        return identity;
    }
    let grid = Grid::new(truth.to_vec(), radius);
    let quick_score = |placed: &SE2| quick_score(placed, estimate, &grid, radius);
    let mut seeds = vec![(quick_score(&identity), identity)];
    let pairs = |n: usize| n * n.saturating_sub(1) / 2;
    if pairs(estimate.len()).saturating_mul(pairs(truth.len())) <= MAX_HYPOTHESES {
        for (i, a) in estimate.iter().enumerate() {
            for b in &estimate[i + 1..] {
                let span = (b - a).norm();
                if span < radius {
                    continue;
                }
                for (k, c) in truth.iter().enumerate() {
                    for d in &truth[k + 1..] {
                        if ((d - c).norm() - span).abs() > radius {
                            continue;
                        }
                        for (p, q) in [(c, d), (d, c)] {
                            if let Some(placed) = two_point(a, b, p, q) {
                                seeds.push((quick_score(&placed), placed));
                            }
                        }
                    }
                }
            }
        }
    }
    seeds.sort_by(|x, y| better(&x.0, &y.0));
    seeds.truncate(REFINED);
    seeds
        .into_iter()
        .map(|(_, seed)| refine(seed, estimate, truth, radius))
        .min_by(|x, y| better(&x.0, &y.0))
        .map_or(identity, |(_, placed)| placed)
}

/// Orders (matched, summed distance) scores best first: more matched, then
/// less distance.
fn better(x: &(usize, f64), y: &(usize, f64)) -> std::cmp::Ordering {
    y.0.cmp(&x.0).then(x.1.total_cmp(&y.1))
}

/// Points with a true point (of `truth`) within `radius` once placed, and
/// their summed nearest distance: an upper bound on the one-to-one count,
/// cheap to get.
fn quick_score(placed: &SE2, estimate: &[Vector2<f64>], truth: &Grid, radius: f64) -> (usize, f64) {
    estimate.iter().fold((0, 0.0), |(n, sum), e| {
        let p = placed.transform_point(e);
        let nearest = truth
            .near(&p, radius)
            .map(|j| (truth.point(j) - p).norm())
            .fold(f64::INFINITY, f64::min);
        if nearest <= radius {
            (n + 1, sum + nearest)
        } else {
            (n, sum)
        }
    })
}

/// Re-aligns on the matched pairs (least squares) and re-matches one-to-one
/// until the matches stop changing, keeping only placements that match as
/// many; returns the (pairs, summed distance) and placement.
fn refine(
    mut placed: SE2,
    estimate: &[Vector2<f64>],
    truth: &[Vector2<f64>],
    radius: f64,
) -> ((usize, f64), SE2) {
    let place = |p: &SE2| -> Vec<_> { estimate.iter().map(|e| p.transform_point(e)).collect() };
    let mut matched = one_to_one(&place(&placed), truth, radius);
    for _ in 0..ROUNDS {
        let (a, b): (Vec<_>, Vec<_>) = matched
            .iter()
            .zip(estimate)
            .filter_map(|(m, e)| Some((*e, truth[(*m)?])))
            .unzip();
        let Some(next) = rigid_motion(&a, &b) else {
            break;
        };
        let next_matched = one_to_one(&place(&next), truth, radius);
        let count = |m: &[Option<usize>]| m.iter().flatten().count();
        if count(&next_matched) < count(&matched) {
            break;
        }
        let settled = next_matched == matched;
        (placed, matched) = (next, next_matched);
        if settled {
            break;
        }
    }
    let score = matched
        .iter()
        .zip(place(&placed))
        .filter_map(|(m, p)| Some((truth[(*m)?] - p).norm()))
        .fold((0, 0.0), |(n, s), d| (n + 1, s + d));
    (score, placed)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64) -> Vector2<f64> {
        Vector2::new(x, y)
    }

    /// An L-shaped layout of groups of tubes, like MRCLAM's.
    fn layout() -> Vec<Vector2<f64>> {
        vec![
            v(0.0, 0.0),
            v(0.2, 0.0),
            v(4.0, 0.1),
            v(4.1, 0.3),
            v(0.0, 5.0),
            v(0.2, 5.1),
            v(2.5, 2.0),
            v(-3.0, 1.0),
        ]
    }

    #[test]
    fn a_map_turned_and_shifted_as_a_whole_is_placed_back_on_the_truth() {
        let truth = layout();
        let moved = SE2::new(12.0, -9.0, 2.0);
        // Slightly off each, and a phantom far away.
        let mut estimate: Vec<_> = truth
            .iter()
            .enumerate()
            .map(|(i, t)| moved.transform_point(&(t + v(0.03 * (i % 3) as f64, -0.02))))
            .collect();
        estimate.push(v(40.0, 40.0));
        // Unplaced, nothing lies within 1 m of its true point.
        assert_eq!(
            one_to_one(&estimate, &truth, 1.0).iter().flatten().count(),
            0
        );
        let placed = best_placement(&estimate, &truth, 1.0);
        let on_truth: Vec<_> = estimate.iter().map(|e| placed.transform_point(e)).collect();
        let matched = one_to_one(&on_truth, &truth, 1.0);
        for i in 0..truth.len() {
            assert_eq!(matched[i], Some(i), "{placed:?}");
            assert!((on_truth[i] - truth[i]).norm() < 0.06);
        }
        assert_eq!(matched[truth.len()], None);
    }

    #[test]
    fn a_map_in_the_right_frame_stays_there() {
        let truth = layout();
        let estimate: Vec<_> = truth.iter().map(|t| t + v(0.05, -0.05)).collect();
        let placed = best_placement(&estimate, &truth, 1.0);
        for (e, t) in estimate.iter().zip(&truth) {
            assert!((placed.transform_point(e) - t).norm() < 1e-9, "{placed:?}");
        }
    }

    #[test]
    fn sixty_four_landmarks_against_eight_are_placed() {
        // Eight copies of the layout 30 m apart, turned and shifted: a
        // copy's landmarks match the truth at once, the others nowhere.
        let truth = layout();
        let moved = SE2::new(-4.0, 7.0, -1.0);
        let estimate: Vec<_> = (0..8)
            .flat_map(|k| {
                let shift = v(30.0 * k as f64, 0.0);
                truth
                    .iter()
                    .map(move |t| moved.transform_point(&(t + shift)))
            })
            .collect();
        let placed = best_placement(&estimate, &truth, 1.0);
        let on_truth: Vec<_> = estimate.iter().map(|e| placed.transform_point(e)).collect();
        let matched = one_to_one(&on_truth, &truth, 1.0);
        assert_eq!(matched.iter().flatten().count(), truth.len());
    }

    #[test]
    fn degenerate_input_leaves_the_map_where_it_is() {
        let truth = layout();
        for (estimate, radius) in [
            (vec![], 1.0),
            (vec![v(1.0, 1.0)], f64::NAN),
            (vec![v(1.0, 1.0)], -1.0),
        ] {
            let placed = best_placement(&estimate, &truth, radius);
            assert_eq!(placed.transform_point(&v(2.0, 3.0)), v(2.0, 3.0));
        }
    }
}
