//! Every exit status the README documents, from the command that gives it.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

/// A loop of four poses whose odometry disagrees with its closure.
const GRAPH: &str = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1.2 0 0\nVERTEX_SE2 2 1 1.1 1.6\n\
VERTEX_SE2 3 0 1 3.1\nEDGE_SE2 0 1 1 0 1.57 1 0 0 1 0 1\nEDGE_SE2 1 2 1 0 1.57 1 0 0 1 0 1\n\
EDGE_SE2 2 3 1 0 1.57 1 0 0 1 0 1\nEDGE_SE2 3 0 1.1 0 1.5 1 0 0 1 0 1\n";

fn status(args: &[&str]) -> i32 {
    let o = Command::new(env!("CARGO_BIN_EXE_cairn"))
        .args(args)
        .output()
        .expect("runs");
    o.status.code().expect("exited, not killed")
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cairn-exit-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8")
}

#[test]
fn each_failure_has_its_own_status() {
    let dir = folder("codes");
    let graph = dir.join("loop.g2o");
    std::fs::write(&graph, GRAPH).unwrap();
    let out = dir.join("out.g2o");
    let (g, o) = (s(&graph), s(&out));

    assert_eq!(status(&["solve", "-q", g, "-o", o]), 0);
    // Bad command lines: clap's own, and the values checked after parsing.
    assert_eq!(status(&["solve", "-q", g, "--no-such-option"]), 2);
    assert_eq!(status(&["solve", "-q", g, "--tau", "-1"]), 2);
    assert_eq!(status(&["solve", "-q", g, "--fix", "99"]), 2);
    assert_eq!(status(&["solve", "-q", g, "-o", o, "--stats", o]), 2);
    assert_eq!(status(&["fs-slam", g, "--estimator", "kalman"]), 2);
    // Bad input files.
    let bad = dir.join("bad.g2o");
    std::fs::write(&bad, "VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 3 1 0 0 1 0 0 1 0 1\n").unwrap();
    assert_eq!(status(&["solve", "-q", s(&bad)]), 3);
    assert_eq!(status(&["check", s(&bad)]), 3);
    let log = dir.join("log.jsonl");
    std::fs::write(
        &log,
        "{\"t\": 0, \"type\": \"odom\", \"v\": 1e9, \"yaw_rate\": 0}\n",
    )
    .unwrap();
    assert_eq!(status(&["fs-slam", s(&log)]), 3);
    let track = dir.join("track.csv");
    std::fs::write(&track, "tag,x,y\nblue,0,0\nyellow,0,0\n").unwrap();
    assert_eq!(
        status(&["fs-sim", "--track", s(&track), "-o", s(&dir.join("run"))]),
        3
    );
    // Files that cannot be read or written.
    let missing = dir.join("missing.g2o");
    assert_eq!(status(&["solve", "-q", s(&missing)]), 4);
    assert_eq!(status(&["fs-slam", s(&missing)]), 4);
    let nowhere = dir.join("no-folder").join("out.g2o");
    assert_eq!(status(&["solve", "-q", g, "-o", s(&nowhere)]), 4);
    // Before the log is even read.
    assert_eq!(status(&["fs-slam", g, "--map-out", s(&nowhere)]), 4);
    // The iteration cap: written and 0, or written and 5 under --strict.
    let _ = std::fs::remove_file(&out);
    assert_eq!(status(&["solve", "-q", g, "-i", "1", "-o", o]), 0);
    let _ = std::fs::remove_file(&out);
    assert_eq!(
        status(&["solve", "-q", g, "-i", "1", "--strict", "-o", o]),
        5
    );
    assert!(out.is_file(), "--strict still writes the result");
    assert_eq!(status(&["solve", "-q", g, "--strict", "-o", o]), 0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A computation that fails on valid input: marginals where H is indefinite.
#[test]
fn a_failed_computation_is_status_1() {
    let Some(shared) = common::shared() else {
        return;
    };
    let file = shared.join("reliability/solve_marginals_fail_discards_output.g2o");
    assert_eq!(status(&["solve", "-q", s(&file), "--marginals", "all"]), 1);
}
