//! `../shared` beside the checkout, for the tests of every crate below the
//! root (included by path where a crate has no `common` module of its own).

use std::path::PathBuf;

/// `relative` under `../shared` beside the checkout, if present. Without it
/// the calling test is skipped with a note, unless `CAIRN_REQUIRE_SHARED`
/// is set (as in CI), which makes a missing path a failure.
pub fn shared_path(relative: &str) -> Option<PathBuf> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared")
        .join(relative);
    if path.exists() {
        return Some(path);
    }
    assert!(
        std::env::var_os("CAIRN_REQUIRE_SHARED").is_none(),
        "CAIRN_REQUIRE_SHARED is set but {} is missing",
        path.display()
    );
    eprintln!("note: {} not found; skipping", path.display());
    None
}
