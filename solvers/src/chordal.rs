//! Chordal initialisation: rotations first, by a linear relaxation (each
//! rotation as a free vector or matrix, constrained linearly by the measured
//! relative rotations, then projected back onto SO(2)/SO(3)), then positions
//! and landmarks by linear least squares with those rotations held fixed.
//!
//! Both steps are linear, so they are solved exactly by one Gauss-Newton step of
//! Cairn's own solver on small auxiliary graphs.

use crate::SolveError;
use crate::config::{Algorithm, Gauge, Initialization, SolverConfig};
use crate::optimizer::{Optimizer, gauge_indices};
use cairn_core::{
    BinaryEdge, EdgePriorSE2, EdgeSE2, EdgeSE2XY, EdgeSE3, Graph, SE2, SE3, UnaryEdge, Variable,
    VertexId,
};
use nalgebra::{Matrix2, Matrix3, Rotation3, SMatrix, SVector, UnitQuaternion, Vector2, Vector3};
use std::any::TypeId;

/// e = x₂ − A·x₁ − b: a linear relation between two vectors.
#[derive(Clone, Debug)]
struct Linear<const N: usize> {
    a: SMatrix<f64, N, N>,
    b: SVector<f64, N>,
}

impl<const N: usize> BinaryEdge<N, N, N> for Linear<N>
where
    SVector<f64, N>: Variable<N>,
{
    type V1 = SVector<f64, N>;
    type V2 = SVector<f64, N>;
    const NAME: &'static str = "CHORDAL_LINEAR";
    fn error(&self, x1: &SVector<f64, N>, x2: &SVector<f64, N>) -> SVector<f64, N> {
        x2 - self.a * x1 - self.b
    }
    fn jacobians(
        &self,
        _: &SVector<f64, N>,
        _: &SVector<f64, N>,
    ) -> (SMatrix<f64, N, N>, SMatrix<f64, N, N>) {
        (-self.a, SMatrix::identity())
    }
}

/// e = x − b.
#[derive(Clone, Debug)]
struct Anchor<const N: usize>(SVector<f64, N>);

impl<const N: usize> UnaryEdge<N, N> for Anchor<N>
where
    SVector<f64, N>: Variable<N>,
{
    type V = SVector<f64, N>;
    const NAME: &'static str = "CHORDAL_PRIOR";
    fn error(&self, x: &SVector<f64, N>) -> SVector<f64, N> {
        x - self.0
    }
    fn jacobian(&self, _: &SVector<f64, N>) -> SMatrix<f64, N, N> {
        SMatrix::identity()
    }
}

/// What [`chordal_initialize`] changed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChordalReport {
    /// SE2 and SE3 poses given new values.
    pub poses: usize,
    /// 2D landmarks given new positions.
    pub landmarks: usize,
}

fn solve_linear(aux: &mut Graph) -> Result<(), SolveError> {
    let config = SolverConfig {
        algorithm: Algorithm::GaussNewton,
        max_iterations: 1,
        init: Initialization::File,
        ..Default::default()
    };
    Optimizer::new(aux, config)?
        .iterate(aux, Initialization::File, &mut |_| {})
        .map(|_| ())
}

/// Vertices that keep their values: the fixed ones and those `gauge` holds
/// (the automatic gauge unless it names vertices: a start needs an anchor
/// even where the priors fix the gauge).
pub(crate) fn anchors(graph: &Graph, gauge: &Gauge) -> Result<Vec<bool>, SolveError> {
    let mut keep: Vec<bool> = (0..graph.num_vertices())
        .map(|v| graph.vertex(v).fixed)
        .collect();
    let held = match gauge {
        Gauge::Vertices(_) => gauge_indices(graph, gauge)?,
        Gauge::Auto | Gauge::None => graph.gauge_indices(&graph.components()),
    };
    for v in held {
        keep[v] = true;
    }
    Ok(keep)
}

fn block<const R: usize, const C: usize>(
    m: &[f64],
    n: usize,
    row: usize,
    col: usize,
) -> SMatrix<f64, R, C> {
    SMatrix::from_fn(|r, c| m[(row + r) + (col + c) * n])
}

/// How the linear relaxations weight each measurement.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ChordalWeights {
    /// From the edges' information matrices (rotation and translation blocks).
    #[default]
    Information,
    /// Every measurement alike. A different start: on some files (M3500c) it
    /// leads to a lower optimum than the weighted one, on others to a higher.
    Isotropic,
}

/// Replaces the values of every free SE2/SE3 pose and 2D landmark by the
/// chordal estimate, weighted by the information matrices. Fixed and gauge
/// vertices keep theirs and anchor the rest.
pub fn chordal_initialize(graph: &mut Graph) -> Result<ChordalReport, SolveError> {
    chordal_initialize_with(graph, ChordalWeights::Information)
}

/// [`chordal_initialize`] with a choice of weights.
pub fn chordal_initialize_with(
    graph: &mut Graph,
    weights: ChordalWeights,
) -> Result<ChordalReport, SolveError> {
    let keep = anchors(graph, &Gauge::Auto)?;
    chordal_initialize_holding(graph, weights, &keep)
}

/// [`chordal_initialize_with`], holding the vertices marked in `keep`.
pub(crate) fn chordal_initialize_holding(
    graph: &mut Graph,
    weights: ChordalWeights,
    keep: &[bool],
) -> Result<ChordalReport, SolveError> {
    let iso = weights == ChordalWeights::Isotropic;
    let mut report = ChordalReport::default();
    if graph
        .vertices()
        .any(|v| v.kind.type_id == TypeId::of::<SE2>())
    {
        initialize_se2(graph, keep, iso, &mut report)?;
    }
    if graph
        .vertices()
        .any(|v| v.kind.type_id == TypeId::of::<SE3>())
    {
        initialize_se3(graph, keep, iso, &mut report)?;
    }
    Ok(report)
}

fn ids_of(graph: &Graph, vs: &[usize]) -> Vec<VertexId> {
    vs.iter().map(|&v| graph.vertex(v).id).collect()
}

fn initialize_se2(
    graph: &mut Graph,
    keep: &[bool],
    iso: bool,
    report: &mut ChordalReport,
) -> Result<(), SolveError> {
    let aux_error =
        |e: cairn_core::GraphError| SolveError::Analysis(format!("chordal initialisation: {e}"));
    // Rotations as (cos θ, sin θ): r_j = M(z)·r_i.
    let mut rotations = Graph::new();
    for v in graph
        .vertices()
        .filter(|v| v.kind.type_id == TypeId::of::<SE2>())
    {
        let theta = v.params[2];
        rotations
            .add_vertex(v.id, Vector2::new(theta.cos(), theta.sin()))
            .map_err(aux_error)?;
        rotations
            .set_fixed(v.id, keep[v.index])
            .map_err(aux_error)?;
    }
    for e in graph.edges() {
        let ids = ids_of(graph, e.vertices());
        let info = e.information();
        if let Some(edge) = e.edge().downcast_ref::<EdgeSE2>() {
            let kappa = if iso { 1.0 } else { info[8] };
            // Rotating (cos θ_i, sin θ_i) by θ_z is multiplying it by R(θ_z).
            let link = Linear {
                a: edge.measurement().rotation(),
                b: Vector2::zeros(),
            };
            rotations
                .add_edge(ids[0], ids[1], link, Matrix2::identity() * kappa)
                .map_err(aux_error)?;
        } else if let Some(prior) = e.edge().downcast_ref::<EdgePriorSE2>() {
            let kappa = if iso { 1.0 } else { info[8] };
            let theta = prior.measurement().theta;
            let anchor = Anchor(Vector2::new(theta.cos(), theta.sin()));
            rotations
                .add_unary_edge(ids[0], anchor, Matrix2::identity() * kappa)
                .map_err(aux_error)?;
        }
    }
    solve_linear(&mut rotations)?;
    for (v, &kept) in keep.iter().enumerate() {
        let view = graph.vertex(v);
        if kept || view.kind.type_id != TypeId::of::<SE2>() {
            continue;
        }
        let r: Vector2<f64> = rotations.value(view.id).map_err(aux_error)?;
        let x: SE2 = graph.value(view.id).map_err(aux_error)?;
        graph
            .set_value(view.id, &SE2::new(x.t.x, x.t.y, r.y.atan2(r.x)))
            .map_err(aux_error)?;
        report.poses += 1;
    }

    // Positions and landmarks: t_j − t_i = R_i·t_z, weighted by R_i·Ω_tt·R_iᵀ.
    let weight = |info: &[f64], n: usize, r: Matrix2<f64>| {
        if iso {
            Matrix2::identity()
        } else {
            r * block::<2, 2>(info, n, 0, 0) * r.transpose()
        }
    };
    let mut positions = Graph::new();
    for v in graph.vertices() {
        let is_pose = v.kind.type_id == TypeId::of::<SE2>();
        if is_pose || v.kind.type_id == TypeId::of::<Vector2<f64>>() {
            positions
                .add_vertex(v.id, Vector2::new(v.params[0], v.params[1]))
                .map_err(aux_error)?;
            positions
                .set_fixed(v.id, keep[v.index])
                .map_err(aux_error)?;
        }
    }
    for e in graph.edges() {
        let ids = ids_of(graph, e.vertices());
        let (info, n) = (e.information(), e.error_dim());
        let pose = |id| graph.value::<SE2, 3>(id).map_err(aux_error);
        if let Some(edge) = e.edge().downcast_ref::<EdgeSE2>() {
            let ri = pose(ids[0])?.rotation();
            let w = weight(info, n, ri);
            let link = Linear {
                a: Matrix2::identity(),
                b: ri * edge.measurement().t,
            };
            positions
                .add_edge(ids[0], ids[1], link, w)
                .map_err(aux_error)?;
        } else if let Some(edge) = e.edge().downcast_ref::<EdgeSE2XY>() {
            let ri = pose(ids[0])?.rotation();
            let w = weight(info, n, ri);
            let link = Linear {
                a: Matrix2::identity(),
                b: ri * edge.measurement(),
            };
            positions
                .add_edge(ids[0], ids[1], link, w)
                .map_err(aux_error)?;
        } else if let Some(prior) = e.edge().downcast_ref::<EdgePriorSE2>() {
            let w = weight(info, n, prior.measurement().rotation());
            positions
                .add_unary_edge(ids[0], Anchor(prior.measurement().t), w)
                .map_err(aux_error)?;
        }
    }
    solve_linear(&mut positions)?;
    for (v, &kept) in keep.iter().enumerate() {
        let view = graph.vertex(v);
        if kept {
            continue;
        }
        let id = view.id;
        if view.kind.type_id == TypeId::of::<SE2>() {
            let t: Vector2<f64> = positions.value(id).map_err(aux_error)?;
            let x: SE2 = graph.value(id).map_err(aux_error)?;
            graph
                .set_value(id, &SE2::new(t.x, t.y, x.theta))
                .map_err(aux_error)?;
        } else if view.kind.type_id == TypeId::of::<Vector2<f64>>() {
            let t: Vector2<f64> = positions.value(id).map_err(aux_error)?;
            graph.set_value(id, &t).map_err(aux_error)?;
            report.landmarks += 1;
        }
    }
    Ok(())
}

/// The nearest rotation (Frobenius norm) to `m`.
fn project_to_so3(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    let mut r = u * vt;
    if r.determinant() < 0.0 {
        let mut u = u;
        u.column_mut(2).neg_mut();
        r = u * vt;
    }
    r
}

fn initialize_se3(
    graph: &mut Graph,
    keep: &[bool],
    iso: bool,
    report: &mut ChordalReport,
) -> Result<(), SolveError> {
    let aux_error =
        |e: cairn_core::GraphError| SolveError::Analysis(format!("chordal initialisation: {e}"));
    // Rotations as 9-vectors (column-major R): vec(R_j) = (Zᵀ ⊗ I₃)·vec(R_i).
    let mut rotations = Graph::new();
    for v in graph
        .vertices()
        .filter(|v| v.kind.type_id == TypeId::of::<SE3>())
    {
        let r = SE3::from_params(v.params).rotation();
        rotations
            .add_vertex(v.id, SVector::<f64, 9>::from_column_slice(r.as_slice()))
            .map_err(aux_error)?;
        rotations
            .set_fixed(v.id, keep[v.index])
            .map_err(aux_error)?;
    }
    for e in graph.edges() {
        let Some(edge) = e.edge().downcast_ref::<EdgeSE3>() else {
            continue;
        };
        let ids = ids_of(graph, e.vertices());
        let rot_info: Matrix3<f64> = block::<3, 3>(e.information(), 6, 3, 3);
        let kappa = if iso {
            1.0
        } else {
            rot_info
                .try_inverse()
                .map_or(1.0, |c| 3.0 / c.trace().max(f64::MIN_POSITIVE))
        };
        let z = edge.measurement().rotation();
        let a = SMatrix::<f64, 9, 9>::from_fn(|r, c| {
            if r % 3 == c % 3 {
                z[(c / 3, r / 3)]
            } else {
                0.0
            }
        });
        let link = Linear {
            a,
            b: SVector::zeros(),
        };
        rotations
            .add_edge(
                ids[0],
                ids[1],
                link,
                SMatrix::<f64, 9, 9>::identity() * kappa,
            )
            .map_err(aux_error)?;
    }
    solve_linear(&mut rotations)?;
    for (v, &kept) in keep.iter().enumerate() {
        let view = graph.vertex(v);
        if kept || view.kind.type_id != TypeId::of::<SE3>() {
            continue;
        }
        let r: SVector<f64, 9> = rotations.value(view.id).map_err(aux_error)?;
        let rotation = project_to_so3(&Matrix3::from_column_slice(r.as_slice()));
        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation));
        let x: SE3 = graph.value(view.id).map_err(aux_error)?;
        graph
            .set_value(view.id, &SE3::new(x.t, q))
            .map_err(aux_error)?;
        report.poses += 1;
    }

    let mut positions = Graph::new();
    for v in graph
        .vertices()
        .filter(|v| v.kind.type_id == TypeId::of::<SE3>())
    {
        positions
            .add_vertex(v.id, Vector3::new(v.params[0], v.params[1], v.params[2]))
            .map_err(aux_error)?;
        positions
            .set_fixed(v.id, keep[v.index])
            .map_err(aux_error)?;
    }
    for e in graph.edges() {
        let Some(edge) = e.edge().downcast_ref::<EdgeSE3>() else {
            continue;
        };
        let ids = ids_of(graph, e.vertices());
        let ri = graph.value::<SE3, 6>(ids[0]).map_err(aux_error)?.rotation();
        let w = if iso {
            Matrix3::identity()
        } else {
            ri * block::<3, 3>(e.information(), 6, 0, 0) * ri.transpose()
        };
        let link = Linear {
            a: Matrix3::identity(),
            b: ri * edge.measurement().t,
        };
        positions
            .add_edge(ids[0], ids[1], link, (w + w.transpose()) * 0.5)
            .map_err(aux_error)?;
    }
    solve_linear(&mut positions)?;
    for (v, &kept) in keep.iter().enumerate() {
        let view = graph.vertex(v);
        if kept || view.kind.type_id != TypeId::of::<SE3>() {
            continue;
        }
        let t: Vector3<f64> = positions.value(view.id).map_err(aux_error)?;
        let x: SE3 = graph.value(view.id).map_err(aux_error)?;
        graph
            .set_value(view.id, &SE3::new(t, x.q))
            .map_err(aux_error)?;
    }
    Ok(())
}
