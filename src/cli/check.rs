//! `cairn check`: a health report of a g2o file.

use cairn::core::diagnostics::{BAD_CONDITION, diagnose};
use cairn::g2o::ReadOptions;
use clap::Args;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Options of `cairn check`.
#[derive(Debug, Args)]
pub struct CheckArgs {
    /// The g2o file (`-` for stdin).
    file: PathBuf,
    /// How many of the largest-χ² edges to list.
    #[arg(long, default_value_t = 10)]
    worst: usize,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
}

fn counts(map: &std::collections::BTreeMap<&str, usize>) -> String {
    map.iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

pub fn run(a: CheckArgs) -> Result<(), super::CliError> {
    let name = a.file.display().to_string();
    let bytes = super::read_input(&a.file)?;
    // Read with repair so that indefinite matrices are counted, not fatal.
    let options = ReadOptions {
        repair_information: true,
        ..Default::default()
    };
    let (graph, report) =
        cairn::g2o::read_bytes(&bytes, &options).map_err(super::bad_input(&name))?;
    let d = diagnose(&graph, a.worst);
    if a.json {
        let edge = |e: &cairn::core::diagnostics::EdgeSummary| serde_json::json!({"edge": e.index, "type": e.name, "vertices": e.vertices, "value": e.value});
        let value = serde_json::json!({
            "file": name,
            "vertices": d.vertex_types,
            "edges": d.edge_types,
            "fixed": d.fixed,
            "chi2": d.chi2,
            "components": d.components,
            "gauge": d.gauge,
            "indefinite_information_lines": report.repaired_information,
            "badly_scaled": d.badly_scaled.iter().map(edge).collect::<Vec<_>>(),
            "worst_edges": d.worst_edges.iter().map(edge).collect::<Vec<_>>(),
            "histogram": d.histogram.iter().map(|b| serde_json::json!([b.lower, b.upper, b.count])).collect::<Vec<_>>(),
            "unknown_lines": report.unknown,
        });
        println!("{value}");
        return Ok(());
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{name}: {} vertices ({}), {} edges ({}); {} fixed",
        graph.num_vertices(),
        counts(&d.vertex_types),
        graph.num_edges(),
        counts(&d.edge_types),
        d.fixed.len()
    );
    if report.unknown_lines() > 0 {
        let _ = writeln!(
            out,
            "skipped lines with unsupported tags: {}",
            counts(
                &report
                    .unknown
                    .iter()
                    .map(|(k, v)| (k.as_str(), *v))
                    .collect()
            )
        );
    }
    if report.created_vertices > 0 {
        let _ = writeln!(
            out,
            "no VERTEX lines: {} vertices created from the edges (spanning-tree initial values)",
            report.created_vertices
        );
    }
    let _ = writeln!(out, "χ² at these values: {:.6}", d.chi2);
    let sizes: Vec<String> = d
        .components
        .iter()
        .take(10)
        .map(|s| s.to_string())
        .collect();
    let _ = writeln!(
        out,
        "connected components: {} (sizes {}{}); automatic gauge fixes {:?}",
        d.components.len(),
        sizes.join(", "),
        if d.components.len() > 10 { ", …" } else { "" },
        d.gauge
    );
    let repaired = &report.repaired_information;
    let _ = writeln!(
        out,
        "information matrices: {} not positive definite{}; {} badly scaled (condition > {BAD_CONDITION:e})",
        repaired.len(),
        if repaired.is_empty() {
            String::new()
        } else {
            let first: Vec<String> = repaired.iter().take(10).map(|l| l.to_string()).collect();
            format!(
                " (lines {}{}; solve with --repair-information)",
                first.join(", "),
                if repaired.len() > 10 { ", …" } else { "" }
            )
        },
        d.badly_scaled.len()
    );
    for e in d.badly_scaled.iter().take(5) {
        let _ = writeln!(
            out,
            "  edge #{} {} {:?}: condition {:.3e}",
            e.index, e.name, e.vertices, e.value
        );
    }
    let widest = d
        .histogram
        .iter()
        .map(|b| b.count)
        .max()
        .unwrap_or(1)
        .max(1);
    let _ = writeln!(out, "per-edge χ²:");
    for b in &d.histogram {
        let bar = "█".repeat((40 * b.count).div_ceil(widest));
        let _ = writeln!(
            out,
            "  [{:>8.0e}, {:>8.0e})  {:>8}  {bar}",
            b.lower, b.upper, b.count
        );
    }
    let _ = writeln!(out, "largest χ²:");
    for e in &d.worst_edges {
        let _ = writeln!(
            out,
            "  edge #{} {} {:?}: χ² {:.6}",
            e.index, e.name, e.vertices, e.value
        );
    }
    print!("{out}");
    Ok(())
}
