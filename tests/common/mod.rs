//! Helpers shared by the scenario tests.

use std::path::{Path, PathBuf};

/// Every shipped scene (`scenes/*.obj`), sorted by name.
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
