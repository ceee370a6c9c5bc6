//! Your own vertex and edge types in g2o text: register each with its tag,
//! then read with the registry in [`crate::ReadOptions`] and write with
//! [`crate::to_string_with`].
//!
//! A vertex line is `TAG id` and the value's [`Variable::PARAMS`] numbers (as
//! [`Variable::write_params`] writes them); an edge line is `TAG`, the ids of
//! its vertices, its [`G2oMeasurement::LEN`] measurement numbers and the
//! upper triangle of its information matrix row by row, as g2o writes its
//! own types.
//!
//! ```
//! use cairn_core::{BinaryEdge, Graph, SE2};
//! use cairn_g2o::{G2oMeasurement, ReadOptions, Registry, read_bytes, to_string_with};
//! use nalgebra::{Matrix1, Vector1, Vector2};
//!
//! /// The distance from a pose's position to a point.
//! #[derive(Clone, Debug)]
//! struct Range(f64);
//! impl BinaryEdge<1, 3, 2> for Range {
//!     type V1 = SE2;
//!     type V2 = Vector2<f64>;
//!     const NAME: &'static str = "RANGE";
//!     fn error(&self, pose: &SE2, point: &Vector2<f64>) -> Vector1<f64> {
//!         Vector1::new((point - pose.t).norm() - self.0)
//!     }
//! }
//! impl G2oMeasurement for Range {
//!     const LEN: usize = 1;
//!     fn write_measurement(&self, out: &mut [f64]) {
//!         out[0] = self.0;
//!     }
//!     fn read_measurement(numbers: &[f64]) -> Result<Self, String> {
//!         match numbers[0] {
//!             r if r >= 0.0 => Ok(Range(r)),
//!             r => Err(format!("a range of {r} is negative")),
//!         }
//!     }
//! }
//!
//! let mut registry = Registry::new();
//! registry.binary_edge::<Range, 1, 3, 2>("EDGE_RANGE_XY")?;
//! let mut graph = Graph::new();
//! graph.add_vertex(0, SE2::identity())?;
//! graph.add_vertex(1, Vector2::new(3.0, 4.0))?;
//! graph.add_edge(0, 1, Range(5.0), Matrix1::new(100.0))?;
//! let text = to_string_with(&graph, &registry)?;
//! assert!(text.contains("\nEDGE_RANGE_XY 0 1 5.0 100.0\n"));
//! let options = ReadOptions { registry, ..Default::default() };
//! let (again, _) = read_bytes(text.as_bytes(), &options)?;
//! assert_eq!(again.chi2(), graph.chi2());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::error::LineError;
use crate::reader::{Fields, Reader};
use crate::tags;
use cairn_core::{BinaryEdge, UnaryEdge, Variable};
use std::any::{Any, TypeId};

/// An edge type whose measurement is written to g2o text as numbers and
/// read back from them.
pub trait G2oMeasurement: Sized {
    /// How many numbers the measurement takes in a line.
    const LEN: usize;
    /// Writes the measurement's `LEN` numbers into `out`.
    fn write_measurement(&self, out: &mut [f64]);
    /// The edge from `LEN` finite numbers as [`Self::write_measurement`]
    /// writes them, or why they make none (the reader names the line).
    fn read_measurement(numbers: &[f64]) -> Result<Self, String>;
}

/// Why a type could not be registered.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RegistryError {
    /// A tag must be one word that does not start a comment.
    #[error(
        "{0:?} cannot be a g2o tag: it must be one word of printable ASCII, not starting with #"
    )]
    BadTag(String),
    /// The tag is one Cairn reads and writes itself.
    #[error("{0} is a built-in g2o tag")]
    BuiltIn(String),
    /// The tag is registered already.
    #[error("{0} is registered already")]
    TagTaken(String),
    /// The type is registered already, under another tag.
    #[error("{name} is registered already, as {tag}")]
    TypeTaken {
        /// The type's name.
        name: &'static str,
        /// Its tag.
        tag: &'static str,
    },
}

/// Reads one record of a registered type; returns the fields it used.
pub(crate) type ReadRecord = for<'a> fn(&mut Reader<'a>, &Fields<'a>) -> Result<usize, LineError>;
/// Writes an edge's measurement (the edge as `&dyn Any`) into the slice.
pub(crate) type WriteMeasurement = fn(&dyn Any, &mut [f64]);

#[derive(Clone, Debug)]
pub(crate) struct VertexType {
    pub(crate) tag: &'static str,
    pub(crate) type_id: TypeId,
    pub(crate) read: ReadRecord,
}

#[derive(Clone, Debug)]
pub(crate) struct EdgeType {
    pub(crate) tag: &'static str,
    pub(crate) type_id: TypeId,
    pub(crate) read: ReadRecord,
    pub(crate) write: WriteMeasurement,
    pub(crate) len: usize,
}

/// The tags of user-defined vertex and edge types. Empty by default: the
/// reader and writer then know the built-in types only.
#[derive(Clone, Debug, Default)]
pub struct Registry {
    vertices: Vec<VertexType>,
    edges: Vec<EdgeType>,
}

impl Registry {
    /// A registry with no types.
    pub fn new() -> Self {
        Self::default()
    }

    /// Registers vertex type `V` under `tag`.
    pub fn vertex<V: Variable<D>, const D: usize>(
        &mut self,
        tag: &'static str,
    ) -> Result<&mut Self, RegistryError> {
        self.check(tag, TypeId::of::<V>(), std::any::type_name::<V>())?;
        self.vertices.push(VertexType {
            tag,
            type_id: TypeId::of::<V>(),
            read: read_vertex::<V, D>,
        });
        Ok(self)
    }

    /// Registers edge type `T` between two vertices under `tag`.
    pub fn binary_edge<T, const E: usize, const D1: usize, const D2: usize>(
        &mut self,
        tag: &'static str,
    ) -> Result<&mut Self, RegistryError>
    where
        T: BinaryEdge<E, D1, D2> + G2oMeasurement,
    {
        self.check(tag, TypeId::of::<T>(), T::NAME)?;
        self.edges.push(EdgeType {
            tag,
            type_id: TypeId::of::<T>(),
            read: read_binary::<T, E, D1, D2>,
            write: write_measurement::<T>,
            len: T::LEN,
        });
        Ok(self)
    }

    /// Registers edge type `T` on one vertex (a prior) under `tag`.
    pub fn unary_edge<T, const E: usize, const D: usize>(
        &mut self,
        tag: &'static str,
    ) -> Result<&mut Self, RegistryError>
    where
        T: UnaryEdge<E, D> + G2oMeasurement,
    {
        self.check(tag, TypeId::of::<T>(), T::NAME)?;
        self.edges.push(EdgeType {
            tag,
            type_id: TypeId::of::<T>(),
            read: read_unary::<T, E, D>,
            write: write_measurement::<T>,
            len: T::LEN,
        });
        Ok(self)
    }

    fn check(
        &self,
        tag: &'static str,
        type_id: TypeId,
        name: &'static str,
    ) -> Result<(), RegistryError> {
        let printable = !tag.is_empty() && tag.bytes().all(|b| b.is_ascii_graphic());
        if !printable || tag.starts_with('#') {
            return Err(RegistryError::BadTag(tag.to_string()));
        }
        if tags::ALL.contains(&tag) {
            return Err(RegistryError::BuiltIn(tag.to_string()));
        }
        if self.reader(tag).is_some() {
            return Err(RegistryError::TagTaken(tag.to_string()));
        }
        let taken = self
            .vertex_tag(type_id)
            .or_else(|| self.edge(type_id).map(|e| e.tag));
        if let Some(tag) = taken {
            return Err(RegistryError::TypeTaken { name, tag });
        }
        Ok(())
    }

    /// The reader of the records tagged `tag`.
    pub(crate) fn reader(&self, tag: &str) -> Option<ReadRecord> {
        let vertex = self.vertices.iter().find(|v| v.tag == tag).map(|v| v.read);
        vertex.or_else(|| self.edges.iter().find(|e| e.tag == tag).map(|e| e.read))
    }

    /// The tag of vertex type `type_id`.
    pub(crate) fn vertex_tag(&self, type_id: TypeId) -> Option<&'static str> {
        self.vertices
            .iter()
            .find(|v| v.type_id == type_id)
            .map(|v| v.tag)
    }

    /// The registration of edge type `type_id`.
    pub(crate) fn edge(&self, type_id: TypeId) -> Option<&EdgeType> {
        self.edges.iter().find(|e| e.type_id == type_id)
    }
}

fn read_vertex<'a, V: Variable<D>, const D: usize>(
    reader: &mut Reader<'a>,
    fields: &Fields<'a>,
) -> Result<usize, LineError> {
    reader.vertex::<V, D>(fields)
}

/// The measurement of a `first`-th field on: `T::LEN` numbers.
fn measurement<T: G2oMeasurement>(fields: &Fields, first: usize) -> Result<T, LineError> {
    let numbers = (first..first + T::LEN)
        .map(|k| fields.number(k))
        .collect::<Result<Vec<_>, _>>()?;
    T::read_measurement(&numbers).map_err(|message| LineError::BadMeasurement {
        tag: fields.tag.to_string(),
        message,
    })
}

fn read_binary<'a, T, const E: usize, const D1: usize, const D2: usize>(
    reader: &mut Reader<'a>,
    fields: &Fields<'a>,
) -> Result<usize, LineError>
where
    T: BinaryEdge<E, D1, D2> + G2oMeasurement,
{
    let used = 2 + T::LEN + E * (E + 1) / 2;
    fields.need(used)?;
    let edge = measurement::<T>(fields, 2)?;
    let information = fields.information::<E>(2 + T::LEN)?;
    reader.binary(fields, edge, information)?;
    Ok(used)
}

fn read_unary<'a, T, const E: usize, const D: usize>(
    reader: &mut Reader<'a>,
    fields: &Fields<'a>,
) -> Result<usize, LineError>
where
    T: UnaryEdge<E, D> + G2oMeasurement,
{
    let used = 1 + T::LEN + E * (E + 1) / 2;
    fields.need(used)?;
    let edge = measurement::<T>(fields, 1)?;
    let information = fields.information::<E>(1 + T::LEN)?;
    reader.unary(fields, edge, information)?;
    Ok(used)
}

fn write_measurement<T: G2oMeasurement + 'static>(edge: &dyn Any, out: &mut [f64]) {
    if let Some(edge) = edge.downcast_ref::<T>() {
        edge.write_measurement(out);
    }
}
