//! Helpers shared by the scenario tests.

use std::path::{Path, PathBuf};

/// Every shipped scene (`scenes/*.obj`), sorted by name.
#[allow(dead_code)]
pub fn shipped_scenes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut scenes: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "obj"))
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 8, "expected at least 8 shipped scenes");
    scenes
}

/// The observable-set cache the scenario tests share (under the build's temporary folder, so it
/// survives between test runs and is never the user's own cache).
#[allow(dead_code)]
pub fn cache_dir() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("tensorscout-cache")
}

#[allow(dead_code)]
pub fn cache() -> tensorscout::sim::ObservableCache {
    tensorscout::sim::ObservableCache::at(cache_dir().join("observable"))
}
