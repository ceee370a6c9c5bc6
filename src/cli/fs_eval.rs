//! `cairn fs-eval`: a cone-SLAM run scored against the simulation's truth.

use super::fs::{TRUTH_ASSOC, TRUTH_MAP, TRUTH_TRAJ, read_text};
use super::{bad_input, file_name};
use cairn::fs_tools::eval::{
    MATCH_RADIUS, Report, evaluate, latency_ms, map_labels, one_to_one_accuracy, place,
    placement_by_associations, position_errors,
};
use cairn::fs_tools::placement::best_placement;
use cairn::plot::{MapPlot, draw};
use cairn::slam::Cone;
use cairn::slam::files::{self, StampedPose};
use cairn::slam::map::map_from_csv;
use clap::Args;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Options of `cairn fs-eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Truth directory (from fs-sim or fs-import) with truth_map.csv,
    /// truth_assoc.csv and truth_traj.tum. Without the trajectory it is not
    /// scored, and the estimate is taken to be in its own frame: with
    /// --assoc the map is first placed on the truth where its landmarks'
    /// detections say they stand.
    #[arg(long)]
    truth: PathBuf,
    /// Estimated map (EUFS CSV).
    #[arg(long)]
    map: PathBuf,
    /// Estimated trajectory (TUM).
    #[arg(long)]
    traj: PathBuf,
    /// Estimated associations (CSV); without them the association accuracy
    /// is not scored.
    #[arg(long)]
    assoc: Option<PathBuf>,
    /// The associations before the end-of-run pass (`fs-slam
    /// --assoc-real-time-out`): their accuracy is the real-time one.
    #[arg(long)]
    assoc_real_time: Option<PathBuf>,
    /// Timings written by `fs-slam --timing-out`.
    #[arg(long)]
    timing: Option<PathBuf>,
    /// Score the map after its best rigid placement on the truth: the one
    /// that matches the most landmarks within 1 m, found from the positions
    /// alone (no associations), as the real-data targets count "mapped".
    /// The trajectory moves with the map, so the ATE is then the placed
    /// one's. Without it the map is scored in its own frame, or placed by
    /// its associations where the truth has no trajectory.
    #[arg(long)]
    align: bool,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Draw the map over the truth and both trajectories: FILE.svg or FILE.png.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// The plot's title (default: the map's file name and the truth's folder).
    #[arg(long)]
    title: Option<String>,
    /// Write each landmark's one-to-one match to a true cone as CSV
    /// (`truth_index,x,y,truth_x,truth_y`, in the frame the map was scored
    /// in), to compare maps over the cones they both mapped.
    #[arg(long)]
    matches_out: Option<PathBuf>,
}

pub fn run_eval(a: EvalArgs) -> Result<(), super::CliError> {
    if let Some(path) = &a.plot {
        check_plot_format(path)?;
    }
    let truth_map =
        map_from_csv(&read_text(&a.truth.join(TRUTH_MAP))?).map_err(bad_input(TRUTH_MAP))?;
    // A real dataset may have no recorded trajectory (MRCLAM's Dataset 1):
    // the map and the associations are scored, the trajectory is not.
    let truth_traj_path = a.truth.join(TRUTH_TRAJ);
    let truth_traj = if truth_traj_path.exists() {
        Some(
            files::trajectory_from_tum(&read_text(&truth_traj_path)?)
                .map_err(bad_input(TRUTH_TRAJ))?,
        )
    } else {
        None
    };
    let (truth_assoc, assoc) = match &a.assoc {
        Some(path) => (
            files::associations_from_csv(&read_text(&a.truth.join(TRUTH_ASSOC))?)
                .map_err(bad_input(TRUTH_ASSOC))?,
            files::associations_from_csv(&read_text(path)?).map_err(bad_input(path.display()))?,
        ),
        None => (Vec::new(), Vec::new()),
    };
    let mut map = map_from_csv(&read_text(&a.map)?).map_err(bad_input(a.map.display()))?;
    let mut traj =
        files::trajectory_from_tum(&read_text(&a.traj)?).map_err(bad_input(a.traj.display()))?;
    // With --align the map's shape places it. Otherwise, without a true
    // trajectory the log had no start pose either: the estimate is in its
    // own frame, and the associations place it.
    let positions = |cones: &[Cone]| cones.iter().map(|c| c.position).collect::<Vec<_>>();
    let aligned = a
        .align
        .then(|| best_placement(&positions(&map), &positions(&truth_map), MATCH_RADIUS));
    let by_associations = (aligned.is_none() && truth_traj.is_none())
        .then(|| placement_by_associations(&truth_map, &map, &truth_assoc, &assoc))
        .flatten();
    if let Some(placement) = aligned.as_ref().or(by_associations.as_ref()) {
        place(placement, &mut map, &mut traj);
    } else if truth_traj.is_none() {
        eprintln!(
            "warning: {} has no {TRUTH_TRAJ}: the map is scored in its own frame \
             (--assoc places it on the truth first)",
            a.truth.display()
        );
    }
    let mut report = evaluate(
        &truth_map,
        &map,
        truth_traj.as_deref().unwrap_or_default(),
        &traj,
        &truth_assoc,
        &assoc,
    );
    report.placed_by_associations = by_associations.is_some();
    report.placed_by_alignment = aligned.is_some();
    if let Some(path) = &a.assoc_real_time {
        let truth = files::associations_from_csv(&read_text(&a.truth.join(TRUTH_ASSOC))?)
            .map_err(bad_input(TRUTH_ASSOC))?;
        let real_time =
            files::associations_from_csv(&read_text(path)?).map_err(bad_input(path.display()))?;
        report.association_accuracy_real_time = Some(one_to_one_accuracy(&truth, &real_time).0);
    }
    if a.assoc.is_none() {
        // JSON writes it as null, the table as not scored.
        report.association_accuracy = f64::NAN;
        report.association_accuracy_majority = f64::NAN;
    }
    if truth_traj.is_none() {
        // JSON writes these as null, the table as not scored.
        report.ate = f64::NAN;
        report.ate_aligned = f64::NAN;
    }
    if let Some(path) = &a.timing {
        let v: serde_json::Value =
            serde_json::from_str(&read_text(path)?).map_err(bad_input(path.display()))?;
        let list = |key: &str| -> Vec<f64> {
            v.get(key)
                .and_then(|x| x.as_array())
                .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
                .unwrap_or_default()
        };
        report.latency_ms = latency_ms(&list("updates_s"));
        report.loop_closure_ms = list("loop_closures_s")
            .into_iter()
            .reduce(f64::max)
            .map(|s| s * 1e3);
        report.final_optimisation_ms = v.get("final_s").and_then(|x| x.as_f64()).map(|s| s * 1e3);
        let sigma = |key: &str| -> Option<[f64; 3]> {
            let list: Vec<f64> = v
                .get("detector_sigma")?
                .get(key)?
                .as_array()?
                .iter()
                .filter_map(|x| x.as_f64())
                .collect();
            list.try_into().ok()
        };
        report.detector_sigma = sigma("assumed")
            .zip(sigma("estimated"))
            .map(|(a, e)| [a, e]);
    }
    if let Some(path) = &a.matches_out {
        super::write_output(path, matches_csv(&truth_map, &map).as_bytes())?;
    }
    if let Some(path) = &a.plot {
        plot_run(
            path,
            &a.title.clone().unwrap_or_else(|| default_title(&a)),
            &truth_map,
            &map,
            truth_traj.as_deref().unwrap_or_default(),
            &traj,
        )?;
    }
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?
        );
    } else {
        print!("{}", table(&report));
    }
    Ok(())
}

/// The landmarks matched one-to-one to true cones, as `--matches-out`
/// writes them, in the true cones' order.
fn matches_csv(truth_map: &[Cone], map: &[Cone]) -> String {
    let mut pairs: Vec<(usize, &Cone)> = map_labels(truth_map, map)
        .into_iter()
        .zip(map)
        .filter_map(|(i, lm)| Some((i?, lm)))
        .collect();
    pairs.sort_by_key(|(i, _)| *i);
    let mut csv = String::from("truth_index,x,y,truth_x,truth_y\n");
    for (i, lm) in pairs {
        let t = truth_map[i].position;
        let _ = writeln!(
            csv,
            "{i},{},{},{},{}",
            lm.position.x, lm.position.y, t.x, t.y
        );
    }
    csv
}

/// `MAP.csv against TRUTH`: the names of the map file and the truth's folder.
fn default_title(a: &EvalArgs) -> String {
    format!("{} against {}", file_name(&a.map), file_name(&a.truth))
}

/// Refuses a plot file that is neither SVG nor PNG, before any work.
pub fn check_plot_format(path: &Path) -> Result<(), super::CliError> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if ext.eq_ignore_ascii_case("svg") || ext.eq_ignore_ascii_case("png") {
        Ok(())
    } else {
        Err(super::CliError::usage(format!(
            "--plot {}: plots are written as .svg or .png",
            path.display()
        )))
    }
}

/// Draws a run over its truth.
pub fn plot_run(
    path: &Path,
    title: &str,
    truth_map: &[Cone],
    map: &[Cone],
    truth_traj: &[StampedPose],
    traj: &[StampedPose],
) -> Result<(), String> {
    let true_path: Vec<_> = truth_traj.iter().map(|p| p.pose.t).collect();
    let est_path: Vec<_> = traj.iter().map(|p| p.pose.t).collect();
    draw(
        &MapPlot {
            title: title.to_string(),
            truth: truth_map,
            map,
            true_path: &true_path,
            path: &est_path,
            errors: &position_errors(truth_traj, traj),
        },
        path,
    )
}

/// A distance to three decimals, or why there is none.
fn scored(metres: f64) -> String {
    if metres.is_nan() {
        format!("not scored (no {TRUTH_TRAJ})")
    } else {
        format!("{metres:.3}")
    }
}

/// The report as an aligned text table.
pub fn table(r: &Report) -> String {
    let mut rows = vec![("landmarks".to_string(), r.landmarks.to_string())];
    if r.placed_by_associations {
        rows.push((
            "map placed by".into(),
            "the associations (no true trajectory)".into(),
        ));
    }
    if r.placed_by_alignment {
        rows.push((
            "map placed by".into(),
            "its best rigid alignment (--align)".into(),
        ));
    }
    rows.extend([
        ("map RMSE (m)".into(), format!("{:.3}", r.map_rmse)),
        (
            "map RMSE, aligned (m)".into(),
            format!("{:.3}", r.map_rmse_aligned),
        ),
    ]);
    if let (Some(predicted), Some(nees)) = (r.map_rmse_predicted, r.map_nees) {
        rows.push(("map RMSE, predicted (m)".into(), format!("{predicted:.3}")));
        rows.push(("map NEES (2 if consistent)".into(), format!("{nees:.2}")));
    }
    for (c, e, n) in &r.map_rmse_by_color {
        rows.push((format!("  {c} ({n})"), format!("{e:.3}")));
    }
    rows.extend([
        ("phantom landmarks".into(), r.phantom.to_string()),
        ("missed cones".into(), r.missed.to_string()),
        ("ATE (m)".into(), scored(r.ate)),
        ("ATE, aligned (m)".into(), scored(r.ate_aligned)),
        (
            "association accuracy".into(),
            if r.association_accuracy.is_nan() {
                "not scored (no --assoc)".into()
            } else {
                format!("{:.2}% of {}", 100.0 * r.association_accuracy, r.detections)
            },
        ),
    ]);
    if !r.association_accuracy_majority.is_nan() {
        rows.push((
            "  by majority (duplicates forgiven)".into(),
            format!("{:.2}%", 100.0 * r.association_accuracy_majority),
        ));
    }
    if let Some(real_time) = r.association_accuracy_real_time {
        rows.push((
            "  in real time (before the end-of-run pass)".into(),
            format!("{:.2}%", 100.0 * real_time),
        ));
    }
    if let Some([p50, p99, p999, max]) = r.latency_ms {
        rows.push((
            "update p50/p99/p99.9/max (ms)".into(),
            format!("{p50:.3} / {p99:.3} / {p999:.3} / {max:.3}"),
        ));
    }
    if let Some(ms) = r.loop_closure_ms {
        rows.push((
            "loop-closure scan, all of it (ms)".into(),
            format!("{ms:.1}"),
        ));
    }
    if let Some(ms) = r.final_optimisation_ms {
        rows.push(("final optimisation (ms)".into(), format!("{ms:.1}")));
    }
    if let Some([assumed, learned]) = r.detector_sigma {
        rows.push(("detector noise, assumed".into(), describe_sigma(assumed)));
        rows.push(("  learned".into(), describe_sigma(learned)));
    }
    let width = rows
        .iter()
        .map(|(k, _)| k.chars().count())
        .max()
        .unwrap_or(0);
    rows.iter()
        .map(|(k, v)| format!("{k:<width$}  {v}\n"))
        .collect()
}

/// A detector's σ (range, its growth with range, bearing in radians) in the
/// units people read.
pub(super) fn describe_sigma([r, relative, b]: [f64; 3]) -> String {
    format!(
        "σ_r {r:.3} m + {:.2}%, σ_b {:.2}°",
        100.0 * relative,
        b.to_degrees()
    )
}
