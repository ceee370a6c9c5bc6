//! `cairn fs-import`: real recordings to the FORMAT.md log and truth files;
//! `cairn fs-smooth`: the batch smoother given the associations.

use super::fs::{EstimateOutputs, LOG, TRUTH_ASSOC, TRUTH_MAP, TRUTH_TRAJ, read_text};
use super::{CliError, bad_input, write_output};
use cairn::fs_tools::{mrclam, smoother};
use cairn::slam::files;
use cairn::slam::frontend::FrontEndConfig;
use cairn::slam::log::{Log, to_jsonl};
use cairn::slam::map::map_to_csv;
use clap::{Args, Subcommand};
use std::path::PathBuf;

/// Options of `cairn fs-import`.
#[derive(Debug, Args)]
pub struct ImportArgs {
    #[command(subcommand)]
    dataset: Dataset,
}

#[derive(Debug, Subcommand)]
enum Dataset {
    /// One robot of a UTIAS MRCLAM dataset folder: log.jsonl (odometry =
    /// the commanded velocities, one scan per measurement time stamp,
    /// range/bearing, colour `unknown`), truth_map.csv, truth_assoc.csv
    /// (the barcodes; -1 for a misread one) and, where Vicon recorded the
    /// robot, truth_traj.tum and a `start` record at its first pose.
    /// Detections of the other robots are left out.
    Mrclam(MrclamArgs),
}

#[derive(Debug, Args)]
struct MrclamArgs {
    /// The dataset folder (Barcodes.dat, Landmark_Groundtruth.dat, RobotN_*.dat).
    dir: PathBuf,
    /// The robot to import, 1 to 5.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=5))]
    robot: u32,
    /// Give each detection its barcode as the tracker id (`"id"`), for
    /// `--association tracking`; without it the log does not say which
    /// landmark a detection is.
    #[arg(long)]
    ids: bool,
    /// Output folder.
    #[arg(short, long)]
    out: PathBuf,
}

pub fn run(a: ImportArgs) -> Result<(), super::CliError> {
    let Dataset::Mrclam(a) = a.dataset;
    let options = mrclam::Options {
        robot: a.robot,
        ids: a.ids,
    };
    let import = mrclam::import(&a.dir, &options).map_err(|e| match e {
        mrclam::MrclamError::Io { .. } => CliError::io(e.to_string()),
        _ => CliError::input(e.to_string()),
    })?;
    std::fs::create_dir_all(&a.out)
        .map_err(|e| CliError::io(format!("{}: {e}", a.out.display())))?;
    write_output(&a.out.join(LOG), to_jsonl(&import.log).as_bytes())?;
    write_output(
        &a.out.join(TRUTH_MAP),
        map_to_csv(&import.truth_map).as_bytes(),
    )?;
    write_output(
        &a.out.join(TRUTH_ASSOC),
        files::associations_to_csv(&import.truth_associations).as_bytes(),
    )?;
    if let Some(truth) = &import.truth_trajectory {
        write_output(
            &a.out.join(TRUTH_TRAJ),
            files::trajectory_to_tum(truth).as_bytes(),
        )?;
    }
    let c = import.counts;
    eprintln!(
        "robot {}: {} odometry records, {} scans, {} detections ({} misread barcodes) → {}; \
         left out: {} detections of other robots, {} measurements before the odometry{}",
        a.robot,
        c.odometry,
        c.scans,
        c.detections,
        c.misread,
        a.out.display(),
        c.robots,
        c.before_odometry,
        if import.truth_trajectory.is_none() {
            "; no Vicon trajectory in this dataset"
        } else {
            ""
        }
    );
    Ok(())
}

/// Options of `cairn fs-smooth`.
#[derive(Debug, Args)]
pub struct SmoothArgs {
    /// Input log (JSON Lines, FORMAT.md).
    log: PathBuf,
    /// The association of every detection (CSV scan,det,landmark; -1 for
    /// none), such as fs-import's truth_assoc.csv from the barcodes.
    #[arg(long)]
    assoc: PathBuf,
    /// The assumed detector and odometry noise (TOML, as fs-slam's).
    #[arg(long, value_name = "FILE.toml")]
    config: Option<PathBuf>,
    #[command(flatten)]
    out: EstimateOutputs,
    /// Write the solved graph (g2o: EDGE_SE2 odometry, EDGE_SE2_XY sightings).
    #[arg(long)]
    g2o_out: Option<PathBuf>,
}

pub fn run_smooth(a: SmoothArgs) -> Result<(), super::CliError> {
    a.out.check()?;
    let name = a.log.display().to_string();
    let log = Log::parse_bytes(&super::read_input(&a.log)?, false, &Default::default())
        .map_err(bad_input(&name))?;
    let associations = files::associations_from_csv(&read_text(&a.assoc)?)
        .map_err(bad_input(a.assoc.display()))?;
    let config = match &a.config {
        Some(path) => {
            FrontEndConfig::from_toml(&read_text(path)?).map_err(bad_input(path.display()))?
        }
        None => FrontEndConfig::default(),
    };
    let smoothed = smoother::smooth(&log.records, &associations, &config)
        .map_err(|e| format!("{name}: {e}"))?;
    let g2o = match &a.g2o_out {
        Some(_) => Some(cairn::g2o::to_string(&smoothed.graph).map_err(|e| e.to_string())?),
        None => None,
    };
    for (path, text) in [
        (&a.out.map_out, Some(map_to_csv(&smoothed.map))),
        (
            &a.out.traj_out,
            Some(files::trajectory_to_tum(&smoothed.trajectory)),
        ),
        (
            &a.out.assoc_out,
            Some(files::associations_to_csv(&smoothed.associations)),
        ),
        (&a.g2o_out, g2o),
    ] {
        if let (Some(path), Some(text)) = (path, text) {
            write_output(path, text.as_bytes())?;
        }
    }
    let s = &smoothed.summary;
    eprintln!(
        "{name}: {} poses, {} landmarks; χ² {:.6} → {:.6} in {} iterations ({:?})",
        smoothed.trajectory.len(),
        smoothed.map.len(),
        s.initial_chi2,
        s.final_chi2,
        s.iterations,
        s.termination
    );
    Ok(())
}
