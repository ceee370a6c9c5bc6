//! The Hessian structure: linearising straight into H against the buffer's
//! assembly, and the assembly against a plain sum of the edges' blocks.

use super::*;
use crate::assembly::Assembly;
use cairn_core::{EdgePriorSE2, EdgeSE2, EdgeSE2XY, EdgeSE3, RobustKernel, SE2, SE3};
use nalgebra::{Matrix2, Matrix3, Matrix6, UnitQuaternion, Vector2, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::collections::{HashMap, HashSet};

/// A random graph of up to `size` poses and as many landmarks, some
/// fixed, with odometry, loop closures, sightings and priors, the ids
/// shuffled so that block order differs from edge order.
fn random_graph(rng: &mut StdRng, size: usize) -> (Graph, Vec<bool>) {
    let mut g = Graph::new();
    let (poses, landmarks) = (rng.random_range(2..size), rng.random_range(0..size));
    let mut ids: Vec<i64> = (0..(poses + landmarks) as i64).collect();
    for i in (1..ids.len()).rev() {
        ids.swap(i, rng.random_range(0..=i));
    }
    let (pose_ids, landmark_ids) = ids.split_at(poses);
    for &p in pose_ids {
        g.add_vertex(p, SE2::new(rng.random(), rng.random(), 0.1))
            .unwrap();
    }
    for &l in landmark_ids {
        g.add_vertex(l, Vector2::new(rng.random(), rng.random()))
            .unwrap();
    }
    for _ in 0..rng.random_range(1..3 * size) {
        let a = pose_ids[rng.random_range(0..pose_ids.len())];
        match rng.random_range(0..3) {
            0 => {
                let b = pose_ids[rng.random_range(0..pose_ids.len())];
                if a != b {
                    let edge = EdgeSE2::new(SE2::new(1.0, 0.0, 0.0));
                    g.add_edge(a, b, edge, Matrix3::identity()).unwrap();
                }
            }
            1 if !landmark_ids.is_empty() => {
                let l = landmark_ids[rng.random_range(0..landmark_ids.len())];
                let edge = EdgeSE2XY::new(Vector2::new(1.0, 0.0));
                g.add_edge(a, l, edge, Matrix2::identity()).unwrap();
            }
            _ => {
                let edge = EdgePriorSE2::new(SE2::identity());
                g.add_unary_edge(a, edge, Matrix3::identity()).unwrap();
            }
        }
    }
    let fixed = (0..g.num_vertices())
        .map(|_| rng.random_bool(0.2))
        .collect();
    (g, fixed)
}

/// Linearising straight into H on one thread gives exactly the bits of
/// linearising into the buffer and assembling from it: H, the gradient
/// and χ², with fixed vertices, landmarks, priors and robust kernels,
/// in every block order, on SE2 and SE3 graphs.
#[test]
fn linearizing_into_h_matches_the_buffer_bit_for_bit() {
    let mut rng = StdRng::seed_from_u64(11);
    let orderings = [Ordering::BlockAmd, Ordering::Identity, Ordering::Schur];
    let mut graphs: Vec<(Graph, Vec<bool>)> = (0..60)
        .map(|k| random_graph(&mut rng, if k % 10 == 0 { 400 } else { 15 }))
        .collect();
    for _ in 0..10 {
        graphs.push(random_se3_graph(&mut rng));
    }
    for (k, (mut graph, fixed)) in graphs.into_iter().enumerate() {
        for v in 0..graph.num_vertices() {
            let dim = graph.vertex(v).kind.dim;
            let delta: Vec<f64> = (0..dim).map(|_| rng.random_range(-0.5..0.5)).collect();
            graph.oplus(v, &delta);
        }
        for e in 0..graph.num_edges() {
            let kernel = [
                None,
                Some(RobustKernel::Huber(0.5)),
                Some(RobustKernel::Cauchy(1.0)),
            ][rng.random_range(0..3)];
            graph.set_robust_kernel(e, kernel);
        }
        let s = HessianStructure::new(&graph, &fixed, orderings[k % 3]).unwrap();
        let a = Assembly::new(&s, &graph);
        let mut buffer = vec![0.0; a.buffer_len];
        for (g, &start) in graph.factor_groups().iter().zip(&a.group_offset) {
            let len = g.len() * layout::stride(g.vertex_dims());
            g.linearize(graph.values(), &mut buffer[start..start + len]);
        }
        let (mut h1, mut g1) = (vec![f64::NAN; s.nnz()], vec![f64::NAN; s.dim]);
        a.assemble(&s, &buffer, &mut h1, &mut g1);
        let (mut h2, mut g2) = (vec![f64::NAN; s.nnz()], vec![f64::NAN; s.dim]);
        let mut terms = vec![f64::NAN; s.num_edges()];
        let chi2 = s.linearize_into(&graph, &mut h2, &mut g2, &mut terms);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&h1), bits(&h2), "graph {k}: H");
        assert_eq!(bits(&g1), bits(&g2), "graph {k}: gradient");
        assert_eq!(a.chi2(&buffer).to_bits(), chi2.to_bits(), "graph {k}: χ²");
        assert!(chi2 > 0.0);
    }
}

/// A random SE3 pose graph (odometry chain and loop closures), some
/// vertices fixed, ids shuffled.
fn random_se3_graph(rng: &mut StdRng) -> (Graph, Vec<bool>) {
    let mut g = Graph::new();
    let n = rng.random_range(3..40);
    let mut ids: Vec<i64> = (0..n as i64).collect();
    for i in (1..ids.len()).rev() {
        ids.swap(i, rng.random_range(0..=i));
    }
    let pose = |rng: &mut StdRng| {
        let t = Vector3::new(rng.random(), rng.random(), rng.random());
        let r = UnitQuaternion::from_euler_angles(rng.random(), rng.random(), rng.random());
        SE3::new(t, r)
    };
    for &id in &ids {
        g.add_vertex(id, pose(rng)).unwrap();
    }
    let mut information = Matrix6::identity();
    information[(0, 4)] = 0.3;
    information[(4, 0)] = 0.3;
    for i in 1..n {
        g.add_edge(ids[i - 1], ids[i], EdgeSE3::new(pose(rng)), information)
            .unwrap();
    }
    for _ in 0..n {
        let (a, b) = (rng.random_range(0..n), rng.random_range(0..n));
        if a != b {
            g.add_edge(ids[a], ids[b], EdgeSE3::new(pose(rng)), information)
                .unwrap();
        }
    }
    let fixed = (0..n).map(|_| rng.random_bool(0.2)).collect();
    (g, fixed)
}

/// H and the gradient assembled from a buffer of random blocks equal the
/// sums of every edge's blocks at its vertices' columns, on small graphs
/// and on graphs large enough to be assembled in several parallel parts,
/// with the vertices' columns in their own order and in fill-reducing ones.
#[test]
fn assembly_matches_a_plain_sum_of_the_edges_blocks() {
    let mut rng = StdRng::seed_from_u64(7);
    let orderings = [Ordering::BlockAmd, Ordering::Identity, Ordering::Schur];
    for (k, size) in [12; 200].into_iter().chain([3000; 4]).enumerate() {
        let (graph, fixed) = random_graph(&mut rng, size);
        let s = HessianStructure::new(&graph, &fixed, orderings[k % 3]).unwrap();
        let a = Assembly::new(&s, &graph);
        let mut buffer: Vec<f64> = (0..a.buffer_len).map(|_| rng.random()).collect();
        // Every (row, column) of H, both triangles, and the gradient.
        let mut expected: HashMap<(usize, usize), f64> = HashMap::new();
        let mut expected_gradient = vec![0.0; s.dim];
        for (g, &start) in graph.factor_groups().iter().zip(&a.group_offset) {
            let dims = g.vertex_dims();
            let stride = layout::stride(dims);
            for e in 0..g.len() {
                let slot = start + e * stride;
                let vs = g.vertices(e);
                for p in 0..vs.len() {
                    let Some(cp) = s.column[vs[p]] else { continue };
                    for q in p..vs.len() {
                        let Some(cq) = s.column[vs[q]] else { continue };
                        let off = slot + layout::block_offset(dims, p, q);
                        for j in 0..dims[q] {
                            for i in 0..dims[p] {
                                let k = off + i + j * dims[p];
                                if p == q && i > j {
                                    // Diagonal blocks are symmetric.
                                    buffer[k] = buffer[off + j + i * dims[p]];
                                }
                                *expected.entry((cp + i, cq + j)).or_default() += buffer[k];
                                if p != q {
                                    *expected.entry((cq + j, cp + i)).or_default() += buffer[k];
                                }
                            }
                        }
                    }
                    let off = slot + layout::gradient_offset(dims, p);
                    for i in 0..dims[p] {
                        expected_gradient[cp + i] += buffer[off + i];
                    }
                }
            }
        }
        let mut values = vec![f64::NAN; s.nnz()];
        let mut gradient = vec![f64::NAN; s.dim];
        a.assemble(&s, &buffer, &mut values, &mut gradient);
        let pattern = s.layout.scalar_pattern();
        let (col_ptr, row_idx) = (pattern.col_ptr(), pattern.row_idx());
        let mut stored = HashSet::new();
        for j in 0..s.dim {
            assert!(row_idx[col_ptr[j]..col_ptr[j + 1]].is_sorted());
            for k in col_ptr[j]..col_ptr[j + 1] {
                let i = row_idx[k];
                assert!(i <= j);
                let want = expected.get(&(i, j)).copied().unwrap_or(0.0);
                assert!((values[k] - want).abs() < 1e-9, "H({i}, {j})");
                stored.insert((i, j));
            }
            let d = s.layout.diagonal().nth(j).unwrap();
            assert_eq!(row_idx[d], j);
            assert!(col_ptr[j] <= d && d < col_ptr[j + 1]);
        }
        // Nothing outside the pattern.
        for &(i, j) in expected.keys() {
            assert!(stored.contains(&(i.min(j), i.max(j))), "({i}, {j})");
        }
        for (a, b) in gradient.iter().zip(&expected_gradient) {
            assert!((a - b).abs() < 1e-9);
        }
        if size > 1000 {
            assert!(a.chunks.len() > 3, "{} parts", a.chunks.len() - 1);
        }
    }
}
