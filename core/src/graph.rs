//! The factor graph: variables keyed by integer id, and edges between them.

use crate::edge::{BinaryEdge, UnaryEdge};
use crate::factor::{BinaryGroup, FactorGroup, UnaryGroup};
use crate::information::{InformationIssue, PositiveDefinite};
use crate::kernel::RobustKernel;
use crate::values::Values;
use crate::variable::Variable;
use nalgebra::{SMatrix, SVector};
use rustc_hash::FxHashMap;
use std::any::{Any, TypeId};

/// A vertex id as written in g2o files.
pub type VertexId = i64;

/// What is wrong with a graph operation.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GraphError {
    /// `add_vertex` with an id that is taken.
    #[error("vertex {0} is already in the graph")]
    DuplicateVertex(VertexId),
    /// An id that names no vertex.
    #[error("vertex {0} is not in the graph")]
    UnknownVertex(VertexId),
    /// A vertex of another type than the edge or the caller expects.
    #[error("vertex {id} is {actual}, but {context} needs {expected}")]
    WrongVertexType {
        /// The vertex.
        id: VertexId,
        /// Who asked.
        context: &'static str,
        /// The type it needs.
        expected: &'static str,
        /// The vertex's type.
        actual: &'static str,
    },
    /// A NaN or infinite parameter.
    #[error("vertex {0} has a non-finite value")]
    NonFiniteValue(VertexId),
    /// A binary edge from a vertex to itself.
    #[error("{edge} connects vertex {id} to itself")]
    SelfLoop {
        /// Edge type.
        edge: &'static str,
        /// The vertex.
        id: VertexId,
    },
    /// An unusable information matrix.
    #[error("{edge} on vertices {vertices:?}: information matrix {issue}")]
    BadInformation {
        /// Edge type.
        edge: &'static str,
        /// The edge's vertex ids.
        vertices: Vec<VertexId>,
        /// What is wrong.
        issue: InformationIssue,
    },
}

/// The type-erased description of a variable type.
#[derive(Clone, Copy, Debug)]
pub struct VariableKind {
    /// [`Variable::NAME`].
    pub name: &'static str,
    /// `TypeId` of the variable type.
    pub type_id: TypeId,
    /// Tangent dimension.
    pub dim: usize,
    /// Stored parameters.
    pub params: usize,
    /// [`Variable::IS_POSE`].
    pub is_pose: bool,
    oplus: fn(&mut [f64], &[f64]),
}

fn oplus_erased<V: Variable<D>, const D: usize>(params: &mut [f64], delta: &[f64]) {
    let x = V::from_params(params).oplus(&SVector::<f64, D>::from_column_slice(delta));
    x.write_params(params);
}

impl VariableKind {
    /// The kind of variable type `V`.
    pub fn of<V: Variable<D>, const D: usize>() -> Self {
        Self {
            name: V::NAME,
            type_id: TypeId::of::<V>(),
            dim: D,
            params: V::PARAMS,
            is_pose: V::IS_POSE,
            oplus: oplus_erased::<V, D>,
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct VertexRecord {
    id: VertexId,
    kind: u16,
    fixed: bool,
}

/// A read-only view of one vertex.
#[derive(Clone, Copy, Debug)]
pub struct VertexView<'a> {
    /// Index in the graph (insertion order).
    pub index: usize,
    /// The vertex's id.
    pub id: VertexId,
    /// Its type.
    pub kind: &'a VariableKind,
    /// Whether it is held constant.
    pub fixed: bool,
    /// Its stored parameters.
    pub params: &'a [f64],
}

/// A read-only view of one edge.
#[derive(Clone, Copy)]
pub struct EdgeView<'a> {
    group: &'a dyn FactorGroup,
    index: usize,
}

impl<'a> EdgeView<'a> {
    /// The edge type's name.
    pub fn name(&self) -> &'static str {
        self.group.name()
    }
    /// The `TypeId` of the edge type.
    pub fn edge_type(&self) -> TypeId {
        self.group.edge_type()
    }
    /// The edge, for downcasting to its concrete type.
    pub fn edge(&self) -> &'a dyn Any {
        self.group.edge(self.index)
    }
    /// Vertex indices in edge order.
    pub fn vertices(&self) -> &'a [usize] {
        self.group.vertices(self.index)
    }
    /// Error dimension.
    pub fn error_dim(&self) -> usize {
        self.group.error_dim()
    }
    /// Information matrix, column-major.
    pub fn information(&self) -> &'a [f64] {
        self.group.information(self.index)
    }
    /// This edge's χ² at `values` (ρ(eᵀΩe) if it has a robust kernel).
    pub fn chi2(&self, values: &Values) -> f64 {
        self.group.chi2(self.index, values)
    }
    /// Its robust kernel, if any.
    pub fn kernel(&self) -> Option<RobustKernel> {
        self.group.kernel(self.index)
    }
    /// The tangent dimension of each of its vertices, in edge order.
    pub fn vertex_dims(&self) -> &'a [usize] {
        self.group.vertex_dims()
    }
    /// Its error at `values` into `error` (`error_dim` long) and each
    /// vertex's Jacobian ∂e/∂δ into `jacobians` (`error_dim × dim`,
    /// column-major, one vertex after the other).
    pub fn jacobians(&self, values: &Values, error: &mut [f64], jacobians: &mut [f64]) {
        self.group.jacobians(self.index, values, error, jacobians)
    }
}

/// A factor graph: variables of any [`Variable`] type keyed by [`VertexId`], and
/// unary and binary edges with information matrices.
///
/// ```
/// use cairn_core::{EdgeSE2, Graph, SE2};
/// use nalgebra::Matrix3;
/// let mut g = Graph::new();
/// g.add_vertex(0, SE2::new(0.0, 0.0, 0.0))?;
/// g.add_vertex(1, SE2::new(0.9, 0.1, 0.0))?;
/// g.add_edge(0, 1, EdgeSE2::new(SE2::new(1.0, 0.0, 0.0)), Matrix3::identity())?;
/// assert!((g.chi2() - 0.02).abs() < 1e-12);
/// # Ok::<(), cairn_core::GraphError>(())
/// ```
#[derive(Default)]
pub struct Graph {
    values: Values,
    vertices: Vec<VertexRecord>,
    kinds: Vec<VariableKind>,
    /// Each id's vertex index. Fx hashing (rustc's) is several times faster
    /// than the default on integer keys; it does not resist ids crafted to
    /// collide, which would slow a load down, not change its result.
    index: FxHashMap<VertexId, usize>,
    groups: Vec<Box<dyn FactorGroup>>,
    /// Each group's edge type: a handful, searched in order.
    group_types: Vec<TypeId>,
    edge_order: Vec<(u32, u32)>,
}

/// A copy with its own values, vertices and edges: solving one leaves the
/// other as it was.
impl Clone for Graph {
    fn clone(&self) -> Self {
        Self {
            values: self.values.clone(),
            vertices: self.vertices.clone(),
            kinds: self.kinds.clone(),
            index: self.index.clone(),
            groups: self.groups.iter().map(|g| g.boxed_clone()).collect(),
            group_types: self.group_types.clone(),
            edge_order: self.edge_order.clone(),
        }
    }
}

impl Graph {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a variable with the given id; returns its index.
    pub fn add_vertex<V: Variable<D>, const D: usize>(
        &mut self,
        id: VertexId,
        value: V,
    ) -> Result<usize, GraphError> {
        if self.index.contains_key(&id) {
            return Err(GraphError::DuplicateVertex(id));
        }
        // The parameters on the stack unless a custom variable has many.
        let (mut stack, mut heap) = ([0.0; 16], Vec::new());
        let p = match V::PARAMS <= stack.len() {
            true => &mut stack[..V::PARAMS],
            false => {
                heap.resize(V::PARAMS, 0.0);
                &mut heap[..]
            }
        };
        value.write_params(p);
        if p.iter().any(|v| !v.is_finite()) {
            return Err(GraphError::NonFiniteValue(id));
        }
        let kind = self.kind_index(VariableKind::of::<V, D>());
        let index = self.values.push(&value);
        self.vertices.push(VertexRecord {
            id,
            kind,
            fixed: false,
        });
        self.index.insert(id, index);
        Ok(index)
    }

    fn kind_index(&mut self, kind: VariableKind) -> u16 {
        match self.kinds.iter().position(|k| k.type_id == kind.type_id) {
            Some(i) => i as u16,
            None => {
                self.kinds.push(kind);
                (self.kinds.len() - 1) as u16
            }
        }
    }

    /// Index of the vertex with this id.
    pub fn vertex_index(&self, id: VertexId) -> Option<usize> {
        self.index.get(&id).copied()
    }

    fn checked_index(&self, id: VertexId) -> Result<usize, GraphError> {
        self.vertex_index(id).ok_or(GraphError::UnknownVertex(id))
    }

    fn check_type<V: 'static>(
        &self,
        index: usize,
        context: &'static str,
        expected: &'static str,
    ) -> Result<(), GraphError> {
        let kind = &self.kinds[self.vertices[index].kind as usize];
        if kind.type_id == TypeId::of::<V>() {
            Ok(())
        } else {
            Err(GraphError::WrongVertexType {
                id: self.vertices[index].id,
                context,
                expected,
                actual: kind.name,
            })
        }
    }

    /// The value of vertex `id` as type `V`.
    pub fn value<V: Variable<D>, const D: usize>(&self, id: VertexId) -> Result<V, GraphError> {
        let i = self.checked_index(id)?;
        self.check_type::<V>(i, "the caller", V::NAME)?;
        Ok(self.values.get::<V, D>(i))
    }

    /// Sets the value of vertex `id`.
    pub fn set_value<V: Variable<D>, const D: usize>(
        &mut self,
        id: VertexId,
        value: &V,
    ) -> Result<(), GraphError> {
        let i = self.checked_index(id)?;
        self.check_type::<V>(i, "the caller", V::NAME)?;
        self.values.set(i, value);
        Ok(())
    }

    /// Holds vertex `id` constant (g2o `setFixed`) or releases it.
    pub fn set_fixed(&mut self, id: VertexId, fixed: bool) -> Result<(), GraphError> {
        let i = self.checked_index(id)?;
        self.vertices[i].fixed = fixed;
        Ok(())
    }

    /// Whether vertex `id` is held constant ([`VertexView::fixed`] reads it
    /// by index).
    pub fn is_fixed(&self, id: VertexId) -> Result<bool, GraphError> {
        Ok(self.vertices[self.checked_index(id)?].fixed)
    }

    /// Adds a binary edge from vertex `from` to vertex `to`; returns its edge number.
    pub fn add_edge<T, const E: usize, const D1: usize, const D2: usize>(
        &mut self,
        from: VertexId,
        to: VertexId,
        edge: T,
        information: SMatrix<f64, E, E>,
    ) -> Result<usize, GraphError>
    where
        T: BinaryEdge<E, D1, D2>,
    {
        let ends = self.binary_ends::<T, E, D1, D2>(from, to)?;
        let information =
            PositiveDefinite::new(information).map_err(|issue| GraphError::BadInformation {
                edge: T::NAME,
                vertices: vec![from, to],
                issue,
            })?;
        Ok(self.push_binary(ends, edge, information))
    }

    /// [`Graph::add_edge`] with an information matrix checked already.
    pub fn add_checked_edge<T, const E: usize, const D1: usize, const D2: usize>(
        &mut self,
        from: VertexId,
        to: VertexId,
        edge: T,
        information: PositiveDefinite<E>,
    ) -> Result<usize, GraphError>
    where
        T: BinaryEdge<E, D1, D2>,
    {
        let ends = self.binary_ends::<T, E, D1, D2>(from, to)?;
        Ok(self.push_binary(ends, edge, information))
    }

    /// The indices of a binary edge's vertices, checked: they exist, have
    /// the edge's vertex types and differ.
    fn binary_ends<T, const E: usize, const D1: usize, const D2: usize>(
        &self,
        from: VertexId,
        to: VertexId,
    ) -> Result<[usize; 2], GraphError>
    where
        T: BinaryEdge<E, D1, D2>,
    {
        let a = self.checked_index(from)?;
        let b = self.checked_index(to)?;
        self.check_type::<T::V1>(a, T::NAME, <T::V1 as Variable<D1>>::NAME)?;
        self.check_type::<T::V2>(b, T::NAME, <T::V2 as Variable<D2>>::NAME)?;
        if a == b {
            return Err(GraphError::SelfLoop {
                edge: T::NAME,
                id: from,
            });
        }
        Ok([a, b])
    }

    fn push_binary<T, const E: usize, const D1: usize, const D2: usize>(
        &mut self,
        ends: [usize; 2],
        edge: T,
        information: PositiveDefinite<E>,
    ) -> usize
    where
        T: BinaryEdge<E, D1, D2>,
    {
        let g = self.group_index::<T>(|| Box::new(BinaryGroup::<T, E, D1, D2>::new()));
        let group = self.groups[g]
            .as_any_mut()
            .downcast_mut::<BinaryGroup<T, E, D1, D2>>();
        let k = group
            .map(|grp| grp.push(edge, ends, *information.matrix()))
            .unwrap_or_else(|| unreachable!());
        self.record_edge(g, k)
    }

    /// Adds a unary edge (a prior) on vertex `id`; returns its edge number.
    pub fn add_unary_edge<T, const E: usize, const D: usize>(
        &mut self,
        id: VertexId,
        edge: T,
        information: SMatrix<f64, E, E>,
    ) -> Result<usize, GraphError>
    where
        T: UnaryEdge<E, D>,
    {
        let a = self.unary_end::<T, E, D>(id)?;
        let information =
            PositiveDefinite::new(information).map_err(|issue| GraphError::BadInformation {
                edge: T::NAME,
                vertices: vec![id],
                issue,
            })?;
        Ok(self.push_unary(a, edge, information))
    }

    /// [`Graph::add_unary_edge`] with an information matrix checked already.
    pub fn add_checked_unary_edge<T, const E: usize, const D: usize>(
        &mut self,
        id: VertexId,
        edge: T,
        information: PositiveDefinite<E>,
    ) -> Result<usize, GraphError>
    where
        T: UnaryEdge<E, D>,
    {
        let a = self.unary_end::<T, E, D>(id)?;
        Ok(self.push_unary(a, edge, information))
    }

    /// The index of a unary edge's vertex, checked: it exists and has the
    /// edge's vertex type.
    fn unary_end<T, const E: usize, const D: usize>(
        &self,
        id: VertexId,
    ) -> Result<usize, GraphError>
    where
        T: UnaryEdge<E, D>,
    {
        let a = self.checked_index(id)?;
        self.check_type::<T::V>(a, T::NAME, <T::V as Variable<D>>::NAME)?;
        Ok(a)
    }

    fn push_unary<T, const E: usize, const D: usize>(
        &mut self,
        a: usize,
        edge: T,
        information: PositiveDefinite<E>,
    ) -> usize
    where
        T: UnaryEdge<E, D>,
    {
        let g = self.group_index::<T>(|| Box::new(UnaryGroup::<T, E, D>::new()));
        let group = self.groups[g]
            .as_any_mut()
            .downcast_mut::<UnaryGroup<T, E, D>>();
        let k = group
            .map(|grp| grp.push(edge, a, *information.matrix()))
            .unwrap_or_else(|| unreachable!());
        self.record_edge(g, k)
    }

    fn group_index<T: 'static>(&mut self, make: impl FnOnce() -> Box<dyn FactorGroup>) -> usize {
        let type_id = TypeId::of::<T>();
        match self.group_types.iter().position(|&t| t == type_id) {
            Some(g) => g,
            None => {
                self.groups.push(make());
                self.group_types.push(type_id);
                self.groups.len() - 1
            }
        }
    }

    fn record_edge(&mut self, group: usize, k: usize) -> usize {
        self.edge_order.push((group as u32, k as u32));
        self.edge_order.len() - 1
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of edges.
    pub fn num_edges(&self) -> usize {
        self.edge_order.len()
    }

    /// The vertex at `index`.
    pub fn vertex(&self, index: usize) -> VertexView<'_> {
        let r = &self.vertices[index];
        VertexView {
            index,
            id: r.id,
            kind: &self.kinds[r.kind as usize],
            fixed: r.fixed,
            params: self.values.params_of(index),
        }
    }

    /// All vertices, in insertion order.
    pub fn vertices(&self) -> impl ExactSizeIterator<Item = VertexView<'_>> + '_ {
        (0..self.vertices.len()).map(|i| self.vertex(i))
    }

    /// Edge number `k` (insertion order).
    pub fn edge(&self, k: usize) -> EdgeView<'_> {
        let (g, i) = self.edge_order[k];
        EdgeView {
            group: self.groups[g as usize].as_ref(),
            index: i as usize,
        }
    }

    /// All edges, in insertion order.
    pub fn edges(&self) -> impl ExactSizeIterator<Item = EdgeView<'_>> + '_ {
        (0..self.edge_order.len()).map(|k| self.edge(k))
    }

    /// The edge groups, one per edge type (what solvers linearise).
    pub fn factor_groups(&self) -> &[Box<dyn FactorGroup>] {
        &self.groups
    }

    /// The current values.
    pub fn values(&self) -> &Values {
        &self.values
    }

    /// The current values, mutable (solvers restore backups through this).
    pub fn values_mut(&mut self) -> &mut Values {
        &mut self.values
    }

    /// Applies the update `x ⊞ δ` to the vertex at `index`.
    pub fn oplus(&mut self, index: usize, delta: &[f64]) {
        let kind = &self.kinds[self.vertices[index].kind as usize];
        (kind.oplus)(self.values.params_of_mut(index), delta);
    }

    /// Sets (or with `None` removes) the robust kernel of edge number `edge`.
    /// Returns `false` if there is no such edge.
    pub fn set_robust_kernel(&mut self, edge: usize, kernel: Option<RobustKernel>) -> bool {
        let Some(&(g, i)) = self.edge_order.get(edge) else {
            return false;
        };
        self.groups[g as usize].set_kernel(i as usize, kernel);
        true
    }

    /// Total χ² = Σ eᵀΩe over all edges (g2o convention, no ½); edges with a
    /// robust kernel contribute ρ(eᵀΩe).
    pub fn chi2(&self) -> f64 {
        self.groups.iter().map(|g| g.total_chi2(&self.values)).sum()
    }

    /// Whether [`Graph::chi2`] is the objective the solvers' steps descend,
    /// so that a lower χ² is a better estimate: true unless an edge has a
    /// kernel whose value is not the integral of its weight
    /// ([`RobustKernel::value_matches_weight`]: DCS).
    pub fn chi2_is_objective(&self) -> bool {
        self.edges()
            .all(|e| e.kernel().is_none_or(|k| k.value_matches_weight()))
    }

    /// Mutable access to the groups and the values at once (for initialisation).
    pub(crate) fn groups_and_values_mut(&mut self) -> (&[Box<dyn FactorGroup>], &mut Values) {
        (&self.groups, &mut self.values)
    }
}
