//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// `../shared` beside the checkout, if present. Without it the calling test is
/// skipped with a note, unless `CAIRN_REQUIRE_SHARED=1` (as in CI), which makes
/// a missing directory a failure.
pub fn shared() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("shared");
    if dir.join("datasets").is_dir() {
        return Some(dir);
    }
    if std::env::var("CAIRN_REQUIRE_SHARED").is_ok_and(|v| v == "1") {
        panic!("CAIRN_REQUIRE_SHARED=1 but {} is missing", dir.display());
    }
    eprintln!(
        "note: {} not found; skipping a test that needs the shared datasets",
        dir.display()
    );
    None
}

/// A file under `../shared/datasets`, or `None` (skipped) as for [`shared`].
pub fn dataset(relative: &str) -> Option<PathBuf> {
    let path = shared()?.join("datasets").join(relative);
    assert!(
        path.is_file(),
        "{} is missing from the shared datasets",
        path.display()
    );
    Some(path)
}

/// The g2o result for `file` and `algo` (`gn`/`lm`) from the peers' baseline.
pub fn g2o_baseline(file: &str, algo: &str) -> Option<(f64, usize)> {
    let text = std::fs::read_to_string(shared()?.join("peers").join("baseline.jsonl")).ok()?;
    text.lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find_map(|r| {
            (r["lib"] == "g2o" && r["algo"] == algo && r["file"] == file)
                .then(|| {
                    Some((
                        r["common_chi2"].as_f64()?,
                        r["iterations"].as_u64()? as usize,
                    ))
                })
                .flatten()
        })
}

/// Levenberg-Marquardt from the file with the default options but
/// `nonmonotonic_steps`.
pub fn lm_config(nonmonotonic_steps: usize) -> cairn::solvers::SolverConfig {
    use cairn::solvers::{Algorithm, Initialization, LevenbergMarquardtConfig, SolverConfig};
    SolverConfig {
        algorithm: Algorithm::LevenbergMarquardt,
        init: Initialization::File,
        lm: LevenbergMarquardtConfig {
            nonmonotonic_steps,
            ..Default::default()
        },
        ..Default::default()
    }
}
