//! What `cairn` writes, where a hostile or careless user points it:
//! devices, FIFOs and links are not replaced, modes are kept, leftovers of
//! killed runs are cleared, interrupted runs leave none, concurrent `--summary` rows all land, and
//! out-of-range options are refused by name.

mod common;

use std::os::unix::fs::{PermissionsExt, symlink};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const GRAPH: &str = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1.1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n";

fn cairn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cairn"))
        .args(args)
        .output()
        .expect("runs")
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cairn-out-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    std::fs::write(dir.join("in.g2o"), GRAPH).expect("writes");
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8")
}

fn solve_to(dir: &Path, out: &Path) -> Output {
    cairn(&["solve", "-q", s(&dir.join("in.g2o")), "-o", s(out)])
}

#[test]
fn links_modes_fifos_and_leftovers() {
    let dir = folder("kinds");
    // A link is followed: its target gets the result, the link stays.
    std::fs::write(dir.join("target.g2o"), "old").unwrap();
    symlink("target.g2o", dir.join("link.g2o")).unwrap();
    assert!(solve_to(&dir, &dir.join("link.g2o")).status.success());
    assert!(
        std::fs::symlink_metadata(dir.join("link.g2o"))
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(
        std::fs::read_to_string(dir.join("target.g2o"))
            .unwrap()
            .contains("EDGE_SE2")
    );
    // A replaced file keeps its mode.
    let private = dir.join("private.g2o");
    std::fs::write(&private, "old").unwrap();
    std::fs::set_permissions(&private, std::fs::Permissions::from_mode(0o600)).unwrap();
    assert!(solve_to(&dir, &private).status.success());
    assert_eq!(
        std::fs::metadata(&private).unwrap().permissions().mode() & 0o777,
        0o600
    );
    // A temporary file of a process that is gone is removed by the next write.
    let stale = dir.join(".private.g2o.4000000000.tmp");
    std::fs::write(&stale, "half a file").unwrap();
    assert!(solve_to(&dir, &private).status.success());
    assert!(!stale.exists());
    // A FIFO is written into, not replaced by a regular file.
    let fifo = dir.join("fifo");
    if Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        let reader = std::thread::spawn({
            let fifo = fifo.clone();
            move || std::fs::read_to_string(fifo).unwrap()
        });
        assert!(solve_to(&dir, &fifo).status.success());
        assert!(reader.join().unwrap().contains("EDGE_SE2"));
        assert!(!std::fs::metadata(&fifo).unwrap().is_file());
    }
    // -o and --stats on one file would overwrite each other.
    let o = cairn(&[
        "solve",
        s(&dir.join("in.g2o")),
        "-o",
        s(&private),
        "--stats",
        s(&private),
    ]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && said.contains("-o and --stats both name"),
        "{said}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn summary_rows_of_concurrent_runs_all_land_and_old_rows_stay() {
    let dir = folder("summary");
    let summary = dir.join("runs.csv");
    std::fs::write(&summary, b"file,algorithm\nold,caf\xe9\n").unwrap();
    let runs: Vec<_> = (0..12)
        .map(|_| {
            Command::new(env!("CARGO_BIN_EXE_cairn"))
                .args([
                    "solve",
                    "-q",
                    s(&dir.join("in.g2o")),
                    "--summary",
                    s(&summary),
                ])
                .spawn()
                .expect("starts")
        })
        .collect();
    for mut run in runs {
        assert!(run.wait().unwrap().success());
    }
    let text = std::fs::read(&summary).unwrap();
    assert!(
        text.starts_with(b"file,algorithm\nold,caf\xe9\n"),
        "the old rows stay"
    );
    assert_eq!(text.iter().filter(|&&b| b == b'\n').count(), 2 + 12);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn out_of_range_options_are_refused_by_name() {
    let dir = folder("options");
    let input = dir.join("in.g2o");
    let out = dir.join("out.g2o");
    for (args, flag) in [
        (
            vec!["corrupt", s(&input), "-o", s(&out), "--spread", "inf"],
            "--spread",
        ),
        (
            vec!["corrupt", s(&input), "-o", s(&out), "--spread", "1e308"],
            "--spread",
        ),
        (
            vec!["corrupt", s(&input), "-o", s(&out), "--fraction", "inf"],
            "--fraction",
        ),
        (
            vec!["corrupt", s(&input), "-o", s(&out), "--fraction", "1e9"],
            "--fraction",
        ),
        (
            vec![
                "generate",
                "manhattan",
                "-n",
                "18446744073709551615",
                "-o",
                s(&out),
            ],
            "--poses",
        ),
        (
            vec!["generate", "manhattan", "-n", "0", "-o", s(&out)],
            "--poses",
        ),
        (
            vec!["solve", "-q", s(&input), "--threads", "100000"],
            "--threads",
        ),
        (vec!["fs-sim", "--laps", "1e9", "-o", s(&out)], "--laps"),
        (vec!["fs-sim", "--speed", "1e-9", "-o", s(&out)], "--speed"),
        (vec!["fs-sim", "--speed", "nan", "-o", s(&out)], "--speed"),
        (
            vec!["fs-sim", "--laps", "900", "--speed", "0.1", "-o", s(&out)],
            "at most 86400 s",
        ),
    ] {
        let o = cairn(&args);
        let said = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {said}");
        assert!(said.contains(flag), "{args:?}: {said}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `solve -o - | head -1`: the reader leaving early is no failure.
#[test]
fn a_closed_stdout_is_not_an_error() {
    use std::io::{BufRead, BufReader};
    let dir = folder("pipe");
    let graph = dir.join("graph.g2o");
    let o = cairn(&["generate", "manhattan", "-n", "3000", "-o", s(&graph)]);
    assert!(o.status.success());
    let mut child = Command::new(env!("CARGO_BIN_EXE_cairn"))
        .args(["solve", "-q", "-o", "-", s(&graph)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("runs");
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    // The pipe is closed here, long before the 3,000 poses are written.
    assert!(first.starts_with("VERTEX_SE2"), "{first}");
    let o = child.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{:?}: {said}", o.status);
    assert!(!said.contains("Broken pipe"), "{said}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// SIGINT or SIGTERM while the result is being written: status 130, the
/// target as it was, and no temporary file left.
#[test]
fn an_interrupted_write_leaves_the_target_and_no_temporary_file() {
    let dir = folder("signal");
    let big = dir.join("big.g2o");
    let o = cairn(&["generate", "manhattan", "-n", "200000", "-o", s(&big)]);
    assert!(o.status.success());
    let out = dir.join("out.g2o");
    let mut interrupted = 0;
    for signal in ["INT", "TERM", "INT", "TERM", "INT", "TERM"] {
        std::fs::write(&out, "old").unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_cairn"))
            .args([
                "solve",
                "-q",
                "-i",
                "0",
                "--init",
                "file",
                "-o",
                s(&out),
                s(&big),
            ])
            .spawn()
            .expect("runs");
        let tmp = dir.join(format!(".out.g2o.{}.tmp", child.id()));
        // The temporary file exists from the write's start to its rename.
        while !tmp.exists() && child.try_wait().unwrap().is_none() {}
        let sent = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .is_ok_and(|s| s.success());
        let status = child.wait().unwrap();
        let caught = sent && status.code() == Some(130);
        if caught {
            interrupted += 1;
            assert_eq!(std::fs::read_to_string(&out).unwrap(), "old");
        } else {
            assert!(status.success(), "SIG{signal}: {status:?}");
        }
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            .collect();
        assert!(left.is_empty(), "SIG{signal} left {left:?}");
    }
    // The write takes tens of milliseconds: most signals land in it.
    assert!(
        interrupted >= 2,
        "only {interrupted} of 6 runs were interrupted"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A solve whose steps climb above the file's χ² returns the lowest
/// estimate it met and says so; a failure of `--marginals` after the solve still writes it.
#[test]
fn worse_than_the_start_is_never_written_and_marginals_do_not_discard_a_solve() {
    let Some(shared) = common::shared() else {
        return;
    };
    let dir = folder("worse");
    let out = dir.join("out.g2o");
    let worse = shared.join("reliability/solver_gn_writes_worse_than_start_loop_err_1e100.g2o");
    let o = cairn(&[
        "solve",
        s(&worse),
        "--init",
        "file",
        "-o",
        s(&out),
        "--json",
    ]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(said.contains("was above the lowest χ² met"), "{said}");
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(json["summary"]["returned_lowest"], serde_json::json!(true));
    let written = cairn(&["solve", s(&out), "-i", "0", "--json"]);
    let written: serde_json::Value = serde_json::from_slice(&written.stdout).expect("JSON");
    let start = json["summary"]["initial_chi2"].as_f64().expect("χ²");
    let kept = written["summary"]["initial_chi2"].as_f64().expect("χ²");
    assert!(kept <= start * (1.0 + 1e-12), "{kept} > {start}");
    let marginals = shared.join("reliability/solve_marginals_fail_discards_output.g2o");
    let _ = std::fs::remove_file(&out);
    let o = cairn(&[
        "solve",
        "-q",
        s(&marginals),
        "--marginals",
        "all",
        "-o",
        s(&out),
    ]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && said.contains("--marginals") && said.contains("was written"),
        "{said}"
    );
    assert!(out.is_file());
    let _ = std::fs::remove_dir_all(&dir);
}
