//! Draws a track's cones and the centre line the simulator drives.
//!
//! `cargo run --release --example track_plot -- TRACK_FILE OUT.svg|OUT.png`

use cairn::fs_tools::Track;
use cairn::fs_tools::course::Course;
use cairn::plot::{MapPlot, draw};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let (Some(file), Some(out)) = (args.next(), args.next()) else {
        return Err("usage: track_plot TRACK_FILE OUT.svg".into());
    };
    let track = Track::load(&PathBuf::from(&file))?;
    let course = Course::from_track(&track)?;
    let plot = MapPlot {
        title: format!("{} ({:.0} m)", track.name, course.length()),
        truth: &track.cones,
        path: course.points(),
        ..Default::default()
    };
    draw(&plot, &PathBuf::from(out))?;
    Ok(())
}
