//! `cairn fs-import`: real recordings to the FORMAT.md log and truth files.

use super::fs::{LOG, TRUTH_ASSOC, TRUTH_MAP, TRUTH_TRAJ};
use super::write_output;
use cairn::fs_tools::mrclam;
use cairn::slam::files;
use cairn::slam::log::to_jsonl;
use cairn::slam::track::map_to_csv;
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

pub fn run(a: ImportArgs) -> Result<(), String> {
    let Dataset::Mrclam(a) = a.dataset;
    let options = mrclam::Options {
        robot: a.robot,
        ids: a.ids,
    };
    let import = mrclam::import(&a.dir, &options).map_err(|e| e.to_string())?;
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    write_output(&a.out.join(LOG), to_jsonl(&import.log).as_bytes())?;
    write_output(&a.out.join(TRUTH_MAP), map_to_csv(&import.truth_map).as_bytes())?;
    write_output(
        &a.out.join(TRUTH_ASSOC),
        files::associations_to_csv(&import.truth_associations).as_bytes(),
    )?;
    if let Some(truth) = &import.truth_trajectory {
        write_output(&a.out.join(TRUTH_TRAJ), files::trajectory_to_tum(truth).as_bytes())?;
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
