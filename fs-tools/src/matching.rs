//! One-to-one matching of an estimated map to the true one: each true cone
//! stands for at most one landmark, so a duplicate is a phantom, not a
//! second good match.

use cairn_slam::frontend::grid::Grid;
use nalgebra::Vector2;
use pathfinding::prelude::{Matrix, kuhn_munkres_min};

/// Components larger than this (estimated landmarks) are matched closest
/// pair first instead of by the Hungarian method, which is cubic. Cones
/// within one metre of each other come in twos and threes; only a hostile
/// file makes a component this large.
const MAX_OPTIMAL: usize = 300;

/// For each estimated point, the true point it is matched to: the most
/// pairs closer than `radius`, no true point taken twice, and among those
/// the smallest summed distance (the Hungarian method on micrometres, per
/// group of points linked by pairs within `radius`).
pub fn one_to_one(estimate: &[Vector2<f64>], truth: &[Vector2<f64>], radius: f64) -> Vec<Option<usize>> {
    let mut matched = vec![None; estimate.len()];
    if estimate.is_empty() || truth.is_empty() || !(radius > 0.0) {
        return matched;
    }
    let grid = Grid::new(truth.to_vec(), radius);
    let pairs: Vec<Vec<(usize, f64)>> = estimate
        .iter()
        .map(|p| {
            grid.near(p, radius)
                .map(|j| (j, (truth[j] - p).norm()))
                .filter(|&(_, d)| d <= radius)
                .collect()
        })
        .collect();
    for (rows, columns) in components(&pairs, truth.len()) {
        let chosen = if rows.len() > MAX_OPTIMAL {
            closest_first(&rows, &pairs)
        } else {
            optimal(&rows, &columns, &pairs, radius)
        };
        for (row, column) in rows.iter().zip(chosen) {
            matched[*row] = column;
        }
    }
    matched
}

/// The groups of estimated points (rows) and true points (columns) linked
/// by pairs, each with at least one pair.
fn components(pairs: &[Vec<(usize, f64)>], truths: usize) -> Vec<(Vec<usize>, Vec<usize>)> {
    // Union-find over rows 0..n and columns n..n+truths.
    let n = pairs.len();
    let mut parent: Vec<usize> = (0..n + truths).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (row, near) in pairs.iter().enumerate() {
        for &(column, _) in near {
            let (a, b) = (root(&mut parent, row), root(&mut parent, n + column));
            parent[a] = b;
        }
    }
    let mut groups: std::collections::BTreeMap<usize, (Vec<usize>, Vec<usize>)> = Default::default();
    for (row, near) in pairs.iter().enumerate() {
        if !near.is_empty() {
            groups.entry(root(&mut parent, row)).or_default().0.push(row);
        }
    }
    for column in 0..truths {
        let r = root(&mut parent, n + column);
        if let Some(group) = groups.get_mut(&r) {
            group.1.push(column);
        }
    }
    groups.into_values().collect()
}

/// The Hungarian method on one group: a pair costs its distance in µm, a
/// row left unmatched more than any group of pairs, an impossible pair more
/// than leaving every row unmatched.
fn optimal(rows: &[usize], columns: &[usize], pairs: &[Vec<(usize, f64)>], radius: f64) -> Vec<Option<usize>> {
    let micro = |d: f64| (d / radius * 1e6).round() as i64;
    let unmatched = 1_000_001 * (rows.len() as i64 + 1);
    let forbidden = unmatched * (rows.len() as i64 + 1);
    // Columns: the true points, then one "unmatched" per row.
    let weights = Matrix::from_fn(rows.len(), columns.len() + rows.len(), |(i, j)| match columns.get(j) {
        Some(column) => pairs[rows[i]]
            .iter()
            .find(|p| p.0 == *column)
            .map_or(forbidden, |p| micro(p.1)),
        None if j - columns.len() == i => unmatched,
        None => forbidden,
    });
    let (_, chosen) = kuhn_munkres_min(&weights);
    chosen.into_iter().map(|j| columns.get(j).copied()).collect()
}

/// Closest pairs first, each point taken once.
fn closest_first(rows: &[usize], pairs: &[Vec<(usize, f64)>]) -> Vec<Option<usize>> {
    let mut all: Vec<(f64, usize, usize)> = rows
        .iter()
        .enumerate()
        .flat_map(|(i, &row)| pairs[row].iter().map(move |&(column, d)| (d, i, column)))
        .collect();
    all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut chosen = vec![None; rows.len()];
    let mut taken = std::collections::HashSet::new();
    for (_, i, column) in all {
        if chosen[i].is_none() && taken.insert(column) {
            chosen[i] = Some(column);
        }
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn v(x: f64, y: f64) -> Vector2<f64> {
        Vector2::new(x, y)
    }

    #[test]
    fn a_duplicate_is_left_unmatched() {
        let truth = [v(0.0, 0.0), v(5.0, 0.0)];
        let estimate = [v(0.1, 0.0), v(-0.2, 0.0), v(5.0, 0.3), v(9.0, 9.0)];
        assert_eq!(one_to_one(&estimate, &truth, 1.0), [Some(0), None, Some(1), None]);
    }

    #[test]
    fn more_pairs_beat_closer_ones() {
        // Nearest-first would give a→1 and leave b unmatched; the most
        // pairs are a→0, b→1.
        let truth = [v(0.0, 0.0), v(0.9, 0.0)];
        let estimate = [v(0.8, 0.0), v(1.7, 0.0)];
        assert_eq!(one_to_one(&estimate, &truth, 1.0), [Some(0), Some(1)]);
    }

    #[test]
    fn the_smaller_sum_wins_among_as_many_pairs() {
        let truth = [v(0.0, 0.0), v(0.5, 0.0)];
        let estimate = [v(0.45, 0.0), v(0.05, 0.0)];
        assert_eq!(one_to_one(&estimate, &truth, 1.0), [Some(1), Some(0)]);
    }

    proptest! {
        /// Never a true point twice, never a pair beyond the radius, and
        /// as many pairs as the closest-first rule or more.
        #[test]
        fn matching_is_one_to_one(
            truth in prop::collection::vec((0.0..6.0f64, 0.0..6.0f64), 0..25),
            estimate in prop::collection::vec((0.0..6.0f64, 0.0..6.0f64), 0..25),
        ) {
            let truth: Vec<_> = truth.into_iter().map(|(x, y)| v(x, y)).collect();
            let estimate: Vec<_> = estimate.into_iter().map(|(x, y)| v(x, y)).collect();
            let matched = one_to_one(&estimate, &truth, 1.0);
            let mut used = std::collections::HashSet::new();
            for (i, m) in matched.iter().enumerate() {
                if let Some(j) = m {
                    prop_assert!(used.insert(*j));
                    prop_assert!((estimate[i] - truth[*j]).norm() <= 1.0);
                }
            }
            let pairs: Vec<Vec<(usize, f64)>> = estimate
                .iter()
                .map(|p| truth.iter().enumerate().map(|(j, q)| (j, (q - p).norm())).filter(|x| x.1 <= 1.0).collect())
                .collect();
            let rows: Vec<usize> = (0..estimate.len()).collect();
            let greedy = closest_first(&rows, &pairs).iter().flatten().count();
            prop_assert!(used.len() >= greedy);
        }
    }
}
