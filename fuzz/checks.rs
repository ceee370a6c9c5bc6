//! The checks of the fuzz targets, one function per target: shared by the
//! targets (`fuzz_targets/`) and by the workspace's test that replays the
//! corpora on stable Rust (`tests/fuzz_corpora.rs`).

use cairn_fs_tools::Track;
use cairn_fs_tools::course::Course;
use cairn_g2o::ReadOptions;
use cairn_slam::frontend::FrontEndConfig;
use cairn_slam::log::{Log, ScanLimits, to_jsonl};
use cairn_slam::map::{map_from_csv, map_to_csv};

/// The g2o reader on arbitrary bytes: it returns a graph or a typed error,
/// never panics, and what it reads writes back to text that reads again to
/// the same graph.
pub fn g2o_reader(data: &[u8]) {
    // The first byte picks the option, the rest is the file.
    let Some((&flags, text)) = data.split_first() else {
        return;
    };
    let options = ReadOptions {
        repair_information: flags & 1 == 1,
        ..Default::default()
    };
    let Ok((graph, _)) = cairn_g2o::read_bytes(text, &options) else {
        return;
    };
    let chi2 = graph.chi2();
    let Ok(written) = cairn_g2o::to_string(&graph) else {
        return;
    };
    let (again, _) = cairn_g2o::read_bytes(written.as_bytes(), &options)
        .unwrap_or_else(|e| panic!("the writer's output does not read back: {e}\n{written}"));
    assert_eq!(again.num_vertices(), graph.num_vertices());
    assert_eq!(again.num_edges(), graph.num_edges());
    let chi2_again = again.chi2();
    assert!(
        chi2 == chi2_again
            || (chi2.is_nan() && chi2_again.is_nan())
            || (chi2 - chi2_again).abs() <= 1e-9 * chi2.abs(),
        "χ² {chi2} read back as {chi2_again}"
    );
}

/// The FS log reader (FORMAT.md) on arbitrary bytes: a log or an error naming
/// the line, never a panic; a log it reads writes back to the same records.
pub fn fs_log(data: &[u8]) {
    let Some((&flags, text)) = data.split_first() else {
        return;
    };
    let skip_bad = flags & 1 == 1;
    let Ok(log) = Log::parse_bytes(text, skip_bad, &ScanLimits::default()) else {
        return;
    };
    let written = to_jsonl(&log.records);
    let again = Log::parse(&written, false)
        .unwrap_or_else(|e| panic!("the writer's output does not read back: {e}\n{written}"));
    assert_eq!(again.records, log.records);
}

/// The track readers (EUFS CSV, EPFL CSV, AMZ fssim YAML) and the course the
/// simulator builds from a track: a track or an error, a course or an error,
/// never a panic, an unbounded allocation or a hang.
pub fn track(data: &[u8]) {
    // The first byte picks the format and the kind the file name would give.
    let Some((&flags, bytes)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(bytes) else {
        return;
    };
    let name = ["track", "acceleration", "skidpad"][usize::from(flags >> 1) % 3];
    let Ok(track) = Track::parse(name, text, flags & 1 == 1) else {
        return;
    };
    let Ok(course) = Course::from_track(&track) else {
        return;
    };
    let length = course.length();
    assert!(length.is_finite() && length > 0.0);
    for k in 0..=16 {
        let p = course.point_at(length * f64::from(k) / 16.0);
        assert!(p.x.is_finite() && p.y.is_finite());
    }
}

/// The map reader (EUFS CSV with variances, FORMAT.md): cones or an error,
/// never a panic; a map it reads writes back to the same cones.
pub fn map(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(cones) = map_from_csv(text) else {
        return;
    };
    let written = map_to_csv(&cones);
    let again = map_from_csv(&written)
        .unwrap_or_else(|e| panic!("the writer's output does not read back: {e}\n{written}"));
    assert_eq!(again.len(), cones.len());
    for (a, b) in again.iter().zip(&cones) {
        assert_eq!(a.position, b.position);
        assert_eq!(a.covariance, b.covariance);
        assert_eq!(a.color, b.color);
    }
}

/// The front end's TOML configuration: settings or an error, never a panic;
/// settings it accepts write back to TOML that reads to the same settings.
pub fn fs_config(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(config) = FrontEndConfig::from_toml(text) else {
        return;
    };
    let written = config.to_toml();
    let again = FrontEndConfig::from_toml(&written)
        .unwrap_or_else(|e| panic!("the writer's output does not read back: {e}\n{written}"));
    assert_eq!(format!("{again:?}"), format!("{config:?}"));
}
