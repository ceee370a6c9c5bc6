//! The fuzz targets' corpora (`fuzz/corpus/TARGET/`, fuzz/README.md) through
//! the same checks as the fuzzers, on stable Rust: every input that once
//! reached new code, and every crash input committed there, is replayed.

#[path = "../fuzz/checks.rs"]
mod checks;

use std::path::Path;

fn replay(target: &str, check: fn(&[u8])) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let mut inputs = 0;
    for entry in std::fs::read_dir(&dir).expect("the corpus folder") {
        let path = entry.expect("a corpus entry").path();
        let bytes = std::fs::read(&path).expect("a corpus file");
        let outcome = std::panic::catch_unwind(|| check(&bytes));
        assert!(outcome.is_ok(), "{target}: {} fails", path.display());
        inputs += 1;
    }
    assert!(inputs > 0, "{target}: the corpus is empty");
}

#[test]
fn g2o_reader_corpus() {
    replay("g2o_reader", checks::g2o_reader);
}

#[test]
fn fs_log_corpus() {
    replay("fs_log", checks::fs_log);
}

#[test]
fn track_corpus() {
    replay("track", checks::track);
}

#[test]
fn map_corpus() {
    replay("map", checks::map);
}

#[test]
fn fs_config_corpus() {
    replay("fs_config", checks::fs_config);
}
