//! One-to-one matching: of an estimated map to the true one, and of
//! landmarks to the true cones their detections came from. Each true cone
//! stands for at most one landmark, so a duplicate is a phantom, not a
//! second good match.

use cairn_core::DisjointSets;
use cairn_slam::frontend::grid::Grid;
use nalgebra::Vector2;
use pathfinding::prelude::{Matrix, kuhn_munkres};
use std::collections::HashSet;

/// Groups larger than this (rows) are assigned largest benefit first
/// instead of by the Hungarian method, which is cubic. Cones within one
/// metre of each other come in twos and threes; only a hostile file makes a
/// group this large.
const MAX_OPTIMAL: usize = 300;

/// For each estimated point, the true point it is matched to: the most
/// pairs closer than `radius`, no true point taken twice, and among those
/// the smallest summed distance.
pub fn one_to_one(
    estimate: &[Vector2<f64>],
    truth: &[Vector2<f64>],
    radius: f64,
) -> Vec<Option<usize>> {
    if estimate.is_empty() || truth.is_empty() || radius.is_nan() || radius <= 0.0 {
        return vec![None; estimate.len()];
    }
    // A pair is worth more than any sum of distance savings (in µm of the
    // radius), so the most pairs win first.
    let pair = 1_000_000 * (estimate.len() as i64 + 2);
    let grid = Grid::new(truth.to_vec(), radius);
    let links: Vec<Vec<(usize, i64)>> = estimate
        .iter()
        .map(|p| {
            grid.near(p, radius)
                .map(|j| (j, (truth[j] - p).norm()))
                .filter(|&(_, d)| d <= radius)
                .map(|(j, d)| (j, pair - (d / radius * 1e6).round() as i64))
                .collect()
        })
        .collect();
    assign(&links, truth.len())
}

/// The assignment of rows to columns (`links[row]`: (column, benefit > 0))
/// with the largest summed benefit, each column taken at most once; a row
/// may stay unassigned. Exact (the Hungarian method, per group of rows and
/// columns linked to each other) up to 300 rows per group.
pub fn assign(links: &[Vec<(usize, i64)>], columns: usize) -> Vec<Option<usize>> {
    let mut chosen = vec![None; links.len()];
    for (rows, cols) in components(links, columns) {
        let picked = if rows.len() > MAX_OPTIMAL {
            largest_first(&rows, links)
        } else {
            optimal(&rows, &cols, links)
        };
        for (row, column) in rows.iter().zip(picked) {
            chosen[*row] = column;
        }
    }
    chosen
}

/// The groups of rows and columns linked to each other, each with a link.
fn components(links: &[Vec<(usize, i64)>], columns: usize) -> Vec<(Vec<usize>, Vec<usize>)> {
    // Rows are 0..n, columns n..n + columns.
    let n = links.len();
    let mut sets = DisjointSets::new(n + columns);
    for (row, near) in links.iter().enumerate() {
        for &(column, _) in near {
            sets.union(row, n + column);
        }
    }
    sets.groups()
        .into_iter()
        .filter(|group| group.len() > 1)
        .map(|group| {
            let split = group.partition_point(|&i| i < n);
            let columns = group[split..].iter().map(|&i| i - n).collect();
            (group[..split].to_vec(), columns)
        })
        .collect()
}

/// The Hungarian method on one group; one "unassigned" column per row
/// (worth 0), and a missing link worth less than leaving every row out.
fn optimal(rows: &[usize], columns: &[usize], links: &[Vec<(usize, i64)>]) -> Vec<Option<usize>> {
    let most: i64 = rows
        .iter()
        .flat_map(|&r| links[r].iter().map(|l| l.1))
        .max()
        .unwrap_or(0);
    let forbidden = -(most.saturating_mul(rows.len() as i64 + 1)).saturating_add(1);
    let weights = Matrix::from_fn(
        rows.len(),
        columns.len() + rows.len(),
        |(i, j)| match columns.get(j) {
            Some(column) => links[rows[i]]
                .iter()
                .find(|l| l.0 == *column)
                .map_or(forbidden, |l| l.1),
            None if j - columns.len() == i => 0,
            None => forbidden,
        },
    );
    let (_, chosen) = kuhn_munkres(&weights);
    chosen
        .into_iter()
        .map(|j| columns.get(j).copied())
        .collect()
}

/// Largest benefit first, each column taken once.
fn largest_first(rows: &[usize], links: &[Vec<(usize, i64)>]) -> Vec<Option<usize>> {
    let mut all: Vec<(i64, usize, usize)> = rows
        .iter()
        .enumerate()
        .flat_map(|(i, &row)| links[row].iter().map(move |&(column, b)| (b, i, column)))
        .collect();
    all.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut chosen = vec![None; rows.len()];
    let mut taken = HashSet::new();
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
        assert_eq!(
            one_to_one(&estimate, &truth, 1.0),
            [Some(0), None, Some(1), None]
        );
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
    fn assignment_takes_the_largest_total() {
        // Row 0 alone would take column 0 (5 > 4); both rows together are
        // worth more with row 0 on column 1.
        let links = vec![vec![(0, 5), (1, 4)], vec![(0, 3)]];
        assert_eq!(assign(&links, 2), [Some(1), Some(0)]);
        assert_eq!(assign(&[vec![], vec![(1, 2)]], 3), [None, Some(1)]);
    }

    #[test]
    fn the_smaller_sum_wins_among_as_many_pairs() {
        let truth = [v(0.0, 0.0), v(0.5, 0.0)];
        let estimate = [v(0.45, 0.0), v(0.05, 0.0)];
        assert_eq!(one_to_one(&estimate, &truth, 1.0), [Some(1), Some(0)]);
    }

    proptest! {
        /// Never a true point twice, never a pair beyond the radius, and
        /// as many pairs as any greedy rule or more.
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
            let links: Vec<Vec<(usize, i64)>> = estimate
                .iter()
                .map(|p| truth.iter().enumerate().filter(|(_, q)| (*q - p).norm() <= 1.0).map(|(j, _)| (j, 1)).collect())
                .collect();
            let rows: Vec<usize> = (0..estimate.len()).collect();
            let greedy = largest_first(&rows, &links).iter().flatten().count();
            prop_assert!(used.len() >= greedy);
        }
    }
}
