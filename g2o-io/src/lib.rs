//! Reading and writing the g2o text format as g2o does.
//!
//! Supported records: `VERTEX_SE2`, `VERTEX_XY`, `VERTEX_SE3:QUAT`, `EDGE_SE2`,
//! `EDGE_SE2_XY`, `EDGE_PRIOR_SE2`, `EDGE_SE3:QUAT`, `FIX`, and `LANDMARK2`
//! (EDGE_SE2_XY semantics, landmark ids in their own id space). `#` comments,
//! blank lines and runs of spaces are allowed; unknown tags are counted in the
//! [`LoadReport`] and skipped. Files without VERTEX lines get their vertices
//! from the edges, initialised by a spanning tree from the gauge vertex.
//! Your own vertex and edge types are read and written under the tags a
//! [`Registry`] gives them.
//!
//! ```
//! use cairn_g2o::{read_bytes, to_string, ReadOptions};
//! let text = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nFIX 0\n\
//!             EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nPARAMS_SE2OFFSET 0 0 0 0\n";
//! let (graph, report) = read_bytes(text.as_bytes(), &ReadOptions::default())?;
//! assert_eq!((graph.num_vertices(), graph.num_edges()), (2, 1));
//! assert_eq!(report.unknown_lines(), 1);
//! let (again, _) = read_bytes(to_string(&graph)?.as_bytes(), &ReadOptions::default())?;
//! assert_eq!(again.values(), graph.values());
//! # Ok::<(), cairn_g2o::G2oError>(())
//! ```

pub mod error;
pub mod reader;
pub mod registry;
pub mod tags;
pub mod writer;

pub use error::{G2oError, LineError};
pub use reader::{LoadReport, ReadOptions, read_bytes, read_file};
pub use registry::{G2oMeasurement, Registry, RegistryError};
pub use writer::{
    remove_temporary_files, to_string, to_string_with, write, write_atomically, write_file,
};
