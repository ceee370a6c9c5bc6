//! Information matrices are kept as given, while the solver computes with
//! subnormal entries flushed to zero (they change no digit of χ²).

use cairn_core::{EdgeSE2, Graph, SE2};
use nalgebra::Matrix3;

#[test]
fn subnormal_information_is_kept_as_given_and_computed_as_zero() {
    let tiny = 6.95335e-310;
    assert!(f64::is_subnormal(tiny));
    let given = Matrix3::new(44.4, 1.1, tiny, 1.1, 376.0, 0.0, tiny, 0.0, 9807.7);
    let flushed = given.map(|w| if w.is_subnormal() { 0.0 } else { w });
    let build = |information: Matrix3<f64>| {
        let mut g = Graph::new();
        g.add_vertex(0, SE2::new(0.0, 0.0, 0.0)).unwrap();
        g.add_vertex(1, SE2::new(1.0, 0.2, 0.3)).unwrap();
        g.add_edge(0, 1, EdgeSE2::new(SE2::new(0.9, 0.1, 0.25)), information)
            .unwrap();
        g
    };
    let (with_tiny, with_zero) = (build(given), build(flushed));
    let edge = with_tiny.edges().next().unwrap();
    let bits = |m: &[f64]| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(edge.information()), bits(given.as_slice()));
    assert!(with_tiny.chi2() > 0.0);
    assert_eq!(with_tiny.chi2().to_bits(), with_zero.chi2().to_bits());
}
