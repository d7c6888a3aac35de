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

/// A sample of the real apartment plans in `scenes/floorplans/` for the heavy tier: six of them,
/// small to large, each explored from its own start.
#[allow(dead_code)]
pub fn sample_plans() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/floorplans");
    [
        "plan_06dec58b2b",
        "plan_0ae54bc5c4",
        "plan_110bb1396f",
        "plan_115c3a7a64",
        "plan_165cad143c",
        "plan_18b39b374f",
    ]
    .iter()
    .map(|name| dir.join(format!("{name}.obj")))
    .collect()
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

/// The OBJ text of `mesh`: `v` and `f` lines, after an optional `# tensorscout spawn X Y YAW` line.
#[allow(dead_code)]
pub fn obj_text(mesh: &tensorscout::scene::TriMesh, spawn: Option<&str>) -> String {
    let mut s = spawn
        .map(|p| format!("# tensorscout spawn {p}\n"))
        .unwrap_or_default();
    for v in &mesh.vertices {
        s.push_str(&format!("v {} {} {}\n", v.x, v.y, v.z));
    }
    for t in &mesh.triangles {
        s.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    s
}

/// The test room: a closed 6 × 4 m room with 2.5 m walls 0.1 m thick (a flat floor box and four
/// wall boxes), as OBJ, with an optional spawn line (`"X Y YAW"`).
#[allow(dead_code)]
pub fn room_obj(spawn: Option<&str>) -> String {
    walled_room_obj(6.0, 4.0, spawn)
}

/// A closed `w` × `d` m room (outer size) with 2.5 m walls 0.1 m thick, as OBJ, with an optional
/// spawn line.
#[allow(dead_code)]
pub fn walled_room_obj(w: f64, d: f64, spawn: Option<&str>) -> String {
    let mut mesh = tensorscout::scene::TriMesh::default();
    for (x0, y0, x1, y1, z1) in [
        (0.0, 0.0, w, d, 0.0),
        (0.0, 0.0, w, 0.1, 2.5),
        (0.0, d - 0.1, w, d, 2.5),
        (0.0, 0.0, 0.1, d, 2.5),
        (w - 0.1, 0.0, w, d, 2.5),
    ] {
        mesh.push_box([x0, y0, 0.0], [x1, y1, z1]);
    }
    obj_text(&mesh, spawn)
}

/// One exploration of the scene at `path` with `planner` under `cfg`, from the scene's own start,
/// with the shared observable-set cache: its result.
#[allow(dead_code)]
pub fn explore(
    path: &Path,
    cfg: &tensorscout::Config,
    planner: tensorscout::plan::PlannerKind,
) -> tensorscout::sim::RunResult {
    let scene = tensorscout::scene::load(path, &cfg.scene).unwrap();
    let world = tensorscout::sim::World::with_cache(&scene, cfg, None, &cache()).unwrap();
    let out = tensorscout::sim::run(
        &scene,
        world,
        cfg,
        planner,
        &mut tensorscout::sim::NoObserver,
    );
    out.unwrap().result
}
