//! Define an edge type of your own — a range measurement from a pose to a 2D
//! point — by its error alone: its dimensions come from the variable types,
//! and Cairn differentiates it numerically. Registered with a tag, it is
//! written to g2o text and read back.
//!
//! `cargo run --release --example custom_edge`

use cairn::core::{Graph, NumericBinaryEdge, SE2};
use cairn::g2o::{G2oMeasurement, ReadOptions, Registry};
use cairn::solvers::{Algorithm, SolverConfig, optimize};
use nalgebra::{Matrix1, Vector1, Vector2};

/// The measured distance between a pose's position and a point.
#[derive(Clone, Debug)]
struct Range(f64);

impl NumericBinaryEdge<1> for Range {
    type V1 = SE2;
    type V2 = Vector2<f64>;
    const NAME: &'static str = "RANGE";

    fn error(&self, pose: &SE2, point: &Vector2<f64>) -> Vector1<f64> {
        Vector1::new((point - pose.t).norm() - self.0)
    }
}

/// How a range is written in g2o text: one number.
impl G2oMeasurement for Range {
    const LEN: usize = 1;
    fn write_measurement(&self, out: &mut [f64]) {
        out[0] = self.0;
    }
    fn read_measurement(numbers: &[f64]) -> Result<Self, String> {
        match numbers[0] {
            r if r >= 0.0 => Ok(Range(r)),
            r => Err(format!("a range of {r} m is negative")),
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let beacon = Vector2::new(3.0, 4.0);
    let mut graph = Graph::new();
    graph.add_vertex(100, Vector2::new(5.0, 5.0))?; // initial guess for the beacon
    // Four surveyed stations (fixed) range it with 1 cm noise.
    let information = Matrix1::new(1.0 / 0.01f64.powi(2));
    for (id, (x, y)) in [(0.0, 0.0), (10.0, 0.0), (0.0, 10.0), (10.0, 10.0)]
        .into_iter()
        .enumerate()
    {
        let id = id as i64;
        graph.add_vertex(id, SE2::new(x, y, 0.0))?;
        graph.set_fixed(id, true)?;
        let range = (beacon - Vector2::new(x, y)).norm();
        graph.add_edge(id, 100, Range(range), information)?;
    }
    let config = SolverConfig {
        algorithm: Algorithm::LevenbergMarquardt,
        ..Default::default()
    };
    let summary = optimize(&mut graph, config)?;
    let found: Vector2<f64> = graph.value(100)?;
    println!(
        "{:?} after {} iterations: beacon at ({:.6}, {:.6})",
        summary.termination, summary.iterations, found.x, found.y
    );
    assert!((found - beacon).norm() < 1e-6);

    // Written as g2o text under a tag of our choosing, and read back.
    let mut registry = Registry::new();
    registry.binary_edge::<Range, _, _, _>("EDGE_RANGE_XY")?;
    let text = cairn::g2o::to_string_with(&graph, &registry)?;
    print!(
        "{}",
        text.lines().find(|l| l.starts_with("EDGE")).unwrap_or("")
    );
    println!("  (one of {} ranges)", graph.num_edges());
    let options = ReadOptions {
        registry,
        ..Default::default()
    };
    let (again, _) = cairn::g2o::read_bytes(text.as_bytes(), &options)?;
    assert_eq!(again.chi2(), graph.chi2());
    Ok(())
}
