//! `cairn fs-study`: the estimators compared on simulated runs, written to
//! `docs/estimators.md` with plots — every estimator × association method
//! on the shared and random tracks, map error against distance driven,
//! FastSLAM against its particle count, and EKF-SLAM against the measurement
//! covariance it assumes.

use super::fs_report::load_tracks;
use super::progress::Progress;
use super::study_sweeps::{noise_study, particle_study, plot_in_report, rmse_by_distance};
use cairn::fs_tools::Track;
use cairn::fs_tools::configs::assumed_config;
use cairn::fs_tools::course::Course;
use cairn::fs_tools::eval::Report;
use cairn::fs_tools::run::run_estimator;
use cairn::fs_tools::sim::{Preset, SimConfig, Simulation, simulate};
use cairn::fs_tools::trackgen::{TrackRules, random_track};
use cairn::plot::LinePlot;
use cairn::slam::estimator::{EstimatorBuilder, EstimatorKind};
use cairn::slam::frontend::association::AssociationMethod;
use clap::Args;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Options of `cairn fs-study`.
#[derive(Debug, Args)]
pub struct StudyArgs {
    /// Directory of track files (the shared tracks); without it only
    /// random tracks are used.
    #[arg(long, default_value = "../shared/tracks")]
    tracks: PathBuf,
    /// Random generated tracks to add, 0 to 1000.
    #[arg(long, default_value_t = 1, value_parser = clap::builder::RangedU64ValueParser::<u64>::new().range(0..=1000))]
    random: u64,
    /// Use at most this many tracks (all by default).
    #[arg(long)]
    max_tracks: Option<usize>,
    /// Seeds per configuration, 1 to 1000.
    #[arg(long, default_value_t = 1, value_parser = clap::builder::RangedU64ValueParser::<u64>::new().range(1..=1000))]
    seeds: u64,
    /// FastSLAM particles in the main table, 1 to 100,000. FastSLAM runs
    /// JCBB per particle, which dominates the study's time.
    #[arg(long, default_value_t = 100, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100000))]
    particles: usize,
    /// Markdown output; plots go into a folder beside it.
    #[arg(short, long)]
    out: PathBuf,
}

struct Run {
    track: usize,
    preset: &'static str,
    kind: EstimatorKind,
    method: AssociationMethod,
    report: Report,
    closed: bool,
}

/// The graph-SLAM thesis's simulation results: map RMSE of FastSLAM 1.0,
/// FastSLAM 2.0 and graph SLAM, and association accuracy of ML+IC, JCBB
/// and the tracking-assisted method.
const THESIS_RMSE: [(EstimatorKind, f64); 3] = [
    (EstimatorKind::FastSlam1, 0.96),
    (EstimatorKind::FastSlam2, 0.38),
    (EstimatorKind::Graph, 0.31),
];
const THESIS_ASSOCIATION: [(AssociationMethod, f64); 3] = [
    (AssociationMethod::MaximumLikelihood, 0.91),
    (AssociationMethod::Jcbb, 0.95),
    (AssociationMethod::Tracking, 0.98),
];

pub fn run(a: StudyArgs) -> Result<(), super::CliError> {
    let (mut tracks, skipped) = match load_tracks(&a.tracks, a.random) {
        Ok(found) => found,
        Err(e) if !a.tracks.exists() => {
            eprintln!("note: {e}; using random tracks only");
            let random =
                (0..a.random.max(1)).map(|seed| random_track(seed, &TrackRules::default()));
            (random.collect(), Vec::new())
        }
        Err(e) => return Err(e.into()),
    };
    if let Some(n) = a.max_tracks {
        // Keep the random tracks (at the end) and the first shared ones.
        let random = a.random.max(1) as usize;
        while tracks.len() > n.max(1) && tracks.len() > random {
            tracks.remove(tracks.len() - random - 1);
        }
        tracks.truncate(n.max(1));
    }
    let presets = [Preset::standard(), Preset::hard()];
    let mut jobs = Vec::new();
    for t in 0..tracks.len() {
        for p in &presets {
            for kind in EstimatorKind::ALL {
                for m in AssociationMethod::ALL {
                    let config = assumed_config(p.name, m, kind).map_err(|e| e.to_string())?;
                    for seed in 0..a.seeds {
                        jobs.push((t, p.clone(), kind, m, seed, config.clone()));
                    }
                }
            }
        }
    }
    eprintln!("{} runs on {} tracks…", jobs.len(), tracks.len());
    let progress = Progress::new(jobs.len(), "runs");
    let runs: Vec<Run> = jobs
        .par_iter()
        .map(|(t, preset, kind, method, seed, assumed)| {
            let sim = simulate_on(&tracks[*t], preset, *seed);
            let mut builder = EstimatorBuilder::new(*kind, assumed.clone());
            builder.particles = a.particles;
            builder.seed = *seed;
            let (slam, report) = run_estimator(&sim, &builder);
            for warning in &report.warnings {
                let name = &tracks[*t].0.name;
                progress.note(&format!("warning: {name} seed {seed}: {warning}"));
            }
            progress.inc();
            Run {
                track: *t,
                preset: preset.name,
                kind: *kind,
                method: *method,
                report,
                closed: slam.loop_closures() > 0,
            }
        })
        .collect();
    progress.finish();

    let plots = a.out.with_extension("");
    std::fs::create_dir_all(&plots).map_err(|e| format!("{}: {e}", plots.display()))?;
    let folder = plots
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# The estimators compared\n\n\
         Generated by `cargo run --release -- fs-study --seeds {} --random {}{} -o {}` \
         ({} runs: {} tracks × 2 presets × 4 estimators × 4 association methods × {} seeds, \
         2 laps at 5 m/s, {} FastSLAM particles). Values are means over tracks and seeds; \
         latency is the p99 of per-scan update time on this 2-core machine. \
         `graph` is the pose/landmark graph of `docs/fs-slam.md`; `ekf` is EKF-SLAM with the \
         full joint covariance; `fastslam1`/`fastslam2` are FastSLAM 1.0/2.0 with a 2×2 EKF \
         per landmark per particle and the best particle's map, its path and map smoothed \
         at the loop closure and at the end of the run. \
         {}\n",
        a.seeds,
        a.random,
        a.max_tracks
            .map(|n| format!(" --max-tracks {n}"))
            .unwrap_or_default()
            + &format!(" --particles {}", a.particles),
        a.out.display(),
        runs.len(),
        tracks.len(),
        a.seeds,
        a.particles,
        if a.max_tracks.is_some() {
            "The tracks are the first shared loop tracks in name order and the random ones."
        } else {
            "The tracks are every shared loop track and the random ones."
        }
    );
    for preset in ["standard", "hard"] {
        let _ = writeln!(
            md,
            "## Every estimator × association method, `{preset}` preset\n"
        );
        let _ = writeln!(md, "{HEADER}");
        for kind in EstimatorKind::ALL {
            for m in AssociationMethod::ALL {
                let sel: Vec<&Run> = runs
                    .iter()
                    .filter(|r| r.preset == preset && r.kind == kind && r.method == m)
                    .collect();
                let _ = writeln!(md, "| {} | {} {}", kind.name(), m.name(), row(&sel));
            }
        }
        let _ = writeln!(md);
    }
    let _ = writeln!(
        md,
        "## Per track, `standard` preset, tracking-assisted association\n"
    );
    let _ = writeln!(
        md,
        "| track | estimator | map RMSE (m) | aligned (m) | ATE (m) | association | phantom | missed | p50 (ms) | p99 (ms) | closed |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|");
    for (t, (track, course)) in tracks.iter().enumerate() {
        for kind in EstimatorKind::ALL {
            let sel: Vec<&Run> = runs
                .iter()
                .filter(|r| {
                    r.track == t
                        && r.preset == "standard"
                        && r.kind == kind
                        && r.method == AssociationMethod::Tracking
                })
                .collect();
            let label = format!("{} ({:.0} m)", track.name, course.length());
            let _ = writeln!(md, "| {label} | {} {}", kind.name(), row(&sel));
        }
    }
    let _ = writeln!(md);
    if !skipped.is_empty() {
        let _ = writeln!(md, "Tracks left out: {}.\n", skipped.join("; "));
    }

    // The track the detailed studies use: the first random one.
    let detail = tracks.len() - 1;
    let (track, course) = &tracks[detail];
    let standard = Preset::standard();
    let _ = writeln!(
        md,
        "## Map error against distance driven\n\n\
         {} ({:.0} m), `standard` preset, tracking-assisted association, seed 0: the RMSE \
         of the confirmed landmarks against their nearest true cones every 20 m, as the \
         graph-SLAM thesis plots it. The drop near {:.0} m is the loop closure.\n",
        track.name,
        course.length(),
        course.length()
    );
    let sim = simulate_on(&tracks[detail], &standard, 0);
    let mut series = Vec::new();
    for kind in EstimatorKind::ALL {
        let (curve, file) = rmse_by_distance(&sim, kind, a.particles, &plots, &track.name)?;
        series.push((kind.name().to_string(), curve));
        let _ = writeln!(md, "![{} map]({folder}/{file})", kind.name());
    }
    let plot = LinePlot {
        title: &format!("{}: map RMSE while driving", track.name),
        x_desc: "distance driven (m)",
        y_desc: "map RMSE (m)",
        series: &series,
    };
    let alt = "map RMSE against distance";
    plot_in_report(&mut md, &plot, &plots, &folder, "rmse_distance.svg", alt)?;

    particle_study(&mut md, &sim, &plots, &folder)?;
    noise_study(&mut md, &tracks[detail], &standard)?;
    comparison(&mut md, &runs);

    super::write_output(&a.out, md.as_bytes())?;
    eprintln!("wrote {}", a.out.display());
    Ok(())
}

const HEADER: &str = "| estimator | association | map RMSE (m) | aligned (m) | ATE (m) | association accuracy | phantom | missed | p50 (ms) | p99 (ms) | closed |\n|---|---|---|---|---|---|---|---|---|---|---|";

pub(super) fn simulate_on(
    (track, course): &(Track, Course),
    preset: &Preset,
    seed: u64,
) -> Simulation {
    let config = SimConfig {
        preset: preset.clone(),
        seed,
        ..SimConfig::default()
    };
    simulate(track, course, &config)
}

fn mean(runs: &[&Run], f: impl Fn(&Report) -> f64) -> f64 {
    runs.iter().map(|r| f(&r.report)).sum::<f64>() / runs.len().max(1) as f64
}

/// The table cells after the first column(s).
fn row(runs: &[&Run]) -> String {
    let latency = |k: usize| mean(runs, |r| r.latency_ms.map_or(0.0, |l| l[k]));
    format!(
        "| {:.3} | {:.3} | {:.3} | {:.2}% | {:.1} | {:.1} | {:.3} | {:.3} | {}/{} |",
        mean(runs, |r| r.map_rmse),
        mean(runs, |r| r.map_rmse_aligned),
        mean(runs, |r| r.ate),
        100.0 * mean(runs, |r| r.association_accuracy),
        mean(runs, |r| r.phantom as f64),
        mean(runs, |r| r.missed as f64),
        latency(0),
        latency(1),
        runs.iter().filter(|r| r.closed).count(),
        runs.len()
    )
}

/// Our numbers next to the graph-SLAM thesis's.
fn comparison(md: &mut String, runs: &[Run]) {
    let select = |kind: Option<EstimatorKind>, method: AssociationMethod| -> Vec<&Run> {
        runs.iter()
            .filter(|r| {
                r.preset == "standard" && r.method == method && kind.is_none_or(|k| r.kind == k)
            })
            .collect()
    };
    let _ = writeln!(
        md,
        "## Next to the theses\n\n\
         `standard` preset; estimators with tracking-assisted association, association \
         methods with the graph.\n\n\
         | quantity | thesis | Cairn |\n|---|---|---|"
    );
    let mut ours = Vec::new();
    for (kind, thesis) in THESIS_RMSE {
        let rmse = mean(&select(Some(kind), AssociationMethod::Tracking), |r| {
            r.map_rmse
        });
        ours.push(rmse);
        let _ = writeln!(
            md,
            "| map RMSE, {} | {thesis:.2} m | {rmse:.3} m |",
            kind.name()
        );
    }
    let ekf = mean(
        &select(Some(EstimatorKind::Ekf), AssociationMethod::Tracking),
        |r| r.map_rmse,
    );
    let _ = writeln!(md, "| map RMSE, ekf | — | {ekf:.3} m |");
    let mut accuracies = Vec::new();
    for (method, thesis) in THESIS_ASSOCIATION {
        let acc = mean(&select(Some(EstimatorKind::Graph), method), |r| {
            r.association_accuracy
        });
        accuracies.push(acc);
        let _ = writeln!(
            md,
            "| association accuracy, {} | {:.0}% | {:.2}% |",
            method.name(),
            100.0 * thesis,
            100.0 * acc
        );
    }
    let ordered = ours[0] > ours[1] && ours[1] > ours[2];
    let mut hard_ate = (f64::INFINITY, 0.0f64);
    for kind in EstimatorKind::ALL {
        for m in AssociationMethod::ALL {
            let sel: Vec<&Run> = runs
                .iter()
                .filter(|r| r.preset == "hard" && r.kind == kind && r.method == m)
                .collect();
            let ate = mean(&sel, |r| r.ate);
            hard_ate = (hard_ate.0.min(ate), hard_ate.1.max(ate));
        }
    }
    let ekf_aligned = mean(
        &select(Some(EstimatorKind::Ekf), AssociationMethod::Tracking),
        |r| r.map_rmse_aligned,
    );
    let methods_ordered = accuracies[0] < accuracies[1] && accuracies[1] < accuracies[2];
    let spread = accuracies.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        - accuracies.iter().copied().fold(f64::INFINITY, f64::min);
    let _ = writeln!(
        md,
        "\nThe thesis ranks FastSLAM 1.0 worst, FastSLAM 2.0 next and graph SLAM best by map \
         RMSE; here that order {}. The thesis ranks ML+IC below JCBB below the \
         tracking-assisted method; here that order {}, and the three lie within {:.1} \
         points of each other, all above the thesis's figures: the simulated tracker ids \
         and colours are cleaner than a real pipeline's, and every method shares the same \
         individual gates, new-landmark test and colour penalty.\n\n\
         Why the filters behave as they do:\n\n\
         - FastSLAM 1.0 draws poses from the motion model alone. With odometry noise far \
         above the detector's, most particles disagree with the scan and a few survive each \
         resampling, so the path random-walks along the track. FastSLAM 2.0's proposal \
         folds the scan into the pose it samples, which narrows that walk but cannot stop \
         it. Each particle's map is conditioned on its own path, and after a lap every \
         particle descends from one ancestor (see the particle table), so no particle's map \
         has undone the lap's drift: choosing among them at the loop closure left the \
         `standard` maps 0.34–0.44 m off (docs/bench/fs-slam-history.md). So the chosen \
         particle's path and map are smoothed with Cairn's solver at the closure, before \
         every particle carries on with it, and again at the end of the run: its own \
         odometry, sightings and associations, with the gyro's bias beside the poses as in \
         the graph's full optimisation. The corridor test in \
         `fs-tools/tests/estimators.rs` (100 m straight, no loop) measures 0.11 m (1.0) and \
         0.09 m (2.0) after it, 0.54 and 0.45 m before. Place recognition at the start (the \
         same scan-to-map alignment the graph uses) is what lets them close the loop at \
         all. As in the graph, FastSLAM's gates leave the start area's landmarks alone on \
         the way back until scans agree on where it is: gated, a lap that ended 2.2 m off \
         matched the start one cone off (FastSLAM 2.0 on epfl_fsds_competition_1_cones, \
         seed 0: 50.9% association, ATE 12 m, before session 55).\n\
         - EKF-SLAM keeps the cross-covariances, so closing the loop corrects the whole map; \
         its gates must use them too. Its state carries the gyro's bias beside the pose, \
         so each step's turn is weighed by the yaw rate's white noise alone, as in the \
         graph's full optimisation, and its predicted map RMSE is 0.87–0.97× the graph's \
         (28 held-out `standard` logs, CHANGELOG). What is left is mostly a turn of the map about \
         the start: aligned, its `standard` maps are {:.3} m off against {:.3} m as they \
         stand. Gating with the pose and landmark covariances alone \
         cost it 12 points of association accuracy (87.6% against 99.4% on \
         `fs-sim --seed 1`), and JCBB without the landmark–landmark terms rejected almost \
         every joint hypothesis. Its update is O(n²) in the landmarks, which shows in the \
         p99 latency.\n\
         - The `hard` preset (mean ATE {:.1}–{:.1} m across estimators and methods): odometry \
         biases of 3% and 0.01 rad/s drift the car metres off before the lap ends, beyond the \
         gates. The graph estimates the gyro bias in its smoothing window and recognises the \
         start by aligning the landmarks of the lap's end to it, so it closes most laps, and \
         its final optimisation weighs the sightings under a Cauchy kernel so the few wrong \
         matches pull less; the filters align one scan and lose more.\n",
        if ordered { "holds" } else { "does not hold" },
        if methods_ordered {
            "holds"
        } else {
            "does not hold"
        },
        100.0 * spread,
        ekf_aligned,
        ekf,
        hard_ate.0,
        hard_ate.1
    );
}
