//! Writing the g2o text format: full precision, atomic file replacement.

use crate::error::G2oError;
use crate::registry::Registry;
use crate::tags;
use cairn_core::{
    EdgePriorSE2, EdgeSE2, EdgeSE2XY, EdgeSE3, EdgeView, Graph, SE2, SE3, Variable, VertexId,
};
use nalgebra::Vector2;
use std::any::TypeId;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

/// Appends ` v` in the shortest form that reads back to the same `f64`
/// (exponents for very large or small values, as `1e+16` and `1e-7`).
fn num(out: &mut String, v: f64) {
    out.push(' ');
    out.push_str(zmij::Buffer::new().format(v));
}

/// Appends ` id`.
fn id(out: &mut String, id: VertexId) {
    out.push(' ');
    out.push_str(itoa::Buffer::new().format(id));
}

fn vertex_tag(type_id: TypeId) -> Option<&'static str> {
    if type_id == TypeId::of::<SE2>() {
        Some(tags::VERTEX_SE2)
    } else if type_id == TypeId::of::<Vector2<f64>>() {
        Some(tags::VERTEX_XY)
    } else if type_id == TypeId::of::<SE3>() {
        Some(tags::VERTEX_SE3_QUAT)
    } else {
        None
    }
}

/// The tag and measurement parameters (the first `len` of at most 7) of a
/// built-in edge.
fn edge_record(e: &EdgeView) -> Option<(&'static str, [f64; 7], usize)> {
    let any = e.edge();
    let mut p = [0.0; 7];
    let mut from = |tag, params: &[f64]| {
        p[..params.len()].copy_from_slice(params);
        Some((tag, p, params.len()))
    };
    if let Some(edge) = any.downcast_ref::<EdgeSE2>() {
        return from(tags::EDGE_SE2, edge.measurement().to_vector().as_slice());
    }
    if let Some(edge) = any.downcast_ref::<EdgeSE2XY>() {
        return from(tags::EDGE_SE2_XY, edge.measurement().as_slice());
    }
    if let Some(edge) = any.downcast_ref::<EdgePriorSE2>() {
        return from(
            tags::EDGE_PRIOR_SE2,
            edge.measurement().to_vector().as_slice(),
        );
    }
    if let Some(edge) = any.downcast_ref::<EdgeSE3>() {
        let mut q = [0.0; 7];
        edge.measurement().write_params(&mut q);
        return from(tags::EDGE_SE3_QUAT, &q);
    }
    None
}

/// The graph as g2o text: vertices in insertion order (each fixed one followed
/// by a FIX line), then edges in insertion order with their information
/// matrices' upper triangles row by row.
pub fn to_string(graph: &Graph) -> Result<String, G2oError> {
    to_string_with(graph, &Registry::default())
}

/// [`to_string`] for graphs that hold your own types, under the tags
/// `registry` gives them.
pub fn to_string_with(graph: &Graph, registry: &Registry) -> Result<String, G2oError> {
    let mut out = String::with_capacity(64 * (graph.num_vertices() + 2 * graph.num_edges()));
    let mut custom = Vec::new();
    for v in graph.vertices() {
        let tag = vertex_tag(v.kind.type_id)
            .or_else(|| registry.vertex_tag(v.kind.type_id))
            .ok_or(G2oError::Unwritable(v.kind.name))?;
        out.push_str(tag);
        id(&mut out, v.id);
        for &p in v.params {
            num(&mut out, p);
        }
        out.push('\n');
        if v.fixed {
            out.push_str(tags::FIX);
            id(&mut out, v.id);
            out.push('\n');
        }
    }
    for e in graph.edges() {
        let (tag, measurement) = match edge_record(&e) {
            Some((tag, p, len)) => {
                custom.clear();
                custom.extend_from_slice(&p[..len]);
                (tag, &custom)
            }
            None => {
                let t = registry
                    .edge(e.edge_type())
                    .ok_or(G2oError::Unwritable(e.name()))?;
                custom.clear();
                custom.resize(t.len, 0.0);
                (t.write)(e.edge(), &mut custom);
                (t.tag, &custom)
            }
        };
        out.push_str(tag);
        for &v in e.vertices() {
            id(&mut out, graph.vertex(v).id);
        }
        for &m in measurement {
            num(&mut out, m);
        }
        let n = e.error_dim();
        let info = e.information();
        for r in 0..n {
            for c in r..n {
                num(&mut out, info[r + c * n]);
            }
        }
        out.push('\n');
    }
    Ok(out)
}

/// Writes the graph as g2o text to `out`.
pub fn write(graph: &Graph, mut out: impl Write) -> Result<(), G2oError> {
    let text = to_string(graph)?;
    out.write_all(text.as_bytes())
        .and_then(|_| out.flush())
        .map_err(|e| G2oError::io("<output>", e))
}

/// Writes the graph to `path` atomically: into a temporary file beside it,
/// synced, then renamed over `path`, so an interrupted run never leaves a
/// truncated file.
pub fn write_file(graph: &Graph, path: impl AsRef<Path>) -> Result<(), G2oError> {
    let text = to_string(graph)?;
    write_atomically(path.as_ref(), text.as_bytes())
}

/// Writes `bytes` to `path` so that it never holds a partial result:
/// - a regular file (or a new one) is replaced atomically: a temporary file
///   beside it, fsync, rename; the replaced file's permissions are kept;
/// - a symbolic link is followed, and its target replaced so;
/// - anything else (a FIFO, a device such as `/dev/null`) is written to
///   directly, never replaced by a regular file.
///
/// Temporary files that a killed run left beside the target (`.NAME.PID.tmp`
/// of a process that no longer runs) are removed first, where `/proc` tells.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), G2oError> {
    let target = follow_links(path).map_err(|e| G2oError::io(path, e))?;
    match std::fs::metadata(&target) {
        Ok(meta) if meta.is_dir() => {
            return Err(G2oError::io(
                path,
                std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a folder"),
            ));
        }
        Ok(meta) if !meta.is_file() => {
            let result = std::fs::OpenOptions::new()
                .write(true)
                .open(&target)
                .and_then(|mut f| f.write_all(bytes));
            return result.map_err(|e| G2oError::io(path, e));
        }
        _ => {}
    }
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    remove_stale_temporaries(&dir, &name);
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let permissions = std::fs::metadata(&target).ok().map(|m| m.permissions());
    in_progress().push(tmp.clone());
    let result = (|| {
        let mut file = std::fs::File::create(&tmp)?;
        file.write_all(bytes)?;
        if let Some(p) = permissions {
            file.set_permissions(p)?;
        }
        file.sync_all()?;
        std::fs::rename(&tmp, &target)
    })();
    in_progress().retain(|p| p != &tmp);
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        G2oError::io(path, e)
    })
}

/// The temporary files of [`write_atomically`] calls under way.
static IN_PROGRESS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn in_progress() -> MutexGuard<'static, Vec<PathBuf>> {
    // A panic elsewhere while holding it leaves the list as good as before.
    IN_PROGRESS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Removes the temporary files of the [`write_atomically`] calls under way,
/// leaving their targets as they were: for a signal handler about to end
/// the process (the `cairn` tool's, on SIGINT and SIGTERM).
pub fn remove_temporary_files() {
    for tmp in in_progress().drain(..) {
        let _ = std::fs::remove_file(tmp);
    }
}

/// `path` with symbolic links followed (at most 40, as Linux allows); a
/// dangling link gives the path it points to.
fn follow_links(path: &Path) -> std::io::Result<PathBuf> {
    let mut path = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&path) {
            Ok(meta) if meta.file_type().is_symlink() => {
                let link = std::fs::read_link(&path)?;
                path = match path.parent() {
                    Some(dir) if link.is_relative() => dir.join(link),
                    _ => link,
                };
            }
            _ => return Ok(path),
        }
    }
    Err(std::io::Error::other("too many levels of symbolic links"))
}

/// Removes `.NAME.PID.tmp` in `dir` whose process is gone (Linux's `/proc`
/// says; elsewhere nothing is removed).
fn remove_stale_temporaries(dir: &Path, name: &str) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let prefix = format!(".{name}.");
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(pid) = file
            .to_str()
            .and_then(|f| f.strip_prefix(&prefix))
            .and_then(|f| f.strip_suffix(".tmp"))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}
