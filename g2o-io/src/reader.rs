//! Reading the g2o text format.

use crate::error::{G2oError, LineError};
use crate::registry::Registry;
use crate::tags;
use cairn_core::information::{PositiveDefinite, nearest_positive_definite};
use cairn_core::{
    EdgePriorSE2, EdgeSE2, EdgeSE2XY, EdgeSE3, Graph, InformationIssue, SE2, SE3, Se3Error,
    SpanningTreeReport, Variable, VertexId,
};
use nalgebra::{SMatrix, Vector2};
use std::collections::BTreeMap;
use std::path::Path;

/// Options of the reader.
#[derive(Clone, Debug, Default)]
pub struct ReadOptions {
    /// Replace information matrices that are not positive definite by the
    /// nearest positive-definite matrix instead of refusing the file.
    pub repair_information: bool,
    /// Tags of your own vertex and edge types, read like the built-in ones
    /// (unknown tags are counted and skipped).
    pub registry: Registry,
    /// The error `EDGE_SE3:QUAT` edges measure. Default g2o's.
    pub se3_error: Se3Error,
}

/// What the reader found besides the graph.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadReport {
    /// Lines read.
    pub lines: usize,
    /// Records read, per tag.
    pub records: BTreeMap<String, usize>,
    /// Lines skipped because their tag is not supported (PARAMS_*, VERTEX_TRACKXYZ,
    /// junk), per tag.
    pub unknown: BTreeMap<String, usize>,
    /// Lines with more fields than their tag uses (the extra ones are ignored, as g2o does).
    pub extra_fields: usize,
    /// Vertices created from edges because the file has no VERTEX lines.
    pub created_vertices: usize,
    /// How created vertices were initialised.
    pub spanning_tree: Option<SpanningTreeReport>,
    /// `LANDMARK2` ids live in their own id space; landmark `l` became vertex
    /// `landmark_id_offset + l`.
    pub landmark_id_offset: Option<VertexId>,
    /// Lines whose information matrix was replaced by the nearest positive-definite one.
    pub repaired_information: Vec<usize>,
    /// Vertices fixed by FIX lines.
    pub fixed: Vec<VertexId>,
}

impl LoadReport {
    /// Total number of skipped lines with unknown tags.
    pub fn unknown_lines(&self) -> usize {
        self.unknown.values().sum()
    }
}

/// Reads a g2o file.
pub fn read_file(
    path: impl AsRef<Path>,
    options: &ReadOptions,
) -> Result<(Graph, LoadReport), G2oError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| G2oError::io(path, e))?;
    read_bytes(&bytes, options)
}

/// Reads g2o text held in memory.
pub fn read_bytes(bytes: &[u8], options: &ReadOptions) -> Result<(Graph, LoadReport), G2oError> {
    Reader::new(bytes, options).run()
}

/// A line split into its tag and fields, with typed access.
pub(crate) struct Fields<'a> {
    pub(crate) tag: &'a str,
    items: Vec<&'a str>,
}

impl<'a> Fields<'a> {
    pub(crate) fn need(&self, n: usize) -> Result<(), LineError> {
        if self.items.len() < n {
            return Err(LineError::MissingFields {
                tag: self.tag.to_string(),
                expected: n,
                found: self.items.len(),
            });
        }
        Ok(())
    }

    pub(crate) fn number(&self, k: usize) -> Result<f64, LineError> {
        let text = self.items[k];
        let v: f64 = text.parse().map_err(|_| LineError::BadNumber {
            field: k + 1,
            text: text.to_string(),
        })?;
        if !v.is_finite() {
            return Err(LineError::NonFinite {
                field: k + 1,
                text: text.to_string(),
            });
        }
        Ok(v)
    }

    fn numbers<const N: usize>(&self, first: usize) -> Result<[f64; N], LineError> {
        let mut out = [0.0; N];
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.number(first + i)?;
        }
        Ok(out)
    }

    fn id(&self, k: usize) -> Result<VertexId, LineError> {
        let text = self.items[k];
        text.parse().map_err(|_| LineError::BadId {
            field: k + 1,
            text: text.to_string(),
        })
    }

    /// An information matrix given as its upper triangle, row by row.
    pub(crate) fn information<const E: usize>(
        &self,
        first: usize,
    ) -> Result<SMatrix<f64, E, E>, LineError> {
        let mut m = SMatrix::<f64, E, E>::zeros();
        let mut k = first;
        for r in 0..E {
            for c in r..E {
                let v = self.number(k)?;
                m[(r, c)] = v;
                m[(c, r)] = v;
                k += 1;
            }
        }
        Ok(m)
    }
}

/// Adds one to `tag`'s count, allocating its name only the first time.
fn count(counts: &mut BTreeMap<String, usize>, tag: &str) {
    match counts.get_mut(tag) {
        Some(n) => *n += 1,
        None => {
            counts.insert(tag.to_string(), 1);
        }
    }
}

fn quaternion_params(f: &Fields, first: usize) -> Result<[f64; 7], LineError> {
    let p = f.numbers::<7>(first)?;
    if p[3..].iter().all(|&q| q == 0.0) {
        return Err(LineError::ZeroQuaternion);
    }
    Ok(p)
}

struct PendingLandmark {
    line: usize,
    pose: VertexId,
    landmark: VertexId,
    z: Vector2<f64>,
    information: SMatrix<f64, 2, 2>,
}

/// The state of one read.
pub(crate) struct Reader<'a> {
    bytes: &'a [u8],
    options: &'a ReadOptions,
    graph: Graph,
    report: LoadReport,
    create_vertices: bool,
    uninitialized: Vec<bool>,
    indefinite: Vec<usize>,
    fix_lines: Vec<(usize, Vec<VertexId>)>,
    landmarks: Vec<PendingLandmark>,
    /// The current line's fields, kept to reuse its allocation.
    items: Vec<&'a str>,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8], options: &'a ReadOptions) -> Self {
        // Files with no VERTEX line at all (CSAIL, manhattan, kitti_*) get their
        // vertices from the edges.
        let has_vertices = memchr::memmem::find_iter(bytes, b"VERTEX_").any(|at| {
            let line_start = memchr::memrchr(b'\n', &bytes[..at]).map_or(0, |n| n + 1);
            bytes[line_start..at].iter().all(u8::is_ascii_whitespace)
        });
        Self {
            bytes,
            options,
            graph: Graph::new(),
            report: LoadReport::default(),
            create_vertices: !has_vertices,
            uninitialized: Vec::new(),
            indefinite: Vec::new(),
            fix_lines: Vec::new(),
            landmarks: Vec::new(),
            items: Vec::new(),
        }
    }

    fn run(mut self) -> Result<(Graph, LoadReport), G2oError> {
        // A UTF-8 byte-order mark (Windows editors) is not part of the first line.
        let mut rest = self
            .bytes
            .strip_prefix(b"\xEF\xBB\xBF")
            .unwrap_or(self.bytes);
        let mut number = 0;
        while !rest.is_empty() {
            // Lines end in LF, CRLF, or CR alone (classic Mac files, which
            // would otherwise read as one line).
            let (raw, next) = match memchr::memchr2(b'\n', b'\r', rest) {
                Some(end) if rest[end] == b'\r' && rest.get(end + 1) == Some(&b'\n') => {
                    (&rest[..end], &rest[end + 2..])
                }
                Some(end) => (&rest[..end], &rest[end + 1..]),
                None => (rest, &rest[rest.len()..]),
            };
            rest = next;
            number += 1;
            self.report.lines = number;
            self.line(raw).map_err(|error| G2oError::Line {
                line: number,
                error,
            })?;
        }
        self.finish()
    }

    fn line(&mut self, raw: &'a [u8]) -> Result<(), LineError> {
        let text = std::str::from_utf8(raw).map_err(|_| LineError::NotUtf8)?;
        if !text.is_ascii()
            && let Some(c) = text.chars().find(|c| c.is_whitespace() && !c.is_ascii())
        {
            return Err(LineError::NonAsciiSpace { code: u32::from(c) });
        }
        let mut tokens = text.split_ascii_whitespace();
        let Some(tag) = tokens.next() else {
            return Ok(());
        };
        if tag.starts_with('#') {
            return Ok(());
        }
        let mut items = std::mem::take(&mut self.items);
        items.clear();
        items.extend(tokens);
        let fields = Fields { tag, items };
        let result = self.record(&fields);
        self.items = fields.items;
        result
    }

    /// Adds the record of a line with a tag.
    fn record(&mut self, fields: &Fields<'a>) -> Result<(), LineError> {
        let (tag, line) = (fields.tag, self.report.lines);
        let used = match tag {
            tags::VERTEX_SE2 => self.vertex::<SE2, 3>(fields)?,
            tags::VERTEX_XY => self.vertex::<Vector2<f64>, 2>(fields)?,
            tags::VERTEX_SE3_QUAT => {
                fields.need(8)?;
                let p = quaternion_params(fields, 1)?;
                self.add_vertex(fields.id(0)?, SE3::from_params(&p))?;
                8
            }
            tags::EDGE_SE2 => {
                fields.need(11)?;
                let z = fields.numbers::<3>(2)?;
                let edge = EdgeSE2::new(SE2::new(z[0], z[1], z[2]));
                self.binary(fields, edge, fields.information::<3>(5)?)?;
                11
            }
            tags::EDGE_SE2_XY => {
                fields.need(7)?;
                let z = fields.numbers::<2>(2)?;
                let edge = EdgeSE2XY::new(Vector2::new(z[0], z[1]));
                self.binary(fields, edge, fields.information::<2>(4)?)?;
                7
            }
            tags::LANDMARK2 => {
                fields.need(7)?;
                let z = fields.numbers::<2>(2)?;
                self.landmarks.push(PendingLandmark {
                    line,
                    pose: fields.id(0)?,
                    landmark: fields.id(1)?,
                    z: Vector2::new(z[0], z[1]),
                    information: fields.information::<2>(4)?,
                });
                7
            }
            tags::EDGE_PRIOR_SE2 => {
                fields.need(10)?;
                let z = fields.numbers::<3>(1)?;
                let edge = EdgePriorSE2::new(SE2::new(z[0], z[1], z[2]));
                self.unary(fields, edge, fields.information::<3>(4)?)?;
                10
            }
            tags::EDGE_SE3_QUAT => {
                fields.need(30)?;
                let z = SE3::from_params(&quaternion_params(fields, 2)?);
                let edge = EdgeSE3::with_error(z, self.options.se3_error);
                self.binary(fields, edge, fields.information::<6>(9)?)?;
                30
            }
            tags::FIX => {
                let ids = (0..fields.items.len())
                    .map(|k| fields.id(k))
                    .collect::<Result<Vec<_>, _>>()?;
                self.fix_lines.push((line, ids));
                fields.items.len()
            }
            other => match self.options.registry.reader(other) {
                Some(read) => read(self, fields)?,
                None => {
                    count(&mut self.report.unknown, other);
                    return Ok(());
                }
            },
        };
        if fields.items.len() > used {
            self.report.extra_fields += 1;
        }
        count(&mut self.report.records, tag);
        Ok(())
    }

    pub(crate) fn vertex<V: Variable<D>, const D: usize>(
        &mut self,
        fields: &Fields,
    ) -> Result<usize, LineError> {
        fields.need(1 + V::PARAMS)?;
        let p: Vec<f64> = (1..=V::PARAMS)
            .map(|k| fields.number(k))
            .collect::<Result<_, _>>()?;
        self.add_vertex(fields.id(0)?, V::from_params(&p))?;
        Ok(1 + V::PARAMS)
    }

    fn add_vertex<V: Variable<D>, const D: usize>(
        &mut self,
        id: VertexId,
        value: V,
    ) -> Result<(), LineError> {
        self.graph.add_vertex(id, value)?;
        self.uninitialized.push(false);
        Ok(())
    }

    /// Creates the vertex an edge names if it is missing and `create` is set
    /// (files without VERTEX lines, and `LANDMARK2` landmarks).
    fn ensure_vertex<V: Variable<D>, const D: usize>(
        &mut self,
        id: VertexId,
        create: bool,
    ) -> Result<(), LineError> {
        if create && self.graph.vertex_index(id).is_none() {
            self.graph.add_vertex(id, V::default())?;
            self.uninitialized.push(true);
            self.report.created_vertices += 1;
        }
        Ok(())
    }

    /// The information matrix to use, or `None` if the edge is to be left out
    /// because its matrix is indefinite (the file is refused at the end).
    fn checked_information<const E: usize>(
        &mut self,
        line: usize,
        m: SMatrix<f64, E, E>,
    ) -> Result<Option<PositiveDefinite<E>>, LineError> {
        match PositiveDefinite::new(m) {
            Ok(checked) => Ok(Some(checked)),
            Err(InformationIssue::NotPositiveDefinite { .. })
                if self.options.repair_information =>
            {
                self.report.repaired_information.push(line);
                PositiveDefinite::new(nearest_positive_definite(&m))
                    .map(Some)
                    .map_err(LineError::Information)
            }
            Err(InformationIssue::NotPositiveDefinite { .. }) => {
                self.indefinite.push(line);
                Ok(None)
            }
            Err(issue) => Err(LineError::Information(issue)),
        }
    }

    /// Adds an edge between the line's first two ids.
    pub(crate) fn binary<T, const E: usize, const D1: usize, const D2: usize>(
        &mut self,
        fields: &Fields,
        edge: T,
        information: SMatrix<f64, E, E>,
    ) -> Result<(), LineError>
    where
        T: cairn_core::BinaryEdge<E, D1, D2>,
    {
        let (i, j) = (fields.id(0)?, fields.id(1)?);
        self.ensure_vertex::<T::V1, D1>(i, self.create_vertices)?;
        self.ensure_vertex::<T::V2, D2>(j, self.create_vertices)?;
        if let Some(info) = self.checked_information(self.report.lines, information)? {
            self.graph.add_checked_edge(i, j, edge, info)?;
        }
        Ok(())
    }

    /// Adds an edge on the line's first id.
    pub(crate) fn unary<T, const E: usize, const D: usize>(
        &mut self,
        fields: &Fields,
        edge: T,
        information: SMatrix<f64, E, E>,
    ) -> Result<(), LineError>
    where
        T: cairn_core::UnaryEdge<E, D>,
    {
        let id = fields.id(0)?;
        self.ensure_vertex::<T::V, D>(id, self.create_vertices)?;
        if let Some(info) = self.checked_information(self.report.lines, information)? {
            self.graph.add_checked_unary_edge(id, edge, info)?;
        }
        Ok(())
    }

    fn finish(mut self) -> Result<(Graph, LoadReport), G2oError> {
        if !self.landmarks.is_empty() {
            let highest = self.graph.vertices().map(|v| v.id).max();
            let offset = highest.map_or(Some(0), |m| m.checked_add(1));
            self.report.landmark_id_offset = offset;
            let landmarks = std::mem::take(&mut self.landmarks);
            for lm in landmarks {
                let result = (|| -> Result<(), LineError> {
                    let id = offset
                        .filter(|_| lm.landmark >= 0)
                        .and_then(|o| o.checked_add(lm.landmark))
                        .ok_or(LineError::LandmarkIdOutOfRange {
                            landmark: lm.landmark,
                            highest: highest.unwrap_or(0),
                        })?;
                    // Landmarks never have VERTEX lines of their own.
                    self.ensure_vertex::<Vector2<f64>, 2>(id, true)?;
                    self.ensure_vertex::<SE2, 3>(lm.pose, self.create_vertices)?;
                    if let Some(info) = self.checked_information(lm.line, lm.information)? {
                        self.graph
                            .add_checked_edge(lm.pose, id, EdgeSE2XY::new(lm.z), info)?;
                    }
                    Ok(())
                })();
                result.map_err(|error| G2oError::Line {
                    line: lm.line,
                    error,
                })?;
            }
        }
        if !self.indefinite.is_empty() {
            let count = self.indefinite.len();
            self.indefinite.truncate(10);
            return Err(G2oError::IndefiniteInformation {
                count,
                lines: self.indefinite,
            });
        }
        for (line, ids) in std::mem::take(&mut self.fix_lines) {
            for id in ids {
                self.graph.set_fixed(id, true).map_err(|e| G2oError::Line {
                    line,
                    error: e.into(),
                })?;
                self.report.fixed.push(id);
            }
        }
        if self.graph.num_vertices() == 0 {
            return Err(G2oError::Empty);
        }
        if self.report.created_vertices > 0 {
            self.report.spanning_tree =
                Some(self.graph.initialize_spanning_tree(&self.uninitialized));
        }
        Ok((self.graph, self.report))
    }
}
