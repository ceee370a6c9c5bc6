//! The `cairn` command line, run as a user would.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn cairn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cairn"))
        .args(args)
        .output()
        .expect("runs")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cairn-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A synthetic graph (`cairn generate KIND -n POSES`) written to `path`.
fn generate(kind: &str, poses: usize, path: &Path) {
    let o = cairn(&["generate", kind, "-n", &poses.to_string(), "-o", s(path)]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn generate_then_solve_writes_an_optimised_graph() {
    let dir = temp_dir("gen");
    let (input, output) = (dir.join("m.g2o"), dir.join("out.g2o"));
    generate("manhattan", 400, &input);
    let o = cairn(&["solve", s(&input), "-o", s(&output), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("iteration= 0\t chi2= ")
            && err.contains("cumTime= ")
            && err.contains("edges= "),
        "{err}"
    );
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let last = json["summary"]["final_chi2"].as_f64().unwrap();
    let initial = cairn::g2o::read_file(&input, &Default::default())
        .unwrap()
        .0
        .chi2();
    assert!(last < 0.01 * initial, "{initial} → {last}");
    assert!(["file", "chordal", "chordal-isotropic"].contains(&json["init"].as_str().unwrap()));
    let o = cairn(&["solve", s(&input), "--init", "file", "--json", "-q"]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["init"], "file");
    assert!((json["summary"]["initial_chi2"].as_f64().unwrap() - initial).abs() <= 1e-9 * initial);
    assert_eq!(json["vertices"], 400);
    // The output reads back and is at the optimum.
    let (mut graph, _) = cairn::g2o::read_file(&output, &Default::default()).unwrap();
    assert!((graph.chi2() - last).abs() <= 1e-9 * last);
    let again = cairn::solvers::optimize(&mut graph, Default::default()).unwrap();
    assert!(again.iterations <= 2);
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .collect();
    assert_eq!(leftovers.len(), 2, "no temporary files are left behind");
}

#[test]
fn stdin_to_stdout() {
    let text = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1.5 0.2 0.1\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n";
    let mut child = Command::new(env!("CARGO_BIN_EXE_cairn"))
        .args(["solve", "-", "-o", "-", "-q"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    child
        .stdin
        .take()
        .unwrap()
        .write_all(text.as_bytes())
        .unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(
        out.starts_with("VERTEX_SE2 0 0.0 0.0 0.0\nVERTEX_SE2 1 1.0"),
        "{out}"
    );
    assert!(o.stderr.is_empty(), "-q prints nothing");
}

#[test]
fn errors_name_the_file_and_line_and_exit_with_their_status() {
    let dir = temp_dir("bad");
    let bad = dir.join("bad.g2o");
    std::fs::write(&bad, "VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 3 1 0 0 1 0 0 1 0 1\n").unwrap();
    let out = dir.join("out.g2o");
    std::fs::write(&out, "precious").unwrap();
    let o = cairn(&["solve", s(&bad), "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(3));
    let err = stderr(&o);
    assert!(
        err.contains("bad.g2o: line 2: vertex 3 is not in the graph"),
        "{err}"
    );
    assert!(!err.contains("panicked"));
    assert_eq!(
        std::fs::read_to_string(&out).unwrap(),
        "precious",
        "a failed run leaves outputs alone"
    );

    let o = cairn(&["solve", s(&dir.join("missing.g2o"))]);
    assert_eq!(o.status.code(), Some(4));
    assert!(stderr(&o).contains("missing.g2o"), "{}", stderr(&o));

    let good = dir.join("good.g2o");
    std::fs::write(&good, "VERTEX_SE2 0 0 0 0\n").unwrap();
    let o = cairn(&["solve", s(&good), "--fix", "5"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--fix: vertex 5 is not in the graph"));
    let o = cairn(&["solve", s(&good), "-o", "-", "--json"]);
    assert_eq!(o.status.code(), Some(2));
    let o = cairn(&["solve", s(&good), "-o", s(&dir.join("no/such/dir/out.g2o"))]);
    assert_eq!(o.status.code(), Some(4));
    let o = cairn(&["solve", s(&good), "--solver", "newton"]);
    assert_eq!(o.status.code(), Some(2), "clap's usage errors too");
}

#[test]
fn summary_and_stats_csv() {
    let dir = temp_dir("csv");
    let input = dir.join("s.g2o");
    generate("sphere", 100, &input);
    let (summary, stats) = (dir.join("summary.csv"), dir.join("stats.csv"));
    for solver in ["gn", "lm"] {
        let o = cairn(&[
            "solve",
            s(&input),
            "--solver",
            solver,
            "--summary",
            s(&summary),
            "--stats",
            s(&stats),
            "-q",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let summary = std::fs::read_to_string(summary).unwrap();
    let rows: Vec<&str> = summary.lines().collect();
    assert_eq!(rows.len(), 3, "header plus one row per run:\n{summary}");
    assert!(rows[0].starts_with("file,algorithm,vertices,edges,initial_chi2,final_chi2"));
    assert!(rows[1].contains(",gn,100,") && rows[2].contains(",lm,100,"));
    let stats = std::fs::read_to_string(stats).unwrap();
    assert!(stats.starts_with("iteration,chi2,lambda,radius,trials"));
    assert!(stats.lines().count() > 2);
    assert!(
        stats
            .lines()
            .nth(1)
            .unwrap()
            .split(',')
            .nth(2)
            .is_some_and(|l| !l.is_empty()),
        "LM has λ"
    );
}

#[test]
fn fix_holds_vertices_and_cubicle_needs_repair() {
    let dir = temp_dir("fix");
    let input = dir.join("m.g2o");
    generate("manhattan", 200, &input);
    let o = cairn(&["solve", s(&input), "--fix", "0,7", "-q", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["summary"]["gauge"], serde_json::json!([]));

    let o = cairn(&["solve", s(&input), "--marginals", "5,150", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("marginal covariance of vertex 150:"));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let m = &json["marginals"][1]["covariance"];
    assert_eq!(
        (
            json["marginals"][1]["vertex"].as_i64(),
            m.as_array().map(|r| r.len())
        ),
        (Some(150), Some(3))
    );
    assert!(m[0][0].as_f64().unwrap() > 0.0 && m[0][1] == m[1][0]);
    let o = cairn(&["solve", s(&input), "--marginals", "0"]);
    assert!(stderr(&o).contains("vertex 0 is fixed"), "{}", stderr(&o));
    // Every vertex but the gauge, by selected inversion: the same blocks.
    let o = cairn(&["solve", s(&input), "--marginals", "all", "-q", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let all: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let blocks = all["marginals"].as_array().unwrap();
    assert_eq!(Some(blocks.len() as u64 + 1), all["vertices"].as_u64());
    let same = blocks.iter().find(|b| b["vertex"] == 150).unwrap();
    for (r, row) in m.as_array().unwrap().iter().enumerate() {
        for (c, value) in row.as_array().unwrap().iter().enumerate() {
            let (a, b) = (
                value.as_f64().unwrap(),
                same["covariance"][r][c].as_f64().unwrap(),
            );
            assert!(
                (a - b).abs() <= 1e-9 * a.abs().max(1e-12),
                "{r},{c}: {a} {b}"
            );
        }
    }
    let o = cairn(&["solve", s(&input), "--marginals", "5,x"]);
    assert!(
        stderr(&o).contains("'x' is neither a vertex id nor all"),
        "{}",
        stderr(&o)
    );

    let Some(cubicle) = common::dataset("3d/cubicle.g2o") else {
        return;
    };
    let o = cairn(&["solve", s(&cubicle), "-i", "1"]);
    assert_eq!(o.status.code(), Some(3));
    let err = stderr(&o);
    assert!(
        err.contains("5021 edges have information matrices that are not positive definite"),
        "{err}"
    );
    let o = cairn(&["solve", s(&cubicle), "-i", "1", "--repair-information"]);
    assert!(o.status.success());
    assert!(stderr(&o).contains("repaired 5021 information matrices"));
}

#[test]
fn check_reports_worst_edges_scaling_and_components() {
    let dir = temp_dir("check");
    let file = dir.join("g.g2o");
    std::fs::write(
        &file,
        "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_SE2 2 5 0 0\nVERTEX_SE2 7 0 0 0\n\
         EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE2 1 2 1 0 0 1e12 0 0 1 0 1\nEDGE_SE2 0 2 2 0 0 1 2 0 1 0 1\nJUNK 1\n",
    )
    .unwrap();
    let o = cairn(&["check", s(&file), "--worst", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("4 vertices (SE2 4), 3 edges (EDGE_SE2 3)"),
        "{out}"
    );
    assert!(out.contains("1 not positive definite (lines 7;"), "{out}");
    assert!(out.contains("1 badly scaled"), "{out}");
    assert!(
        out.contains("connected components: 2 (sizes 3, 1); automatic gauge fixes [0, 7]"),
        "{out}"
    );
    assert!(
        out.contains("edge #1 EDGE_SE2 [1, 2]: χ² 9000000000000"),
        "{out}"
    );
    assert!(
        out.contains("skipped lines with unsupported tags: JUNK 1"),
        "{out}"
    );
    let o = cairn(&["check", s(&file), "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["worst_edges"][0]["edge"], 1);
    assert_eq!(json["indefinite_information_lines"], serde_json::json!([7]));
}

#[test]
fn corrupt_then_solve_with_a_robust_kernel() {
    let dir = temp_dir("robust");
    let (clean, bad) = (dir.join("clean.g2o"), dir.join("bad.g2o"));
    generate("manhattan", 500, &clean);
    let o = cairn(&[
        "corrupt",
        s(&clean),
        "--fraction",
        "0.1",
        "--seed",
        "3",
        "-o",
        s(&bad),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("added"), "{}", stderr(&o));
    let chi2 = |args: &[&str]| -> f64 {
        let o = cairn(args);
        assert!(o.status.success(), "{}", stderr(&o));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()["summary"]["final_chi2"]
            .as_f64()
            .unwrap()
    };
    let clean_chi2 = chi2(&["solve", s(&clean), "-q", "--json"]);
    let naive = chi2(&["solve", s(&bad), "-q", "--json"]);
    let robust = chi2(&[
        "solve",
        s(&bad),
        "-q",
        "--json",
        "--robust-kernel",
        "dcs",
        "--non-sequential",
    ]);
    assert!(naive > 100.0 * clean_chi2, "{naive} vs {clean_chi2}");
    assert!(robust < 2.0 * clean_chi2, "{robust} vs {clean_chi2}");
    let o = cairn(&["solve", s(&bad), "--robust-kernel", "l3"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("invalid value 'l3' for '--robust-kernel"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn lm_damping_and_tau_are_chosen_on_the_command_line() {
    let dir = temp_dir("damping");
    let input = dir.join("m.g2o");
    generate("manhattan", 600, &input);
    let solve = |extra: &[&str]| {
        let mut args = vec!["solve", s(&input), "--init", "file", "--solver", "lm"];
        args.extend_from_slice(&["--json", "-q"]);
        args.extend_from_slice(extra);
        let o = cairn(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let summary = &json["summary"];
        let first_lambda = summary["trace"][0]["lambda"].as_f64().unwrap();
        (summary["iterations"].as_u64().unwrap(), first_lambda)
    };
    let (marquardt, lambda) = solve(&[]);
    let (levenberg, g2o_lambda) = solve(&["--damping", "levenberg"]);
    let (_, small) = solve(&["--damping", "levenberg", "--tau", "1e-9"]);
    // g2o's λ is sized by the largest diagonal entry of H: far above 1e-9.
    assert!(lambda < 1e-9 && g2o_lambda > 1e-6, "{lambda} {g2o_lambda}");
    // λ after the first step: τ's ratio, 1e-4, times the two updates' ratio.
    let ratio = small / g2o_lambda;
    assert!((1e-5..1e-3).contains(&ratio), "{small} {g2o_lambda}");
    assert!(marquardt <= levenberg, "{marquardt} {levenberg}");
    for bad in ["0", "-1", "nan", "inf"] {
        let tau = format!("--tau={bad}");
        let o = cairn(&["solve", s(&input), "--solver", "lm", &tau, "-q"]);
        assert!(!o.status.success() && stderr(&o).contains("--tau"), "{bad}");
    }
}

#[test]
fn gn_stops_on_a_rise_when_asked() {
    // A loop of 60 poses, 1 m apart, with exact odometry and closures every
    // three poses; the headings start up to 2.6 rad off, which makes GN's
    // fourth step climb eightfold before it descends below where it was.
    let dir = temp_dir("rise");
    let (input, output) = (dir.join("loop.g2o"), dir.join("out.g2o"));
    let n = 60;
    let turn = 2.0 * std::f64::consts::PI / n as f64;
    let (mut text, mut pose) = (String::new(), (0.0f64, 0.0f64, 0.0f64));
    for i in 0..n {
        let off = if i == 0 {
            0.0
        } else {
            2.6 * ((i * 5 % 23) as f64 / 11.0 - 1.0)
        };
        text += &format!("VERTEX_SE2 {i} {} {} {}\n", pose.0, pose.1, pose.2 + off);
        pose = (pose.0 + pose.2.cos(), pose.1 + pose.2.sin(), pose.2 + turn);
    }
    let info = "100 0 0 100 0 1000";
    for i in 0..n {
        text += &format!("EDGE_SE2 {i} {} 1 0 {turn} {info}\n", (i + 1) % n);
        if i + 3 < n {
            // Three steps of (1 m, turn): the chord and its direction.
            let (mut x, mut y, mut t) = (0.0f64, 0.0f64, 0.0f64);
            for _ in 0..3 {
                (x, y, t) = (x + t.cos(), y + t.sin(), t + turn);
            }
            text += &format!("EDGE_SE2 {i} {} {x} {y} {t} {info}\n", i + 3);
        }
    }
    std::fs::write(&input, text).unwrap();
    let solve = |extra: &[&str]| {
        let mut args = vec!["solve", s(&input), "--init", "file", "--json", "-q"];
        args.extend_from_slice(extra);
        let o = cairn(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        json["summary"].clone()
    };
    let chi2s = |summary: &serde_json::Value| -> Vec<f64> {
        let trace = summary["trace"].as_array().unwrap();
        let mut chi2 = vec![summary["initial_chi2"].as_f64().unwrap()];
        chi2.extend(trace.iter().map(|t| t["chi2"].as_f64().unwrap()));
        chi2
    };
    let plain = solve(&[]);
    let path = chi2s(&plain);
    let rise = (1..path.len()).find(|&k| path[k] > path[k - 1]);
    let rise = rise.expect("GN climbs from this start");
    assert!(
        plain["final_chi2"].as_f64().unwrap() < path[rise - 1],
        "{plain}"
    );

    let stopped = solve(&["--stop-on-increase", "-o", s(&output)]);
    assert_eq!(stopped["termination"], "ErrorIncreased");
    assert_eq!(chi2s(&stopped), path[..=rise]);
    let kept = stopped["final_chi2"].as_f64().unwrap();
    assert_eq!(kept, path[rise - 1]);
    let (written, _) = cairn::g2o::read_file(&output, &Default::default()).unwrap();
    assert!(
        (written.chi2() - kept).abs() <= 1e-9 * kept,
        "{}",
        written.chi2()
    );

    let o = cairn(&[
        "solve",
        s(&input),
        "--solver",
        "lm",
        "--stop-on-increase",
        "-q",
    ]);
    assert!(!o.status.success() && stderr(&o).contains("--stop-on-increase"));
}

#[test]
fn linearize_writes_matrix_market_files_that_agree() {
    let dir = temp_dir("linearize");
    let input = dir.join("m.g2o");
    generate("manhattan", 200, &input);
    let files: Vec<PathBuf> = ["h.mtx", "j.mtx", "b.mtx", "cols.csv", "rows.csv"]
        .iter()
        .map(|f| dir.join(f))
        .collect();
    let o = cairn(&[
        "linearize",
        s(&input),
        "--hessian",
        s(&files[0]),
        "--jacobian",
        s(&files[1]),
        "--rhs",
        s(&files[2]),
        "--columns",
        s(&files[3]),
        "--rows",
        s(&files[4]),
    ]);
    let said = stderr(&o);
    assert!(o.status.success(), "{said}");
    for ordering in ["block-amd", "amd", "schur", "identity"] {
        assert!(said.contains(ordering), "{said}");
    }
    // H as written (its lower triangle, symmetric) is JᵀJ of J as written.
    let h: sprs::TriMat<f64> = sprs::io::read_matrix_market(&files[0]).unwrap();
    let j: sprs::TriMat<f64> = sprs::io::read_matrix_market(&files[1]).unwrap();
    let b: sprs::TriMat<f64> = sprs::io::read_matrix_market(&files[2]).unwrap();
    let (h, j): (sprs::CsMat<f64>, sprs::CsMat<f64>) = (h.to_csc(), j.to_csc());
    let n = 199 * 3;
    assert_eq!((h.rows(), h.cols(), j.cols(), b.rows()), (n, n, n, n));
    let jtj = &j.transpose_view().to_csc() * &j;
    let scale = h.iter().fold(0.0f64, |m, (v, _)| m.max(v.abs()));
    let diff = (&jtj - &h).iter().fold(0.0f64, |m, (v, _)| m.max(v.abs()));
    assert!(diff < 1e-9 * scale, "JᵀJ and H differ by {diff}");
    let columns = std::fs::read_to_string(&files[3]).unwrap();
    assert_eq!(columns.lines().count(), n + 1);
    let rows = std::fs::read_to_string(&files[4]).unwrap();
    assert_eq!(rows.lines().count(), j.rows() + 1);
    // A missing folder is named before any work; a bad ordering by its flag.
    let o = cairn(&[
        "linearize",
        s(&input),
        "--hessian",
        s(&dir.join("none/h.mtx")),
    ]);
    assert!(
        !o.status.success() && stderr(&o).contains("does not exist"),
        "{}",
        stderr(&o)
    );
    let o = cairn(&["linearize", s(&input), "--ordering", "nested"]);
    assert!(
        !o.status.success() && stderr(&o).contains("--ordering"),
        "{}",
        stderr(&o)
    );
}

/// `--help` lists every choice's values, and `solve`'s options come in groups.
#[test]
fn help_lists_the_choices_and_groups_the_options() {
    let help = |args: &[&str]| String::from_utf8_lossy(&cairn(args).stdout).into_owned();
    let solve = help(&["solve", "--help"]);
    for heading in [
        "Output:",
        "Algorithm:",
        "Levenberg-Marquardt:",
        "Robust kernels:",
        "Linear solver:",
    ] {
        assert!(solve.contains(heading), "{heading}: {solve}");
    }
    assert!(
        solve.contains("[possible values: huber, pseudo-huber"),
        "{solve}"
    );
    let slam = help(&["fs-slam", "--help"]);
    for values in [
        "[possible values: ml, scnn, jcbb, tracking]",
        "[possible values: graph, ekf, fastslam1, fastslam2]",
        "[possible values: unicycle, bicycle]",
        "[possible values: velocity, rot-trans-rot]",
        "[possible values: standard, hard, realistic]",
    ] {
        assert!(slam.contains(values), "{values}: {slam}");
    }
    let o = cairn(&["fs-sim", "--preset", "wet", "-o", "unused"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("[possible values: standard, hard, realistic]"));
    // A preset effect out of range names its flag.
    let o = cairn(&["fs-sim", "--latency", "5", "-o", "unused"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--latency must be from 0 to 1 s"),
        "{}",
        stderr(&o)
    );
}

/// Shell completions and man pages come from the command-line definitions.
#[test]
fn completions_and_man_pages() {
    for shell in ["bash", "zsh", "fish"] {
        let o = cairn(&["completions", shell]);
        assert!(o.status.success(), "{shell}");
        let script = String::from_utf8_lossy(&o.stdout);
        assert!(
            script.contains("fs-slam") && script.contains("robust-kernel"),
            "{shell}"
        );
    }
    let dir = temp_dir("man");
    let o = cairn(&["man", "-o", s(&dir)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let solve = std::fs::read_to_string(dir.join("cairn-solve.1")).unwrap();
    assert!(solve.starts_with(".ie") || solve.contains(".TH"), "{solve}");
    assert!(solve.contains("robust\\-kernel"), "{solve}");
    assert!(dir.join("cairn.1").is_file() && dir.join("cairn-fs-slam.1").is_file());
}

/// Marginals are results: printed on stdout even with -q; a run without -o
/// reports no write time.
#[test]
fn marginals_print_with_quiet_and_no_write_time_without_output() {
    let dir = temp_dir("marginals-quiet");
    let graph = dir.join("g.g2o");
    std::fs::write(
        &graph,
        "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1.1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n",
    )
    .unwrap();
    let o = cairn(&["solve", "-q", s(&graph), "--marginals", "1"]);
    assert!(o.status.success());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("marginal covariance of vertex 1"), "{out}");
    let o = cairn(&["solve", s(&graph)]);
    assert!(!stderr(&o).contains("write"), "{}", stderr(&o));
}
