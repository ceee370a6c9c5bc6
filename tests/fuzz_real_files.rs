//! Mutated lines of real benchmark files: the reader returns a graph or a typed
//! error, and a short solve of any graph it accepts returns a summary or a typed
//! error. Never a panic.

mod common;

use cairn::g2o::{ReadOptions, read_bytes};
use cairn::solvers::{Algorithm, SolverConfig, optimize};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};

const FILES: [&str; 5] = [
    "parser/pose2example.txt",
    "parser/pose3example.txt",
    "landmarks/simulation-pose-landmark.g2o",
    "parser/test_se3.g2o",
    "3d/tinyGrid3D.g2o",
];

const TOKENS: &[&str] = &[
    "0",
    "-1",
    "1e308",
    "5e-324",
    "nan",
    "-inf",
    "zz",
    "",
    "FIX",
    "EDGE_SE2",
    "LANDMARK2",
    "3",
];

fn mutate(text: &str, edits: &[(usize, usize, usize, u8)]) -> String {
    let mut lines: Vec<Vec<String>> = text
        .lines()
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect();
    for &(line, token, replacement, op) in edits {
        let n = lines.len();
        let l = &mut lines[line % n];
        let k = token % (l.len() + 1);
        match op {
            0 if k < l.len() => l[k] = TOKENS[replacement % TOKENS.len()].to_string(),
            1 if k < l.len() => {
                l.remove(k);
            }
            2 => l.insert(k, TOKENS[replacement % TOKENS.len()].to_string()),
            _ => lines.swap(line % n, (line / 7) % n),
        }
    }
    lines
        .iter()
        .map(|l| l.join(" "))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn mutated_real_files_never_panic() {
    let Some(dir) = common::shared() else { return };
    for file in FILES {
        let text = std::fs::read_to_string(dir.join("datasets").join(file)).unwrap();
        let mut runner = TestRunner::new(Config {
            cases: 300,
            ..Config::default()
        });
        let edits =
            proptest::collection::vec((0usize..10_000, 0usize..40, 0usize..100, 0u8..4), 1..8);
        runner
            .run(&edits, |edits| {
                let mutated = mutate(&text, &edits);
                for repair in [false, true] {
                    if let Ok((mut graph, _)) = read_bytes(
                        mutated.as_bytes(),
                        &ReadOptions {
                            repair_information: repair,
                            ..Default::default()
                        },
                    ) {
                        for algorithm in [Algorithm::GaussNewton, Algorithm::LevenbergMarquardt] {
                            let config = SolverConfig {
                                algorithm,
                                max_iterations: 5,
                                ..Default::default()
                            };
                            if let Ok(summary) = optimize(&mut graph, config) {
                                prop_assert!(
                                    summary.final_chi2.is_finite()
                                        || algorithm == Algorithm::GaussNewton
                                );
                            }
                        }
                    }
                }
                Ok(())
            })
            .unwrap_or_else(|e| panic!("{file}: {e}"));
    }
}
