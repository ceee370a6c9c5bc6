//! Every kind of bad input gets a typed error naming its line, or a documented,
//! reported recovery. Nothing panics.

use cairn_core::{GraphError, InformationIssue};
use cairn_g2o::{G2oError, LineError, ReadOptions, read_bytes};

fn error_of(text: &str) -> G2oError {
    match read_bytes(text.as_bytes(), &ReadOptions::default()) {
        Ok(_) => panic!("accepted bad input:\n{text}"),
        Err(e) => e,
    }
}

fn line_error(text: &str) -> (usize, LineError) {
    match error_of(text) {
        G2oError::Line { line, error } => (line, error),
        other => panic!("expected a line error, got {other}"),
    }
}

const TWO: &str = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n";

#[test]
fn malformed_number() {
    let (line, e) = line_error("VERTEX_SE2 0 1.0 abc 0\n");
    assert_eq!(line, 1);
    assert_eq!(
        e,
        LineError::BadNumber {
            field: 3,
            text: "abc".into()
        }
    );
    assert!(
        error_of("VERTEX_SE2 0 1.0 abc 0\n")
            .to_string()
            .starts_with("line 1: field 3 (\"abc\")")
    );
}

#[test]
fn missing_numbers() {
    let (line, e) = line_error(&format!("{TWO}EDGE_SE2 0 1 1 0\n"));
    assert_eq!(line, 3);
    assert_eq!(
        e,
        LineError::MissingFields {
            tag: "EDGE_SE2".into(),
            expected: 11,
            found: 4
        }
    );
}

#[test]
fn nan_and_infinity() {
    for bad in ["nan", "NaN", "inf", "-inf", "1e999"] {
        let (line, e) = line_error(&format!("VERTEX_SE2 0 {bad} 0 0\n"));
        assert_eq!(line, 1);
        assert!(
            matches!(e, LineError::NonFinite { field: 2, .. }),
            "{bad}: {e}"
        );
    }
    let (line, e) = line_error(&format!("{TWO}EDGE_SE2 0 1 1 0 0 1 0 0 nan 0 1\n"));
    assert_eq!(
        (line, matches!(e, LineError::NonFinite { field: 9, .. })),
        (3, true)
    );
}

#[test]
fn bad_vertex_id() {
    let (_, e) = line_error("VERTEX_SE2 1.5 0 0 0\n");
    assert_eq!(
        e,
        LineError::BadId {
            field: 1,
            text: "1.5".into()
        }
    );
}

#[test]
fn edge_naming_an_unknown_vertex() {
    let (line, e) = line_error(&format!("{TWO}EDGE_SE2 0 7 1 0 0 1 0 0 1 0 1\n"));
    assert_eq!(
        (line, e),
        (3, LineError::Graph(GraphError::UnknownVertex(7)))
    );
}

#[test]
fn duplicate_vertex_id() {
    let (line, e) = line_error("VERTEX_SE2 0 0 0 0\nVERTEX_XY 0 1 1\n");
    assert_eq!(
        (line, e),
        (2, LineError::Graph(GraphError::DuplicateVertex(0)))
    );
}

#[test]
fn wrong_vertex_type() {
    let (line, e) =
        line_error("VERTEX_SE2 0 0 0 0\nVERTEX_XY 1 1 1\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n");
    assert_eq!(line, 3);
    assert!(
        matches!(
            e,
            LineError::Graph(GraphError::WrongVertexType {
                id: 1,
                actual: "XY",
                ..
            })
        ),
        "{e}"
    );
}

#[test]
fn self_loop() {
    let (_, e) = line_error("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 0 1 0 0 1 0 0 1 0 1\n");
    assert!(matches!(
        e,
        LineError::Graph(GraphError::SelfLoop { id: 0, .. })
    ));
}

#[test]
fn zero_quaternion() {
    let (_, e) = line_error("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 0\n");
    assert_eq!(e, LineError::ZeroQuaternion);
}

#[test]
fn fix_of_an_unknown_vertex() {
    let (line, e) = line_error(&format!("FIX 9\n{TWO}"));
    assert_eq!(
        (line, e),
        (1, LineError::Graph(GraphError::UnknownVertex(9)))
    );
}

#[test]
fn empty_files() {
    for text in [
        "",
        "\n\n",
        "# only a comment\n",
        "PARAMS_SE2OFFSET 0 1 2 3\nsome junk\n",
    ] {
        assert!(matches!(error_of(text), G2oError::Empty), "{text:?}");
    }
}

#[test]
fn not_utf8() {
    let bytes = b"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 \xff\xfe 0 0\n";
    match read_bytes(bytes, &ReadOptions::default()) {
        Err(G2oError::Line {
            line: 2,
            error: LineError::NotUtf8,
        }) => {}
        other => panic!("{:?}", other.map(|_| ())),
    }
}

#[test]
fn indefinite_information_is_refused_then_repaired() {
    let text = format!("{TWO}EDGE_SE2 0 1 1 0 0 1 2 0 1 0 1\nEDGE_SE2 1 0 -1 0 0 1 0 0 1 0 -5\n");
    match error_of(&text) {
        G2oError::IndefiniteInformation { count, lines } => {
            assert_eq!((count, lines), (2, vec![3, 4]))
        }
        other => panic!("{other}"),
    }
    let msg = error_of(&text).to_string();
    assert!(
        msg.contains("2 edges")
            && msg.contains("lines 3, 4")
            && msg.contains("--repair-information"),
        "{msg}"
    );
    let (g, r) = read_bytes(
        text.as_bytes(),
        &ReadOptions {
            repair_information: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(
        (g.num_edges(), r.repaired_information.clone()),
        (2, vec![3, 4])
    );
    for e in g.edges() {
        let m = nalgebra::Matrix3::from_column_slice(e.information());
        assert!(
            m.symmetric_eigenvalues().min() > 0.0,
            "repaired matrix is positive definite"
        );
    }
}

#[test]
fn asymmetric_or_non_finite_information_cannot_be_built() {
    let info = nalgebra::Matrix2::new(1.0, 0.5, 0.0, 1.0);
    let issue = cairn_core::information::check_information(&info).unwrap_err();
    assert_eq!(issue, InformationIssue::Asymmetric);
}

#[test]
fn unknown_tags_and_extra_fields_are_counted_not_fatal() {
    let text = format!(
        "{TWO}PARAMS_SE2OFFSET 0 1 2 3\nVERTEX_TRACKXYZ 5 1 2 3\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1 99 98\n"
    );
    let (g, r) = read_bytes(text.as_bytes(), &ReadOptions::default()).unwrap();
    assert_eq!(g.num_edges(), 1);
    assert_eq!(r.unknown_lines(), 2);
    assert_eq!(r.extra_fields, 1);
}

#[test]
fn unknown_tags_are_counted_by_tag() {
    let text = format!("{TWO}VERTEX_TRACKXYZ 5 1 2 3\nPARAMS_X 1\nVERTEX_TRACKXYZ 6 1 2 3\n");
    let (_, r) = read_bytes(text.as_bytes(), &ReadOptions::default()).unwrap();
    let counts: Vec<(&str, usize)> = r.unknown.iter().map(|(k, &v)| (k.as_str(), v)).collect();
    assert_eq!(counts, [("PARAMS_X", 1), ("VERTEX_TRACKXYZ", 2)]);
    assert_eq!(r.unknown_lines(), 3);
}

/// Line endings of every platform read the same records, with the same line
/// numbers; a UTF-8 byte-order mark is not part of the first line.
#[test]
fn cr_crlf_lf_and_a_byte_order_mark_read_alike() {
    let good = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n";
    let bad = format!("{good}VERTEX_SE2 x 0 0 0\n");
    let kinds: [fn(&str) -> String; 4] = [
        |t| t.to_string(),
        |t| t.replace('\n', "\r\n"),
        |t| t.replace('\n', "\r"),
        |t| format!("\u{feff}{t}"),
    ];
    for kind in kinds {
        let text = kind(good);
        let (graph, _) = read_bytes(text.as_bytes(), &ReadOptions::default()).expect("reads");
        assert_eq!(
            (graph.num_vertices(), graph.num_edges()),
            (2, 1),
            "{text:?}"
        );
        let (line, e) = line_error(&kind(&bad));
        assert_eq!(line, 4, "{text:?}");
        assert!(matches!(e, LineError::BadId { .. }), "{e}");
    }
}

#[test]
fn a_non_ascii_space_is_named() {
    let (line, e) = line_error("VERTEX_SE2 0 0 0 0\nVERTEX_SE2\u{a0}1 1 0 0\n");
    assert_eq!((line, e), (2, LineError::NonAsciiSpace { code: 0xa0 }));
}

/// LANDMARK2 ids go after the highest vertex id: a negative one, or one
/// past i64::MAX, is refused instead of wrapping onto a pose.
#[test]
fn landmark_ids_that_do_not_fit_are_refused() {
    let (line, e) =
        line_error("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 2 0 0 0\nLANDMARK2 0 -2 1 0 1 0 1\n");
    assert_eq!(
        (line, e),
        (
            3,
            LineError::LandmarkIdOutOfRange {
                landmark: -2,
                highest: 2
            }
        )
    );
    let max = i64::MAX;
    let (line, e) = line_error(&format!(
        "VERTEX_SE2 {max} 0 0 0\nLANDMARK2 {max} 0 1 0 1 0 1\n"
    ));
    assert_eq!(
        (line, e),
        (
            2,
            LineError::LandmarkIdOutOfRange {
                landmark: 0,
                highest: max
            }
        )
    );
    let (line, _) = line_error(&format!(
        "VERTEX_SE2 5 0 0 0\nLANDMARK2 5 {max} 1 0 1 0 1\n"
    ));
    assert_eq!(line, 2);
}
