//! A bucket grid over a set of points, so that the points near a query
//! point are found without a pass over all of them. Each scan pairs every
//! detection with the landmarks near it, and place recognition scores a few
//! hundred candidate alignments on every detection: with a pass over the
//! map for each, these were the slowest parts of an update where 40–70
//! cones are in view (eufs_comp_2021).

use nalgebra::Vector2;

/// Most cells along one side; a map wider than this many query radii gets
/// coarser cells rather than more memory.
const MAX_CELLS: usize = 128;

/// Points bucketed in square cells (compressed rows: the points of cell
/// `c` are `indices[start[c]..start[c + 1]]`, in ascending order).
pub struct Grid {
    points: Vec<Vector2<f64>>,
    origin: Vector2<f64>,
    cell: f64,
    cols: usize,
    rows: usize,
    start: Vec<usize>,
    indices: Vec<usize>,
}

impl Grid {
    /// Buckets `points` in cells at least `radius` wide, the distance that
    /// [`Self::near`] will be asked about.
    pub fn new(points: Vec<Vector2<f64>>, radius: f64) -> Grid {
        let (mut lo, mut hi) = (Vector2::repeat(f64::MAX), Vector2::repeat(f64::MIN));
        for p in &points {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        if points.is_empty() || !(lo.x.is_finite() && lo.y.is_finite()) {
            lo = Vector2::zeros();
            hi = Vector2::zeros();
        }
        let extent = (hi - lo).max();
        let cell = radius.max(extent / MAX_CELLS as f64).max(f64::MIN_POSITIVE);
        let span = |d: f64| ((d / cell) as usize + 1).min(MAX_CELLS + 1);
        let mut grid = Grid {
            points: Vec::new(),
            origin: lo,
            cell,
            cols: span(hi.x - lo.x),
            rows: span(hi.y - lo.y),
            start: Vec::new(),
            indices: vec![0; points.len()],
        };
        // Count per cell, turn the counts into starts, then place.
        let cells: Vec<usize> = points.iter().map(|p| grid.cell_of(p)).collect();
        let mut start = vec![0; grid.cols * grid.rows + 1];
        for &c in &cells {
            start[c + 1] += 1;
        }
        for c in 1..start.len() {
            start[c] += start[c - 1];
        }
        let mut next = start.clone();
        for (i, &c) in cells.iter().enumerate() {
            grid.indices[next[c]] = i;
            next[c] += 1;
        }
        grid.start = start;
        grid.points = points;
        grid
    }

    /// Point `i`, as given.
    pub fn point(&self, i: usize) -> Vector2<f64> {
        self.points[i]
    }

    /// Column or row of coordinate offset `d`, clamped to the grid.
    fn slot(&self, d: f64, len: usize) -> usize {
        // `as` saturates: negative and NaN offsets give 0.
        ((d / self.cell) as usize).min(len - 1)
    }

    fn cell_of(&self, p: &Vector2<f64>) -> usize {
        let d = p - self.origin;
        self.slot(d.y, self.rows) * self.cols + self.slot(d.x, self.cols)
    }

    /// The indices of the points in the cells that the square of half-side
    /// `radius` (at most the grid's) around `p` touches, cell by cell: a
    /// superset of the points within `radius` of `p`.
    pub fn near(&self, p: &Vector2<f64>, radius: f64) -> impl Iterator<Item = usize> + '_ {
        let d = p - self.origin;
        // Also false for NaN.
        let inside = d.x + radius >= 0.0
            && d.y + radius >= 0.0
            && d.x - radius <= self.cell * self.cols as f64
            && d.y - radius <= self.cell * self.rows as f64;
        let (x0, x1) = (
            self.slot(d.x - radius, self.cols),
            self.slot(d.x + radius, self.cols),
        );
        let (y0, y1) = (
            self.slot(d.y - radius, self.rows),
            self.slot(d.y + radius, self.rows),
        );
        let rows = if inside { y0..y1 + 1 } else { 0..0 };
        rows.flat_map(move |y| {
            let row = y * self.cols;
            &self.indices[self.start[row + x0]..self.start[row + x1 + 1]]
        })
        .copied()
    }

    /// The lowest index of a point within `radius` (at most the grid's) of
    /// `p` that `accept` takes, if any.
    pub fn first_near(
        &self,
        p: &Vector2<f64>,
        radius: f64,
        accept: impl Fn(usize) -> bool,
    ) -> Option<usize> {
        let mut first = None;
        for i in self.near(p, radius) {
            if first.is_none_or(|f| i < f) && (self.points[i] - p).norm() < radius && accept(i) {
                first = Some(i);
            }
        }
        first
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng, rngs::StdRng};

    /// The first point within the radius that `accept` takes, by a pass
    /// over all of them.
    fn brute(
        points: &[Vector2<f64>],
        p: &Vector2<f64>,
        radius: f64,
        accept: impl Fn(usize) -> bool,
    ) -> Option<usize> {
        (0..points.len()).find(|&i| (points[i] - p).norm() < radius && accept(i))
    }

    #[test]
    fn first_near_is_the_first_point_within_the_radius() {
        let mut rng = StdRng::seed_from_u64(7);
        let mut found = 0;
        for spread in [0.3, 5.0, 40.0, 400.0] {
            let points: Vec<Vector2<f64>> = (0..300)
                .map(|_| {
                    let x = rng.random_range(-spread..spread);
                    Vector2::new(x, rng.random_range(0.0..spread))
                })
                .collect();
            let grid = Grid::new(points.clone(), 0.5);
            for _ in 0..2000 {
                let q = Vector2::new(
                    rng.random_range(-1.2 * spread..1.2 * spread),
                    rng.random_range(-0.2 * spread..1.2 * spread),
                );
                // Every other point, so that the first within reach is
                // passed over now and then.
                let odd = |i: usize| i % 2 == 1;
                let first = grid.first_near(&q, 0.5, odd);
                assert_eq!(
                    first,
                    brute(&points, &q, 0.5, odd),
                    "spread {spread}, query {q:?}"
                );
                found += first.is_some() as usize;
            }
        }
        // The queries hit points often enough for the comparison to say something.
        assert!(found > 1000, "{found}");
    }

    #[test]
    fn near_is_a_superset_of_the_points_within_the_radius() {
        let mut rng = StdRng::seed_from_u64(11);
        let points: Vec<Vector2<f64>> = (0..200)
            .map(|_| Vector2::new(rng.random_range(-30.0..30.0), rng.random_range(-30.0..30.0)))
            .collect();
        let grid = Grid::new(points.clone(), 4.0);
        for _ in 0..500 {
            let q = Vector2::new(rng.random_range(-40.0..40.0), rng.random_range(-40.0..40.0));
            let near: Vec<usize> = grid.near(&q, 4.0).collect();
            for (i, p) in points.iter().enumerate() {
                if (p - q).norm() <= 4.0 {
                    assert!(near.contains(&i), "{i} missing near {q:?}");
                }
            }
            // Each once, and not the whole set: the cells do the filtering.
            let mut unique = near.clone();
            unique.sort();
            unique.dedup();
            assert_eq!(unique.len(), near.len());
            assert!(near.len() < points.len() / 4, "{}", near.len());
        }
    }

    #[test]
    fn an_empty_grid_and_odd_queries_find_nothing() {
        let all = |_| true;
        let grid = Grid::new(Vec::new(), 0.5);
        assert_eq!(grid.first_near(&Vector2::zeros(), 0.5, all), None);
        let grid = Grid::new(vec![Vector2::new(1.0, 1.0), Vector2::new(2.0, 1.0)], 0.5);
        assert_eq!(
            grid.first_near(&Vector2::new(f64::NAN, 1.0), 0.5, all),
            None
        );
        assert_eq!(grid.first_near(&Vector2::new(-5.0, 1.0), 0.5, all), None);
        assert_eq!(grid.first_near(&Vector2::new(9.0, 9.0), 0.5, all), None);
        assert_eq!(grid.first_near(&Vector2::new(1.2, 1.1), 0.5, all), Some(0));
        assert_eq!(grid.first_near(&Vector2::new(1.6, 1.0), 0.5, all), Some(1));
    }
}
