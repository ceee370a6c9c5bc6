//! Choosing the starting point: the file's values, a spanning tree, the chordal
//! relaxation, or (by default) whichever of the file's values and the two
//! chordal starts ends at the lowest χ².

use crate::chordal::{ChordalWeights, chordal_initialize, chordal_initialize_with};
use crate::config::{Algorithm, IterationStats, SolverConfig, Summary};
use crate::{Optimizer, SolveError};
use cairn_core::Graph;
use serde::{Deserialize, Serialize};

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
    /// Solve from [`Initialization::File`], [`Initialization::Chordal`] and
    /// [`Initialization::ChordalIsotropic`]; keep the lowest final χ². When
    /// Gauss-Newton overshoots from a chordal start (χ² rises in a step),
    /// Levenberg-Marquardt from that start is tried as well.
    #[default]
    Auto,
}

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

/// Sets the free vertices' values by breadth-first spanning tree from the fixed
/// and gauge vertices.
pub fn spanning_tree_initialize(graph: &mut Graph) {
    let mut unknown: Vec<bool> = (0..graph.num_vertices())
        .map(|v| !graph.vertex(v).fixed)
        .collect();
    for v in graph.gauge_indices(&graph.components()) {
        unknown[v] = false;
    }
    graph.initialize_spanning_tree(&unknown);
}

/// Whether χ² rose in some iteration.
fn overshot(summary: &Summary) -> bool {
    let mut previous = summary.initial_chi2;
    summary.trace.iter().any(|it| {
        let rose = it.chi2 > previous;
        previous = it.chi2;
        rose
    })
}

/// One solve after another on the same graph structure.
struct Starts<'a> {
    optimizer: Optimizer,
    config: SolverConfig,
    on_iteration: &'a mut dyn FnMut(Initialization, &IterationStats),
}

/// The run of the lowest final χ² so far: its summary, start and estimate.
struct Best {
    summary: Summary,
    start: Initialization,
    estimate: Vec<f64>,
}

impl Best {
    /// Keeps the graph's values if `summary` ends lower than the best so far.
    fn keep_if_lower(&mut self, summary: Summary, start: Initialization, graph: &Graph) {
        if summary.final_chi2 < self.summary.final_chi2 {
            self.estimate.copy_from_slice(graph.values().params());
            self.summary = summary;
            self.start = start;
        }
    }
}

impl Starts<'_> {
    /// Optimises from the graph's current values with `algorithm`.
    fn run(
        &mut self,
        graph: &mut Graph,
        start: Initialization,
        algorithm: Algorithm,
    ) -> Result<Summary, SolveError> {
        self.optimizer.set_config(SolverConfig {
            algorithm,
            ..self.config
        });
        let on_iteration = &mut *self.on_iteration;
        self.optimizer
            .optimize_with(graph, &mut |s| on_iteration(start, s))
    }

    /// [`Starts::run`] with the configured algorithm; if that is Gauss-Newton
    /// and it overshot, Levenberg-Marquardt from the same start as well.
    /// Each run's estimate replaces `best` if it ends lower.
    fn run_guarded(
        &mut self,
        graph: &mut Graph,
        start: Initialization,
        best: &mut Best,
    ) -> Result<(), SolveError> {
        let values = graph.values().params().to_vec();
        let summary = self.run(graph, start, self.config.algorithm)?;
        let retry = self.config.algorithm == Algorithm::GaussNewton && overshot(&summary);
        best.keep_if_lower(summary, start, graph);
        if retry {
            graph.values_mut().params_mut().copy_from_slice(&values);
            let summary = self.run(graph, start, Algorithm::LevenbergMarquardt)?;
            best.keep_if_lower(summary, start, graph);
        }
        Ok(())
    }
}

/// The graph's values and χ² before a solve, put back if the solve ends
/// worse: a solve must not replace an estimate by a worse one silently
/// (Gauss-Newton through an indefinite H, say).
#[derive(Clone, Debug)]
pub struct StartPoint {
    values: Vec<f64>,
    chi2: f64,
}

impl StartPoint {
    /// The graph's current values.
    pub fn of(graph: &Graph) -> Self {
        Self {
            values: graph.values().params().to_vec(),
            chi2: graph.chi2(),
        }
    }

    /// χ² at the start.
    pub fn chi2(&self) -> f64 {
        self.chi2
    }

    /// Puts the start back when the graph's χ² is now NaN, or above the
    /// start's where χ² is the objective (with DCS a lower χ² is not a
    /// better estimate); returns whether it did.
    pub fn restore_if_better(&self, graph: &mut Graph) -> bool {
        let end = graph.chi2();
        let worse = end.is_nan() || (end > self.chi2 && graph.chi2_is_objective());
        if worse {
            graph
                .values_mut()
                .params_mut()
                .copy_from_slice(&self.values);
        }
        worse
    }
}

/// Initialises as `init` says and optimises. Returns the summary of the run
/// whose estimate the graph now holds, and which start that was.
pub fn optimize_from(
    graph: &mut Graph,
    config: SolverConfig,
    init: Initialization,
    on_iteration: &mut dyn FnMut(Initialization, &IterationStats),
) -> Result<(Summary, Initialization), SolveError> {
    let algorithm = config.algorithm;
    let mut starts = Starts {
        optimizer: Optimizer::new(graph, config)?,
        config,
        on_iteration,
    };
    match init {
        Initialization::File => {}
        Initialization::SpanningTree => spanning_tree_initialize(graph),
        Initialization::Chordal => {
            chordal_initialize(graph)?;
        }
        Initialization::ChordalIsotropic => {
            chordal_initialize_with(graph, ChordalWeights::Isotropic)?;
        }
        Initialization::Auto => return optimize_from_best_start(graph, &mut starts),
    }
    let summary = starts.run(graph, init, algorithm)?;
    Ok((summary, init))
}

/// [`Initialization::Auto`]: the file's values first, then both chordal
/// starts; the graph ends with the estimate of the lowest final χ².
fn optimize_from_best_start(
    graph: &mut Graph,
    starts: &mut Starts<'_>,
) -> Result<(Summary, Initialization), SolveError> {
    let initial = graph.values().params().to_vec();
    let summary = starts.run(graph, Initialization::File, starts.config.algorithm)?;
    let mut best = Best {
        summary,
        start: Initialization::File,
        estimate: graph.values().params().to_vec(),
    };
    // A failure from a chordal start only rules that start out.
    for (start, weights) in [
        (Initialization::Chordal, ChordalWeights::Information),
        (Initialization::ChordalIsotropic, ChordalWeights::Isotropic),
    ] {
        graph.values_mut().params_mut().copy_from_slice(&initial);
        if chordal_initialize_with(graph, weights).is_ok() {
            let _ = starts.run_guarded(graph, start, &mut best);
        }
    }
    graph
        .values_mut()
        .params_mut()
        .copy_from_slice(&best.estimate);
    Ok((best.summary, best.start))
}
