//! Users define their own variable and edge types outside Cairn's crates,
//! solve them like the built-in ones, and read and write them as g2o text.

use approx::assert_relative_eq;
use cairn::core::edge::numeric_binary;
use cairn::core::{BinaryEdge, Graph, NumericBinaryEdge, NumericUnaryEdge, SE2, Variable};
use cairn::g2o::{G2oError, G2oMeasurement, LineError, ReadOptions, Registry, RegistryError};
use cairn::solvers::{Algorithm, SolverConfig, Termination, optimize};
use nalgebra::{Matrix1, SMatrix, SVector, Vector1, Vector2};

/// A scalar state, e.g. a clock offset.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Offset(f64);

impl Variable<1> for Offset {
    const PARAMS: usize = 1;
    const NAME: &'static str = "OFFSET";
    fn from_params(p: &[f64]) -> Self {
        Offset(p[0])
    }
    fn write_params(&self, out: &mut [f64]) {
        out[0] = self.0;
    }
    fn oplus(&self, d: &SVector<f64, 1>) -> Self {
        Offset(self.0 + d[0])
    }
}

/// Measured difference b − a of two offsets, with analytic Jacobians (whose
/// sizes state the dimensions).
#[derive(Clone, Debug)]
struct Difference(f64);

impl BinaryEdge<1, 1, 1> for Difference {
    type V1 = Offset;
    type V2 = Offset;
    const NAME: &'static str = "DIFFERENCE";
    fn error(&self, a: &Offset, b: &Offset) -> Vector1<f64> {
        Vector1::new(b.0 - a.0 - self.0)
    }
    fn jacobians(&self, _: &Offset, _: &Offset) -> (Matrix1<f64>, Matrix1<f64>) {
        (Matrix1::new(-1.0), Matrix1::new(1.0))
    }
}

/// A prior on an offset: the error alone, the dimension from `Offset`.
#[derive(Clone, Debug)]
struct OffsetPrior(f64);

impl NumericUnaryEdge<1> for OffsetPrior {
    type V = Offset;
    const NAME: &'static str = "OFFSET_PRIOR";
    fn error(&self, x: &Offset) -> Vector1<f64> {
        Vector1::new(x.0 - self.0)
    }
}

/// Range from a pose to a point: one number for two unknowns, mixing built-in
/// variable types with a user edge; the dimensions come from SE2 and the point.
#[derive(Clone, Debug)]
struct Range(f64);

impl NumericBinaryEdge<1> for Range {
    type V1 = SE2;
    type V2 = Vector2<f64>;
    const NAME: &'static str = "RANGE";
    fn error(&self, x: &SE2, l: &Vector2<f64>) -> Vector1<f64> {
        Vector1::new((l - x.t).norm() - self.0)
    }
}

impl G2oMeasurement for Difference {
    const LEN: usize = 1;
    fn write_measurement(&self, out: &mut [f64]) {
        out[0] = self.0;
    }
    fn read_measurement(numbers: &[f64]) -> Result<Self, String> {
        Ok(Difference(numbers[0]))
    }
}

impl G2oMeasurement for OffsetPrior {
    const LEN: usize = 1;
    fn write_measurement(&self, out: &mut [f64]) {
        out[0] = self.0;
    }
    fn read_measurement(numbers: &[f64]) -> Result<Self, String> {
        Ok(OffsetPrior(numbers[0]))
    }
}

impl G2oMeasurement for Range {
    const LEN: usize = 1;
    fn write_measurement(&self, out: &mut [f64]) {
        out[0] = self.0;
    }
    fn read_measurement(numbers: &[f64]) -> Result<Self, String> {
        match numbers[0] {
            r if r >= 0.0 => Ok(Range(r)),
            r => Err(format!("range {r} is negative")),
        }
    }
}

fn registry() -> Registry {
    let mut registry = Registry::new();
    registry
        .vertex::<Offset, 1>("VERTEX_OFFSET")
        .and_then(|r| r.binary_edge::<Difference, 1, 1, 1>("EDGE_OFFSET_DIFFERENCE"))
        .and_then(|r| r.unary_edge::<OffsetPrior, _, _>("EDGE_OFFSET_PRIOR"))
        .and_then(|r| r.binary_edge::<Range, _, _, _>("EDGE_RANGE_XY"))
        .unwrap();
    registry
}

#[test]
fn a_chain_of_user_variables_solves_exactly() {
    let mut g = Graph::new();
    for i in 0..5 {
        g.add_vertex(i, Offset(0.0)).unwrap();
    }
    g.add_unary_edge(0, OffsetPrior(1.0), Matrix1::new(1.0))
        .unwrap();
    for i in 0..4 {
        g.add_edge(i, i + 1, Difference(0.5), Matrix1::new(4.0))
            .unwrap();
    }
    let s = optimize(&mut g, SolverConfig::default()).unwrap();
    assert!(s.gauge.is_empty(), "the prior fixes the gauge");
    assert!(s.termination.converged(), "{:?}", s.termination);
    for i in 0..5 {
        assert_relative_eq!(
            g.value::<Offset, 1>(i).unwrap().0,
            1.0 + 0.5 * i as f64,
            epsilon = 1e-8
        );
    }
}

#[test]
fn numeric_jacobians_are_the_default() {
    let e = Range(5.0);
    let (x, l) = (SE2::new(1.0, 2.0, 0.3), Vector2::new(4.0, 6.0));
    let (jx, jl) = e.jacobians(&x, &l);
    let (nx, nl) = numeric_binary(&e, &x, &l);
    assert_eq!((jx, jl), (nx, nl));
    // d|l − t|/dl is the unit direction (0.6, 0.8).
    assert_relative_eq!(jl, SMatrix::<f64, 1, 2>::new(0.6, 0.8), epsilon = 1e-8);
    assert_relative_eq!(jx[(0, 2)], 0.0, epsilon = 1e-12);
}

#[test]
fn user_edges_mix_with_built_in_types_and_trilaterate() {
    // Three known beacons (fixed poses) range a point: the point is found.
    let target = Vector2::new(2.0, 1.0);
    let mut g = Graph::new();
    let beacons = [(0, 0.0, 0.0), (1, 5.0, 0.0), (2, 0.0, 5.0)];
    for &(id, x, y) in &beacons {
        g.add_vertex(id, SE2::new(x, y, 0.0)).unwrap();
        g.set_fixed(id, true).unwrap();
    }
    g.add_vertex(10, Vector2::new(1.0, 2.0)).unwrap();
    for &(id, x, y) in &beacons {
        let r = (target - Vector2::new(x, y)).norm();
        g.add_edge(id, 10, Range(r), Matrix1::new(1.0)).unwrap();
    }
    let config = SolverConfig {
        algorithm: Algorithm::LevenbergMarquardt,
        ..Default::default()
    };
    let s = optimize(&mut g, config).unwrap();
    assert_ne!(s.termination, Termination::MaxIterations);
    let p: Vector2<f64> = g.value(10).unwrap();
    assert_relative_eq!(p, target, epsilon = 1e-6);
}

#[test]
fn type_mismatches_are_errors() {
    let mut g = Graph::new();
    g.add_vertex(0, Offset(0.0)).unwrap();
    g.add_vertex(1, SE2::identity()).unwrap();
    let err = g
        .add_edge(0, 1, Difference(1.0), Matrix1::new(1.0))
        .unwrap_err();
    assert!(
        err.to_string()
            .contains("vertex 1 is SE2, but DIFFERENCE needs OFFSET"),
        "{err}"
    );
    assert!(g.value::<SE2, 3>(0).is_err());
    // And a custom type cannot be written as g2o: there is no tag for it.
    g.add_vertex(2, Offset(1.0)).unwrap();
    assert!(
        cairn::g2o::to_string(&g)
            .unwrap_err()
            .to_string()
            .contains("OFFSET")
    );
}

/// A state of 20 numbers (a calibration vector, say): more parameters than
/// `Graph::add_vertex` checks on the stack.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Calibration([f64; 20]);

impl Variable<20> for Calibration {
    const PARAMS: usize = 20;
    const NAME: &'static str = "CALIBRATION";
    fn from_params(p: &[f64]) -> Self {
        Calibration(std::array::from_fn(|k| p[k]))
    }
    fn write_params(&self, out: &mut [f64]) {
        out.copy_from_slice(&self.0);
    }
    fn oplus(&self, d: &SVector<f64, 20>) -> Self {
        Calibration(std::array::from_fn(|k| self.0[k] + d[k]))
    }
}

#[test]
fn variables_with_many_parameters_are_kept_and_checked() {
    let mut g = Graph::new();
    let c = Calibration(std::array::from_fn(|k| k as f64 * 0.5 - 3.0));
    g.add_vertex(7, c).unwrap();
    assert_eq!(g.value::<Calibration, 20>(7).unwrap(), c);
    let mut bad = c;
    bad.0[19] = f64::NAN;
    assert_eq!(
        g.add_vertex(8, bad),
        Err(cairn::core::GraphError::NonFiniteValue(8))
    );
    assert_eq!(g.num_vertices(), 1);
}

/// A graph of user types and built-in ones, written with a registry and
/// read back: the same vertices, values and χ².
#[test]
fn registered_types_round_trip_through_g2o_text() {
    let mut g = Graph::new();
    g.add_vertex(0, Offset(0.25)).unwrap();
    g.add_vertex(1, Offset(-1.5)).unwrap();
    g.add_vertex(2, SE2::new(1.0, 2.0, 0.3)).unwrap();
    g.add_vertex(3, Vector2::new(4.0, 6.5)).unwrap();
    g.set_fixed(2, true).unwrap();
    g.add_unary_edge(0, OffsetPrior(0.1), Matrix1::new(4.0))
        .unwrap();
    g.add_edge(0, 1, Difference(-1.7), Matrix1::new(2.0))
        .unwrap();
    g.add_edge(2, 3, Range(5.1), Matrix1::new(9.0)).unwrap();
    let registry = registry();
    let text = cairn::g2o::to_string_with(&g, &registry).unwrap();
    for line in [
        "VERTEX_OFFSET 1 -1.5",
        "EDGE_OFFSET_PRIOR 0 0.1 4.0",
        "EDGE_OFFSET_DIFFERENCE 0 1 -1.7 2.0",
        "EDGE_RANGE_XY 2 3 5.1 9.0",
    ] {
        assert!(text.lines().any(|l| l == line), "{line} not in\n{text}");
    }
    let options = ReadOptions {
        registry,
        ..Default::default()
    };
    let (again, report) = cairn::g2o::read_bytes(text.as_bytes(), &options).unwrap();
    assert_eq!(report.unknown_lines(), 0);
    assert_eq!((again.num_vertices(), again.num_edges()), (4, 3));
    assert_eq!(again.values(), g.values());
    assert!(again.is_fixed(2).unwrap());
    assert_eq!(again.chi2().to_bits(), g.chi2().to_bits());
    // Without the registry the user types are neither written nor read.
    assert!(matches!(
        cairn::g2o::to_string(&g),
        Err(G2oError::Unwritable(_))
    ));
    let (plain, report) = cairn::g2o::read_bytes(text.as_bytes(), &Default::default()).unwrap();
    assert_eq!(report.unknown_lines(), 5);
    assert_eq!(plain.num_vertices(), 2);
}

#[test]
fn registered_records_are_checked_like_built_in_ones() {
    let options = ReadOptions {
        registry: registry(),
        ..Default::default()
    };
    let read = |text: &str| cairn::g2o::read_bytes(text.as_bytes(), &options).map(|_| ());
    let pose = "VERTEX_SE2 0 0 0 0\nVERTEX_XY 1 3 4\n";
    let line_error = |text: &str| match read(text) {
        Err(G2oError::Line { line, error }) => (line, error),
        other => panic!("{other:?}"),
    };
    let (line, error) = line_error(&format!("{pose}EDGE_RANGE_XY 0 1 -2 1\n"));
    assert_eq!(line, 3);
    assert_eq!(
        error,
        LineError::BadMeasurement {
            tag: "EDGE_RANGE_XY".into(),
            message: "range -2 is negative".into()
        }
    );
    let (line, error) = line_error(&format!("{pose}EDGE_RANGE_XY 0 1 5\n"));
    assert_eq!(line, 3);
    assert!(matches!(
        error,
        LineError::MissingFields {
            expected: 4,
            found: 3,
            ..
        }
    ));
    let (_, error) = line_error(&format!("{pose}EDGE_RANGE_XY 0 1 5 nan\n"));
    assert!(matches!(error, LineError::NonFinite { field: 4, .. }));
    // A range between two offsets: the types do not fit.
    let (_, error) = line_error("VERTEX_OFFSET 0 1\nVERTEX_OFFSET 1 2\nEDGE_RANGE_XY 0 1 5 1\n");
    assert!(matches!(error, LineError::Graph(_)), "{error:?}");
    assert!(matches!(
        read(&format!("{pose}EDGE_RANGE_XY 0 1 5 -1\n")),
        Err(G2oError::IndefiniteInformation { .. })
    ));
}

#[test]
fn a_tag_or_type_is_registered_once() {
    let mut r = registry();
    assert_eq!(
        r.vertex::<Offset, 1>("VERTEX_SE2").unwrap_err(),
        RegistryError::BuiltIn("VERTEX_SE2".into())
    );
    assert_eq!(
        r.binary_edge::<Range, 1, 3, 2>("EDGE_OFFSET_DIFFERENCE")
            .unwrap_err(),
        RegistryError::TagTaken("EDGE_OFFSET_DIFFERENCE".into())
    );
    assert!(matches!(
        r.binary_edge::<Range, 1, 3, 2>("EDGE_RANGE_2").unwrap_err(),
        RegistryError::TypeTaken {
            tag: "EDGE_RANGE_XY",
            ..
        }
    ));
    for bad in ["", "EDGE RANGE", "#EDGE", "EDGE_É"] {
        assert_eq!(
            r.vertex::<Calibration, 20>(bad).unwrap_err(),
            RegistryError::BadTag(bad.into())
        );
    }
    assert!(r.vertex::<Calibration, 20>("VERTEX_CALIBRATION").is_ok());
}
