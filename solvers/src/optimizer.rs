//! Gauss-Newton and Levenberg-Marquardt over the fixed Hessian structure.

use crate::SolveError;
use crate::assembly::Assembly;
use crate::config::{
    Algorithm, Gauge, Initialization, IterationStats, PhaseTimes, SolverConfig, Summary,
    Termination,
};
use crate::linear::SparseCholesky;
use crate::structure::HessianStructure;
use cairn_core::{Graph, VertexId};
use std::time::Instant;

mod dogleg;
mod gauss_newton;
mod levenberg_marquardt;

/// Seconds since `t`.
fn since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Where the last linearisation put its result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Pending {
    /// In H and the gradient already.
    Nothing,
    /// In the buffer, to be assembled.
    Buffer,
    /// In `trial`, to be swapped in.
    Trial,
}

/// An optimiser bound to one graph's structure. Build it once and call
/// [`Optimizer::optimize`] as often as the values change; the Hessian pattern,
/// the symbolic factorisation and every buffer are reused.
///
/// Linearisation and assembly run on rayon's current thread pool, with the
/// same result for any number of threads. Called from outside a pool, each
/// of those loops is handed to the pool and waited for; on small graphs
/// that costs a tenth of an iteration, so call it inside
/// `ThreadPool::install` (as `cairn solve` does) where latency matters.
///
/// ```
/// use cairn_core::{EdgeSE2, Graph, SE2};
/// use cairn_solvers::{Algorithm, Optimizer, SolverConfig};
/// use nalgebra::Matrix3;
///
/// let mut graph = Graph::new();
/// let corners = [(0.0, 0.0), (1.1, 0.1), (0.9, 1.2), (-0.1, 0.9)];
/// for (i, (x, y)) in corners.into_iter().enumerate() {
///     graph.add_vertex(i as i64, SE2::new(x, y, 1.5 * i as f64))?;
/// }
/// for i in 0..4 {
///     let odometry = EdgeSE2::new(SE2::new(1.0, 0.0, std::f64::consts::FRAC_PI_2));
///     graph.add_edge(i, (i + 1) % 4, odometry, Matrix3::identity())?;
/// }
/// let config = SolverConfig { algorithm: Algorithm::GaussNewton, ..Default::default() };
/// let summary = Optimizer::new(&graph, config)?.optimize(&mut graph)?;
/// assert!(summary.final_chi2 < 1e-12); // a consistent square closes exactly
/// assert_eq!(summary.gauge, vec![0]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct Optimizer {
    config: SolverConfig,
    structure: HessianStructure,
    cholesky: Option<SparseCholesky>,
    /// The edges' blocks and where they sum into H, for linearising in
    /// parallel (built on first use).
    parallel: Option<(Assembly, Vec<f64>)>,
    /// H and the gradient at a trial point, linearised on one thread while
    /// H and the gradient still hold the current point's (allocated on first use).
    trial: Option<(Vec<f64>, Vec<f64>)>,
    /// Each edge's χ², linearised on one thread.
    chi2_terms: Vec<f64>,
    /// What the last linearisation left for [`Self::accept`] to make current.
    pending: Pending,
    hessian: Vec<f64>,
    diagonal_backup: Vec<f64>,
    damping: Vec<f64>,
    gradient: Vec<f64>,
    step: Vec<f64>,
    /// H⁻¹g with the last factorisation, for Gauss-Newton's look ahead.
    predicted: Vec<f64>,
    backup: Vec<f64>,
    free: Vec<usize>,
    gauge: Vec<VertexId>,
    components: usize,
    shape: (usize, usize),
    setup_time: f64,
}

impl Optimizer {
    /// Builds the structure for `graph`: its FIX vertices are held constant,
    /// and so is the gauge ([`SolverConfig::gauge`]: by default each
    /// connected component without a fixed vertex or full prior gets its
    /// lowest-id pose held).
    pub fn new(graph: &Graph, config: SolverConfig) -> Result<Self, SolveError> {
        let start = Instant::now();
        let components = graph.components();
        let gauge_vertices = gauge_indices(graph, &config.gauge)?;
        let mut fixed: Vec<bool> = (0..graph.num_vertices())
            .map(|v| graph.vertex(v).fixed)
            .collect();
        for &v in &gauge_vertices {
            fixed[v] = true;
        }
        let structure = HessianStructure::new(graph, &fixed, config.linear.ordering)?;
        let cholesky = if structure.dim > 0 {
            Some(SparseCholesky::analyze(&structure.layout, &config.linear)?)
        } else {
            None
        };
        let free = (0..graph.num_vertices()).filter(|&v| !fixed[v]).collect();
        Ok(Self {
            config,
            parallel: None,
            trial: None,
            chi2_terms: vec![0.0; structure.num_edges()],
            pending: Pending::Nothing,
            hessian: vec![0.0; structure.nnz()],
            diagonal_backup: vec![0.0; structure.dim],
            damping: vec![0.0; structure.dim],
            gradient: vec![0.0; structure.dim],
            step: vec![0.0; structure.dim],
            predicted: vec![0.0; structure.dim],
            backup: graph.values().params().to_vec(),
            free,
            gauge: gauge_vertices.iter().map(|&v| graph.vertex(v).id).collect(),
            components: components.count,
            shape: (graph.num_vertices(), graph.num_edges()),
            structure,
            cholesky,
            setup_time: since(start),
        })
    }

    /// The options in use.
    pub fn config(&self) -> &SolverConfig {
        &self.config
    }

    /// The options, to change those that do not affect the structure.
    pub(crate) fn config_mut(&mut self) -> &mut SolverConfig {
        &mut self.config
    }

    /// Changes the options that do not affect the structure (start,
    /// algorithm, stopping rules, LM settings); the linear solver and the
    /// gauge stay as built.
    pub fn set_config(&mut self, config: SolverConfig) {
        let linear = self.config.linear;
        let gauge = std::mem::take(&mut self.config.gauge);
        self.config = SolverConfig {
            linear,
            gauge,
            ..config
        };
    }

    /// One run of the configured algorithm from the graph's current values,
    /// which it replaces; `start` names where those values came from.
    pub(crate) fn iterate(
        &mut self,
        graph: &mut Graph,
        start_point: Initialization,
        on_iteration: &mut dyn FnMut(&IterationStats),
    ) -> Result<Summary, SolveError> {
        if (graph.num_vertices(), graph.num_edges()) != self.shape {
            return Err(SolveError::GraphChanged);
        }
        let start = Instant::now();
        let mut phases = PhaseTimes::default();
        let chi2 = self.linearize(graph, &mut phases);
        if !chi2.is_finite() {
            return Err(non_finite_edge(graph));
        }
        let mut summary = Summary {
            algorithm: self.config.algorithm,
            initial_chi2: chi2,
            final_chi2: chi2,
            iterations: 0,
            termination: Termination::MaxIterations,
            init: start_point,
            kept_start: false,
            gauge: self.gauge.clone(),
            components: self.components,
            dimension: self.structure.dim,
            hessian_nnz: self.structure.nnz(),
            factor_nnz: self.cholesky.as_ref().map_or(0, |c| c.factor_nnz()),
            supernodal: self.cholesky.as_ref().is_some_and(|c| c.is_supernodal()),
            setup_time: self.setup_time,
            solve_time: 0.0,
            phases,
            trace: Vec::new(),
            returned_lowest: false,
        };
        if self.structure.dim == 0 {
            summary.termination = Termination::NothingToOptimize;
            return Ok(summary);
        }
        let termination = match self.config.algorithm {
            Algorithm::GaussNewton => self.gauss_newton(graph, &mut summary, start, on_iteration),
            Algorithm::LevenbergMarquardt => {
                self.levenberg_marquardt(graph, &mut summary, start, on_iteration)
            }
            Algorithm::Dogleg => self.dogleg(graph, &mut summary, start, on_iteration),
        };
        summary.termination = termination;
        summary.iterations = summary.trace.len();
        summary.solve_time = since(start);
        summary.phases = summary.trace.iter().fold(phases, |mut acc, s| {
            acc.add(&s.phases);
            acc
        });
        Ok(summary)
    }

    /// (vertices, edges) of the graph this optimizer was built for.
    pub(crate) fn shape(&self) -> (usize, usize) {
        self.shape
    }

    /// First column of vertex index `v` in H, `None` if it is fixed.
    pub(crate) fn column(&self, v: usize) -> Option<usize> {
        self.structure.column[v]
    }

    /// Number of stored values of the Cholesky factor L of H under the
    /// configured ordering (none when every vertex is fixed): the fill an
    /// ordering leaves.
    pub fn factor_nnz(&self) -> Option<usize> {
        self.cholesky.as_ref().map(SparseCholesky::factor_nnz)
    }

    /// H's structure.
    pub(crate) fn structure(&self) -> &HessianStructure {
        &self.structure
    }

    /// H's upper triangle as last assembled, in its layout's order.
    pub(crate) fn hessian_values(&self) -> &[f64] {
        &self.hessian
    }

    /// The gradient JᵀWe as last assembled.
    pub(crate) fn gradient_values(&self) -> &[f64] {
        &self.gradient
    }

    /// Dimension of H.
    pub(crate) fn dimension(&self) -> usize {
        self.structure.dim
    }

    /// Linearises and assembles H and the gradient at the graph's values.
    pub(crate) fn relinearize(&mut self, graph: &Graph, phases: &mut PhaseTimes) -> f64 {
        self.linearize(graph, phases)
    }

    /// Factorises the assembled H without damping.
    pub(crate) fn factorize_undamped(&mut self) -> Result<(), SolveError> {
        let cholesky = self.cholesky.as_mut().ok_or(SolveError::NothingToSolve)?;
        cholesky
            .factorize(&self.hessian)
            .map_err(|e| SolveError::NotPositiveDefinite(e.pivot))
    }

    /// H⁻¹ on the pattern of the last factorisation's L.
    pub(crate) fn selected_inverse(&self) -> Option<crate::selected_inverse::SelectedInverse> {
        self.cholesky.as_ref()?.selected_inverse()
    }

    /// Solves H x = rhs with the last factorisation.
    pub(crate) fn solve_factorized(&mut self, rhs: &mut [f64]) {
        if let Some(c) = self.cholesky.as_mut() {
            c.solve_in_place(rhs);
        }
    }

    /// Linearises every edge and assembles H and the gradient; returns χ².
    fn linearize(&mut self, graph: &Graph, phases: &mut PhaseTimes) -> f64 {
        let chi2 = self.linearize_trial(graph, phases, false);
        self.accept(phases);
        chi2
    }

    /// Linearises every edge at the graph's values and returns χ²; with
    /// `keep_current`, H and the gradient keep the current point's until
    /// [`Self::accept`] makes the new point's current (a step may still be
    /// rejected). On one thread, or on a graph too small for threads to pay
    /// off, the edges add straight into H (or the trial copy); otherwise they
    /// write their blocks into the buffer in parallel, and `accept` sums
    /// them. Both give the same bits.
    fn linearize_trial(
        &mut self,
        graph: &Graph,
        phases: &mut PhaseTimes,
        keep_current: bool,
    ) -> f64 {
        let t = Instant::now();
        let parallel = self.structure.buffer_len >= self.config.parallel_min_values;
        let chi2 = if parallel && rayon::current_num_threads() > 1 {
            self.linearize_parallel(graph)
        } else {
            let (hessian, gradient) = if keep_current {
                let (nnz, dim) = (self.hessian.len(), self.gradient.len());
                self.pending = Pending::Trial;
                let (h, g) = self
                    .trial
                    .get_or_insert_with(|| (vec![0.0; nnz], vec![0.0; dim]));
                (h, g)
            } else {
                self.pending = Pending::Nothing;
                (&mut self.hessian, &mut self.gradient)
            };
            self.structure
                .linearize_into(graph, hessian, gradient, &mut self.chi2_terms)
        };
        phases.linearize += since(t);
        chi2
    }

    /// Linearises every edge into the buffer in parallel; returns χ².
    fn linearize_parallel(&mut self, graph: &Graph) -> f64 {
        let structure = &self.structure;
        let (assembly, buffer) = self.parallel.get_or_insert_with(|| {
            let assembly = Assembly::new(structure, graph);
            let buffer = vec![0.0; assembly.buffer_len];
            (assembly, buffer)
        });
        let values = graph.values();
        let groups = graph.factor_groups();
        for (k, group) in groups.iter().enumerate() {
            let start = assembly.group_offset[k];
            let end = (assembly.group_offset.get(k + 1).copied()).unwrap_or(assembly.buffer_len);
            group.linearize(values, &mut buffer[start..end]);
        }
        self.pending = Pending::Buffer;
        assembly.chi2(buffer)
    }

    /// Makes the last linearisation's H and gradient current.
    fn accept(&mut self, phases: &mut PhaseTimes) {
        match std::mem::replace(&mut self.pending, Pending::Nothing) {
            Pending::Nothing => {}
            Pending::Buffer => {
                let t = Instant::now();
                if let Some((assembly, buffer)) = &self.parallel {
                    assembly.assemble(
                        &self.structure,
                        buffer,
                        &mut self.hessian,
                        &mut self.gradient,
                    );
                }
                phases.assemble += since(t);
            }
            Pending::Trial => {
                if let Some((h, g)) = self.trial.as_mut() {
                    std::mem::swap(h, &mut self.hessian);
                    std::mem::swap(g, &mut self.gradient);
                }
            }
        }
    }

    /// Factorises H + λD (λ = 0 for GN; D is `self.damping`) and solves for
    /// the step −(H + λD)⁻¹g.
    fn compute_step(&mut self, lambda: f64, phases: &mut PhaseTimes) -> bool {
        let Some(cholesky) = self.cholesky.as_mut() else {
            return false;
        };
        let t = Instant::now();
        if lambda != 0.0 {
            for (k, d) in self.structure.layout.diagonal().enumerate() {
                self.diagonal_backup[k] = self.hessian[d];
                self.hessian[d] += lambda * self.damping[k];
            }
        }
        for (s, g) in self.step.iter_mut().zip(&self.gradient) {
            *s = -g;
        }
        let begun = cholesky.factorize_and_begin_solve(&self.hessian, &mut self.step);
        if lambda != 0.0 {
            for (k, d) in self.structure.layout.diagonal().enumerate() {
                self.hessian[d] = self.diagonal_backup[k];
            }
        }
        phases.factorize += since(t);
        let Ok(begun) = begun else {
            return false;
        };
        let t = Instant::now();
        cholesky.finish_solve(begun, &mut self.step);
        phases.solve += since(t);
        self.step.iter().all(|s| s.is_finite())
    }

    fn apply_step(&self, graph: &mut Graph) {
        for &v in &self.free {
            if let Some(c) = self.structure.column[v] {
                let dim = graph.vertex(v).kind.dim;
                graph.oplus(v, &self.step[c..c + dim]);
            }
        }
    }

    fn save(&mut self, graph: &Graph) {
        self.backup.copy_from_slice(graph.values().params());
    }

    fn restore(&self, graph: &mut Graph) {
        graph
            .values_mut()
            .params_mut()
            .copy_from_slice(&self.backup);
    }

    /// Whether the gradient is small by MINPACK's scale-free test: the
    /// largest cosine between the whitened residual and a column of the
    /// whitened Jacobian, |gᵢ| / √(Hᵢᵢ·χ²), is below `gradient_tolerance`.
    /// Scaling all information, or the units of an unknown, leaves it
    /// unchanged. χ² = 0 is an exact fit: nothing is left to lower.
    pub(super) fn gradient_is_small(&self, chi2: f64) -> bool {
        if chi2 <= 0.0 {
            return true;
        }
        let threshold = self.config.gradient_tolerance * chi2.sqrt();
        self.gradient
            .iter()
            .zip(self.structure.layout.diagonal())
            .all(|(g, d)| g.abs() <= threshold * self.hessian[d].max(0.0).sqrt())
    }

    fn step_is_small(&self, graph: &Graph) -> bool {
        let scale = 1.0 + max_abs(graph.values().params());
        max_abs(&self.step) <= self.config.step_tolerance * scale
    }

    /// Ends an iteration whose step was taken, χ² going from `old_chi2` (for
    /// LM, the lowest χ² before the step) to `new_chi2`: makes the new
    /// point's H and gradient current unless this was the last iteration,
    /// records `stats` (timed from `clock`: the iteration's and the
    /// optimisation's start), and says whether to stop (the step was too
    /// small, or χ² fell by less than the tolerance).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn end_iteration(
        &mut self,
        graph: &Graph,
        old_chi2: f64,
        new_chi2: f64,
        mut stats: IterationStats,
        (began, start): (Instant, Instant),
        summary: &mut Summary,
        on_iteration: &mut dyn FnMut(&IterationStats),
    ) -> Option<Termination> {
        let decrease = (old_chi2 - new_chi2) / old_chi2;
        summary.final_chi2 = new_chi2;
        let small_step = self.step_is_small(graph);
        let converged = (0.0..self.config.relative_decrease).contains(&decrease);
        if !(small_step || converged || stats.iteration + 1 == self.config.max_iterations) {
            self.accept(&mut stats.phases);
        }
        stats.chi2 = new_chi2;
        stats.step_max = max_abs(&self.step);
        record(stats, began, start, summary, on_iteration);
        if small_step {
            Some(Termination::StepSize)
        } else if converged {
            Some(Termination::RelativeDecrease)
        } else {
            None
        }
    }
}

/// Times one iteration's statistics (it began at `began`, the optimisation at
/// `start`), reports them and appends them to the trace.
fn record(
    mut stats: IterationStats,
    began: Instant,
    start: Instant,
    summary: &mut Summary,
    on_iteration: &mut dyn FnMut(&IterationStats),
) {
    stats.time = since(began);
    stats.cumulative_time = since(start);
    stats.start = summary.init;
    on_iteration(&stats);
    summary.trace.push(stats);
}

/// The error for a non-finite initial χ², naming the first offending edge.
fn non_finite_edge(graph: &Graph) -> SolveError {
    for (k, e) in graph.edges().enumerate() {
        if !e.chi2(graph.values()).is_finite() {
            return SolveError::NonFiniteChi2 {
                edge: k,
                name: e.name(),
                vertices: e.vertices().iter().map(|&v| graph.vertex(v).id).collect(),
            };
        }
    }
    SolveError::NonFiniteChi2 {
        edge: usize::MAX,
        name: "?",
        vertices: vec![],
    }
}

/// The vertex indices [`Gauge`] holds in `graph`.
pub(crate) fn gauge_indices(graph: &Graph, gauge: &Gauge) -> Result<Vec<usize>, SolveError> {
    match gauge {
        Gauge::Auto => Ok(graph.gauge_indices(&graph.components())),
        Gauge::None => Ok(Vec::new()),
        Gauge::Vertices(ids) => ids
            .iter()
            .map(|&id| graph.vertex_index(id).ok_or(SolveError::UnknownVertex(id)))
            .collect(),
    }
}
