//! `cairn solve`: optimise a g2o file.

use cairn::core::RobustKernel;
use cairn::g2o::{LoadReport, ReadOptions};
use cairn::solvers::{
    Algorithm, Factorization, Initialization, IterationStats, LevenbergMarquardtConfig,
    LinearSolverConfig, Optimizer, Ordering, SolverConfig, Summary, optimize_from,
};
use clap::{Args, ValueEnum};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum SolverName {
    /// Gauss-Newton.
    Gn,
    /// Levenberg-Marquardt.
    Lm,
    /// Powell's dogleg.
    Dogleg,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum DampingName {
    /// H + λ·diag(H), first λ = τ (Marquardt's scaling, as Ceres).
    Marquardt,
    /// H + λI, first λ = τ·max(diag H), as g2o (with the default τ, g2o's
    /// iterates; on SE3 graphs up to the form of the update). Better where H is singular.
    Levenberg,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum InitName {
    /// The file's vertices (spanning tree for files without VERTEX lines).
    File,
    /// Breadth-first spanning tree (odometry chaining) from the gauge.
    SpanningTree,
    /// Chordal relaxation: rotations first, then positions, weighted by the information.
    Chordal,
    /// Chordal relaxation with every measurement weighted alike.
    ChordalIsotropic,
    /// Solve from the file's vertices and both chordal starts; keep the lowest χ².
    Auto,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(super) enum OrderingName {
    /// Approximate minimum degree on the scalar pattern.
    Amd,
    /// Approximate minimum degree on the vertex graph.
    BlockAmd,
    /// No reordering.
    Identity,
    /// Landmarks first (the Schur complement on the landmarks), then block AMD on the poses.
    Schur,
}

impl OrderingName {
    /// The solver's ordering.
    pub(super) fn ordering(self) -> Ordering {
        match self {
            OrderingName::Amd => Ordering::Amd,
            OrderingName::BlockAmd => Ordering::BlockAmd,
            OrderingName::Identity => Ordering::Identity,
            OrderingName::Schur => Ordering::Schur,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum FactorizationName {
    /// From the flop count: supernodal when the factor has dense fronts.
    Auto,
    /// Column by column.
    Simplicial,
    /// Dense supernodes.
    Supernodal,
}

/// Options of `cairn solve`.
#[derive(Debug, Args)]
pub struct SolveArgs {
    /// Input g2o file (`-` for stdin).
    file: PathBuf,
    /// Write the optimised graph here (`-` for stdout), atomically.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Maximum number of iterations.
    #[arg(short = 'i', long, default_value_t = 100)]
    iterations: usize,
    /// Algorithm (g2o's default is Gauss-Newton too).
    #[arg(long, value_enum, default_value = "gn")]
    solver: SolverName,
    /// Levenberg-Marquardt's damping.
    #[arg(long, value_enum, default_value = "marquardt")]
    damping: DampingName,
    /// Levenberg-Marquardt's τ, which sets the first λ (see --damping).
    /// Default 1e-12 (marquardt), 1e-5 (levenberg, g2o's).
    #[arg(long)]
    tau: Option<f64>,
    /// Levenberg-Marquardt's non-monotonic steps: how many steps in a row
    /// may raise χ² (the estimate written is the lowest-χ² one met). 0 makes
    /// every accepted step lower χ². Default 5 (marquardt), 0 (levenberg, as g2o).
    #[arg(long)]
    nonmonotonic_steps: Option<usize>,
    /// Levenberg-Marquardt's look-ahead: when its first step raises χ², it
    /// follows up to this many Gauss-Newton steps and keeps them if they
    /// settle below the starting χ². 0 rejects that step. Default 10
    /// (marquardt), 0 (levenberg, as g2o).
    #[arg(long)]
    lookahead_steps: Option<usize>,
    /// Levenberg-Marquardt's line search: a step that lowers χ² by less than
    /// a quarter of its model's prediction is shortened to where a parabola
    /// puts χ²'s minimum, if that lowers χ² further. Default true
    /// (marquardt), false (levenberg, as g2o).
    #[arg(long)]
    line_search: Option<bool>,
    /// Starting point.
    #[arg(long, value_enum, default_value = "auto")]
    init: InitName,
    /// Hold these vertex ids fixed (comma-separated), besides FIX lines.
    #[arg(long, value_delimiter = ',')]
    fix: Vec<i64>,
    /// Stop when χ² falls by less than this fraction in an iteration.
    #[arg(long, default_value_t = SolverConfig::default().relative_decrease)]
    relative_decrease: f64,
    /// Gauss-Newton: stop at the first step that raises χ² and keep the
    /// estimate before it (GTSAM's Gauss-Newton stops there too, keeping the
    /// step). Without it GN carries on, as g2o's does.
    #[arg(long)]
    stop_on_increase: bool,
    /// Replace information matrices that are not positive definite by the
    /// nearest positive-definite ones (cubicle.g2o needs this) instead of refusing.
    #[arg(long)]
    repair_information: bool,
    /// Robust kernel on the edges' squared errors: huber, pseudo-huber, cauchy,
    /// geman-mcclure, welsch, fair, tukey, saturated or dcs. (With dcs, use gn or
    /// dogleg: its weights are not the derivative of its cost, which LM's gain
    /// ratio needs.)
    #[arg(long)]
    robust_kernel: Option<String>,
    /// Width δ of the robust kernel.
    #[arg(long, default_value_t = 1.0)]
    robust_kernel_width: f64,
    /// Apply the robust kernel only to loop closures: edges between vertices
    /// whose ids are not consecutive (g2o's -nonSequential).
    #[arg(long)]
    non_sequential: bool,
    /// Cholesky variant.
    #[arg(long, value_enum, default_value = "auto")]
    factorization: FactorizationName,
    /// Fill-reducing ordering.
    #[arg(long, value_enum, default_value = "block-amd")]
    ordering: OrderingName,
    /// Worker threads, 0 to 1024 (0: one per core). Only graphs with
    /// millions of Jacobian-block entries are linearised in parallel;
    /// results are the same for any number.
    #[arg(long, default_value_t = 0,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=1024))]
    threads: usize,
    /// Print the marginal covariances of these vertex ids (comma-separated),
    /// or of every vertex not held fixed with `all`, at the optimum, in each
    /// vertex's tangent coordinates (SE2: x, y, θ).
    #[arg(long, value_delimiter = ',', value_name = "IDS|all")]
    marginals: Vec<String>,
    /// Append a one-line CSV summary of the run to this file (header if new).
    #[arg(long)]
    summary: Option<PathBuf>,
    /// Write per-iteration statistics as CSV to this file.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// No per-iteration output on stderr.
    #[arg(short, long)]
    quiet: bool,
}

fn iteration_line(s: &IterationStats, edges: usize) -> String {
    let mut line = format!(
        "iteration= {}\t chi2= {:.6}\t time= {:.6}\t cumTime= {:.6}\t edges= {}",
        s.iteration, s.chi2, s.time, s.cumulative_time, edges
    );
    if let Some(l) = s.lambda {
        let _ = write!(line, "\t lambda= {l:.6e}");
    }
    if let Some(r) = s.radius {
        let _ = write!(line, "\t radius= {r:.6e}");
    }
    line
}

fn start_name(init: Initialization) -> &'static str {
    match init {
        Initialization::File => "file",
        Initialization::SpanningTree => "spanning-tree",
        Initialization::Chordal => "chordal",
        Initialization::ChordalIsotropic => "chordal-isotropic",
        Initialization::Auto => "auto",
    }
}

/// Refuses, before the solve, outputs that cannot be written (a missing
/// folder) and two outputs naming one file, which would overwrite each other.
fn check_outputs(a: &SolveArgs) -> Result<(), String> {
    let named: Vec<(&str, &PathBuf)> = [
        ("-o", &a.output),
        ("--stats", &a.stats),
        ("--summary", &a.summary),
    ]
    .into_iter()
    .filter_map(|(flag, p)| p.as_ref().map(|p| (flag, p)))
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
            return Err(format!("{flag} and {other} both name {}", path.display()));
        }
    }
    Ok(())
}

/// Appends `row` to the summary file, with the header if the file is new
/// or empty. The file is locked while the row is written in one call, so
/// runs appending at once keep every row; nothing already there is read
/// or rewritten.
fn append_summary(path: &std::path::Path, row: &str) -> Result<(), String> {
    use std::io::Write;
    let error = |e: std::io::Error| format!("{}: {e}", path.display());
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

fn stats_csv(summary: &Summary) -> String {
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

const SUMMARY_HEADER: &str = "file,algorithm,vertices,edges,initial_chi2,final_chi2,iterations,termination,\
                              load_s,solve_s,write_s\n";

struct Times {
    load: f64,
    solve: f64,
    write: f64,
}

fn summary_row(file: &str, v: usize, e: usize, s: &Summary, t: &Times) -> String {
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

fn report_json(r: &LoadReport) -> serde_json::Value {
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

fn describe_load(name: &str, r: &LoadReport, vertices: usize, edges: usize) -> String {
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

pub fn run(a: SolveArgs) -> Result<(), String> {
    if a.json && a.output.as_ref().is_some_and(|o| o.as_os_str() == "-") {
        return Err("--json and -o - both want stdout; write the graph to a file".into());
    }
    // The whole solve runs on one of the pool's threads: the solver's
    // parallel loops then start from inside the pool instead of handing
    // each one over from the main thread and waiting for it (tens of
    // microseconds per loop, a tenth of a small file's iteration). Its
    // threads get the main thread's 8 MiB stack.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads)
        .stack_size(8 << 20)
        .build()
        .map_err(|e| e.to_string())?;
    pool.install(|| solve(a))
}

/// `cairn solve`, on the calling thread.
fn solve(a: SolveArgs) -> Result<(), String> {
    let name = a.file.display().to_string();
    check_outputs(&a)?;
    let t = Instant::now();
    let options = ReadOptions {
        repair_information: a.repair_information,
    };
    // The file's bytes are dropped once parsed: on a 10⁶-pose file they are
    // 250 MB that the solve does not need.
    let (mut graph, report) = cairn::g2o::read_bytes(&super::read_input(&a.file)?, &options)
        .map_err(|e| format!("{name}: {e}"))?;
    for &id in &a.fix {
        graph
            .set_fixed(id, true)
            .map_err(|e| format!("--fix: {e}"))?;
    }
    if let Some(name) = &a.robust_kernel {
        let kernel = RobustKernel::from_name(name, a.robust_kernel_width).ok_or_else(|| {
            format!(
                "unknown robust kernel {name:?}; choose one of {}",
                RobustKernel::NAMES.join(", ")
            )
        })?;
        // Also rejects NaN.
        if a.robust_kernel_width.is_nan() || a.robust_kernel_width <= 0.0 {
            return Err("--robust-kernel-width must be positive".into());
        }
        cairn::outliers::set_robust_kernel(&mut graph, kernel, a.non_sequential);
    }
    let load = t.elapsed().as_secs_f64();
    let (vertices, edges) = (graph.num_vertices(), graph.num_edges());
    if !a.quiet {
        eprintln!("{}", describe_load(&name, &report, vertices, edges));
    }

    let lm = match a.damping {
        DampingName::Marquardt => LevenbergMarquardtConfig::default(),
        DampingName::Levenberg => LevenbergMarquardtConfig::g2o(),
    };
    let tau = a.tau.unwrap_or(lm.tau);
    if !(tau > 0.0 && tau.is_finite()) {
        return Err("--tau must be positive and finite".into());
    }
    if a.stop_on_increase && !matches!(a.solver, SolverName::Gn) {
        return Err(
            "--stop-on-increase is for --solver gn: LM and dogleg control their steps themselves"
                .into(),
        );
    }
    let config = SolverConfig {
        algorithm: match a.solver {
            SolverName::Gn => Algorithm::GaussNewton,
            SolverName::Lm => Algorithm::LevenbergMarquardt,
            SolverName::Dogleg => Algorithm::Dogleg,
        },
        max_iterations: a.iterations,
        relative_decrease: a.relative_decrease,
        stop_on_increase: a.stop_on_increase,
        lm: LevenbergMarquardtConfig {
            tau,
            nonmonotonic_steps: a.nonmonotonic_steps.unwrap_or(lm.nonmonotonic_steps),
            lookahead_steps: a.lookahead_steps.unwrap_or(lm.lookahead_steps),
            line_search: a.line_search.unwrap_or(lm.line_search),
            ..lm
        },
        linear: LinearSolverConfig {
            factorization: match a.factorization {
                FactorizationName::Auto => Factorization::Auto,
                FactorizationName::Simplicial => Factorization::Simplicial,
                FactorizationName::Supernodal => Factorization::Supernodal,
            },
            ordering: a.ordering.ordering(),
            ..Default::default()
        },
        ..Default::default()
    };
    let t = Instant::now();
    let init = match a.init {
        InitName::File => Initialization::File,
        InitName::SpanningTree => Initialization::SpanningTree,
        InitName::Chordal => Initialization::Chordal,
        InitName::ChordalIsotropic => Initialization::ChordalIsotropic,
        InitName::Auto => Initialization::Auto,
    };
    let quiet = a.quiet;
    // A solve that ends above where the file started (Gauss-Newton through
    // an indefinite H, say) must not replace the file's estimate silently.
    let (start_values, start_chi2) = (graph.values().params().to_vec(), graph.chi2());
    let (summary, used) = optimize_from(&mut graph, config, init, &mut |start, s| {
        if !quiet {
            eprintln!(
                "{}\t start= {}",
                iteration_line(s, edges),
                start_name(start)
            );
        }
    })
    .map_err(|e| format!("{name}: {e}"))?;
    let solve = t.elapsed().as_secs_f64();
    let end_chi2 = graph.chi2();
    let kept_start = end_chi2.is_nan() || end_chi2 > start_chi2;
    if kept_start {
        graph
            .values_mut()
            .params_mut()
            .copy_from_slice(&start_values);
        eprintln!(
            "warning: {name}: the solve ended at χ² {:.6e} ({:?}), above the file's {start_chi2:.6e}; \
             the file's estimate is kept",
            summary.final_chi2, summary.termination
        );
    }

    let marginal_ids = marginal_ids(&a.marginals, &graph, &summary.gauge)?;
    let marginals = if marginal_ids.is_empty() {
        Ok(Vec::new())
    } else {
        Optimizer::new(&graph, config)
            .and_then(|mut optimizer| optimizer.marginals(&graph, &marginal_ids))
            .map_err(|e| format!("--marginals: {e}"))
    };

    // The solved graph is written even when its marginals fail.
    let t = Instant::now();
    if let Some(out) = &a.output {
        let text = cairn::g2o::to_string(&graph).map_err(|e| e.to_string())?;
        super::write_output(out, text.as_bytes())?;
    }
    let write = t.elapsed().as_secs_f64();
    let marginals = marginals.map_err(|e| match &a.output {
        Some(out) => format!("{e} (the solved graph was written to {})", out.display()),
        None => e,
    })?;
    if !a.quiet {
        for (id, m) in marginal_ids.iter().zip(&marginals) {
            eprint!("marginal covariance of vertex {id}:{m}");
        }
    }
    let times = Times { load, solve, write };

    if !a.quiet {
        eprintln!(
            "{} from {} start: {:?} after {} iterations: χ² {:.6} → {:.6}; load {:.3}s, solve {:.3}s, write {:.3}s{}",
            summary.algorithm.short_name(),
            start_name(used),
            summary.termination,
            summary.iterations,
            summary.initial_chi2,
            summary.final_chi2,
            load,
            solve,
            write,
            if summary.gauge.is_empty() {
                String::new()
            } else {
                format!(
                    "; gauge: fixed vertex {:?} ({} components)",
                    summary.gauge, summary.components
                )
            }
        );
    }
    if let Some(path) = &a.stats {
        super::write_output(path, stats_csv(&summary).as_bytes())?;
    }
    if let Some(path) = &a.summary {
        append_summary(path, &summary_row(&name, vertices, edges, &summary, &times))?;
    }
    if a.json {
        let value = serde_json::json!({
            "file": name,
            "vertices": vertices,
            "edges": edges,
            "load": report_json(&report),
            "summary": summary,
            "kept_start": kept_start,
            "init": start_name(used),
            "marginals": marginal_ids.iter().zip(&marginals).map(|(id, m)| serde_json::json!({
                "vertex": id,
                "covariance": m.row_iter().map(|r| r.iter().copied().collect::<Vec<f64>>()).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "load_s": load,
            "solve_s": solve,
            "write_s": write,
        });
        println!("{value}");
    }
    Ok(())
}

/// The vertex ids `--marginals` names: its ids, or with `all` every vertex
/// neither fixed nor taken as the gauge.
fn marginal_ids(
    args: &[String],
    graph: &cairn_core::Graph,
    gauge: &[i64],
) -> Result<Vec<i64>, String> {
    if args.iter().any(|a| a == "all") {
        return Ok(graph
            .vertices()
            .filter(|v| !v.fixed && !gauge.contains(&v.id))
            .map(|v| v.id)
            .collect());
    }
    args.iter()
        .map(|a| {
            a.trim()
                .parse()
                .map_err(|_| format!("--marginals: '{a}' is neither a vertex id nor all"))
        })
        .collect()
}
