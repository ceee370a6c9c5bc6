//! Choosing the starting point: the file's values, a spanning tree, the chordal
//! relaxation, or (by default) whichever of the file's values and the chordal
//! start ends at the lower χ².

use crate::chordal::chordal_initialize;
use crate::config::{IterationStats, SolverConfig, Summary};
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
    /// Chordal relaxation of the rotations, then linear positions.
    Chordal,
    /// Solve from [`Initialization::File`] and from [`Initialization::Chordal`];
    /// keep the lower final χ².
    #[default]
    Auto,
}

/// Sets the free vertices' values by breadth-first spanning tree from the fixed
/// and gauge vertices.
pub fn spanning_tree_initialize(graph: &mut Graph) {
    let mut unknown: Vec<bool> = (0..graph.num_vertices())
        .map(|v| !graph.is_fixed(v))
        .collect();
    for v in graph.gauge_vertices() {
        unknown[v] = false;
    }
    graph.initialize_spanning_tree(&unknown);
}

/// Initialises as `init` says and optimises. Returns the summary of the run
/// whose estimate the graph now holds, and which start that was.
pub fn optimize_from(
    graph: &mut Graph,
    config: SolverConfig,
    init: Initialization,
    on_iteration: &mut dyn FnMut(Initialization, &IterationStats),
) -> Result<(Summary, Initialization), SolveError> {
    let mut optimizer = Optimizer::new(graph, config)?;
    let mut run = |graph: &mut Graph, start: Initialization| {
        optimizer
            .optimize_with(graph, &mut |s| on_iteration(start, s))
            .map(|s| (s, start))
    };
    match init {
        Initialization::File => run(graph, Initialization::File),
        Initialization::SpanningTree => {
            spanning_tree_initialize(graph);
            run(graph, Initialization::SpanningTree)
        }
        Initialization::Chordal => {
            chordal_initialize(graph)?;
            run(graph, Initialization::Chordal)
        }
        Initialization::Auto => {
            let initial = graph.values().params().to_vec();
            let from_file = run(graph, Initialization::File)?;
            let file_estimate = graph.values().params().to_vec();
            graph.values_mut().params_mut().copy_from_slice(&initial);
            let from_chordal =
                chordal_initialize(graph).and_then(|_| run(graph, Initialization::Chordal));
            match from_chordal {
                Ok(chordal) if chordal.0.final_chi2 <= from_file.0.final_chi2 => Ok(chordal),
                _ => {
                    graph
                        .values_mut()
                        .params_mut()
                        .copy_from_slice(&file_estimate);
                    Ok(from_file)
                }
            }
        }
    }
}
