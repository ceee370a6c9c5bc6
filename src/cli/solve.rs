//! `cairn solve`: optimise a g2o file.

use super::solve_output::{
    Times, append_summary, check_outputs, describe_load, report_json, stats_csv, summary_row,
};
use super::trajectory::{TrajectoryFormat, trajectory};
use super::{CliError, bad_input};
use cairn::core::{RobustKernel, Se3Error};
use cairn::g2o::ReadOptions;
use cairn::solvers::{
    Algorithm, Factorization, Initialization, IterationStats, LevenbergMarquardtConfig,
    LinearSolverConfig, Optimizer, Ordering, SolverConfig,
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
enum Se3ErrorName {
    /// g2o's: (t, q.xyz) of Z⁻¹·Xᵢ⁻¹·Xⱼ
    G2o,
    /// (t, Log R) of Z⁻¹·Xᵢ⁻¹·Xⱼ
    Logmap,
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
    /// The file's vertices; if that run has not converged within 10 iterations, both chordal starts too, keeping the lowest χ²
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
    #[arg(help_heading = "Output", short, long)]
    output: Option<PathBuf>,
    /// Maximum number of iterations.
    #[arg(help_heading = "Algorithm", short = 'i', long, default_value_t = 100)]
    iterations: usize,
    /// Algorithm (g2o's default is Gauss-Newton too).
    #[arg(help_heading = "Algorithm", long, value_enum, default_value = "gn")]
    solver: SolverName,
    /// Levenberg-Marquardt's damping.
    #[arg(
        help_heading = "Levenberg-Marquardt",
        long,
        value_enum,
        default_value = "marquardt"
    )]
    damping: DampingName,
    /// Levenberg-Marquardt's τ, which sets the first λ (see --damping).
    /// Default 1e-12 (marquardt), 1e-5 (levenberg, g2o's).
    #[arg(help_heading = "Levenberg-Marquardt", long)]
    tau: Option<f64>,
    /// Levenberg-Marquardt's non-monotonic steps: how many steps in a row
    /// may raise χ² (the estimate written is the lowest-χ² one met). 0 makes
    /// every accepted step lower χ². Default 5 (marquardt), 0 (levenberg, as g2o).
    #[arg(help_heading = "Levenberg-Marquardt", long)]
    nonmonotonic_steps: Option<usize>,
    /// Levenberg-Marquardt's look-ahead: when its first step raises χ², it
    /// follows up to this many Gauss-Newton steps and keeps them if they
    /// settle below the starting χ². 0 rejects that step. Default 10
    /// (marquardt), 0 (levenberg, as g2o).
    #[arg(help_heading = "Levenberg-Marquardt", long)]
    lookahead_steps: Option<usize>,
    /// Levenberg-Marquardt's line search: a step that lowers χ² by less than
    /// a quarter of its model's prediction is shortened to where a parabola
    /// puts χ²'s minimum, if that lowers χ² further. Default true
    /// (marquardt), false (levenberg, as g2o).
    #[arg(help_heading = "Levenberg-Marquardt", long)]
    line_search: Option<bool>,
    /// Starting point.
    #[arg(help_heading = "Algorithm", long, value_enum, default_value = "auto")]
    init: InitName,
    /// Hold these vertex ids fixed (comma-separated), besides FIX lines.
    #[arg(help_heading = "Algorithm", long, value_delimiter = ',')]
    fix: Vec<i64>,
    /// Stop when χ² falls by less than this fraction in an iteration.
    #[arg(help_heading = "Algorithm", long, default_value_t = SolverConfig::default().relative_decrease)]
    relative_decrease: f64,
    /// Gauss-Newton: stop at the first step that raises χ² and keep the
    /// estimate before it (GTSAM's Gauss-Newton stops there too, keeping the
    /// step). Without it GN carries on, as g2o's does.
    #[arg(help_heading = "Algorithm", long)]
    stop_on_increase: bool,
    /// Replace information matrices that are not positive definite by the
    /// nearest positive-definite ones (cubicle.g2o needs this) instead of refusing.
    #[arg(help_heading = "Algorithm", long)]
    repair_information: bool,
    /// The error of EDGE_SE3:QUAT edges: g2o's (translation and the
    /// quaternion's vector part, ≈ θ/2) or logmap (translation and the
    /// rotation vector θ·axis, the objective of GTSAM, apex-solver and
    /// factrs to first order).
    #[arg(help_heading = "Algorithm", long, value_enum, default_value = "g2o")]
    se3_error: Se3ErrorName,
    /// Robust kernel on the edges' squared errors: huber, pseudo-huber, cauchy,
    /// geman-mcclure, welsch, fair, tukey, saturated or dcs. (With dcs, use gn or
    /// dogleg: its weights are not the derivative of its cost, which LM's gain
    /// ratio needs.)
    #[arg(help_heading = "Robust kernels", long, ignore_case = true,
          value_parser = clap::builder::PossibleValuesParser::new(RobustKernel::NAMES))]
    robust_kernel: Option<String>,
    /// Width δ of the robust kernel.
    #[arg(help_heading = "Robust kernels", long, default_value_t = 1.0)]
    robust_kernel_width: f64,
    /// Apply the robust kernel only to loop closures: edges between vertices
    /// whose ids are not consecutive (g2o's -nonSequential).
    #[arg(help_heading = "Robust kernels", long)]
    non_sequential: bool,
    /// Cholesky variant.
    #[arg(
        help_heading = "Linear solver",
        long,
        value_enum,
        default_value = "auto"
    )]
    factorization: FactorizationName,
    /// Fill-reducing ordering.
    #[arg(
        help_heading = "Linear solver",
        long,
        value_enum,
        default_value = "block-amd"
    )]
    ordering: OrderingName,
    /// Worker threads, 0 to 1024 (0: one per core). Only graphs with
    /// millions of Jacobian-block entries are linearised in parallel;
    /// results are the same for any number.
    #[arg(help_heading = "Linear solver", long, default_value_t = 0,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=1024))]
    threads: usize,
    /// Print the marginal covariances of these vertex ids (comma-separated),
    /// or of every vertex not held fixed with `all`, at the optimum, in each
    /// vertex's tangent coordinates (SE2: x, y, θ).
    #[arg(
        help_heading = "Output",
        long,
        value_delimiter = ',',
        value_name = "IDS|all"
    )]
    marginals: Vec<String>,
    /// Append a one-line CSV summary of the run to this file (header if new).
    #[arg(help_heading = "Output", long)]
    summary: Option<PathBuf>,
    /// Write the solved poses (SE2 and SE3, in id order) as a trajectory
    /// file, for evo and other trajectory tools.
    #[arg(help_heading = "Output", long, value_name = "FILE")]
    traj_out: Option<PathBuf>,
    /// The trajectory's format: tum (the vertex id as time) or kitti.
    #[arg(help_heading = "Output", long, value_enum, default_value = "tum")]
    traj_format: TrajectoryFormat,
    /// Write per-iteration statistics as CSV to this file.
    #[arg(help_heading = "Output", long)]
    stats: Option<PathBuf>,
    /// Print the summary as JSON on stdout.
    #[arg(help_heading = "Output", long)]
    json: bool,
    /// No per-iteration output on stderr.
    #[arg(help_heading = "Output", short, long)]
    quiet: bool,
    /// Exit with status 5 when the solve does not converge (the iteration
    /// cap, an indefinite Hessian, a non-finite χ²), after writing its
    /// result as without it. Without it such a run exits 0, as g2o's does.
    #[arg(help_heading = "Algorithm", long)]
    strict: bool,
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

pub fn run(a: SolveArgs) -> Result<(), super::CliError> {
    if a.json && a.output.as_ref().is_some_and(|o| o.as_os_str() == "-") {
        return Err(CliError::usage(
            "--json and -o - both want stdout; write the graph to a file",
        ));
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
fn solve(a: SolveArgs) -> Result<(), CliError> {
    let name = a.file.display().to_string();
    check_outputs(&[
        ("-o", a.output.as_ref()),
        ("--stats", a.stats.as_ref()),
        ("--summary", a.summary.as_ref()),
        ("--traj-out", a.traj_out.as_ref()),
    ])?;
    let t = Instant::now();
    let options = ReadOptions {
        repair_information: a.repair_information,
        se3_error: match a.se3_error {
            Se3ErrorName::G2o => Se3Error::G2o,
            Se3ErrorName::Logmap => Se3Error::Logmap,
        },
        ..Default::default()
    };
    // The file's bytes are dropped once parsed: on a 10⁶-pose file they are
    // 250 MB that the solve does not need.
    let (mut graph, report) =
        cairn::g2o::read_bytes(&super::read_input(&a.file)?, &options).map_err(bad_input(&name))?;
    for &id in &a.fix {
        graph
            .set_fixed(id, true)
            .map_err(|e| CliError::usage(format!("--fix: {e}")))?;
    }
    if let Some(name) = &a.robust_kernel {
        let kernel = RobustKernel::from_name(name, a.robust_kernel_width).ok_or_else(|| {
            CliError::usage(format!(
                "unknown robust kernel {name:?}; choose one of {}",
                RobustKernel::NAMES.join(", ")
            ))
        })?;
        // Also rejects NaN.
        if a.robust_kernel_width.is_nan() || a.robust_kernel_width <= 0.0 {
            return Err(CliError::usage("--robust-kernel-width must be positive"));
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
        return Err(CliError::usage("--tau must be positive and finite"));
    }
    if a.stop_on_increase && !matches!(a.solver, SolverName::Gn) {
        return Err(CliError::usage(
            "--stop-on-increase is for --solver gn: LM and dogleg control their steps themselves",
        ));
    }
    let config = SolverConfig {
        init: match a.init {
            InitName::File => Initialization::File,
            InitName::SpanningTree => Initialization::SpanningTree,
            InitName::Chordal => Initialization::Chordal,
            InitName::ChordalIsotropic => Initialization::ChordalIsotropic,
            InitName::Auto => Initialization::Auto,
        },
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
    let quiet = a.quiet;
    // The optimizer never replaces the file's estimate by a worse one
    // (Gauss-Newton through an indefinite H, say): it keeps the start.
    let mut optimizer = Optimizer::new(&graph, config).map_err(|e| format!("{name}: {e}"))?;
    let summary = optimizer
        .optimize_with(&mut graph, &mut |s| {
            if !quiet {
                eprintln!("{}\t start= {}", iteration_line(s, edges), s.start.name());
            }
        })
        .map_err(|e| format!("{name}: {e}"))?;
    let solve = t.elapsed().as_secs_f64();
    if summary.returned_lowest {
        eprintln!(
            "warning: {name}: the last iterate ({:?}) was above the lowest χ² met, {:.6e}; \
             that estimate is the result",
            summary.termination, summary.final_chi2
        );
    }
    if summary.kept_start {
        let ended = summary.trace.last().map_or(f64::NAN, |s| s.chi2);
        eprintln!(
            "warning: {name}: the solve ended at χ² {ended:.6e} ({:?}), above the file's {:.6e}; \
             the file's estimate is kept",
            summary.termination, summary.final_chi2
        );
    }

    let marginal_ids = marginal_ids(&a.marginals, &graph, &summary.gauge)?;
    let marginals = if marginal_ids.is_empty() {
        Ok(Vec::new())
    } else {
        optimizer
            .marginals(&graph, &marginal_ids)
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
    // Asked-for results: printed even with -q, on stdout unless the graph
    // or the JSON (which holds them) goes there.
    let stdout_taken = a.json || a.output.as_ref().is_some_and(|o| o.as_os_str() == "-");
    for (id, m) in marginal_ids.iter().zip(&marginals) {
        if stdout_taken {
            eprint!("marginal covariance of vertex {id}:{m}");
        } else {
            print!("marginal covariance of vertex {id}:{m}");
        }
    }
    let times = Times { load, solve, write };

    if !a.quiet {
        eprintln!(
            "{} from {} start: {:?} after {} iterations: χ² {:.6} → {:.6}; load {:.3}s, solve {:.3}s{}{}",
            summary.algorithm.short_name(),
            summary.init.name(),
            summary.termination,
            summary.iterations,
            summary.initial_chi2,
            summary.final_chi2,
            load,
            solve,
            if a.output.is_some() {
                format!(", write {write:.3}s")
            } else {
                String::new()
            },
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
    if let Some(path) = &a.traj_out {
        super::write_output(path, trajectory(&graph, a.traj_format)?.as_bytes())?;
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
            "kept_start": summary.kept_start,
            "init": summary.init.name(),
            "se3_error": options.se3_error.name(),
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
    if a.strict && !summary.termination.converged() {
        return Err(CliError::not_converged(format!(
            "{name}: the solve did not converge ({:?}; --strict)",
            summary.termination
        )));
    }
    Ok(())
}

/// The vertex ids `--marginals` names: its ids, or with `all` every vertex
/// neither fixed nor taken as the gauge.
fn marginal_ids(
    args: &[String],
    graph: &cairn_core::Graph,
    gauge: &[i64],
) -> Result<Vec<i64>, CliError> {
    if args.iter().any(|a| a == "all") {
        return Ok(graph
            .vertices()
            .filter(|v| !v.fixed && !gauge.contains(&v.id))
            .map(|v| v.id)
            .collect());
    }
    args.iter()
        .map(|a| {
            a.trim().parse().map_err(|_| {
                CliError::usage(format!("--marginals: '{a}' is neither a vertex id nor all"))
            })
        })
        .collect()
}
