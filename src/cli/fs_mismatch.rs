//! `cairn fs-mismatch`: logs that differ from what the estimator assumes.
//! Every shared and random track × case × association method × seed is
//! simulated, mapped by the graph front end told `configs/standard.toml`,
//! and scored.

use super::fs_report::{TrackSet, Tracks};
use super::progress::Progress;
use cairn::fs_tools::configs::assumed_config;
use cairn::fs_tools::course::{Course, start_on_line};
use cairn::fs_tools::eval::Report;
use cairn::fs_tools::oracle::association_ceiling;
use cairn::fs_tools::run::run_and_score;
use cairn::fs_tools::sim::{Preset, simulate_preset};
use cairn::fs_tools::track::Track;
use cairn::slam::Color;
use cairn::slam::estimator::EstimatorKind;
use cairn::slam::frontend::FrontEndConfig;
use cairn::slam::frontend::association::AssociationMethod;
use clap::Args;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Options of `cairn fs-mismatch`.
#[derive(Debug, Args)]
pub struct MismatchArgs {
    #[command(flatten)]
    set: TrackSet,
    /// The first seed (pick seeds nothing was tuned on).
    #[arg(long, default_value_t = 100)]
    first_seed: u64,
    /// Markdown output.
    #[arg(short, long)]
    out: PathBuf,
}

/// How a log differs from what the estimator assumes.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Case {
    /// Detector noise σ times this.
    Noise(f64),
    /// Detector noise twice the assumed, the front end learning it.
    NoiseLearned,
    /// Student-t noise with 3 degrees of freedom at the same σ.
    StudentT,
    /// The gyro's bias random-walking at 5·10⁻⁴ rad/s/√s.
    BiasWalk,
    /// The same, the config giving the gyro's bias instability.
    BiasWalkTold,
    /// The track without its big orange cones.
    NoBigOrange,
    /// The car starting on the start line.
    StartOnLine,
    /// The car sliding 0.01 rad per m/s² of lateral acceleration.
    Sideslip,
    /// Scans stamped 50 ms after they were measured.
    Latency,
    /// The same, the config giving the latency.
    LatencyTold,
    /// The `realistic` preset.
    Realistic,
    /// The same, the graph told `configs/realistic.toml`.
    RealisticTold,
}

const CASES: [Case; 13] = [
    Case::Noise(0.5),
    Case::Noise(2.0),
    Case::NoiseLearned,
    Case::StudentT,
    Case::BiasWalk,
    Case::BiasWalkTold,
    Case::NoBigOrange,
    Case::StartOnLine,
    Case::Sideslip,
    Case::Latency,
    Case::LatencyTold,
    Case::Realistic,
    Case::RealisticTold,
];

impl Case {
    fn label(self) -> String {
        match self {
            Case::Noise(k) => format!("detector noise {k}× the assumed"),
            Case::NoiseLearned => "detector noise 2×, `--learn-noise`".into(),
            Case::StudentT => "Student-t (3 dof) noise".into(),
            Case::BiasWalk => "gyro bias walk 5·10⁻⁴ rad/s/√s".into(),
            Case::BiasWalkTold => "the same, `yaw_rate_bias_walk = 5e-4` in the config".into(),
            Case::NoBigOrange => "no big orange cones".into(),
            Case::StartOnLine => "starting on the start line".into(),
            Case::Sideslip => "sideslip 0.01 rad per m/s²".into(),
            Case::Latency => "scans 50 ms late".into(),
            Case::LatencyTold => "the same, `scan_latency = 0.05` in the config".into(),
            Case::Realistic => "`realistic` preset".into(),
            Case::RealisticTold => "the same, told `configs/realistic.toml`".into(),
        }
    }

    /// The track, its course and the preset the log is made with; `None`
    /// when the case does not apply to the track.
    fn log_of(self, track: &Track, course: &Course) -> Option<(Track, Course, Preset)> {
        let mut preset = Preset::standard();
        let mut track = track.clone();
        let mut course = course.clone();
        match self {
            Case::Noise(k) => preset.sensor.scale_noise(k),
            Case::NoiseLearned => return Case::Noise(2.0).log_of(&track, &course),
            Case::StudentT => preset.sensor.noise_dof = Some(3.0),
            Case::BiasWalk | Case::BiasWalkTold => preset.odometry.yaw_rate_bias_walk = 5e-4,
            Case::NoBigOrange => {
                track.cones.retain(|c| c.color != Color::BigOrange);
                course = Course::from_track(&track).ok()?;
            }
            Case::StartOnLine => track.start = start_on_line(&track, &course)?,
            Case::Sideslip => preset.odometry.sideslip = 0.01,
            Case::Latency | Case::LatencyTold => preset.sensor.latency = 0.05,
            Case::Realistic | Case::RealisticTold => preset = Preset::realistic(),
        }
        Some((track, course, preset))
    }
}

/// One run's score.
struct Run {
    case: Case,
    track: usize,
    seed: u64,
    method: AssociationMethod,
    report: Report,
    closed: bool,
    /// The share of detections matched right knowing the truth
    /// ([`association_ceiling`]).
    ceiling: Option<f64>,
}

pub fn run(a: MismatchArgs) -> Result<(), super::CliError> {
    let (tracks, _) = a.set.load()?;
    let mut jobs = Vec::new();
    for case in CASES {
        for t in 0..tracks.len() {
            for method in AssociationMethod::ALL {
                let file = if case == Case::RealisticTold {
                    "realistic"
                } else {
                    "standard"
                };
                let mut told = assumed_config(file, method, EstimatorKind::Graph)
                    .map_err(|e| e.to_string())?;
                told.learn_detector_noise = case == Case::NoiseLearned;
                if case == Case::BiasWalkTold {
                    told.yaw_rate_bias_walk = 5e-4;
                }
                if case == Case::LatencyTold {
                    told.scan_latency = 0.05;
                }
                for seed in a.first_seed..a.first_seed + a.set.seeds {
                    jobs.push((case, t, method, seed, told.clone()));
                }
            }
        }
    }
    eprintln!("{} runs on {} tracks…", jobs.len(), tracks.len());
    let progress = Progress::new(jobs.len(), "runs");
    let runs: Vec<Run> = jobs
        .par_iter()
        .filter_map(|(case, t, method, seed, told)| {
            let result = simulate_and_score(&tracks, (*case, *t, *method, *seed), told.clone());
            progress.inc();
            result
        })
        .collect();
    progress.finish();
    let md = markdown(&a, &tracks, &runs);
    super::write_output(&a.out, md.as_bytes())?;
    eprintln!("wrote {}", a.out.display());
    Ok(())
}

/// One run of `case` on track `t`, mapped by the graph `told` what to assume;
/// `None` when the case does not apply to the track.
fn simulate_and_score(
    tracks: &Tracks,
    (case, t, method, seed): (Case, usize, AssociationMethod, u64),
    told: FrontEndConfig,
) -> Option<Run> {
    let (track, course, preset) = case.log_of(&tracks[t].0, &tracks[t].1)?;
    let sensor = preset.sensor.clone();
    let sim = simulate_preset(&track, &course, preset, seed);
    let (slam, report) = run_and_score(&sim, told);
    Some(Run {
        case,
        track: t,
        seed,
        method,
        report,
        closed: slam.loop_closures() > 0,
        ceiling: association_ceiling(&sim, &sensor),
    })
}

/// A share as a percentage, or a dash where there is none.
fn percent(share: Option<f64>) -> String {
    share.map_or("–".into(), |s| format!("{:.2}%", 100.0 * s))
}

/// Association below which a run whose loop closed is listed by name.
const ASTRAY: f64 = 0.9;

fn markdown(a: &MismatchArgs, tracks: &Tracks, runs: &[Run]) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Cone SLAM on logs that differ from what it assumes\n\n\
         Generated by `cargo run --release -- fs-mismatch --seeds {} --random {} --first-seed {} -o {}` \
         ({} runs: {} tracks × {} cases × 4 association methods × {} seeds, 2 laps at 5 m/s; \
         cases that do not apply to a track, such as a start line on a track without big \
         orange cones, are left out). The graph front end is told `configs/standard.toml` \
         for every log, and what a case's label adds (`--learn-noise`, a config value, or \
         `configs/realistic.toml` in its place); each log is `standard` but for the case. Scored as in \
         `docs/fs-slam.md`: association with each true cone standing for one landmark, the \
         map matched one-to-one. `mean` is over runs; `worst` the worst run, named by its track and seed. \
         `at best` is what a matcher gets right knowing what no estimator knows: each scan matched \
         by maximum likelihood given the car's true pose, the true cones and the detector's true \
         noise (`cairn_fs_tools::oracle`). Where two cones stand closer than the noise separates \
         (the start line's big orange pairs, 0.28 m apart), it is below 100%. It is a reference, \
         not a strict bound: `tracking` passes it with the ids it does not use, and a run can pass \
         it by a little, as matching a scan by its likelihood is not the same as counting the \
         most detections right.\n",
        a.set.seeds,
        a.set.random,
        a.first_seed,
        a.out.display(),
        runs.len(),
        tracks.len(),
        CASES.len(),
        a.set.seeds
    );
    let _ = writeln!(
        md,
        "| the log | method | association, mean | at best, mean | worst (at best) | map RMSE (m), mean | worst | aligned (m), mean | loops closed |\n|---|---|---|---|---|---|---|---|---|"
    );
    let name = |r: &Run| format!("{} seed {}", tracks[r.track].0.name, r.seed);
    for case in CASES {
        for method in AssociationMethod::ALL {
            let sel: Vec<&Run> = runs
                .iter()
                .filter(|r| r.case == case && r.method == method)
                .collect();
            if sel.is_empty() {
                continue;
            }
            let n = sel.len() as f64;
            let mean = |f: fn(&Report) -> f64| sel.iter().map(|r| f(&r.report)).sum::<f64>() / n;
            // The worst runs are named, so that they can be made again.
            let worst_assoc = sel
                .iter()
                .min_by(|a, b| {
                    a.report
                        .association_accuracy
                        .total_cmp(&b.report.association_accuracy)
                })
                .map(|r| {
                    let accuracy = 100.0 * r.report.association_accuracy;
                    format!("{accuracy:.2}% ({}; {})", name(r), percent(r.ceiling))
                });
            let ceilings: Vec<f64> = sel.iter().filter_map(|r| r.ceiling).collect();
            let ceiling = (!ceilings.is_empty())
                .then(|| ceilings.iter().sum::<f64>() / ceilings.len() as f64);
            let worst_rmse = sel
                .iter()
                .max_by(|a, b| a.report.map_rmse.total_cmp(&b.report.map_rmse))
                .map(|r| format!("{:.3} ({})", r.report.map_rmse, name(r)));
            let _ = writeln!(
                md,
                "| {} | {} | {:.2}% | {} | {} | {:.3} | {} | {:.3} | {}/{} |",
                case.label(),
                method.name(),
                100.0 * mean(|r| r.association_accuracy),
                percent(ceiling),
                worst_assoc.unwrap_or_default(),
                mean(|r| r.map_rmse),
                worst_rmse.unwrap_or_default(),
                mean(|r| r.map_rmse_aligned),
                sel.iter().filter(|r| r.closed).count(),
                sel.len()
            );
        }
    }
    let describe = |r: &Run| {
        format!(
            "{} on {} with {}, seed {} ({:.1}%)",
            r.case.label(),
            tracks[r.track].0.name,
            r.method.name(),
            r.seed,
            100.0 * r.report.association_accuracy
        )
    };
    let open: Vec<String> = runs.iter().filter(|r| !r.closed).map(describe).collect();
    // A loop closed at the wrong place, or a lap mapped twice beside a
    // closed loop, shows as association near 50%.
    let astray: Vec<String> = runs
        .iter()
        .filter(|r| r.closed && r.report.association_accuracy < ASTRAY)
        .map(describe)
        .collect();
    for (title, list) in [
        ("Runs whose loop did not close", open),
        ("Runs whose loop closed, with association below 90%", astray),
    ] {
        if !list.is_empty() {
            let _ = writeln!(md, "\n{title}:\n");
            for run in list {
                let _ = writeln!(md, "- {run}");
            }
        }
    }
    md
}
