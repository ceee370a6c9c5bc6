//! A health report of a graph: where χ² comes from, badly scaled information
//! matrices, and how the graph splits into connected components.

use crate::graph::{Graph, VertexId};
use nalgebra::DMatrix;
use std::collections::BTreeMap;

/// Condition number above which an information matrix is reported as badly scaled.
pub const BAD_CONDITION: f64 = 1e10;

/// One edge in a report.
#[derive(Clone, Debug, PartialEq)]
pub struct EdgeSummary {
    /// Edge number (insertion order).
    pub index: usize,
    /// Edge type.
    pub name: &'static str,
    /// Its vertex ids.
    pub vertices: Vec<VertexId>,
    /// Its χ² (or condition number, in [`Diagnostics::badly_scaled`]).
    pub value: f64,
}

/// A bin of the per-edge χ² histogram: edges with `lower ≤ χ² < upper`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bin {
    /// Lower bound (inclusive).
    pub lower: f64,
    /// Upper bound (exclusive).
    pub upper: f64,
    /// Edges in the bin.
    pub count: usize,
}

/// See [`diagnose`].
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostics {
    /// Vertices per type.
    pub vertex_types: BTreeMap<&'static str, usize>,
    /// Edges per type.
    pub edge_types: BTreeMap<&'static str, usize>,
    /// Fixed vertices.
    pub fixed: Vec<VertexId>,
    /// Total χ².
    pub chi2: f64,
    /// The edges with the largest χ², largest first.
    pub worst_edges: Vec<EdgeSummary>,
    /// Per-edge χ² by decade, from the smallest non-empty one.
    pub histogram: Vec<Bin>,
    /// Edges whose information matrix has condition number above
    /// [`BAD_CONDITION`], worst first (`value` is the condition number).
    pub badly_scaled: Vec<EdgeSummary>,
    /// Size of each connected component, largest first.
    pub components: Vec<usize>,
    /// The vertices the automatic gauge would fix.
    pub gauge: Vec<VertexId>,
}

/// Examines `graph`, listing the `worst` edges by χ².
pub fn diagnose(graph: &Graph, worst: usize) -> Diagnostics {
    let ids = |vs: &[usize]| vs.iter().map(|&v| graph.vertex(v).id).collect::<Vec<_>>();
    let mut vertex_types = BTreeMap::new();
    let mut fixed = Vec::new();
    for v in graph.vertices() {
        *vertex_types.entry(v.kind.name).or_insert(0) += 1;
        if v.fixed {
            fixed.push(v.id);
        }
    }
    let mut edge_types = BTreeMap::new();
    let mut chi2s = Vec::with_capacity(graph.num_edges());
    let mut badly_scaled = Vec::new();
    for (k, e) in graph.edges().enumerate() {
        *edge_types.entry(e.name()).or_insert(0) += 1;
        chi2s.push((e.chi2(graph.values()), k));
        let n = e.error_dim();
        let eig = DMatrix::from_column_slice(n, n, e.information()).symmetric_eigenvalues();
        let condition = eig.max() / eig.min();
        // A NaN condition (0/0) counts as badly scaled too.
        if condition.is_nan() || condition > BAD_CONDITION {
            badly_scaled.push(EdgeSummary {
                index: k,
                name: e.name(),
                vertices: ids(e.vertices()),
                value: condition,
            });
        }
    }
    badly_scaled.sort_by(|a, b| b.value.total_cmp(&a.value));
    let chi2 = graph.chi2();
    let histogram = decades(chi2s.iter().map(|c| c.0));
    chi2s.sort_by(|a, b| b.0.total_cmp(&a.0));
    let worst_edges = chi2s
        .iter()
        .take(worst)
        .map(|&(value, k)| {
            let e = graph.edge(k);
            EdgeSummary {
                index: k,
                name: e.name(),
                vertices: ids(e.vertices()),
                value,
            }
        })
        .collect();
    let comps = graph.components();
    let mut components = vec![0; comps.count];
    for &c in &comps.label {
        components[c] += 1;
    }
    components.sort_unstable_by(|a, b| b.cmp(a));
    let gauge = graph
        .gauge_indices(&comps)
        .into_iter()
        .map(|v| graph.vertex(v).id)
        .collect();
    Diagnostics {
        vertex_types,
        edge_types,
        fixed,
        chi2,
        worst_edges,
        histogram,
        badly_scaled,
        components,
        gauge,
    }
}

/// Counts by decade [10ᵏ, 10ᵏ⁺¹); values below 1e-12 go to the first bin.
fn decades(values: impl Iterator<Item = f64>) -> Vec<Bin> {
    let mut counts: BTreeMap<i32, usize> = BTreeMap::new();
    for v in values {
        let k = if v < 1e-12 {
            -12
        } else {
            v.log10().floor().clamp(-12.0, 300.0) as i32
        };
        *counts.entry(k).or_insert(0) += 1;
    }
    let (Some(&lo), Some(&hi)) = (counts.keys().next(), counts.keys().next_back()) else {
        return Vec::new();
    };
    (lo..=hi)
        .map(|k| Bin {
            lower: if k == -12 { 0.0 } else { 10f64.powi(k) },
            upper: 10f64.powi(k + 1),
            count: counts.get(&k).copied().unwrap_or(0),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{EdgeSE2, SE2};
    use nalgebra::Matrix3;

    #[test]
    fn reports_worst_edges_histogram_scaling_and_components() {
        let mut g = Graph::new();
        for i in 0..4 {
            g.add_vertex(i, SE2::new(i as f64, 0.0, 0.0)).unwrap();
        }
        g.add_vertex(9, SE2::identity()).unwrap();
        g.add_edge(
            0,
            1,
            EdgeSE2::new(SE2::new(1.0, 0.0, 0.0)),
            Matrix3::identity(),
        )
        .unwrap();
        g.add_edge(
            1,
            2,
            EdgeSE2::new(SE2::new(1.1, 0.0, 0.0)),
            Matrix3::identity(),
        )
        .unwrap();
        let stiff = Matrix3::from_diagonal(&nalgebra::Vector3::new(1e12, 1.0, 1.0));
        g.add_edge(2, 3, EdgeSE2::new(SE2::new(4.0, 0.0, 0.0)), stiff)
            .unwrap();
        let d = diagnose(&g, 2);
        assert_eq!(
            d.worst_edges.iter().map(|e| e.index).collect::<Vec<_>>(),
            vec![2, 1]
        );
        assert!((d.worst_edges[0].value - 9e12).abs() < 1e-3);
        assert_eq!(d.badly_scaled.len(), 1);
        assert_eq!(d.badly_scaled[0].vertices, vec![2, 3]);
        assert_eq!(d.components, vec![4, 1]);
        assert_eq!(d.gauge, vec![0, 9]);
        assert_eq!(d.histogram.iter().map(|b| b.count).sum::<usize>(), 3);
        assert_eq!(d.histogram.first().map(|b| b.lower), Some(0.0)); // the exact edge
        assert_eq!(d.histogram.last().map(|b| b.lower), Some(1e12));
        assert_eq!(d.edge_types.get("EDGE_SE2"), Some(&3));
    }
}
