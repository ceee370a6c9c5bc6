//! What `cairn solve` reports and where: the checks on its output paths,
//! the load line, the `--stats` and `--summary` CSV, the JSON load report.

use super::CliError;
use cairn::g2o::LoadReport;
use cairn::solvers::Summary;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Refuses, before the solve, outputs (each an option and its path, if
/// given) that cannot be written (a missing folder) and two outputs naming
/// one file, which would overwrite each other.
pub fn check_outputs(outputs: &[(&'static str, Option<&PathBuf>)]) -> Result<(), CliError> {
    let named: Vec<(&str, &PathBuf)> = outputs
        .iter()
        .filter_map(|&(flag, p)| p.map(|p| (flag, p)))
        .filter(|(_, p)| p.as_os_str() != "-")
        .collect();
    for (_, path) in &named {
        super::check_writable(path)?;
    }
    let same = |p: &PathBuf, q: &PathBuf| {
        p == q
            || matches!((std::fs::canonicalize(p), std::fs::canonicalize(q)), (Ok(a), Ok(b)) if a == b)
    };
    for (k, (flag, path)) in named.iter().enumerate() {
        if let Some((other, _)) = named[k + 1..].iter().find(|(_, q)| same(path, q)) {
            return Err(CliError::usage(format!(
                "{flag} and {other} both name {}",
                path.display()
            )));
        }
    }
    Ok(())
}

/// Appends `row` to the summary file, with the header if the file is new
/// or empty. The file is locked while the row is written in one call, so
/// runs appending at once keep every row; nothing already there is read
/// or rewritten.
pub fn append_summary(path: &std::path::Path, row: &str) -> Result<(), CliError> {
    use std::io::Write;
    let error = |e: std::io::Error| CliError::io(format!("{}: {e}", path.display()));
    let mut file = std::fs::OpenOptions::new()
        .append(true)
        .create(true)
        .open(path)
        .map_err(error)?;
    file.lock().map_err(error)?;
    let empty = file.metadata().map_err(error)?.len() == 0;
    let text = if empty {
        format!("{SUMMARY_HEADER}{row}")
    } else {
        row.to_string()
    };
    file.write_all(text.as_bytes()).map_err(error)
}

pub fn stats_csv(summary: &Summary) -> String {
    let mut out = String::from(
        "iteration,chi2,lambda,radius,trials,gradient_max,step_max,time_s,cumulative_s,\
         linearize_s,assemble_s,factorize_s,solve_s,update_s,chi2_s\n",
    );
    for s in &summary.trace {
        let p = &s.phases;
        let _ = writeln!(
            out,
            "{},{:?},{},{},{},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?}",
            s.iteration,
            s.chi2,
            s.lambda.map_or(String::new(), |l| format!("{l:?}")),
            s.radius.map_or(String::new(), |r| format!("{r:?}")),
            s.trials,
            s.gradient_max,
            s.step_max,
            s.time,
            s.cumulative_time,
            p.linearize,
            p.assemble,
            p.factorize,
            p.solve,
            p.update,
            p.chi2
        );
    }
    out
}

pub const SUMMARY_HEADER: &str = "file,algorithm,vertices,edges,initial_chi2,final_chi2,iterations,termination,\
                              load_s,solve_s,write_s\n";

pub struct Times {
    pub load: f64,
    pub solve: f64,
    pub write: f64,
}

pub fn summary_row(file: &str, v: usize, e: usize, s: &Summary, t: &Times) -> String {
    format!(
        "{},{},{},{},{:?},{:?},{},{:?},{:?},{:?},{:?}\n",
        file,
        s.algorithm.short_name(),
        v,
        e,
        s.initial_chi2,
        s.final_chi2,
        s.iterations,
        s.termination,
        t.load,
        t.solve,
        t.write
    )
}

pub fn report_json(r: &LoadReport) -> serde_json::Value {
    serde_json::json!({
        "lines": r.lines,
        "records": r.records,
        "unknown": r.unknown,
        "extra_fields": r.extra_fields,
        "created_vertices": r.created_vertices,
        "landmark_id_offset": r.landmark_id_offset,
        "repaired_information": r.repaired_information.len(),
        "fixed": r.fixed,
        "spanning_tree_roots": r.spanning_tree.as_ref().map(|s| s.roots.clone()),
    })
}

pub fn describe_load(name: &str, r: &LoadReport, vertices: usize, edges: usize) -> String {
    let mut s = format!("loaded {name}: {vertices} vertices, {edges} edges");
    if r.unknown_lines() > 0 {
        let tags: Vec<String> = r.unknown.iter().map(|(t, n)| format!("{t} ×{n}")).collect();
        let _ = write!(
            s,
            "; skipped {} lines with unsupported tags ({})",
            r.unknown_lines(),
            tags.join(", ")
        );
    }
    if r.created_vertices > 0 {
        let _ = write!(
            s,
            "; created {} vertices from the edges, initialised by spanning tree",
            r.created_vertices
        );
    }
    if let Some(off) = r.landmark_id_offset {
        let _ = write!(s, "; LANDMARK2 landmark l is vertex {off}+l");
    }
    if !r.repaired_information.is_empty() {
        let _ = write!(
            s,
            "; repaired {} information matrices that were not positive definite",
            r.repaired_information.len()
        );
    }
    s
}
