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

/// `PositiveDefinite` holds exactly the matrices `check_information`
/// accepts, and refuses the others with the same issue.
#[test]
fn positive_definite_holds_what_the_check_accepts() {
    use cairn_core::information::check_information;
    use cairn_core::{InformationIssue, PositiveDefinite};
    let (mut accepted, mut refused) = (0, 0);
    for k in 0..600 {
        let t = k as f64 * 0.37;
        // Diagonal entries from −1 to 3 and couplings up to 1.5: some
        // positive definite, some indefinite.
        let mut m = Matrix3::new(
            1.0 + 2.0 * t.sin(),
            (1.3 * t).cos(),
            0.5 * (0.7 * t).sin(),
            0.0,
            1.0 + 2.0 * (1.1 * t).cos(),
            (2.3 * t).sin(),
            0.0,
            0.0,
            1.0 + 2.0 * (0.9 * t).sin(),
        );
        m.fill_lower_triangle_with_upper_triangle();
        match k % 10 {
            0 => m[(0, 1)] += 0.5,
            1 => m[(2, 2)] = f64::NAN,
            _ => {}
        }
        match (check_information(&m), PositiveDefinite::new(m)) {
            (Ok(()), Ok(checked)) => {
                assert_eq!(checked.matrix(), &m);
                accepted += 1;
            }
            (Err(issue), Err(same)) => {
                assert_eq!(issue, same);
                refused += 1;
                if k % 10 == 0 {
                    assert_eq!(issue, InformationIssue::Asymmetric);
                }
            }
            (check, new) => panic!("{m}: {check:?} against {:?}", new.map(|_| ())),
        }
    }
    assert!(accepted > 100 && refused > 200, "{accepted} {refused}");
}

/// An edge with checked information is refused for the same reasons as
/// any other (unknown vertex, wrong type, self-loop), and added alike.
#[test]
fn checked_edges_are_added_as_edges_are() {
    use cairn_core::{EdgeSE2XY, GraphError, PositiveDefinite};
    use nalgebra::{Matrix2, Vector2};
    let mut g = Graph::new();
    g.add_vertex(0, SE2::new(0.0, 0.0, 0.0)).unwrap();
    g.add_vertex(1, SE2::new(1.0, 0.2, 0.3)).unwrap();
    g.add_vertex(2, Vector2::new(2.0, 1.0)).unwrap();
    let z = SE2::new(0.9, 0.1, 0.25);
    let info = PositiveDefinite::new(Matrix3::identity()).unwrap();
    let refused = |e: Result<usize, GraphError>| e.map_err(|e| e.to_string()).unwrap_err();
    assert_eq!(
        refused(g.add_checked_edge(0, 9, EdgeSE2::new(z), info)),
        refused(g.add_edge(0, 9, EdgeSE2::new(z), Matrix3::identity()))
    );
    assert_eq!(
        refused(g.add_checked_edge(0, 2, EdgeSE2::new(z), info)),
        refused(g.add_edge(0, 2, EdgeSE2::new(z), Matrix3::identity()))
    );
    assert_eq!(
        refused(g.add_checked_edge(1, 1, EdgeSE2::new(z), info)),
        refused(g.add_edge(1, 1, EdgeSE2::new(z), Matrix3::identity()))
    );
    assert_eq!(g.num_edges(), 0);
    let point = PositiveDefinite::new(Matrix2::new(2.0, 0.1, 0.1, 3.0)).unwrap();
    assert_eq!(g.add_checked_edge(0, 1, EdgeSE2::new(z), info), Ok(0));
    assert_eq!(
        g.add_checked_edge(1, 2, EdgeSE2XY::new(Vector2::new(1.0, 0.5)), point),
        Ok(1)
    );
    // The same graph built with unchecked matrices has the same χ².
    let mut same = Graph::new();
    same.add_vertex(0, SE2::new(0.0, 0.0, 0.0)).unwrap();
    same.add_vertex(1, SE2::new(1.0, 0.2, 0.3)).unwrap();
    same.add_vertex(2, Vector2::new(2.0, 1.0)).unwrap();
    same.add_edge(0, 1, EdgeSE2::new(z), Matrix3::identity())
        .unwrap();
    same.add_edge(
        1,
        2,
        EdgeSE2XY::new(Vector2::new(1.0, 0.5)),
        Matrix2::new(2.0, 0.1, 0.1, 3.0),
    )
    .unwrap();
    assert!(g.chi2() > 0.0);
    assert_eq!(g.chi2().to_bits(), same.chi2().to_bits());
}

/// A prior with checked information is refused for the same reasons as any
/// other (unknown vertex, wrong type), and added alike.
#[test]
fn checked_priors_are_added_as_priors_are() {
    use cairn_core::{EdgePriorSE2, GraphError, PositiveDefinite};
    use nalgebra::Vector2;
    let build = || {
        let mut g = Graph::new();
        g.add_vertex(0, SE2::new(0.5, -0.2, 0.1)).unwrap();
        g.add_vertex(1, Vector2::new(2.0, 1.0)).unwrap();
        g
    };
    let prior = EdgePriorSE2::new(SE2::new(0.0, 0.0, 0.0));
    let info = Matrix3::new(4.0, 0.5, 0.0, 0.5, 3.0, 0.1, 0.0, 0.1, 9.0);
    let checked = PositiveDefinite::new(info).unwrap();
    let refused = |e: Result<usize, GraphError>| e.map_err(|e| e.to_string()).unwrap_err();
    let (mut g, mut same) = (build(), build());
    for id in [9, 1] {
        assert_eq!(
            refused(g.add_checked_unary_edge(id, prior.clone(), checked)),
            refused(same.add_unary_edge(id, prior.clone(), info))
        );
    }
    assert_eq!(g.add_checked_unary_edge(0, prior.clone(), checked), Ok(0));
    assert_eq!(same.add_unary_edge(0, prior, info), Ok(0));
    assert!(g.chi2() > 0.0);
    assert_eq!(g.chi2().to_bits(), same.chi2().to_bits());
}
