//! Connected components, the automatic gauge and spanning-tree initialisation.

use crate::disjoint::DisjointSets;
use crate::graph::{Graph, VertexId};
use std::collections::VecDeque;

/// Connected components of a graph.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Components {
    /// Component number of each vertex index; components are numbered in the
    /// order of their first vertex.
    pub label: Vec<usize>,
    /// Number of components.
    pub count: usize,
}

/// Edges incident to each vertex, as (group, edge, position of the vertex in the edge).
struct Adjacency {
    start: Vec<usize>,
    items: Vec<(u32, u32, u8)>,
}

impl Adjacency {
    fn new(graph: &Graph) -> Self {
        let n = graph.num_vertices();
        let mut count = vec![0usize; n + 1];
        let groups = graph.factor_groups();
        for g in groups {
            for i in 0..g.len() {
                for &v in g.vertices(i) {
                    count[v + 1] += 1;
                }
            }
        }
        for v in 0..n {
            count[v + 1] += count[v];
        }
        let mut fill = count.clone();
        let mut items = vec![(0, 0, 0); count[n]];
        for (gi, g) in groups.iter().enumerate() {
            for i in 0..g.len() {
                for (pos, &v) in g.vertices(i).iter().enumerate() {
                    items[fill[v]] = (gi as u32, i as u32, pos as u8);
                    fill[v] += 1;
                }
            }
        }
        Self {
            start: count,
            items,
        }
    }

    fn of(&self, v: usize) -> &[(u32, u32, u8)] {
        &self.items[self.start[v]..self.start[v + 1]]
    }
}

impl Graph {
    /// The connected components (edges of any arity join their vertices).
    pub fn components(&self) -> Components {
        let mut sets = DisjointSets::new(self.num_vertices());
        for g in self.factor_groups() {
            for i in 0..g.len() {
                for w in g.vertices(i).windows(2) {
                    sets.union(w[0], w[1]);
                }
            }
        }
        // Each set's root is its least member, so it is labelled first.
        let mut label = vec![0; self.num_vertices()];
        let mut count = 0;
        for v in 0..self.num_vertices() {
            let root = sets.find(v);
            label[v] = if root == v {
                count += 1;
                count - 1
            } else {
                label[root]
            };
        }
        Components { label, count }
    }

    /// The ids of the vertices to hold fixed so that every component has a
    /// gauge: for each component with no fixed vertex and no full-rank
    /// prior, its lowest-id pose (its lowest-id vertex if it has no pose).
    /// Deterministic, unlike g2o's choice of an arbitrary vertex.
    pub fn gauge_vertices(&self) -> Vec<VertexId> {
        let comps = self.components();
        let indices = self.gauge_indices(&comps);
        indices.into_iter().map(|v| self.vertex(v).id).collect()
    }

    /// The indices (insertion order) of [`Graph::gauge_vertices`], given the
    /// graph's [`Graph::components`], for callers that need both.
    pub fn gauge_indices(&self, comps: &Components) -> Vec<usize> {
        let mut anchored = vec![false; comps.count];
        for v in self.vertices() {
            if v.fixed {
                anchored[comps.label[v.index]] = true;
            }
        }
        for g in self.factor_groups() {
            if g.vertex_dims().len() == 1 && g.error_dim() >= g.vertex_dims()[0] {
                for i in 0..g.len() {
                    anchored[comps.label[g.vertices(i)[0]]] = true;
                }
            }
        }
        // Best candidate per component: poses first, then the lowest id.
        let mut best: Vec<Option<(bool, VertexId, usize)>> = vec![None; comps.count];
        for v in self.vertices() {
            let c = comps.label[v.index];
            let key = (!v.kind.is_pose, v.id, v.index);
            if best[c].is_none_or(|b| key < b) {
                best[c] = Some(key);
            }
        }
        let mut out: Vec<usize> = (0..comps.count)
            .filter(|&c| !anchored[c])
            .filter_map(|c| best[c].map(|b| b.2))
            .collect();
        out.sort_unstable();
        out
    }

    /// Initialises the vertices flagged in `unknown` by breadth-first search over
    /// the edges from the known ones (g2o's spanning-tree initialisation with
    /// unit edge cost): each reached vertex is predicted from its neighbour and
    /// the edge's measurement. Where no known vertex reaches, the search restarts
    /// from the lowest-id unknown pose, which keeps its current value.
    pub fn initialize_spanning_tree(&mut self, unknown: &[bool]) -> SpanningTreeReport {
        let n = self.num_vertices();
        let is_unknown = |v: usize| unknown.get(v).copied().unwrap_or(false);
        let adjacency = Adjacency::new(self);
        let mut known: Vec<bool> = (0..n).map(|v| !is_unknown(v)).collect();
        let mut order: Vec<usize> = (0..n).filter(|&v| is_unknown(v)).collect();
        order.sort_by_key(|&v| (!self.vertex(v).kind.is_pose, self.vertex(v).id));
        let mut report = SpanningTreeReport::default();
        let mut root_indices = Vec::new();
        let mut queue: VecDeque<usize> = (0..n).filter(|&v| known[v]).collect();
        let (groups, values) = self.groups_and_values_mut();
        let mut next_root = order.into_iter();
        loop {
            while let Some(u) = queue.pop_front() {
                for &(g, i, pos) in adjacency.of(u) {
                    let g = &groups[g as usize];
                    let vs = g.vertices(i as usize);
                    if vs.len() != 2 || known[vs[1 - pos as usize]] {
                        continue;
                    }
                    if let Some(w) = g.propagate(i as usize, pos as usize, values) {
                        known[w] = true;
                        report.predicted += 1;
                        queue.push_back(w);
                    }
                }
            }
            match next_root.find(|&v| !known[v]) {
                Some(root) => {
                    known[root] = true;
                    root_indices.push(root);
                    queue.push_back(root);
                }
                None => break,
            }
        }
        report.roots = root_indices
            .into_iter()
            .map(|v| self.vertex(v).id)
            .collect();
        report
    }
}

/// What [`Graph::initialize_spanning_tree`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SpanningTreeReport {
    /// Vertices set from a neighbour.
    pub predicted: usize,
    /// Unknown vertices no known vertex reached, which kept their values and
    /// started a search of their own.
    pub roots: Vec<VertexId>,
}
