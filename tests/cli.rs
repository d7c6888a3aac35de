//! The command-line contract: exit codes, one-line errors naming the culprit, JSON keys, and
//! determinism of whole runs.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_tensorscout"));
    c.env("TENSORSCOUT_CACHE_DIR", common::cache_dir());
    c
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A usage error or run-time failure: the given exit code and exactly one line on stderr.
fn assert_fails(o: &Output, code: i32, needle: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(code), "stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(err.contains(needle), "`{needle}` not in: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn config_default_prints_every_section() {
    let o = run(&["config", "default"]);
    assert!(o.status.success());
    let text = String::from_utf8(o.stdout).unwrap();
    let parsed: toml::Table = text.parse().unwrap();
    for section in [
        "sim", "scene", "map", "camera", "robot", "motion", "search", "greedy",
    ] {
        assert!(parsed.contains_key(section), "missing [{section}]");
    }
}

#[test]
fn bad_flags_and_config_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    let s = scene.to_str().unwrap();
    assert_fails(
        &run(&["explore", "--scene", s, "--set", "map.voxl_m=0.1"]),
        2,
        "unknown config key `map.voxl_m`",
    );
    assert_fails(
        &run(&["explore", "--scene", s, "--set", "map.voxel_m=-0.1"]),
        2,
        "`map.voxel_m` must lie in [0.01, 1], got -0.1",
    );
    let cfg = write(dir.path(), "bad.toml", "[camera]\nwidht = 10\n");
    assert_fails(
        &run(&["explore", "--scene", s, "--config", cfg.to_str().unwrap()]),
        2,
        "unknown config key `camera.widht`",
    );
    let o = run(&["explore", "--scene", s, "--planner", "astar"]);
    assert_eq!(o.status.code(), Some(2));
    let o = run(&["explore", "--scene", s, "--spawn", "1,nope"]);
    assert_eq!(o.status.code(), Some(2));
    // The scene commands take the scene as a positional argument: the error says so.
    assert_fails(
        &run(&["scene", "info", "--scene", s]),
        2,
        "unexpected argument '--scene' found: the scene commands take the scene file as their first argument",
    );
}

#[test]
fn bad_scenes_fail_with_one_line_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let empty = write(dir.path(), "empty.obj", "");
    assert_fails(
        &run(&["scene", "info", empty.to_str().unwrap()]),
        1,
        "empty.obj",
    );
    let garbage = write(dir.path(), "garbage.ply", "\u{1}\u{2}this is not a mesh\n");
    assert_fails(
        &run(&["scene", "info", garbage.to_str().unwrap()]),
        1,
        "garbage.ply",
    );
    let nan = write(
        dir.path(),
        "nan.obj",
        "v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 0 2\nf 1 2 3\nf 1 2 4\n",
    );
    assert_fails(
        &run(&["scene", "info", nan.to_str().unwrap()]),
        1,
        "nan.obj",
    );
    let missing = dir.path().join("missing.obj");
    assert_fails(
        &run(&["scene", "info", missing.to_str().unwrap()]),
        1,
        "missing.obj",
    );
}

#[test]
fn bad_spawns_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    let s = scene.to_str().unwrap();
    // Inside the wall at x = 0..0.1.
    assert_fails(
        &run(&["explore", "--scene", s, "--spawn", "0.05,2"]),
        2,
        "spawn",
    );
    assert_fails(
        &run(&["explore", "--scene", s, "--spawn", "40,2"]),
        2,
        "spawn",
    );
}

#[test]
fn output_in_missing_folder_fails_before_running() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    let png = dir.path().join("no/such/dir/out.png");
    assert_fails(
        &run(&[
            "explore",
            "--scene",
            scene.to_str().unwrap(),
            "--png",
            png.to_str().unwrap(),
        ]),
        1,
        "does not exist",
    );
}

#[test]
fn existing_output_is_not_overwritten_without_force() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    let png = write(dir.path(), "mine.png", "precious");
    let o = run(&[
        "scene",
        "render",
        scene.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
    ]);
    assert_fails(&o, 1, "--force");
    assert_eq!(std::fs::read_to_string(&png).unwrap(), "precious");
}

fn explore_json(scene: &str, threads: &str) -> serde_json::Value {
    let o = bin()
        .args(["explore", "--scene", scene, "--planner", "greedy", "--json"])
        .env("RAYON_NUM_THREADS", threads)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).expect("exactly one JSON object")
}

/// Removes the wall-clock fields, which are the only ones allowed to differ between runs.
fn without_wall_clock(mut v: serde_json::Value) -> serde_json::Value {
    let o = v.as_object_mut().unwrap();
    for k in ["wall_time_s", "real_time_factor", "timings_ms"] {
        o.remove(k);
    }
    v
}

#[test]
fn explore_json_has_the_contract_keys_and_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    let s = scene.to_str().unwrap();
    let a = explore_json(s, "1");
    for key in [
        "scene",
        "planner",
        "seed",
        "termination",
        "completeness",
        "explored_volume_m3",
        "observable_volume_m3",
        "reachable_area_m2",
        "explored_outside_observable_fraction",
        "unseen_observable",
        "frontiers_left",
        "frontier_groups_left",
        "surface_coverage",
        "path_length_m",
        "sim_time_s",
        "wall_time_s",
        "real_time_factor",
        "collisions",
        "steps",
        "timings_ms",
        "version",
        "config_hash",
    ] {
        assert!(a.get(key).is_some(), "missing key {key}");
    }
    for stage in ["sense", "map", "field", "plan", "motion"] {
        for stat in ["mean", "p50", "p95", "max"] {
            assert!(a["timings_ms"][stage][stat].is_number());
        }
    }
    assert_eq!(a["termination"], "complete");
    assert_eq!(a["collisions"], 0);
    // The band's top (1.8 m) is only in view 2.8 m or more from the 0.6 m camera, so a small room
    // keeps some voxels high up unseen.
    assert!(a["completeness"].as_f64().unwrap() > 0.85);
    assert!(a["surface_coverage"].as_f64().unwrap() > 0.9);
    let b = explore_json(s, "2");
    assert_eq!(without_wall_clock(a.clone()), without_wall_clock(b));
    let c = explore_json(s, "1");
    assert_eq!(without_wall_clock(a), without_wall_clock(c));
}

#[test]
fn every_example_config_loads() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs");
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            tensorscout::Config::load(Some(&path), &[])
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            n += 1;
        }
    }
    assert!(n >= 3);
}

#[test]
fn y_up_flag_rotates_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    // The test room with y and z swapped: (x, y, z) -> (x, z, -y), i.e. written y-up.
    let y_up: String = common::room_obj(None)
        .lines()
        .map(|l| {
            let parts: Vec<&str> = l.split_whitespace().collect();
            if parts.first() == Some(&"v") {
                let (x, y, z) = (parts[1], parts[2], parts[3]);
                let neg_y = if let Some(stripped) = y.strip_prefix('-') {
                    stripped.to_string()
                } else {
                    format!("-{y}")
                };
                format!("v {x} {z} {neg_y}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let scene = write(dir.path(), "room_yup.obj", &y_up);
    let s = scene.to_str().unwrap();
    let info = |extra: &[&str]| {
        let mut args = vec!["scene", "info", s, "--json"];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()
    };
    let rotated = info(&["--y-up"]);
    // Back to the z-up room: 6 × 4 m footprint, 2.5 m tall.
    let min = &rotated["bounds_min"];
    let max = &rotated["bounds_max"];
    let size = |k: usize| max[k].as_f64().unwrap() - min[k].as_f64().unwrap();
    assert!(
        (size(0) - 6.0).abs() < 1e-4
            && (size(1) - 4.0).abs() < 1e-4
            && (size(2) - 2.5).abs() < 1e-4
    );
    let same = info(&["--set", "scene.y_up=true"]);
    assert_eq!(rotated["bounds_max"], same["bounds_max"]);
}
