//! The sweeps of `cairn fs-study`: map error along the run, particles,
//! detector noise.

use super::fs_eval::plot_run;
use super::progress::Progress;
use super::study::simulate_on;
use cairn::fs_tools::Track;
use cairn::fs_tools::configs::assumed_config;
use cairn::fs_tools::course::Course;
use cairn::fs_tools::eval::{Report, evaluate};
use cairn::fs_tools::run::run_estimator;
use cairn::fs_tools::sim::{Preset, Simulation};
use cairn::plot::{LinePlot, draw_lines};
use cairn::slam::estimator::{EstimatorBuilder, EstimatorKind};
use cairn::slam::frontend::FrontEndConfig;
use cairn::slam::frontend::association::AssociationMethod;
use cairn::slam::log::Record;
use rayon::prelude::*;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

/// Map RMSE every 20 m of the run for one estimator; also draws its final
/// map. Returns the curve and the map's file name.
pub(super) fn rmse_by_distance(
    sim: &Simulation,
    kind: EstimatorKind,
    particles: usize,
    plots: &Path,
    track: &str,
) -> Result<(Vec<(f64, f64)>, String), String> {
    // Distance driven at every true pose time.
    let mut driven = HashMap::new();
    let mut total = 0.0;
    for w in sim.truth.windows(2) {
        driven.insert(w[0].t.to_bits(), total);
        total += (w[1].pose.t - w[0].pose.t).norm();
    }
    let mut builder = EstimatorBuilder::new(
        kind,
        assumed_config("standard", AssociationMethod::Tracking, kind).map_err(|e| e.to_string())?,
    );
    builder.particles = particles;
    let mut slam = builder.build();
    let mut next = 20.0;
    let mut curve = Vec::new();
    for record in &sim.log {
        slam.process(record);
        let Record::Cones { t, .. } = record else {
            continue;
        };
        let Some(&d) = driven.get(&t.to_bits()) else {
            continue;
        };
        if d >= next {
            next += 20.0;
            let map = slam.map();
            if map.is_empty() {
                continue;
            }
            let report = evaluate(&sim.truth_map, &map, &[], &[], &[], &[]);
            curve.push((d, report.map_rmse));
        }
    }
    let file = format!("{}_{}.svg", track, kind.name());
    plot_run(
        &plots.join(&file),
        &format!("{track}: {}", kind.name()),
        &sim.truth_map,
        &slam.map(),
        &sim.truth,
        &slam.trajectory(),
    )?;
    Ok((curve, file))
}

/// FastSLAM 1.0 and 2.0 with 1 to 300 particles, three sampler seeds each.
pub(super) fn particle_study(
    md: &mut String,
    sim: &Simulation,
    plots: &Path,
    folder: &str,
) -> Result<(), String> {
    let counts = [1usize, 3, 10, 30, 100, 300];
    let seeds = 3u64;
    let mut jobs = Vec::new();
    for kind in [EstimatorKind::FastSlam1, EstimatorKind::FastSlam2] {
        for &n in &counts {
            for seed in 0..seeds {
                jobs.push((kind, n, seed));
            }
        }
    }
    let assumed = |kind| {
        assumed_config("standard", AssociationMethod::Tracking, kind).map_err(|e| e.to_string())
    };
    let (fast1, fast2) = (
        assumed(EstimatorKind::FastSlam1)?,
        assumed(EstimatorKind::FastSlam2)?,
    );
    let progress = Progress::new(jobs.len(), "FastSLAM runs");
    let results: Vec<(EstimatorKind, usize, Report)> = jobs
        .par_iter()
        .map(|&(kind, n, seed)| {
            let mut builder = EstimatorBuilder::new(
                kind,
                if kind == EstimatorKind::FastSlam1 {
                    fast1.clone()
                } else {
                    fast2.clone()
                },
            );
            builder.particles = n;
            builder.seed = seed;
            let report = run_estimator(sim, &builder).1;
            progress.inc();
            (kind, n, report)
        })
        .collect();
    progress.finish();
    let _ = writeln!(
        md,
        "## FastSLAM against its particle count\n\n\
         Same run, {seeds} sampler seeds per count.\n\n\
         | estimator | particles | map RMSE (m) | aligned (m) | ATE (m) | association | p99 (ms) |\n\
         |---|---|---|---|---|---|---|"
    );
    let mut series = Vec::new();
    for kind in [EstimatorKind::FastSlam1, EstimatorKind::FastSlam2] {
        let mut curve = Vec::new();
        for &n in &counts {
            let sel: Vec<&Report> = results
                .iter()
                .filter(|r| r.0 == kind && r.1 == n)
                .map(|r| &r.2)
                .collect();
            let m = |f: &dyn Fn(&Report) -> f64| {
                sel.iter().map(|r| f(r)).sum::<f64>() / sel.len() as f64
            };
            let rmse = m(&|r| r.map_rmse);
            let _ = writeln!(
                md,
                "| {} | {n} | {rmse:.3} | {:.3} | {:.3} | {:.2}% | {:.3} |",
                kind.name(),
                m(&|r| r.map_rmse_aligned),
                m(&|r| r.ate),
                100.0 * m(&|r| r.association_accuracy),
                m(&|r| r.latency_ms.map_or(0.0, |l| l[1])),
            );
            curve.push(((n as f64).log10(), rmse));
        }
        series.push((kind.name().to_string(), curve));
    }
    let plot = LinePlot {
        title: "FastSLAM: map RMSE against particles",
        x_desc: "particles (log10)",
        y_desc: "map RMSE (m)",
        series: &series,
    };
    plot_in_report(
        md,
        &plot,
        plots,
        folder,
        "particles.svg",
        "map RMSE against particles",
    )
}

/// Draws `plot` as `plots/file` and links it from the report, captioned `alt`.
pub(super) fn plot_in_report(
    md: &mut String,
    plot: &LinePlot,
    plots: &Path,
    folder: &str,
    file: &str,
    alt: &str,
) -> Result<(), String> {
    draw_lines(plot, &plots.join(file))?;
    let _ = writeln!(md, "\n![{alt}]({folder}/{file})\n");
    Ok(())
}

/// EKF-SLAM with the measurement covariance it assumes scaled by k, with
/// known correspondences and with tracking-assisted association.
pub(super) fn noise_study(
    md: &mut String,
    track: &(Track, Course),
    preset: &Preset,
) -> Result<(), String> {
    let scales = [0.01, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0];
    let seeds = 3u64;
    let jobs: Vec<(f64, u64)> = scales
        .iter()
        .flat_map(|&k| (0..seeds).map(move |s| (k, s)))
        .collect();
    let assumed = assumed_config(preset.name, AssociationMethod::Tracking, EstimatorKind::Ekf)
        .map_err(|e| e.to_string())?;
    let progress = Progress::new(jobs.len(), "EKF runs");
    let results: Vec<(f64, Report, Report)> = jobs
        .par_iter()
        .map(|&(k, seed)| {
            let sim = simulate_on(track, preset, seed);
            let mut config: FrontEndConfig = assumed.clone();
            let f = k.sqrt();
            config.range_sigma *= f;
            config.range_sigma_relative *= f;
            config.bearing_sigma *= f;
            let mut known = EstimatorBuilder::new(EstimatorKind::Ekf, config.clone());
            known.known = Some(&sim.truth_associations);
            let with_truth = run_estimator(&sim, &known).1;
            let associated =
                run_estimator(&sim, &EstimatorBuilder::new(EstimatorKind::Ekf, config)).1;
            progress.inc();
            (k, with_truth, associated)
        })
        .collect();
    progress.finish();
    let _ = writeln!(
        md,
        "## EKF-SLAM against its assumed measurement noise\n\n\
         As in the rover thesis's Table 5.1: the filter assumes the measurement covariance \
         k·Q, where Q is the `standard` preset's true range and bearing noise; {} ({seeds} seeds). \
         With known correspondences only the estimate changes; with tracking-assisted \
         association the gates change too.\n\n\
         | k | map RMSE, known (m) | ATE, known (m) | map RMSE, associated (m) | ATE, associated (m) | association |\n\
         |---|---|---|---|---|---|",
        track.0.name
    );
    let mut known_rmse = Vec::new();
    let mut accuracy = Vec::new();
    for &k in &scales {
        let sel: Vec<&(f64, Report, Report)> = results.iter().filter(|r| r.0 == k).collect();
        let m = |f: &dyn Fn(&(f64, Report, Report)) -> f64| {
            sel.iter().map(|r| f(r)).sum::<f64>() / sel.len() as f64
        };
        known_rmse.push((k, m(&|r| r.1.map_rmse)));
        accuracy.push((k, m(&|r| r.2.association_accuracy)));
        let _ = writeln!(
            md,
            "| {k} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2}% |",
            m(&|r| r.1.map_rmse),
            m(&|r| r.1.ate),
            m(&|r| r.2.map_rmse),
            m(&|r| r.2.ate),
            100.0 * m(&|r| r.2.association_accuracy),
        );
    }
    let best = |v: &[(f64, f64)], better: fn(f64, f64) -> bool| {
        v.iter()
            .copied()
            .reduce(|a, b| if better(b.1, a.1) { b } else { a })
            .unwrap_or((1.0, 0.0))
    };
    let (k_rmse, rmse) = best(&known_rmse, |a, b| a < b);
    let (k_acc, acc) = best(&accuracy, |a, b| a > b);
    let _ = writeln!(
        md,
        "\nWith known correspondences the map RMSE is lowest at k = {k_rmse} ({rmse:.3} m) \
         and {:.3} m at k = 100: assuming more noise than there is weighs odometry too \
         much. With association, accuracy peaks at k = {k_acc} ({:.2}%): smaller gates \
         reject true matches, larger ones admit wrong ones, so Q matters far more to the \
         associations than to the estimate.\n",
        known_rmse.last().map_or(0.0, |x| x.1),
        100.0 * acc
    );
    Ok(())
}
