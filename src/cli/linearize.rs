//! `cairn linearize`: H, b and the whitened Jacobian of a g2o file as
//! Matrix Market files, and the Cholesky factor's fill under each ordering.

use super::solve::OrderingName;
use super::write_output;
use cairn::solvers::{LinearSolverConfig, LinearSystem, Optimizer, SolverConfig, optimize};
use clap::{Args, ValueEnum};
use sprs::CsMat;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// Options of `cairn linearize`.
#[derive(Debug, Args)]
pub struct LinearizeArgs {
    /// The g2o file (`-` for stdin).
    file: PathBuf,
    /// Linearise at the solution `cairn solve` reaches with its defaults
    /// instead of at the file's values.
    #[arg(long)]
    at_solution: bool,
    /// Write H (Matrix Market, symmetric: its lower triangle).
    #[arg(long, value_name = "H.mtx")]
    hessian: Option<PathBuf>,
    /// Write the whitened Jacobian (Matrix Market): a row per error
    /// component of every edge, a column per free tangent coordinate.
    #[arg(long, value_name = "J.mtx")]
    jacobian: Option<PathBuf>,
    /// Write b = −JᵀWe, the right-hand side of the Gauss-Newton step H δ = b
    /// (Matrix Market, one column).
    #[arg(long, value_name = "b.mtx")]
    rhs: Option<PathBuf>,
    /// Write which vertex and tangent coordinate each column is (CSV
    /// column,vertex,coordinate).
    #[arg(long, value_name = "cols.csv")]
    columns: Option<PathBuf>,
    /// Write which edge (insertion order, 0-based) and error component each
    /// row of the Jacobian is (CSV row,edge,component).
    #[arg(long, value_name = "rows.csv")]
    rows: Option<PathBuf>,
    /// The orderings whose factor fill to report; the matrices are written
    /// in the first one's column order.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "block-amd,amd,schur,identity"
    )]
    ordering: Vec<OrderingName>,
}

pub fn run(a: LinearizeArgs) -> Result<(), super::CliError> {
    let name = a.file.display().to_string();
    for path in [&a.hessian, &a.jacobian, &a.rhs, &a.columns, &a.rows]
        .into_iter()
        .flatten()
    {
        super::check_writable(path)?;
    }
    let (mut graph, _) = cairn::g2o::read_bytes(&super::read_input(&a.file)?, &Default::default())
        .map_err(super::bad_input(&name))?;
    if a.at_solution {
        let summary =
            optimize(&mut graph, SolverConfig::default()).map_err(|e| format!("{name}: {e}"))?;
        eprintln!(
            "solved: χ² {:.6} → {:.6}",
            summary.initial_chi2, summary.final_chi2
        );
    }
    let config = |ordering: OrderingName| SolverConfig {
        linear: LinearSolverConfig {
            ordering: ordering.ordering(),
            ..Default::default()
        },
        ..Default::default()
    };
    let first = *a
        .ordering
        .first()
        .ok_or("--ordering needs at least one ordering")?;
    let t = Instant::now();
    let mut optimizer =
        Optimizer::new(&graph, config(first)).map_err(|e| format!("{name}: {e}"))?;
    let system = optimizer
        .linear_system(&graph)
        .map_err(|e| format!("{name}: {e}"))?;
    let export = t.elapsed().as_secs_f64();
    let h_nnz = system.hessian.nnz();
    eprintln!(
        "{name}: H {n}×{n}, {h_nnz} stored entries (upper triangle); J {}×{n}, {} entries; χ² {:.6}; linearised and exported in {:.1} ms",
        system.jacobian.rows(),
        system.jacobian.nnz(),
        system.chi2,
        1e3 * export,
        n = system.rhs.len(),
    );
    eprintln!("ordering     nnz(L)      nnz(L)/nnz(H)  analysis (ms)");
    for &ordering in &a.ordering {
        let t = Instant::now();
        let optimizer =
            Optimizer::new(&graph, config(ordering)).map_err(|e| format!("{name}: {e}"))?;
        let nnz = optimizer.factor_nnz().unwrap_or(0);
        eprintln!(
            "{:<12} {:<11} {:<14.2} {:.1}",
            ordering
                .to_possible_value()
                .map_or_else(String::new, |v| v.get_name().to_string()),
            nnz,
            nnz as f64 / h_nnz.max(1) as f64,
            1e3 * t.elapsed().as_secs_f64()
        );
    }
    write_files(&a, &system)
}

fn write_files(a: &LinearizeArgs, s: &LinearSystem) -> Result<(), super::CliError> {
    if let Some(path) = &a.hessian {
        // Matrix Market's symmetric format lists the lower triangle.
        let lower = s.hessian.transpose_view().to_csc();
        let text = matrix_market(&lower)?.replacen(" general", " symmetric", 1);
        write_output(path, text.as_bytes())?;
    }
    if let Some(path) = &a.jacobian {
        write_output(path, matrix_market(&s.jacobian)?.as_bytes())?;
    }
    if let Some(path) = &a.rhs {
        let n = s.rhs.len();
        let column = CsMat::new_csc((n, 1), vec![0, n], (0..n).collect(), s.rhs.clone());
        write_output(path, matrix_market(&column)?.as_bytes())?;
    }
    if let Some(path) = &a.columns {
        let mut text = String::from("column,vertex,coordinate\n");
        for (c, (id, k)) in s.columns.iter().enumerate() {
            let _ = writeln!(text, "{c},{id},{k}");
        }
        write_output(path, text.as_bytes())?;
    }
    if let Some(path) = &a.rows {
        let mut text = String::from("row,edge,component\n");
        for (r, (edge, k)) in s.rows.iter().enumerate() {
            let _ = writeln!(text, "{r},{edge},{k}");
        }
        write_output(path, text.as_bytes())?;
    }
    Ok(())
}

/// The matrix in Matrix Market's coordinate format (sprs's writer).
fn matrix_market(m: &CsMat<f64>) -> Result<String, String> {
    let mut bytes = Vec::new();
    sprs::io::write_matrix_market_to_bufwrite(&mut bytes, m).map_err(|e| e.to_string())?;
    String::from_utf8(bytes).map_err(|e| e.to_string())
}
