//! Property tests: random bytes and mutated lines never make the reader or the
//! writer panic. (The root package's `fuzz_real_files` also solves what they accept.)

use cairn_g2o::{ReadOptions, read_bytes};
use proptest::prelude::*;

const SEED: &str = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0.1\nVERTEX_XY 2 2 1\nFIX 0\n\
EDGE_SE2 0 1 1 0 0.1 100 0 0 100 0 1000\nEDGE_SE2_XY 1 2 1 1 10 0 10\nEDGE_PRIOR_SE2 1 1 0 0 1 0 0 1 0 1\n\
VERTEX_SE3:QUAT 3 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 4 1 0 0 0 0 0 1\n\
EDGE_SE3:QUAT 3 4 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";

const TOKENS: &[&str] = &[
    "0",
    "1",
    "-1",
    "1e308",
    "-1e-320",
    "nan",
    "inf",
    "x",
    "",
    "VERTEX_SE2",
    "EDGE_SE2",
    "FIX",
    "LANDMARK2",
    "EDGE_SE3:QUAT",
    "VERTEX_XY",
    "#",
    "99",
    "0.5",
    "\t",
    "\u{e9}",
];

fn accept_anything(bytes: &[u8]) {
    if let Ok((graph, _)) = read_bytes(
        bytes,
        &ReadOptions {
            repair_information: true,
            ..Default::default()
        },
    ) {
        let text = cairn_g2o::to_string(&graph).expect("built-in types are writable");
        read_bytes(text.as_bytes(), &ReadOptions::default()).expect("what we write reads back");
    }
    let _ = read_bytes(bytes, &ReadOptions::default());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn random_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        accept_anything(&bytes);
    }

    #[test]
    fn mutated_lines(edits in proptest::collection::vec((0usize..64, 0usize..32, 0usize..TOKENS.len(), 0u8..4), 1..6)) {
        let mut lines: Vec<Vec<String>> =
            SEED.lines().map(|l| l.split(' ').map(str::to_string).collect()).collect();
        for (line, token, replacement, op) in edits {
            let n = lines.len();
            let l = &mut lines[line % n];
            let k = token % (l.len() + 1);
            match op {
                0 if k < l.len() => l[k] = TOKENS[replacement].to_string(),
                1 if k < l.len() => { l.remove(k); }
                2 => l.insert(k, TOKENS[replacement].to_string()),
                _ => { let copy = l.clone(); lines.insert(line % n, copy); }
            }
        }
        let text = lines.iter().map(|l| l.join(" ")).collect::<Vec<_>>().join("\n");
        accept_anything(text.as_bytes());
    }
}
