//! Solver options with documented defaults, the per-iteration statistics and
//! the final summary.

use crate::linear::LinearSolverConfig;
use serde::{Deserialize, Serialize};

/// The nonlinear least-squares algorithm.
///
/// The default is Gauss-Newton, as in g2o's command-line tool: the fastest
/// from the benchmark files' own initial estimates. Levenberg-Marquardt and
/// dogleg guard against steps that raise χ² (bad starts, outliers).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Algorithm {
    /// Gauss-Newton: solve H δ = −g and take the full step. The estimate
    /// returned is the lowest-χ² iterate (see [`Summary::returned_lowest`]).
    #[default]
    GaussNewton,
    /// Levenberg-Marquardt: H + λD, with λ adapted to how well each step's
    /// decrease was predicted (see [`LevenbergMarquardtConfig`]).
    LevenbergMarquardt,
    /// Powell's dogleg: a trust region mixing the Gauss-Newton and the
    /// steepest-descent steps.
    Dogleg,
}

impl Algorithm {
    /// Short name (`gn`, `lm`, `dogleg`).
    pub fn short_name(&self) -> &'static str {
        match self {
            Algorithm::GaussNewton => "gn",
            Algorithm::LevenbergMarquardt => "lm",
            Algorithm::Dogleg => "dogleg",
        }
    }

    /// The algorithm with this [`Algorithm::short_name`].
    pub fn by_short_name(name: &str) -> Option<Self> {
        [Self::GaussNewton, Self::LevenbergMarquardt, Self::Dogleg]
            .into_iter()
            .find(|a| a.short_name() == name)
    }
}

/// How the optimiser removes the gauge freedom (the rigid motion that
/// changes no error) of the graph's connected components.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Gauge {
    /// Hold each component's lowest-id pose fixed, unless a fixed vertex or
    /// a full-rank prior already anchors the component.
    #[default]
    Auto,
    /// Hold only the graph's fixed vertices: for graphs whose priors fix
    /// the gauge together though none does alone (two position-only GPS
    /// priors, say). Where they do not, H is singular: Gauss-Newton and
    /// dogleg end with [`Termination::NotPositiveDefinite`].
    None,
    /// Hold these vertex ids (besides the fixed ones) at their values, and
    /// nothing else: to anchor a graph at a vertex of your choosing without
    /// marking it fixed in the graph (or in the g2o file written from it).
    Vertices(Vec<i64>),
}

/// Where the optimisation starts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Initialization {
    /// The graph's current values (the file's vertices).
    File,
    /// Every free vertex predicted along a breadth-first spanning tree from the
    /// fixed and gauge vertices (odometry chaining, for pose graphs).
    SpanningTree,
    /// Chordal relaxation of the rotations, then linear positions, weighted by
    /// the information matrices.
    Chordal,
    /// The chordal relaxation with every measurement weighted alike.
    ChordalIsotropic,
    /// The graph's current values first, with a budget of
    /// [`AUTO_TRUSTED_ITERATIONS`]: a run that converges within it is the
    /// result. Otherwise both chordal starts of its poses are solved too (and, where
    /// Gauss-Newton overshoots from one, Levenberg-Marquardt from it), and
    /// the lowest final χ² is kept; if that is the current values' run, it
    /// carries on to `max_iterations`.
    #[default]
    Auto,
}

/// Iterations within which a run from the graph's own values must converge
/// for [`Initialization::Auto`] to take it without trying the chordal starts.
/// From a start in its minimum's basin Gauss-Newton converges in a handful of
/// steps (3–11 on the benchmark files where the file's values reach the best
/// minimum); the runs that end in a worse minimum took 21 or more
/// (docs/defaults.md).
pub const AUTO_TRUSTED_ITERATIONS: usize = 10;

impl Initialization {
    /// Every start, in the order the command line lists them.
    pub const ALL: [Initialization; 5] = [
        Initialization::File,
        Initialization::SpanningTree,
        Initialization::Chordal,
        Initialization::ChordalIsotropic,
        Initialization::Auto,
    ];

    /// The name `cairn solve --init` and the Python package give it.
    pub fn name(self) -> &'static str {
        match self {
            Initialization::File => "file",
            Initialization::SpanningTree => "spanning-tree",
            Initialization::Chordal => "chordal",
            Initialization::ChordalIsotropic => "chordal-isotropic",
            Initialization::Auto => "auto",
        }
    }

    /// The start with this [`Initialization::name`].
    pub fn by_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|i| i.name() == name)
    }
}

/// How Levenberg-Marquardt damps the Hessian and picks its first λ.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Damping {
    /// Marquardt's: H + λ·diag(H) (each entry kept above 1e-10 × the
    /// largest), first λ = `tau`. Every unknown is damped in proportion to its
    /// own curvature, so the step does not depend on the units of the
    /// unknowns. Where H is singular (an unknown that no measurement fixes
    /// along some direction, e.g. a point seen once by range only), the
    /// step keeps a component along diag(H)⁻¹g that λ never removes, and LM
    /// crawls; use [`Damping::Levenberg`] for such problems.
    #[default]
    Marquardt,
    /// Levenberg's, as g2o: H + λI, first λ = `tau × max(diag H)`. With g2o's
    /// τ (1e-5, [`LevenbergMarquardtConfig::g2o`]) it reproduces g2o's
    /// iterates (exactly on SE2 graphs; on SE3 ones up to the form of the
    /// update, see `SE3`'s `Variable::oplus`), including where one λ sized by the stiffest unknown
    /// holds the others back for a hundred iterations (city10000,
    /// ais2klinik, M3500a and manhattan stall at 10–500× the optimum's χ²).
    Levenberg,
}

/// Options of Levenberg-Marquardt. Both dampings update λ by Nielsen's rule
/// (as g2o and Ceres): after an accepted step λ shrinks by up to 3× as the
/// model predicted the decrease well; after a rejected one it grows 2×, 4×,
/// 8×, … in a row.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LevenbergMarquardtConfig {
    /// How H is damped. Default [`Damping::Marquardt`].
    pub damping: Damping,
    /// The first λ: relative to each diagonal entry (Marquardt), or
    /// × max(diag H) (Levenberg). Default 1e-12; g2o's is 1e-5.
    ///
    /// Small because the bending of long chains of poses has curvatures far
    /// below any diagonal entry; damping it slows convergence
    /// (docs/bench/lm-options.md has the measurements).
    pub tau: f64,
    /// Rejected steps in a row, with λ raised each time, before giving up. Default 10.
    pub max_trials: usize,
    /// Steps that may raise χ², in a row, before the χ² they are measured
    /// from moves up (Ceres's `max_consecutive_nonmonotonic_steps`). 0
    /// makes LM monotone: every accepted step lowers χ². Default 5.
    ///
    /// A step is accepted if it lowers χ² from a reference a few steps back
    /// by a fair share of what the models predicted since, even if it
    /// raises χ² from the current point; the estimate returned is the one
    /// with the lowest χ² met. From poor starts this lets LM follow the
    /// Gauss-Newton path out of a nearer, worse minimum.
    pub nonmonotonic_steps: usize,
    /// Gauss-Newton steps LM may follow when its first step raises χ²
    /// (with non-monotonic steps allowed: a monotone LM never climbs).
    /// Default 10; 0 (as g2o) rejects that step and raises λ.
    ///
    /// LM keeps the Gauss-Newton path from its first step if each step
    /// after the first lowers χ² and the path settles (χ² falls by less than
    /// 0.1% in a step) below the starting χ² within this many steps;
    /// otherwise it goes back to the start and raises λ.
    #[serde(default = "default_lookahead_steps")]
    pub lookahead_steps: usize,
    /// Shorten a step whose χ² falls by less than a quarter of what its
    /// model predicted, to the minimum of the parabola through χ² at the
    /// point, its slope along the step and χ² at the step's end, if that
    /// lowers χ² further (one more linearisation). Default true; false (as
    /// g2o) keeps every accepted step whole.
    #[serde(default = "default_line_search")]
    pub line_search: bool,
}

fn default_line_search() -> bool {
    true
}

fn default_lookahead_steps() -> usize {
    10
}

impl Default for LevenbergMarquardtConfig {
    fn default() -> Self {
        Self {
            damping: Damping::default(),
            tau: 1e-12,
            max_trials: 10,
            nonmonotonic_steps: 5,
            lookahead_steps: default_lookahead_steps(),
            line_search: default_line_search(),
        }
    }
}

impl LevenbergMarquardtConfig {
    /// g2o's damping and τ, monotone, without the look-ahead or the line
    /// search: the same iterates as g2o's (see [`Damping::Levenberg`]).
    pub fn g2o() -> Self {
        Self {
            damping: Damping::Levenberg,
            tau: 1e-5,
            nonmonotonic_steps: 0,
            lookahead_steps: 0,
            line_search: false,
            ..Self::default()
        }
    }
}

/// Options of Powell's dogleg.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DoglegConfig {
    /// Initial trust-region radius (Euclidean norm of the step). Default 1e4, as g2o.
    pub initial_radius: f64,
    /// Rejected steps in a row, with the radius halved each time, before giving up. Default 10.
    pub max_trials: usize,
}

impl Default for DoglegConfig {
    fn default() -> Self {
        Self {
            initial_radius: 1e4,
            max_trials: 10,
        }
    }
}

/// Options of [`crate::Optimizer`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolverConfig {
    /// GN or LM. Default GN.
    pub algorithm: Algorithm,
    /// Iteration cap. Default 100.
    pub max_iterations: usize,
    /// Stop when an iteration lowers χ² by less than this fraction. Default 1e-7.
    pub relative_decrease: f64,
    /// Gauss-Newton: stop at the first step that raises χ², keeping the
    /// estimate before it ([`Termination::ErrorIncreased`]). GTSAM's
    /// Gauss-Newton stops there too (keeping the step). Default false: GN
    /// carries on, as g2o's does, which is what reaches the optimum on
    /// graphs whose first steps overshoot (M3500b, torus3D).
    #[serde(default)]
    pub stop_on_increase: bool,
    /// Stop when the gradient is this close to orthogonal to the residual:
    /// every |gᵢ| ≤ this × √(Hᵢᵢ·χ²), the cosine between the whitened
    /// residual and the whitened Jacobian's column i (MINPACK's `gtol`).
    /// Unlike a bound on |g| it does not depend on the scale of the
    /// information or the units of the unknowns. Default 1e-10.
    pub gradient_tolerance: f64,
    /// Stop when the largest step component is below this × (1 + largest
    /// parameter). Default 1e-12.
    pub step_tolerance: f64,
    /// Where each [`crate::Optimizer::optimize`] starts. Default
    /// [`Initialization::Auto`], as `cairn solve`; [`Initialization::File`]
    /// to iterate from the graph's current values (an estimator re-solving
    /// a growing graph).
    #[serde(default)]
    pub init: Initialization,
    /// How the gauge is fixed. Default [`Gauge::Auto`].
    #[serde(default)]
    pub gauge: Gauge,
    /// Levenberg-Marquardt options.
    pub lm: LevenbergMarquardtConfig,
    /// Dogleg options.
    pub dogleg: DoglegConfig,
    /// Linear solver options.
    pub linear: LinearSolverConfig,
    /// Linearise in parallel, into a buffer summed afterwards, when the
    /// edges' blocks hold at least this many scalars and the thread pool has
    /// more than one thread; below it, one thread adds every edge's blocks
    /// straight into H, which is faster on small graphs. Same bits either
    /// way. Default 2·10⁶ (by measurement on 2 cores, BENCHMARKS.md: about
    /// 60,000 2D or 16,000 3D pose edges); lower it on many cores.
    #[serde(default = "default_parallel_min_values")]
    pub parallel_min_values: usize,
}

fn default_parallel_min_values() -> usize {
    2_000_000
}

impl Default for SolverConfig {
    fn default() -> Self {
        Self {
            algorithm: Algorithm::default(),
            max_iterations: 100,
            relative_decrease: 1e-7,
            stop_on_increase: false,
            gradient_tolerance: 1e-10,
            step_tolerance: 1e-12,
            init: Initialization::Auto,
            gauge: Gauge::Auto,
            lm: LevenbergMarquardtConfig::default(),
            dogleg: DoglegConfig::default(),
            linear: LinearSolverConfig::default(),
            parallel_min_values: default_parallel_min_values(),
        }
    }
}

/// Why the optimisation stopped. Reaching the iteration cap is not an error.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Termination {
    /// χ² fell by less than `relative_decrease` in an iteration.
    RelativeDecrease,
    /// The gradient is orthogonal to the residual to within
    /// `gradient_tolerance`, or χ² is 0.
    GradientNorm,
    /// The step is below `step_tolerance` (LM: also a rejected step).
    StepSize,
    /// `max_iterations` done.
    MaxIterations,
    /// LM or dogleg: `max_trials` rejected steps in a row, none of them
    /// small; the estimate is the best found, but not shown to be a minimum.
    NoImprovement,
    /// GN or dogleg: the Hessian was not positive definite (dogleg: even damped);
    /// the estimate is the last one.
    NotPositiveDefinite,
    /// χ² became NaN or infinite after a GN step; the estimate is the last one.
    NonFinite,
    /// GN with `stop_on_increase`: a step raised χ²; the estimate is the
    /// one before it.
    ErrorIncreased,
    /// Every vertex is fixed: nothing to optimise.
    NothingToOptimize,
}

impl Termination {
    /// Whether this counts as convergence: χ², the gradient or the step
    /// became negligible, or there was nothing to optimise.
    pub fn converged(&self) -> bool {
        matches!(
            self,
            Self::RelativeDecrease | Self::GradientNorm | Self::StepSize | Self::NothingToOptimize
        )
    }
}

/// Seconds spent in each phase.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PhaseTimes {
    /// Errors, Jacobians and the edges' blocks; on one thread the blocks
    /// are added straight into H and the gradient, so this includes the
    /// assembly.
    pub linearize: f64,
    /// Summing the edges' blocks into H and the gradient, when they were
    /// linearised in parallel (zero on one thread).
    pub assemble: f64,
    /// Numeric Cholesky.
    pub factorize: f64,
    /// Triangular solves.
    pub solve: f64,
    /// Applying the step (and LM backups).
    pub update: f64,
    /// χ² evaluations apart from a linearisation. GN, LM and dogleg take χ²
    /// from the linearisation of each point they try, so theirs is 0; kept
    /// for the `--stats` and JSON columns.
    pub chi2: f64,
}

impl PhaseTimes {
    /// Adds `other` to `self`.
    pub fn add(&mut self, other: &PhaseTimes) {
        self.linearize += other.linearize;
        self.assemble += other.assemble;
        self.factorize += other.factorize;
        self.solve += other.solve;
        self.update += other.update;
        self.chi2 += other.chi2;
    }
    /// Sum of all phases.
    pub fn total(&self) -> f64 {
        self.linearize + self.assemble + self.factorize + self.solve + self.update + self.chi2
    }
}

/// Statistics of one iteration (g2o's `-stats` columns and more).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct IterationStats {
    /// Iteration number, from 0.
    pub iteration: usize,
    /// The start this run began from (one of several with
    /// [`Initialization::Auto`]).
    #[serde(default)]
    pub start: Initialization,
    /// χ² after the iteration. For the step that ends GN with
    /// [`Termination::ErrorIncreased`], the χ² that step reached (the
    /// estimate returned is the one before it).
    pub chi2: f64,
    /// λ after the iteration (LM only).
    pub lambda: Option<f64>,
    /// Trust-region radius after the iteration (dogleg only).
    pub radius: Option<f64>,
    /// Steps tried (LM: 1 + rejected steps).
    pub trials: usize,
    /// Largest absolute gradient component at the linearisation point.
    pub gradient_max: f64,
    /// Largest absolute component of the accepted step (0 if none; for
    /// GN's step that raised χ² and ended it, that step's).
    pub step_max: f64,
    /// Seconds of this iteration.
    pub time: f64,
    /// Seconds since the optimisation started.
    pub cumulative_time: f64,
    /// Per-phase seconds of this iteration.
    pub phases: PhaseTimes,
}

/// The outcome of an optimisation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// GN or LM.
    pub algorithm: Algorithm,
    /// χ² before the first iteration.
    pub initial_chi2: f64,
    /// χ² at the returned estimate.
    pub final_chi2: f64,
    /// Iterations done.
    pub iterations: usize,
    /// Why it stopped.
    pub termination: Termination,
    /// The start whose run gave the estimate the graph holds.
    #[serde(default)]
    pub init: Initialization,
    /// Whether the run ended worse than the graph's values before it (χ²
    /// NaN, or higher where χ² is the objective) and those values were put
    /// back: an optimisation never replaces an estimate by a worse one.
    /// `final_chi2` is then the kept values' χ², and the trace says where
    /// the run ended.
    #[serde(default)]
    pub kept_start: bool,
    /// Vertex ids held to remove the gauge freedom (automatic or
    /// [`Gauge::Vertices`]).
    pub gauge: Vec<i64>,
    /// Number of connected components.
    pub components: usize,
    /// Dimension of the linear system.
    pub dimension: usize,
    /// Stored entries of the upper triangle of H.
    pub hessian_nnz: usize,
    /// Stored values of the Cholesky factor.
    pub factor_nnz: usize,
    /// Whether faer chose a supernodal factorisation.
    pub supernodal: bool,
    /// Seconds for structure and symbolic analysis.
    pub setup_time: f64,
    /// Seconds of the iterations.
    pub solve_time: f64,
    /// Per-phase seconds summed over iterations.
    pub phases: PhaseTimes,
    /// One entry per iteration.
    pub trace: Vec<IterationStats>,
    /// Whether the solve ended above the lowest χ² it met (Gauss-Newton
    /// after a step that raised χ², Levenberg-Marquardt after non-monotonic
    /// steps) and the estimate returned is that lowest one's, not the last
    /// iterate's. Gauss-Newton does so only where χ² is the objective
    /// ([`cairn_core::Graph::chi2_is_objective`]: no DCS kernel).
    #[serde(default)]
    pub returned_lowest: bool,
}
