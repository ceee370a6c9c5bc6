//! `cairn fs-sim`, `fs-slam` and `fs-eval`, run as a user would: the README demo.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn cairn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cairn"))
        .args(args)
        .output()
        .expect("runs")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cairn-fs-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn simulate_map_and_evaluate_a_random_track() {
    let dir = temp_dir("demo");
    // Seed 1 is the known failure of place recognition (see
    // fs-tools/tests/slam.rs); the demo in the README uses seed 2.
    let o = cairn(&["fs-sim", "--seed", "2", "-o", s(&dir)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (map, traj, assoc, timing, real_time) = (
        dir.join("map.csv"),
        dir.join("traj.tum"),
        dir.join("assoc.csv"),
        dir.join("timing.json"),
        dir.join("real_time.csv"),
    );
    let o = cairn(&[
        "fs-slam",
        s(&dir.join("log.jsonl")),
        "--map-out",
        s(&map),
        "--traj-out",
        s(&traj),
        "--assoc-out",
        s(&assoc),
        "--timing-out",
        s(&timing),
        "--assoc-real-time-out",
        s(&real_time),
    ]);
    let summary = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{summary}");
    // The loop closed: its optimisation and the final one are reported.
    for part in [
        "1 loop closure(s)",
        "p99",
        "; loop closure ",
        "; final optimisation ",
        "odometry learnt: speed ×",
        "gyro bias walk ",
    ] {
        assert!(summary.contains(part), "{part:?} missing from {summary}");
    }
    // What the graph learnt of the odometry is kept with the timings; this
    // log's car does not slide, and its speed reads 1% high.
    let kept: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&timing).unwrap()).unwrap();
    let learnt = &kept["odometry_calibration"];
    let slide = learnt["sideslip"].as_f64().unwrap();
    assert!(slide.abs() < 0.003, "{learnt}");
    let scale = learnt["speed_scale"].as_f64().unwrap();
    assert!((scale - 1.0 / 1.01).abs() < 0.01, "{learnt}");
    // Its gyro's bias holds: the walk stays the one assumed.
    let walk = learnt["yaw_rate_bias_walk"].as_f64().unwrap();
    assert_eq!(walk, 1e-5, "{learnt}");
    let plot = dir.join("plot.svg");
    let o = cairn(&[
        "fs-eval",
        "--truth",
        s(&dir),
        "--map",
        s(&map),
        "--traj",
        s(&traj),
        "--assoc",
        s(&assoc),
        "--timing",
        s(&timing),
        "--assoc-real-time",
        s(&real_time),
        "--plot",
        s(&plot),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["phantom"], 0);
    let accuracy = report["association_accuracy"].as_f64().unwrap();
    assert!(accuracy > 0.97);
    // The real-time associations, before the end-of-run pass matched every
    // detection again, are scored apart: measured 99.70% against 100.00%.
    let real_time = report["association_accuracy_real_time"].as_f64().unwrap();
    assert!(
        real_time > 0.95 && real_time <= accuracy,
        "{real_time} vs {accuracy}"
    );
    // p50 ≤ p99 ≤ p99.9 ≤ max, all positive.
    let latency: Vec<f64> = (0..4)
        .map(|k| report["latency_ms"][k].as_f64().unwrap())
        .collect();
    assert!(latency[0] > 0.0, "{latency:?}");
    assert!(latency.windows(2).all(|w| w[0] <= w[1]), "{latency:?}");
    assert!(std::fs::read_to_string(&plot).unwrap().contains("<svg"));
}

#[test]
fn a_bad_log_line_is_named_and_leaves_no_output() {
    let dir = temp_dir("bad");
    let log = dir.join("log.jsonl");
    std::fs::write(
        &log,
        "{\"t\": 0, \"type\": \"start\"}\n{\"t\": 0.1, \"type\": \"odom\", \"v\": 1}\n",
    )
    .unwrap();
    let map = dir.join("map.csv");
    let o = cairn(&["fs-slam", s(&log), "--map-out", s(&map)]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("line 2") && err.contains("yaw_rate"), "{err}");
    assert!(!map.exists());
    let o = cairn(&["fs-slam", s(&log), "--map-out", s(&map), "--skip-bad"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("skipped line 2"));
    assert!(map.exists());
}

/// Simulates 1.2 laps of random track 2 into `dir`, with `extra` options.
fn simulate_short_run(dir: &Path, extra: &[&str]) {
    let mut args = vec!["fs-sim", "--seed", "2", "--laps", "1.2", "-o", s(dir)];
    args.extend(extra);
    let o = cairn(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Runs `fs-slam` with `extra` options on `dir`'s log and scores it.
fn slam_and_score(dir: &Path, extra: &[&str]) -> serde_json::Value {
    let (map, traj, assoc) = (dir.join("m.csv"), dir.join("t.tum"), dir.join("a.csv"));
    let log = dir.join("log.jsonl");
    let mut args = vec![
        "fs-slam",
        s(&log),
        "--map-out",
        s(&map),
        "--traj-out",
        s(&traj),
    ];
    args.extend(["--assoc-out", s(&assoc)]);
    args.extend(extra);
    let o = cairn(&args);
    assert!(
        o.status.success(),
        "{extra:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let o = cairn(&[
        "fs-eval",
        "--truth",
        s(dir),
        "--map",
        s(&map),
        "--traj",
        s(&traj),
        "--assoc",
        s(&assoc),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn every_estimator_and_point_clouds_run_from_the_command_line() {
    let dir = temp_dir("estimators");
    let o = cairn(&["fs-sim", "--seed", "1", "--laps", "1.2", "-o", s(&dir)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let truth = dir.join("truth_assoc.csv");
    let log = dir.join("log.jsonl");
    for extra in [
        vec!["--estimator", "ekf"],
        vec!["--estimator", "ekf", "--odometry-noise", "rot-trans-rot"],
        // The README's values, comma-separated.
        vec![
            "--odometry-noise",
            "rot-trans-rot",
            "--alpha",
            "1e-3,1.6e-5,2.5e-3,1e-4",
        ],
        vec!["--estimator", "fastslam2", "--particles", "20"],
        vec![
            "--estimator",
            "fastslam1",
            "--particles",
            "20",
            "--known-assoc",
            s(&truth),
        ],
    ] {
        let report = slam_and_score(&dir, &extra);
        let accuracy = report["association_accuracy"].as_f64().unwrap();
        assert!(accuracy > 0.9, "{extra:?}: {report}");
    }
    // Options that make no sense are refused with a message.
    for bad in [
        vec!["--estimator", "kalman"],
        vec!["--estimator", "graph", "--known-assoc", s(&truth)],
        vec!["--odometry-noise", "velocity", "--alpha", "1,1,1,1"],
        vec!["--odometry-noise", "rot-trans-rot", "--alpha", "1,1"],
        vec!["--particles", "0"],
    ] {
        let mut args = vec!["fs-slam", s(&log)];
        args.extend(&bad);
        let o = cairn(&args);
        assert!(!o.status.success(), "{bad:?} accepted");
        assert!(String::from_utf8_lossy(&o.stderr).contains("--"), "{bad:?}");
    }

    let points = temp_dir("points");
    simulate_short_run(&points, &["--points"]);
    let log = std::fs::read_to_string(points.join("log.jsonl")).unwrap();
    assert!(log.contains("\"points\"") && !log.contains("\"cones\""));
    let report = slam_and_score(&points, &["--estimator", "ekf"]);
    assert_eq!(report["phantom"], 0, "{report}");
    assert!(report["map_rmse"].as_f64().unwrap() < 0.2, "{report}");
}

/// `--config configs/standard.toml` assumes what `--noise standard` does,
/// for the graph and for the filters, whose χ² gate is narrower: the file
/// leaves the gate to the estimator.
#[test]
fn the_shipped_config_and_the_noise_preset_map_alike() {
    let dir = temp_dir("config-noise");
    simulate_short_run(&dir, &[]);
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/standard.toml");
    for estimator in ["graph", "ekf"] {
        let mut maps = Vec::new();
        for told in [["--noise", "standard"], ["--config", s(&file)]] {
            let mut extra = vec!["--estimator", estimator, "--association", "ml"];
            extra.extend(told);
            slam_and_score(&dir, &extra);
            maps.push(std::fs::read_to_string(dir.join("m.csv")).unwrap());
        }
        assert!(maps[0].lines().count() > 10, "{estimator}: {}", maps[0]);
        assert_eq!(maps[0], maps[1], "{estimator}");
    }
}

/// Median distance from each blue or yellow cone of `truth_map.csv` in
/// `dir` to the nearest cone of its colour (m).
fn boundary_spacing(dir: &Path) -> f64 {
    let text = std::fs::read_to_string(dir.join("truth_map.csv")).unwrap();
    let cones: Vec<(String, f64, f64)> = text
        .lines()
        .skip(1)
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            (
                f[0].to_string(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
            )
        })
        .filter(|(tag, _, _)| tag == "blue" || tag == "yellow")
        .collect();
    let mut gaps: Vec<f64> = cones
        .iter()
        .enumerate()
        .map(|(i, (tag, x, y))| {
            cones
                .iter()
                .enumerate()
                .filter(|(j, (other, _, _))| *j != i && other == tag)
                .map(|(_, (_, u, v))| (u - x).hypot(v - y))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    gaps.sort_by(f64::total_cmp);
    gaps[gaps.len() / 2]
}

#[test]
fn the_cone_spacing_of_a_random_track_can_be_chosen() {
    for (spacing, low, high) in [("1.5,2", 1.5, 2.0), ("4", 4.0, 4.0)] {
        let dir = temp_dir(&format!("spacing-{spacing}"));
        let args = ["fs-sim", "--seed", "3", "--laps", "0.2"];
        let o = cairn(&[&args[..], &["--cone-spacing", spacing, "-o", s(&dir)]].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // Spread evenly along a curved boundary: a little under the spacing drawn.
        let median = boundary_spacing(&dir);
        assert!(
            median > 0.9 * low && median <= high + 1e-9,
            "{spacing}: {median}"
        );
    }
    let dir = temp_dir("spacing-default");
    let o = cairn(&["fs-sim", "--seed", "3", "--laps", "0.2", "-o", s(&dir)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(boundary_spacing(&dir) > 2.7);

    let track = "tracks/any.csv";
    for bad in [
        vec!["--cone-spacing", "2,1"],
        vec!["--cone-spacing", "0"],
        vec!["--cone-spacing", "6"],
        vec!["--cone-spacing", "nan"],
        vec!["--cone-spacing", "2", "--track", track],
    ] {
        let args = [&["fs-sim", "-o", s(&dir)][..], &bad[..]].concat();
        let o = cairn(&args);
        assert!(!o.status.success(), "{bad:?} accepted");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains("--cone-spacing"),
            "{bad:?}"
        );
    }
}

#[test]
fn a_detector_noisier_than_assumed_is_warned_about_and_can_be_described() {
    let dir = temp_dir("noise");
    simulate_short_run(&dir, &["--preset", "hard"]);
    let log = dir.join("log.jsonl");
    let run = |extra: &[&str]| {
        let mut args = vec!["fs-slam", s(&log)];
        args.extend(extra);
        let o = cairn(&args);
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    // Read with the `standard` noise, the `hard` detector's far cones fall
    // outside the gates and are rejected as spurious.
    let (ok, stderr) = run(&[]);
    assert!(ok && stderr.contains("rejected as spurious"), "{stderr}");
    assert!(stderr.contains("--noise hard"), "{stderr}");
    // Told the noise, by preset or by its parts, it keeps them.
    let described = [
        "--range-sigma",
        "0.1",
        "--range-sigma-relative",
        "0.02",
        "--bearing-sigma-deg",
        "2",
        "--detection-probability",
        "0.8",
        "--false-positives",
        "1",
    ];
    for extra in [&["--noise", "hard"][..], &described[..]] {
        let (ok, stderr) = run(extra);
        assert!(ok && !stderr.contains("rejected"), "{extra:?}: {stderr}");
    }
    let scored = slam_and_score(&dir, &described);
    let accuracy = scored["association_accuracy"].as_f64().unwrap();
    assert!(accuracy > 0.97, "{accuracy}");
    let bad = ["0", "-1", "nan", "inf"].map(|v| ("--bearing-sigma-deg", v));
    for (name, value) in bad.into_iter().chain([
        ("--detection-probability", "1.5"),
        ("--false-positives", "-1"),
    ]) {
        let (ok, stderr) = run(&[&format!("{name}={value}")]);
        assert!(!ok && stderr.contains(name), "{name}={value}: {stderr}");
    }
    let (ok, _) = run(&["--range-sigma-relative", "0"]);
    assert!(ok, "a range σ that does not grow with range is allowed");
}

#[test]
fn the_report_runs_the_seeds_it_is_given() {
    // One random track, no shared ones: 2 presets × 4 methods × 2 seeds.
    let dir = temp_dir("report");
    let (tracks, out) = (dir.join("tracks"), dir.join("report.md"));
    std::fs::create_dir_all(&tracks).unwrap();
    let report = |first: &str| {
        let args = ["--random", "1", "--seeds", "2", "--first-seed", first];
        let command = [
            &["fs-report", "--tracks", s(&tracks), "-o", s(&out)],
            &args[..],
        ];
        let o = cairn(&command.concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read_to_string(&out).unwrap()
    };
    let (first, later) = (report("0"), report("3"));
    let head = |r: &str| r[..300].to_string();
    let named = format!(" -o {}`", out.display());
    assert!(
        first.contains(&format!("fs-report --seeds 2 --random 1{named}")),
        "{}",
        head(&first)
    );
    assert!(
        later.contains(&format!(
            "fs-report --seeds 2 --random 1 --first-seed 3{named}"
        )),
        "{}",
        head(&later)
    );
    assert!(later.contains("(16 runs: 1 tracks"), "{}", head(&later));
    assert!(dir.join("report").join("random-0.svg").exists());
    // Other seeds, other runs: the per-track tables differ.
    let tables = |r: &str| r[r.find("## Per track").unwrap()..].to_string();
    assert_ne!(tables(&first), tables(&later));
}

#[test]
fn a_simulation_with_a_noisier_detector_says_how_to_map_it() {
    // The log does not carry the detector's noise, and fs-slam's gates
    // assume `standard` unless told: run on a `hard` log they reject most
    // far detections.
    for (preset, hint) in [("hard", true), ("standard", false)] {
        let dir = temp_dir(&format!("hint-{preset}"));
        let o = cairn(&[
            "fs-sim",
            "--seed",
            "2",
            "--laps",
            "0.1",
            "--preset",
            preset,
            "-o",
            s(&dir),
        ]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{stderr}");
        assert_eq!(stderr.contains("--noise hard"), hint, "{stderr}");
    }
}

/// Localising on another track's map: the run says that the map may be
/// the wrong one.
#[test]
fn localising_on_another_tracks_map_is_warned_about() {
    let (here, there) = (temp_dir("map-here"), temp_dir("map-there"));
    simulate_short_run(&here, &[]);
    let o = cairn(&["fs-sim", "--seed", "5", "--laps", "0.3", "-o", s(&there)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = cairn(&[
        "fs-slam",
        s(&here.join("log.jsonl")),
        "--map-in",
        s(&there.join("truth_map.csv")),
    ]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(
        said.contains("is not the map of this run's track"),
        "{said}"
    );
    let o = cairn(&[
        "fs-slam",
        s(&here.join("log.jsonl")),
        "--map-in",
        s(&here.join("truth_map.csv")),
    ]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(!said.contains("is not the map"), "{said}");
}

/// `fs-eval` scores a map and trajectory without associations, and refuses
/// a plot format it cannot write before doing any work.
#[test]
fn fs_eval_without_associations_and_with_a_plot_it_cannot_write() {
    let dir = temp_dir("eval-noassoc");
    simulate_short_run(&dir, &[]);
    let (map, traj) = (dir.join("m.csv"), dir.join("t.tum"));
    let log = dir.join("log.jsonl");
    let o = cairn(&[
        "fs-slam",
        s(&log),
        "--map-out",
        s(&map),
        "--traj-out",
        s(&traj),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let eval = |extra: &[&str]| {
        let mut args = vec![
            "fs-eval",
            "--truth",
            s(&dir),
            "--map",
            s(&map),
            "--traj",
            s(&traj),
        ];
        args.extend(extra);
        cairn(&args)
    };
    let o = eval(&[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(table.contains("not scored (no --assoc)"), "{table}");
    assert!(table.contains("map RMSE (m)"), "{table}");
    let o = eval(&["--json"]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(json["association_accuracy"].is_null());
    assert!(json["map_rmse"].as_f64().is_some_and(|e| e < 0.5));
    let svg = dir.join("plot.svg");
    let o = eval(&["--plot", s(&svg)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let drawn = std::fs::read_to_string(&svg).unwrap();
    for part in [
        "m.csv against",
        "map error, ×20",
        "1σ of a mapped cone",
        "position error (m)",
    ] {
        assert!(drawn.contains(part), "{part} is not in the plot");
    }
    let pdf = dir.join("plot.pdf");
    let o = eval(&["--plot", s(&pdf)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains(".svg or .png"));
    assert!(!pdf.exists());
}

/// `fs-eval --align` scores a map that turned as a whole on its shape: 20
/// cones of a track, turned by 0.5 rad and shifted, match almost nothing in
/// their own frame and every cone once placed.
#[test]
fn fs_eval_align_places_a_turned_map_on_the_truth() {
    let dir = temp_dir("eval-align");
    simulate_short_run(&dir, &[]);
    let truth = std::fs::read_to_string(dir.join("truth_map.csv")).unwrap();
    let lines: Vec<&str> = truth.lines().take(21).collect();
    let (c, s0) = (0.5f64.cos(), 0.5f64.sin());
    let mut turned = vec![lines[0].to_string()];
    for line in &lines[1..] {
        let mut f: Vec<String> = line.split(',').map(str::to_string).collect();
        let (x, y): (f64, f64) = (f[1].parse().unwrap(), f[2].parse().unwrap());
        f[1] = (c * x - s0 * y + 3.0).to_string();
        f[2] = (s0 * x + c * y - 2.0).to_string();
        turned.push(f.join(","));
    }
    let small = dir.join("small");
    std::fs::create_dir_all(&small).unwrap();
    std::fs::write(small.join("truth_map.csv"), lines.join("\n") + "\n").unwrap();
    std::fs::copy(dir.join("truth_traj.tum"), small.join("truth_traj.tum")).unwrap();
    let map = dir.join("turned.csv");
    std::fs::write(&map, turned.join("\n") + "\n").unwrap();
    let traj = dir.join("truth_traj.tum");
    let score = |extra: &[&str]| {
        let mut args = vec![
            "fs-eval",
            "--truth",
            s(&small),
            "--map",
            s(&map),
            "--traj",
            s(&traj),
        ];
        args.extend(extra);
        let o = cairn(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        o.stdout
    };
    let json = |out: Vec<u8>| serde_json::from_slice::<serde_json::Value>(&out).unwrap();
    let unplaced = json(score(&["--json"]));
    assert!(unplaced["phantom"].as_u64().unwrap() > 10, "{unplaced}");
    let placed = json(score(&["--json", "--align"]));
    assert_eq!(placed["phantom"].as_u64(), Some(0), "{placed}");
    assert_eq!(placed["landmarks"].as_u64(), Some(20), "{placed}");
    assert_eq!(placed["placed_by_alignment"].as_bool(), Some(true));
    assert!(placed["map_rmse"].as_f64().unwrap() < 1e-6, "{placed}");
    let table = String::from_utf8_lossy(&score(&["--align"])).to_string();
    assert!(table.contains("its best rigid alignment"), "{table}");
    // Each landmark lands on the true cone it was made from, in its row.
    let matches = dir.join("matches.csv");
    score(&["--align", "--matches-out", s(&matches)]);
    let rows = std::fs::read_to_string(&matches).unwrap();
    let mut lines = rows.lines();
    assert_eq!(lines.next(), Some("truth_index,x,y,truth_x,truth_y"));
    let mut count = 0;
    for (k, line) in lines.enumerate() {
        let f: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
        assert_eq!(f[0], k as f64, "{rows}");
        assert!((f[1] - f[3]).hypot(f[2] - f[4]) < 1e-6, "{line}");
        count += 1;
    }
    assert_eq!(count, 20, "{rows}");
}
