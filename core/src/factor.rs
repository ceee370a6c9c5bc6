//! Factor groups: all edges of one type, stored together so that linearising
//! them is one monomorphised, parallel loop (one `dyn` call per edge type per
//! iteration, none per edge or per block).

use crate::edge::{BinaryEdge, UnaryEdge};
use crate::kernel::RobustKernel;
use crate::layout::{self, Scatter};
use crate::values::Values;
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;
use std::any::{Any, TypeId};

/// Edges per parallel work item; also the chunk of the deterministic χ² sum.
pub const CHUNK: usize = 512;

/// Sums `f(0) + … + f(n−1)` in parallel, always in the same order whatever the
/// number of threads, so results are reproducible bit for bit.
pub fn deterministic_sum(n: usize, f: impl Fn(usize) -> f64 + Sync) -> f64 {
    let partial: Vec<f64> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| (c * CHUNK..n.min((c + 1) * CHUNK)).map(&f).sum())
        .collect();
    partial.iter().sum()
}

/// Where an edge's linearisation goes, block by block as it is computed:
/// its slot of the buffer (see [`crate::layout`]) or straight into H.
trait Sink {
    /// The edge's k-th block (a, b), a ≤ b, of JᵀΩJ, in slot order.
    fn block<const R: usize, const C: usize>(&mut self, k: usize, b: &SMatrix<f64, R, C>);
    /// Vertex a's gradient segment JₐᵀΩe.
    fn gradient<const R: usize>(&mut self, a: usize, g: &SVector<f64, R>);
    /// The edge's objective contribution.
    fn chi2(&mut self, chi2: f64);
}

/// An edge's slot of the buffer, with the offsets of its blocks and segments.
struct SlotSink<'a> {
    slot: &'a mut [f64],
    blocks: &'a [usize],
    gradients: &'a [usize],
}

impl Sink for SlotSink<'_> {
    #[inline(always)]
    fn block<const R: usize, const C: usize>(&mut self, k: usize, b: &SMatrix<f64, R, C>) {
        self.slot[self.blocks[k]..][..R * C].copy_from_slice(b.as_slice());
    }
    #[inline(always)]
    fn gradient<const R: usize>(&mut self, a: usize, g: &SVector<f64, R>) {
        self.slot[self.gradients[a]..][..R].copy_from_slice(g.as_slice());
    }
    #[inline(always)]
    fn chi2(&mut self, chi2: f64) {
        let last = self.slot.len() - 1;
        self.slot[last] = chi2;
    }
}

/// One edge's targets in H and the gradient (its blocks (a, a) are
/// diagonal blocks of H).
struct HessianSink<'a> {
    hessian: &'a mut [f64],
    gradient: &'a mut [f64],
    blocks: &'a [layout::BlockTarget],
    columns: &'a [u32],
    chi2: &'a mut f64,
    diagonal: &'a [bool],
}

impl Sink for HessianSink<'_> {
    #[inline(always)]
    fn block<const R: usize, const C: usize>(&mut self, k: usize, b: &SMatrix<f64, R, C>) {
        if self.diagonal[k] {
            self.blocks[k].add_diagonal(self.hessian, b);
        } else {
            self.blocks[k].add(self.hessian, b);
        }
    }
    #[inline(always)]
    fn gradient<const R: usize>(&mut self, a: usize, g: &SVector<f64, R>) {
        layout::add_gradient(self.gradient, self.columns[a], g);
    }
    #[inline(always)]
    fn chi2(&mut self, chi2: f64) {
        *self.chi2 = chi2;
    }
}

/// The object-safe view of a group of edges of one type.
pub trait FactorGroup: Send + Sync + 'static {
    /// The edge type's name (g2o tag style).
    fn name(&self) -> &'static str;
    /// A copy of the group, for [`Graph`](crate::Graph)'s `Clone`.
    fn boxed_clone(&self) -> Box<dyn FactorGroup>;
    /// `TypeId` of the edge type.
    fn edge_type(&self) -> TypeId;
    /// Number of edges.
    fn len(&self) -> usize;
    /// Whether the group is empty.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Dimension of the error vector.
    fn error_dim(&self) -> usize;
    /// Tangent dimension of each of the edge's vertices, in edge order.
    fn vertex_dims(&self) -> &[usize];
    /// Vertex indices of edge `i`.
    fn vertices(&self, i: usize) -> &[usize];
    /// Edge `i` itself, for downcasting to its concrete type.
    fn edge(&self, i: usize) -> &dyn Any;
    /// Information matrix of edge `i`, column-major `error_dim × error_dim`.
    fn information(&self, i: usize) -> &[f64];
    /// Edge `i`'s contribution to the objective: eᵀΩe, or ρ(eᵀΩe) with a robust kernel.
    fn chi2(&self, i: usize, values: &Values) -> f64;
    /// The robust kernel of edge `i`, if any.
    fn kernel(&self, i: usize) -> Option<RobustKernel>;
    /// Sets or removes the robust kernel of edge `i`.
    fn set_kernel(&mut self, i: usize, kernel: Option<RobustKernel>);
    /// Error vector of edge `i` written into `out` (length `error_dim`).
    fn error(&self, i: usize, values: &Values, out: &mut [f64]);
    /// Edge `i`'s error into `error` and each vertex's Jacobian ∂e/∂δ
    /// (`error_dim × dim`, column-major, one vertex after the other, in edge
    /// order) into `jacobians`, as the solver linearises it.
    fn jacobians(&self, i: usize, values: &Values, error: &mut [f64], jacobians: &mut [f64]);
    /// Writes every edge's slot (see [`crate::layout`]) into `out`, which holds
    /// `len × stride` scalars.
    fn linearize(&self, values: &Values, out: &mut [f64]);
    /// Linearises every edge on the calling thread and adds its blocks
    /// straight into H and the gradient where `out` says. In edge order,
    /// so each entry gets exactly the sum the buffer's assembly makes.
    fn linearize_into(&self, values: &Values, out: Scatter<'_>);
    /// Sets the other vertex of edge `i` from the vertex in position `known`
    /// (spanning-tree initialisation). Returns the vertex set, if any.
    fn propagate(&self, i: usize, known: usize, values: &mut Values) -> Option<usize>;
    /// Upcast for downcasting to the concrete group.
    fn as_any_mut(&mut self) -> &mut dyn Any;

    /// Sum of χ² over the group, deterministic.
    fn total_chi2(&self, values: &Values) -> f64 {
        deterministic_sum(self.len(), |i| self.chi2(i, values))
    }
}

/// An edge and its information. Its vertices are kept apart, in one array
/// per group, so that the passes over the graph's structure read 16 bytes
/// per edge instead of the whole entry.
#[derive(Clone)]
struct Entry<T, const E: usize> {
    edge: T,
    /// Ω as computed with: subnormal entries flushed to zero.
    information: SMatrix<f64, E, E>,
    /// Ω as given, kept only when flushing changed it (for writing it back).
    given: Option<Box<SMatrix<f64, E, E>>>,
    kernel: Option<RobustKernel>,
}

impl<T, const E: usize> Entry<T, E> {
    /// Subnormal entries of Ω (such as FRH.g2o's 6.95335e-310) change no digit
    /// of χ² but slow every product they enter by two orders of magnitude on
    /// x86, so the solver computes with zeros in their place.
    fn new(edge: T, information: SMatrix<f64, E, E>) -> Self {
        let flushed = information.map(|w| if w.is_subnormal() { 0.0 } else { w });
        let given = (flushed != information).then(|| Box::new(information));
        Self {
            edge,
            information: flushed,
            given,
            kernel: None,
        }
    }

    /// Ω as given.
    fn given_information(&self) -> &[f64] {
        self.given
            .as_deref()
            .unwrap_or(&self.information)
            .as_slice()
    }

    /// (objective contribution, weight of Ω) for the error `e`.
    #[inline]
    fn robust(&self, e: &SVector<f64, E>) -> (f64, f64) {
        let s = e.dot(&(self.information * e));
        match self.kernel {
            None => (s, 1.0),
            Some(k) => {
                let [rho, weight, _] = k.robustify(s);
                (rho, weight)
            }
        }
    }
}

/// All edges of one unary type.
#[derive(Clone)]
pub struct UnaryGroup<T, const E: usize, const D: usize> {
    entries: Vec<Entry<T, E>>,
    vertices: Vec<[usize; 1]>,
    dims: [usize; 1],
}

impl<T: UnaryEdge<E, D>, const E: usize, const D: usize> UnaryGroup<T, E, D> {
    /// An empty group.
    pub fn new() -> Self {
        Self {
            entries: Vec::new(),
            vertices: Vec::new(),
            dims: [D],
        }
    }
    /// Appends an edge (vertex index and information already checked).
    pub fn push(&mut self, edge: T, vertex: usize, information: SMatrix<f64, E, E>) -> usize {
        self.entries.push(Entry::new(edge, information));
        self.vertices.push([vertex]);
        self.entries.len() - 1
    }
    fn eval(&self, i: usize, values: &Values) -> (T::V, SVector<f64, E>) {
        let x = values.get::<T::V, D>(self.vertices[i][0]);
        let e = self.entries[i].edge.error(&x);
        (x, e)
    }
    /// Linearises edge `i` (`en`) into `sink`: JᵀΩJ, JᵀΩe, χ².
    #[inline(always)]
    fn emit(&self, i: usize, en: &Entry<T, E>, values: &Values, sink: &mut impl Sink) {
        let (x, e) = self.eval(i, values);
        let j = en.edge.jacobian(&x);
        let (chi2, weight) = en.robust(&e);
        let oj = en.information * j * weight;
        sink.block(0, &(j.transpose() * oj));
        sink.gradient(0, &(oj.transpose() * e));
        sink.chi2(chi2);
    }
}

impl<T: UnaryEdge<E, D>, const E: usize, const D: usize> Default for UnaryGroup<T, E, D> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: UnaryEdge<E, D>, const E: usize, const D: usize> FactorGroup for UnaryGroup<T, E, D> {
    fn name(&self) -> &'static str {
        T::NAME
    }
    fn boxed_clone(&self) -> Box<dyn FactorGroup> {
        Box::new(self.clone())
    }
    fn edge_type(&self) -> TypeId {
        TypeId::of::<T>()
    }
    fn len(&self) -> usize {
        self.entries.len()
    }
    fn error_dim(&self) -> usize {
        E
    }
    fn vertex_dims(&self) -> &[usize] {
        &self.dims
    }
    fn vertices(&self, i: usize) -> &[usize] {
        &self.vertices[i]
    }
    fn edge(&self, i: usize) -> &dyn Any {
        &self.entries[i].edge
    }
    fn information(&self, i: usize) -> &[f64] {
        self.entries[i].given_information()
    }
    fn chi2(&self, i: usize, values: &Values) -> f64 {
        self.entries[i].robust(&self.eval(i, values).1).0
    }
    fn kernel(&self, i: usize) -> Option<RobustKernel> {
        self.entries[i].kernel
    }
    fn set_kernel(&mut self, i: usize, kernel: Option<RobustKernel>) {
        self.entries[i].kernel = kernel;
    }
    fn error(&self, i: usize, values: &Values, out: &mut [f64]) {
        out.copy_from_slice(self.eval(i, values).1.as_slice());
    }
    fn jacobians(&self, i: usize, values: &Values, error: &mut [f64], jacobians: &mut [f64]) {
        let (x, e) = self.eval(i, values);
        error.copy_from_slice(e.as_slice());
        jacobians.copy_from_slice(self.entries[i].edge.jacobian(&x).as_slice());
    }
    fn linearize(&self, values: &Values, out: &mut [f64]) {
        let stride = layout::stride(&self.dims);
        let gradients = [layout::gradient_offset(&self.dims, 0)];
        out.par_chunks_mut(stride)
            .zip(self.entries.par_iter())
            .with_min_len(CHUNK)
            .enumerate()
            .for_each(|(i, (slot, en))| {
                let (blocks, gradients) = (&[0][..], &gradients[..]);
                let mut sink = SlotSink {
                    slot,
                    blocks,
                    gradients,
                };
                self.emit(i, en, values, &mut sink);
            });
    }
    fn linearize_into(&self, values: &Values, out: Scatter<'_>) {
        for (i, (en, chi2)) in self.entries.iter().zip(out.chi2.iter_mut()).enumerate() {
            let mut sink = HessianSink {
                hessian: &mut *out.hessian,
                gradient: &mut *out.gradient,
                blocks: &out.blocks[i..=i],
                columns: &out.columns[i..=i],
                chi2,
                diagonal: &[true],
            };
            self.emit(i, en, values, &mut sink);
        }
    }
    fn propagate(&self, _i: usize, _known: usize, _values: &mut Values) -> Option<usize> {
        None
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// All edges of one binary type.
#[derive(Clone)]
pub struct BinaryGroup<T, const E: usize, const D1: usize, const D2: usize> {
    entries: Vec<Entry<T, E>>,
    vertices: Vec<[usize; 2]>,
    dims: [usize; 2],
}

impl<T: BinaryEdge<E, D1, D2>, const E: usize, const D1: usize, const D2: usize>
    BinaryGroup<T, E, D1, D2>
{
    /// An empty group.
    pub fn new() -> Self {
        Self {
            entries: Vec::new(),
            vertices: Vec::new(),
            dims: [D1, D2],
        }
    }
    /// Appends an edge (vertex indices and information already checked).
    pub fn push(
        &mut self,
        edge: T,
        vertices: [usize; 2],
        information: SMatrix<f64, E, E>,
    ) -> usize {
        self.entries.push(Entry::new(edge, information));
        self.vertices.push(vertices);
        self.entries.len() - 1
    }
    fn eval(&self, i: usize, values: &Values) -> (T::V1, T::V2, SVector<f64, E>) {
        let [a, b] = self.vertices[i];
        let (x1, x2) = (values.get::<T::V1, D1>(a), values.get::<T::V2, D2>(b));
        let e = self.entries[i].edge.error(&x1, &x2);
        (x1, x2, e)
    }
    /// Linearises `en` on vertices `a` and `b` into `sink`: the blocks
    /// (1, 1), (1, 2), (2, 2) of JᵀΩJ, each vertex's JᵀΩe, χ².
    #[inline(always)]
    fn emit(en: &Entry<T, E>, [a, b]: [usize; 2], values: &Values, sink: &mut impl Sink) {
        let (x1, x2) = (values.get::<T::V1, D1>(a), values.get::<T::V2, D2>(b));
        let lin = en.edge.linearize(&x1, &x2);
        let (chi2, weight) = en.robust(&lin.0);
        let weighted;
        let w = if weight == 1.0 {
            &en.information
        } else {
            weighted = en.information * weight;
            &weighted
        };
        let blocks = en.edge.normal_blocks(&lin, w);
        sink.block(0, &blocks.h11);
        sink.block(1, &blocks.h12);
        sink.block(2, &blocks.h22);
        sink.gradient(0, &blocks.g1);
        sink.gradient(1, &blocks.g2);
        sink.chi2(chi2);
    }
}

impl<T: BinaryEdge<E, D1, D2>, const E: usize, const D1: usize, const D2: usize> Default
    for BinaryGroup<T, E, D1, D2>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<T: BinaryEdge<E, D1, D2>, const E: usize, const D1: usize, const D2: usize> FactorGroup
    for BinaryGroup<T, E, D1, D2>
{
    fn name(&self) -> &'static str {
        T::NAME
    }
    fn boxed_clone(&self) -> Box<dyn FactorGroup> {
        Box::new(self.clone())
    }
    fn edge_type(&self) -> TypeId {
        TypeId::of::<T>()
    }
    fn len(&self) -> usize {
        self.entries.len()
    }
    fn error_dim(&self) -> usize {
        E
    }
    fn vertex_dims(&self) -> &[usize] {
        &self.dims
    }
    fn vertices(&self, i: usize) -> &[usize] {
        &self.vertices[i]
    }
    fn edge(&self, i: usize) -> &dyn Any {
        &self.entries[i].edge
    }
    fn information(&self, i: usize) -> &[f64] {
        self.entries[i].given_information()
    }
    fn chi2(&self, i: usize, values: &Values) -> f64 {
        self.entries[i].robust(&self.eval(i, values).2).0
    }
    fn kernel(&self, i: usize) -> Option<RobustKernel> {
        self.entries[i].kernel
    }
    fn set_kernel(&mut self, i: usize, kernel: Option<RobustKernel>) {
        self.entries[i].kernel = kernel;
    }
    fn error(&self, i: usize, values: &Values, out: &mut [f64]) {
        out.copy_from_slice(self.eval(i, values).2.as_slice());
    }
    fn jacobians(&self, i: usize, values: &Values, error: &mut [f64], jacobians: &mut [f64]) {
        let [a, b] = self.vertices[i];
        let (x1, x2) = (values.get::<T::V1, D1>(a), values.get::<T::V2, D2>(b));
        let (e, j1, j2) = self.entries[i].edge.linearize(&x1, &x2);
        error.copy_from_slice(e.as_slice());
        jacobians[..E * D1].copy_from_slice(j1.as_slice());
        jacobians[E * D1..].copy_from_slice(j2.as_slice());
    }
    fn linearize(&self, values: &Values, out: &mut [f64]) {
        let stride = layout::stride(&self.dims);
        let blocks = [0, D1 * D1, D1 * D1 + D1 * D2];
        let g1 = layout::gradient_offset(&self.dims, 0);
        let gradients = [g1, g1 + D1];
        out.par_chunks_mut(stride)
            .zip(self.entries.par_iter())
            .zip(self.vertices.par_iter())
            .with_min_len(CHUNK)
            .for_each(|((slot, en), &vertices)| {
                let (blocks, gradients) = (&blocks[..], &gradients[..]);
                Self::emit(
                    en,
                    vertices,
                    values,
                    &mut SlotSink {
                        slot,
                        blocks,
                        gradients,
                    },
                );
            });
    }
    fn linearize_into(&self, values: &Values, out: Scatter<'_>) {
        let targets = out.blocks.chunks_exact(3).zip(out.columns.chunks_exact(2));
        let edges = self.entries.iter().zip(self.vertices.iter());
        for (((en, &vertices), (blocks, columns)), chi2) in
            edges.zip(targets).zip(out.chi2.iter_mut())
        {
            let mut sink = HessianSink {
                hessian: &mut *out.hessian,
                gradient: &mut *out.gradient,
                blocks,
                columns,
                chi2,
                diagonal: &[true, false, true],
            };
            Self::emit(en, vertices, values, &mut sink);
        }
    }
    fn propagate(&self, i: usize, known: usize, values: &mut Values) -> Option<usize> {
        let en = &self.entries[i];
        let [a, b] = self.vertices[i];
        if known == 0 {
            let x2 = en.edge.predict_second(&values.get::<T::V1, D1>(a))?;
            values.set(b, &x2);
            Some(b)
        } else {
            let x1 = en.edge.predict_first(&values.get::<T::V2, D2>(b))?;
            values.set(a, &x1);
            Some(a)
        }
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
