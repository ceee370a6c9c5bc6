//! Real data end to end: a robot of MRCLAM Dataset 6 imported, mapped by
//! every estimator from `configs/mrclam.toml`, and scored, as a user would
//! run it, and Dataset 1 (no true trajectory) scored with its map placed by
//! its associations. The bounds are regression guards near today's results (see
//! docs/real-data.md), far from the targets of the real-data issue.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn cairn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cairn"))
        .args(args)
        .output()
        .expect("runs")
}

fn dataset6() -> Option<PathBuf> {
    Some(common::shared()?.join("real/mrclam/MRCLAM_Dataset6"))
}

fn dataset1() -> Option<PathBuf> {
    Some(common::shared()?.join("real/mrclam/MRCLAM_Dataset1"))
}

/// An empty scratch folder named for `what` and this process.
fn scratch(what: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cairn-{what}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// `fs-eval --json` of an estimate against the truth in `dir`.
fn evaluate(dir: &Path, map: &Path, traj: &Path, assoc: &Path) -> serde_json::Value {
    evaluate_with(dir, map, traj, assoc, &[])
}

/// [`evaluate`] with more `fs-eval` options.
fn evaluate_with(
    dir: &Path,
    map: &Path,
    traj: &Path,
    assoc: &Path,
    options: &[&str],
) -> serde_json::Value {
    let mut args = vec![
        "fs-eval",
        "--truth",
        s(dir),
        "--map",
        s(map),
        "--traj",
        s(traj),
        "--assoc",
        s(assoc),
        "--json",
    ];
    args.extend(options);
    let o = cairn(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("JSON")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

/// `fs-slam` on the imported log in `dir` with `configs/mrclam.toml` and
/// `options`, its outputs in `dir` as (map, trajectory, associations).
fn slam(dir: &Path, options: &[&str]) -> (Output, [PathBuf; 3]) {
    slam_with(dir, &shipped_config(), options)
}

/// `configs/mrclam.toml`.
fn shipped_config() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/mrclam.toml")
}

/// [`slam`] with the config file `config`.
fn slam_with(dir: &Path, config: &Path, options: &[&str]) -> (Output, [PathBuf; 3]) {
    let outputs = [
        dir.join("map.csv"),
        dir.join("traj.tum"),
        dir.join("assoc.csv"),
    ];
    let [map, traj, assoc] = &outputs;
    let log = dir.join("log.jsonl");
    let mut args = vec!["fs-slam", s(&log), "--config", s(config)];
    args.extend_from_slice(options);
    args.extend([
        "--map-out",
        s(map),
        "--traj-out",
        s(traj),
        "--assoc-out",
        s(assoc),
    ]);
    (cairn(&args), outputs)
}

/// Graph SLAM with maximum likelihood on `robot` of `dataset`, imported
/// into a scratch folder named for `what`: the folder and `fs-eval`'s report.
fn graph_ml(dataset: &Path, robot: &str, what: &str) -> (PathBuf, serde_json::Value) {
    let dir = scratch(what);
    import(dataset, robot, &dir);
    let (o, [map, traj, assoc]) = slam(&dir, &["--estimator", "graph", "--association", "ml"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = evaluate(&dir, &map, &traj, &assoc);
    (dir, report)
}

/// `fs-import mrclam` of `robot` of `dataset` into `dir`; what it said.
fn import(dataset: &Path, robot: &str, dir: &Path) -> String {
    let o = cairn(&[
        "fs-import",
        "mrclam",
        s(dataset),
        "--robot",
        robot,
        "-o",
        s(dir),
    ]);
    let said = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{said}");
    said
}

/// `fs-smooth` of the imported log in `dir` given the barcodes, with
/// `extra` options; its outputs in `dir` as (map, trajectory, associations).
fn smooth(dir: &Path, extra: &[&str]) -> [PathBuf; 3] {
    let config = shipped_config();
    let outputs = [
        dir.join("s.csv"),
        dir.join("s.tum"),
        dir.join("s_assoc.csv"),
    ];
    let [map, traj, assoc] = &outputs;
    let (log, truth) = (dir.join("log.jsonl"), dir.join("truth_assoc.csv"));
    let mut args = vec![
        "fs-smooth",
        s(&log),
        "--assoc",
        s(&truth),
        "--config",
        s(&config),
        "--map-out",
        s(map),
        "--traj-out",
        s(traj),
        "--assoc-out",
        s(assoc),
    ];
    args.extend_from_slice(extra);
    let o = cairn(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    outputs
}

#[test]
fn every_estimator_maps_an_imported_mrclam_robot() {
    let Some(dataset) = dataset6() else { return };
    let dir = std::env::temp_dir().join(format!("cairn-real-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let said = import(&dataset, "4", &dir);
    assert!(
        said.contains("2026 detections (3 misread barcodes)"),
        "{said}"
    );
    for estimator in ["graph", "ekf", "fastslam1", "fastslam2"] {
        let (o, [map, traj, assoc]) = slam(&dir, &["--estimator", estimator]);
        assert!(
            o.status.success(),
            "{estimator}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let report = evaluate(&dir, &map, &traj, &assoc);
        let number = |key: &str| report[key].as_f64().unwrap_or(f64::NAN);
        eprintln!("{estimator}: {report}");
        // Every detection scored, some landmarks on true ones, a bounded
        // trajectory (integrating the commanded velocities: 2.05 m).
        // Regression guards near today's results, in the map's own frame:
        // the graph 4 of 15 (robot 4's blind spin turns its whole map),
        // ATE 1.19 m, 92% right; the filters 7-11 of 15 and 37-44% right,
        // EKF ATE 0.98 m. FastSLAM's ATE here is chaotic: FastSLAM 1.0 gives
        // 2.2-7.8 m over seeds 0-3.
        assert_eq!(number("detections"), 2026.0, "{estimator}");
        let on_landmarks = number("landmarks") - number("phantom");
        assert!(on_landmarks >= 3.0, "{estimator}: {report}");
        let ate_bound = if estimator.starts_with("fastslam") {
            9.0
        } else {
            1.5
        };
        assert!(number("ate") < ate_bound, "{estimator}: {report}");
        assert!(
            number("association_accuracy") > 0.33,
            "{estimator}: {report}"
        );
    }
    // The batch smoother given the barcodes maps every landmark (today
    // 0.129 m aligned on this robot; the bound is a regression guard), and
    // its graph solves again from the g2o file at no lower χ².
    let g2o = dir.join("s.g2o");
    let [map, traj, assoc] = smooth(&dir, &["--g2o-out", s(&g2o)]);
    let report = evaluate(&dir, &map, &traj, &assoc);
    assert_eq!(
        (report["landmarks"].as_u64(), report["phantom"].as_u64()),
        (Some(15), Some(0)),
        "{report}"
    );
    assert!(
        report["map_rmse_aligned"]
            .as_f64()
            .is_some_and(|e| e < 0.25),
        "{report}"
    );
    assert_eq!(
        report["association_accuracy"].as_f64(),
        Some(1.0),
        "{report}"
    );
    let o = cairn(&[
        "solve",
        s(&g2o),
        "--init",
        "file",
        "--solver",
        "lm",
        "--robust-kernel",
        "cauchy",
        "--json",
    ]);
    let solved: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    let (start, end) = (
        solved["summary"]["initial_chi2"].as_f64(),
        solved["summary"]["final_chi2"].as_f64(),
    );
    assert!(
        start.zip(end).is_some_and(|(a, b)| b <= a * (1.0 + 1e-9)),
        "{solved}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_config_file_is_checked_and_its_values_overridden() {
    let dir = std::env::temp_dir().join(format!("cairn-config-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let o = cairn(&["fs-sim", "--seed", "3", "--laps", "0.3", "-o", s(&dir)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let log = dir.join("log.jsonl");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "range_sigma = 0.05\nbearing_sigma_deg = 1.0\n").expect("writes");
    let o = cairn(&["fs-slam", s(&log), "--config", s(&bad)]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        said.contains("bad.toml") && said.contains("bearing_sigma_deg"),
        "{said}"
    );
    std::fs::write(&bad, "gate = -1.0\n").expect("writes");
    let o = cairn(&["fs-slam", s(&log), "--config", s(&bad)]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(said.contains("gate must be finite and positive"), "{said}");
    let o = cairn(&["fs-slam", s(&log), "--config", s(&bad), "--noise", "hard"]);
    assert!(
        !o.status.success(),
        "--config and --noise together are refused"
    );
    // A config whose assumed range noise is far too small rejects most
    // detections (the warning names the noise it assumed); the option
    // overrides it.
    std::fs::write(
        &bad,
        "range_sigma = 0.0001\nrange_sigma_relative = 0.0\nbearing_sigma = 0.00001\n",
    )
    .expect("writes");
    let o = cairn(&["fs-slam", s(&log), "--config", s(&bad)]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{said}");
    assert!(said.contains("range σ 0.0001 m"), "{said}");
    let o = cairn(&[
        "fs-slam",
        s(&log),
        "--config",
        s(&bad),
        "--range-sigma",
        "0.05",
        "--range-sigma-relative",
        "0.01",
        "--bearing-sigma-deg",
        "0.5",
    ]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && !said.contains("rejected as spurious"),
        "{said}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every Dataset 6 robot, graph SLAM with maximum likelihood: after the
/// stretches where the robots spin or see nothing for up to a minute, the
/// front end finds itself on its map again instead of matching one
/// detection through a wide gate (robots 1 and 2 ended 3.5 and 5.3 m off
/// before; robot 4 failed with the turn noise and lag of configs/mrclam.toml
/// until its yaw-rate bias had a tight prior). The bounds are regression
/// guards a little past today's results (ATE 0.12–1.19 m in the map's own
/// frame, robot 4's turned as a whole in its first blind spin; after the
/// map's best rigid placement, as the issue counts them, 13–15 of 15 true
/// landmarks mapped one-to-one, no phantom, 0.067–0.118 m aligned map RMSE,
/// 79–94% of detections right; docs/real-data.md), short of the issue's
/// association target.
#[test]
fn the_graph_front_end_finds_itself_again_on_every_robot() {
    let Some(dataset) = dataset6() else { return };
    let dir = std::env::temp_dir().join(format!("cairn-reloc-{}", std::process::id()));
    for robot in 1..=5 {
        let _ = std::fs::remove_dir_all(&dir);
        let robot = robot.to_string();
        import(&dataset, &robot, &dir);
        let (o, [map, traj, assoc]) = slam(&dir, &["--estimator", "graph", "--association", "ml"]);
        let said = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "robot {robot}: {said}");
        assert!(
            !said.contains(" 0 relocalisation(s)"),
            "robot {robot}: {said}"
        );
        let report = evaluate(&dir, &map, &traj, &assoc);
        let number = |key: &str| report[key].as_f64().unwrap_or(f64::NAN);
        eprintln!("robot {robot}: {report}");
        assert!(number("ate") < 1.5, "robot {robot}: {report}");
        let report = evaluate_with(&dir, &map, &traj, &assoc, &["--align"]);
        let number = |key: &str| report[key].as_f64().unwrap_or(f64::NAN);
        eprintln!("robot {robot}, placed: {report}");
        assert!(number("missed") <= 3.0, "robot {robot}: {report}");
        assert!(number("phantom") <= 1.0, "robot {robot}: {report}");
        assert!(number("map_rmse_aligned") < 0.2, "robot {robot}: {report}");
        assert!(
            number("association_accuracy") > 0.7,
            "robot {robot}: {report}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// MRCLAM's Dataset 1 has no Vicon trajectory: the import writes no start
/// pose and no true trajectory, the estimate is in the robot's own frame,
/// and `fs-eval` places it on the truth by its associations before scoring
/// the map. The batch smoother given the barcodes lands every landmark
/// there (today 0.048 m on robot 2; the bound is a regression guard), and
/// the placement is the best rigid fit: the map RMSE is the aligned one.
#[test]
fn a_recording_without_a_trajectory_is_placed_by_its_associations() {
    let Some(dataset) = dataset1() else { return };
    let dir = scratch("dataset1");
    import(&dataset, "2", &dir);
    assert!(!dir.join("truth_traj.tum").exists());
    let [map, traj, assoc] = smooth(&dir, &[]);
    let report = evaluate(&dir, &map, &traj, &assoc);
    let number = |key: &str| report[key].as_f64().unwrap_or(f64::NAN);
    assert_eq!(report["placed_by_associations"].as_bool(), Some(true));
    assert_eq!(
        (number("landmarks"), number("phantom")),
        (15.0, 0.0),
        "{report}"
    );
    assert!(number("map_rmse") < 0.1, "{report}");
    assert!(
        number("map_rmse") - number("map_rmse_aligned") < 0.01,
        "{report}"
    );
    assert!(report["ate"].is_null(), "{report}");
    // The graph front end, not told the barcodes, is scored the same way.
    let (o, [map, traj, assoc]) = slam(&dir, &["--estimator", "graph"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = evaluate(&dir, &map, &traj, &assoc);
    assert_eq!(report["placed_by_associations"].as_bool(), Some(true));
    assert!(
        report["map_rmse"].as_f64().is_some_and(f64::is_finite),
        "{report}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Robot 1 of Dataset 1 loses itself after about 16 minutes: relocalisation
/// gives up and the landmarks in view are mapped again, 4.8 m and 0.9 rad
/// off. At the end of the run that batch is fitted onto the earlier map and
/// merged into it (16 landmarks, 2 phantoms, 81% of detections right when
/// the merge came; 30, 15 and 64% without it; today, with the odometry
/// model of configs/mrclam.toml, 16, 3 and 78%). The bounds are regression
/// guards.
#[test]
fn landmarks_mapped_again_after_the_robot_lost_itself_are_merged() {
    let Some(dataset) = dataset1() else { return };
    let (dir, report) = graph_ml(&dataset, "1", "remapped");
    let number = |key: &str| report[key].as_f64().unwrap_or(f64::NAN);
    assert!(number("phantom") <= 4.0, "{report}");
    assert!(number("association_accuracy") > 0.7, "{report}");
    assert!(number("map_rmse_aligned") < 0.3, "{report}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Robot 2 of Dataset 1 (held out: `configs/mrclam.toml` was measured on
/// Dataset 6) wiggles on the spot on commanded spins its wheels execute
/// 35% short. Told that a turn's heading error grows with the angle
/// turned (`turn_sigma`) and that the robot answers its commands late
/// (`scan_latency`), the gates widen through the spins and the landmarks
/// seen during them are matched, not mapped again: today all 15 landmarks,
/// no phantom and 99.0% of detections right (44 landmarks, 31 phantoms and
/// 39.8% without the two). The bounds are regression guards.
#[test]
fn a_robot_spinning_on_commanded_turns_maps_each_landmark_once() {
    let Some(dataset) = dataset1() else { return };
    let (dir, report) = graph_ml(&dataset, "2", "spins");
    let number = |key: &str| report[key].as_f64().unwrap_or(f64::NAN);
    assert_eq!(number("missed"), 0.0, "{report}");
    assert!(number("phantom") <= 1.0, "{report}");
    assert!(number("association_accuracy") >= 0.95, "{report}");
    assert!(number("map_rmse_aligned") < 0.1, "{report}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `configs/mrclam.toml` with `replacements` (each a line of it and its
/// replacement) applied, written into `dir` as `name`.
fn config_with(dir: &Path, name: &str, replacements: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(shipped_config()).expect("the shipped config reads");
    for (line, replacement) in replacements {
        assert!(text.contains(line), "{line} is not in the shipped config");
        text = text.replace(line, replacement);
    }
    let path = dir.join(name);
    std::fs::write(&path, text).expect("writes");
    path
}

/// Association accuracy and phantoms of a graph run on the robot imported
/// into `dir`, with `config` and the association `method`.
fn accuracy(dir: &Path, config: &Path, method: &str) -> (f64, f64) {
    let (o, [map, traj, assoc]) = slam_with(dir, config, &["--association", method]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = evaluate(dir, &map, &traj, &assoc);
    let number = |key: &str| report[key].as_f64().unwrap_or(f64::NAN);
    (number("association_accuracy"), number("phantom"))
}

const ANNEALED: &str = "hindsight_anneal = 8.0";
const NOT_ANNEALED: &str = "hindsight_anneal = 1.0";

/// Dataset 6's tubes stand 0.15–0.25 m apart, closer than the camera's
/// range noise: which detection is which tube, and where the tubes stand,
/// settle together over rounds of matching in hindsight, annealed from a
/// wide σ and then at the detector's (configs/mrclam.toml). Robot 3 with
/// SCNN: today 96.5% of detections right after them, 82.9% after one
/// round at the detector's σ. The bounds are regression guards; 95% is
/// the real-data issue's target.
#[test]
fn tubes_closer_than_the_noise_settle_over_rounds_of_matching() {
    let Some(dataset) = dataset6() else { return };
    let dir = scratch("rounds");
    import(&dataset, "3", &dir);
    let once = config_with(
        &dir,
        "once.toml",
        &[
            ("hindsight_rounds = 5", "hindsight_rounds = 1"),
            (ANNEALED, NOT_ANNEALED),
        ],
    );
    let (rounds, phantoms) = accuracy(&dir, &shipped_config(), "scnn");
    let (one, _) = accuracy(&dir, &once, "scnn");
    assert_eq!(phantoms, 0.0);
    assert!(rounds >= 0.95, "{rounds}");
    assert!(
        rounds > one + 0.05,
        "{rounds} after the rounds, {one} after one"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Robot 2 of Dataset 6 with maximum likelihood: matched at the detector's
/// σ from the first round, the rounds settled with a landmark midway
/// between two tubes of a group of three (72.2% of detections right);
/// annealed from 8 times that σ, 81.2% today. The bound is a regression
/// guard.
#[test]
fn annealing_the_matching_in_hindsight_tells_close_tubes_apart() {
    let Some(dataset) = dataset6() else { return };
    let dir = scratch("anneal");
    import(&dataset, "2", &dir);
    let plain = config_with(&dir, "plain.toml", &[(ANNEALED, NOT_ANNEALED)]);
    let (annealed, phantoms) = accuracy(&dir, &shipped_config(), "ml");
    let (not_annealed, _) = accuracy(&dir, &plain, "ml");
    assert_eq!(phantoms, 0.0);
    assert!(
        annealed > not_annealed + 0.05,
        "{annealed} annealed, {not_annealed} not"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
