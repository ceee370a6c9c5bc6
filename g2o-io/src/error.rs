//! Typed errors of the g2o reader and writer.

use cairn_core::{GraphError, InformationIssue};
use std::path::PathBuf;

/// What is wrong with one line of a g2o file.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LineError {
    /// The line is not valid UTF-8.
    #[error("not valid UTF-8 text")]
    NotUtf8,
    /// A space that is not ASCII (a no-break space, U+00A0, from a word
    /// processor): g2o separates fields with ASCII spaces and tabs only.
    #[error("a non-ASCII space (U+{code:04X}) where g2o expects ASCII spaces or tabs")]
    NonAsciiSpace {
        /// The character's code point.
        code: u32,
    },
    /// A `LANDMARK2` landmark id that is negative, or past the ids the
    /// graph can give landmarks after its highest vertex id.
    #[error(
        "LANDMARK2 landmark id {landmark} cannot be placed after vertex id {highest} (landmark ids are ≥ 0 and the sum must fit 64 bits)"
    )]
    LandmarkIdOutOfRange {
        /// The landmark's id in the file.
        landmark: i64,
        /// The highest vertex id of the graph.
        highest: i64,
    },
    /// Fewer fields than the tag needs.
    #[error("{tag} needs {expected} fields after the tag, found {found}")]
    MissingFields {
        /// The record's tag.
        tag: String,
        /// Fields needed.
        expected: usize,
        /// Fields present.
        found: usize,
    },
    /// A field that is not a number.
    #[error("field {field} ({text:?}) is not a number")]
    BadNumber {
        /// 1-based field number after the tag.
        field: usize,
        /// The text.
        text: String,
    },
    /// NaN or infinity.
    #[error("field {field} ({text:?}) is not finite")]
    NonFinite {
        /// 1-based field number after the tag.
        field: usize,
        /// The text.
        text: String,
    },
    /// A vertex id that is not an integer.
    #[error("field {field} ({text:?}) is not a vertex id")]
    BadId {
        /// 1-based field number after the tag.
        field: usize,
        /// The text.
        text: String,
    },
    /// A registered edge type refused the measurement.
    #[error("{tag}: {message}")]
    BadMeasurement {
        /// The record's tag.
        tag: String,
        /// Why, in the edge type's words.
        message: String,
    },
    /// A quaternion of zero length.
    #[error("the quaternion has zero length")]
    ZeroQuaternion,
    /// An information matrix that is NaN, infinite or asymmetric.
    #[error("information matrix {0}")]
    Information(InformationIssue),
    /// The record does not fit the graph (unknown or duplicate vertex, wrong type…).
    #[error("{0}")]
    Graph(#[from] GraphError),
}

/// Why a g2o file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum G2oError {
    /// The operating system refused.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A bad line.
    #[error("line {line}: {error}")]
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        error: LineError,
    },
    /// Nothing in the file makes a vertex.
    #[error("the file has no vertices (empty, or only comments and unknown records)")]
    Empty,
    /// Edges with information matrices that are not positive definite.
    #[error(
        "{count} edges have information matrices that are not positive definite (lines {}{}); \
         χ² would be unbounded below. Repair them with the nearest positive-definite matrix \
         (ReadOptions::repair_information, or `--repair-information` on the command line)",
        lines.iter().map(|l| l.to_string()).collect::<Vec<_>>().join(", "),
        if *count > lines.len() { ", …" } else { "" }
    )]
    IndefiniteInformation {
        /// How many.
        count: usize,
        /// The first lines (at most 10).
        lines: Vec<usize>,
    },
    /// A vertex or edge type the writer has no g2o tag for.
    #[error("cannot write {0} in g2o format: no tag is registered for it")]
    Unwritable(&'static str),
}

impl G2oError {
    /// Prefixes I/O-free errors with nothing; attaches `path` to I/O errors.
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }
}
