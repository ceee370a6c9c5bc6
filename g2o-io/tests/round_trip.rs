//! read → write → read is exact for every record type.

use cairn_g2o::{ReadOptions, read_bytes, to_string};

/// Reads `text`, writes it, reads that, writes again: the two writes must be
/// identical and the values bit-for-bit equal.
fn round_trip(text: &str) -> String {
    let opts = ReadOptions::default();
    let (a, _) = read_bytes(text.as_bytes(), &opts).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let first = to_string(&a).unwrap();
    let (b, _) = read_bytes(first.as_bytes(), &opts).unwrap();
    let second = to_string(&b).unwrap();
    assert_eq!(first, second);
    assert_eq!(a.values().params(), b.values().params());
    assert_eq!(a.num_edges(), b.num_edges());
    for (ea, eb) in a.edges().zip(b.edges()) {
        assert_eq!(ea.information(), eb.information());
        assert_eq!(ea.chi2(a.values()).to_bits(), eb.chi2(b.values()).to_bits());
    }
    first
}

#[test]
fn vertex_se2() {
    let out = round_trip("VERTEX_SE2 7 1.2345678901234567 -9.87654321e-12 3.141592653589793\n");
    assert_eq!(
        out,
        "VERTEX_SE2 7 1.2345678901234567 -9.87654321e-12 3.141592653589793\n"
    );
}

#[test]
fn vertex_xy() {
    round_trip("VERTEX_XY -3 1e300 -2.5e-310\n");
}

#[test]
fn vertex_se3_quat() {
    // A quaternion printed with few digits is normalised once; after that the
    // round trip is exact.
    round_trip("VERTEX_SE3:QUAT 0 1 2 3 0.1 0.2 0.3 0.927\n");
    round_trip("VERTEX_SE3:QUAT 0 1 2 3 0 0 0 1\n");
}

#[test]
fn edge_se2_and_fix() {
    let out = round_trip(
        "VERTEX_SE2 0 0 0 0\nFIX 0\nVERTEX_SE2 1 1 0 0.1\n\
         EDGE_SE2 0 1 1.1 -0.2 0.05 500 6.95335e-310 1 500 2 1000\n",
    );
    assert!(out.contains("FIX 0\n"));
    assert!(out.contains("6.95335e-310"), "{out}");
}

#[test]
fn edge_se2_xy() {
    round_trip("VERTEX_SE2 0 0 0 0\nVERTEX_XY 1 3 4\nEDGE_SE2_XY 0 1 2.9 4.1 100 0.5 80\n");
}

#[test]
fn edge_prior_se2() {
    round_trip("VERTEX_SE2 0 0.1 0.2 0.3\nEDGE_PRIOR_SE2 0 0 0 0 10 0 0 10 0 100\n");
}

#[test]
fn edge_se3_quat() {
    let info = "10000 1 1 1 1 1 10000 2 2 2 2 10000 3 3 3 10000 4 4 10000 5 10000";
    round_trip(&format!(
        "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1.001367 0.015390 0.004948 0.190253 0.283162 -0.392318 0.854230\n\
         EDGE_SE3:QUAT 0 1 1.001367 0.015390 0.004948 0.190253 0.283162 -0.392318 0.854230 {info}\n"
    ));
}

#[test]
fn landmark2_becomes_vertex_xy_and_edge_se2_xy() {
    let text = "EDGE_SE2 0 1 1 0 0 100 0 0 100 0 1000\nLANDMARK2 0 0 2 1 10 0 10\nLANDMARK2 1 0 1 1 10 0 10\n";
    let out = round_trip(text);
    // Landmark 0 lives in its own id space: it becomes vertex max(pose id) + 1 = 2.
    assert!(out.contains("VERTEX_XY 2 2.0 1.0\n"), "{out}");
    assert!(
        out.contains("EDGE_SE2_XY 0 2 2.0 1.0 10.0 0.0 10.0\n"),
        "{out}"
    );
    assert!(out.contains("EDGE_SE2_XY 1 2 1.0 1.0"), "{out}");
}

#[test]
fn comments_blank_lines_tabs_and_crlf() {
    let text = "# a comment\r\n\r\nVERTEX_SE2\t0   0 0 0\r\n   # indented comment\nVERTEX_SE2 1 1 0 0\r\n\
                EDGE_SE2 0 1  1 0 0   1 0 0 1 0 1   \r\n";
    let (g, r) = read_bytes(text.as_bytes(), &ReadOptions::default()).unwrap();
    assert_eq!((g.num_vertices(), g.num_edges(), r.lines), (2, 1, 6));
    round_trip(text);
}

/// The last line counts with or without a final newline, and every record
/// is counted under its tag.
#[test]
fn last_line_without_a_newline_and_record_counts() {
    let text = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1";
    for text in [text.to_string(), format!("{text}\n")] {
        let (g, r) = read_bytes(text.as_bytes(), &ReadOptions::default()).unwrap();
        assert_eq!((g.num_vertices(), g.num_edges(), r.lines), (2, 1, 4));
        let counts: Vec<(&str, usize)> = r.records.iter().map(|(k, &v)| (k.as_str(), v)).collect();
        assert_eq!(counts, [("EDGE_SE2", 1), ("VERTEX_SE2", 2)]);
    }
}

/// A file takes its vertices from its edges only if no line starts (after
/// blanks) with a VERTEX_ tag: VERTEX_ in a comment or inside another
/// word does not count, an indented VERTEX_ line does.
#[test]
fn vertices_from_edges_only_without_vertex_lines() {
    let edge = "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n";
    for prefix in ["", "# VERTEX_SE2 5 0 0 0\n", "PARAMS_VERTEX_X 1\n"] {
        let text = format!("{prefix}{edge}");
        let (g, _) = read_bytes(text.as_bytes(), &ReadOptions::default()).unwrap();
        assert_eq!(g.num_vertices(), 2, "{text:?}");
    }
    let text = format!(" \tVERTEX_SE2 0 0 0 0\n{edge}");
    assert!(read_bytes(text.as_bytes(), &ReadOptions::default()).is_err());
}

proptest::proptest! {
    /// Every finite `f64` is written in a form that reads back to the same
    /// bits, whatever its exponent (subnormals, ±0, 1e±300, 1e16, 1e-5).
    #[test]
    fn numbers_read_back_to_the_same_bits(bits in proptest::collection::vec(proptest::num::u64::ANY, 2..40)) {
        let values: Vec<f64> = bits
            .iter()
            .map(|&b| f64::from_bits(b))
            .filter(|v| v.is_finite())
            .chain([1e16, -1e-5, 1.5e-5, -0.0, 5e-324, 123456789012345680.0])
            .collect();
        let text: String = values
            .chunks(2)
            .enumerate()
            .filter(|(_, xy)| xy.len() == 2)
            .map(|(k, xy)| format!("VERTEX_XY {k} {:e} {:e}\n", xy[0], xy[1]))
            .collect();
        let (graph, _) = read_bytes(text.as_bytes(), &ReadOptions::default()).unwrap();
        let written = to_string(&graph).unwrap();
        let (again, _) = read_bytes(written.as_bytes(), &ReadOptions::default()).unwrap();
        let bits_of = |g: &cairn_core::Graph| -> Vec<u64> {
            g.values().params().iter().map(|v| v.to_bits()).collect()
        };
        proptest::prop_assert_eq!(bits_of(&graph), bits_of(&again));
        proptest::prop_assert_eq!(bits_of(&graph).len(), 2 * (values.len() / 2));
    }
}
