//! Sensor and odometry noise in whole runs: the presets are deterministic whatever the thread
//! count, a noisy log replays identically and carries the true pose, the exported trajectories give
//! the reported pose error, and noise parameters change nothing while their models are off (that
//! noise off leaves every default result as it was is `tests/default_profile_unchanged.rs`).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use tensorscout::plan::PlannerKind;
use tensorscout::sim::{run, NoObserver, World};
use tensorscout::Config;

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_tensorscout"));
    c.env("TENSORSCOUT_CACHE_DIR", common::cache_dir());
    c
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn preset(name: &str) -> PathBuf {
    root().join("configs").join(format!("{name}.toml"))
}

fn scene() -> PathBuf {
    root().join("scenes/apartment_small.obj")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A run of apartment_small under `cfg` on a pool of `threads` threads: its result without the
/// wall-clock fields.
fn result_json(cfg: &Config, planner: PlannerKind, threads: usize) -> serde_json::Value {
    let scene = tensorscout::scene::load(&scene(), &cfg.scene).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let out = pool.install(|| {
        let world = World::with_cache(&scene, cfg, None, &common::cache()).unwrap();
        run(&scene, world, cfg, planner, &mut NoObserver).unwrap()
    });
    let mut v = serde_json::to_value(&out.result).unwrap();
    let o = v.as_object_mut().unwrap();
    for k in ["wall_time_s", "real_time_factor", "timings_ms"] {
        o.remove(k);
    }
    v
}

/// Each preset gives the same result with one and two threads (depth noise is drawn per pixel,
/// pose noise per step), and reports map quality, and pose error where the pose is noisy.
#[test]
fn presets_do_not_depend_on_the_thread_count() {
    for (name, planner) in [
        ("kinect_noisy", PlannerKind::Thp),
        ("realsense_noisy", PlannerKind::Greedy),
        ("odometry_drift", PlannerKind::Nbv),
    ] {
        let cfg = Config::load(Some(&preset(name)), &["sim.budget_s=60".into()]).unwrap();
        let one = result_json(&cfg, planner, 1);
        assert!(one["steps"].as_u64().unwrap() > 100, "{name}");
        assert_eq!(one, result_json(&cfg, planner, 2), "{name}");
        for key in ["map_precision", "map_recall", "free_but_occupied"] {
            let v = one[key]
                .as_f64()
                .unwrap_or_else(|| panic!("{name}: no {key}"));
            assert!((0.0..=1.0).contains(&v), "{name}: {key} {v}");
        }
        assert!(one["ate_rmse_m"].as_f64().unwrap() > 0.0, "{name}");
        assert!(one["ate_max_m"].as_f64() >= one["ate_rmse_m"].as_f64());
    }
}

/// Noise parameters do nothing while the models are off: the result is the default's, without
/// the noise fields.
#[test]
fn noise_parameters_are_inert_while_the_models_are_off() {
    let base = Config::load(None, &["sim.budget_s=60".into()]).unwrap();
    let mut changed = base.clone();
    let d = &mut changed.noise.depth;
    (d.dropout, d.edge_dropout, d.axial_base_m, d.subpixel_px) = (0.5, 0.5, 0.1, 3.0);
    let p = &mut changed.noise.pose;
    (p.alpha1, p.alpha3, p.sigma_xy_m) = (0.5, 0.5, 1.0);
    let m = &mut changed.noise.motion;
    (m.alpha1, m.alpha3) = (0.5, 0.5);
    let mut a = result_json(&base, PlannerKind::Greedy, 1);
    let mut b = result_json(&changed, PlannerKind::Greedy, 1);
    assert_ne!(a["config_hash"], b["config_hash"]);
    a.as_object_mut().unwrap().remove("config_hash");
    b.as_object_mut().unwrap().remove("config_hash");
    assert_eq!(a, b);
    for key in ["map_precision", "ate_rmse_m", "ate_max_m"] {
        assert!(a.get(key).is_none(), "{key} in a noise-free result");
    }
}

/// Depth noise alone: map quality is reported, pose error is not (the pose is exact).
#[test]
fn depth_noise_alone_reports_no_pose_error() {
    let cfg = Config::load(
        None,
        &[
            "sim.budget_s=30".into(),
            "noise.depth.model=\"stereo\"".into(),
            "noise.depth.dropout=0.05".into(),
        ],
    )
    .unwrap();
    let r = result_json(&cfg, PlannerKind::Greedy, 1);
    assert!(r["map_precision"].as_f64().unwrap() > 0.5);
    assert!(r.get("ate_rmse_m").is_none());
}

/// The TUM files of a drifting run differ from each other, and the reported ATE is the root mean
/// square of their position differences (recomputed here from the files, as `evo_ape` does).
#[test]
fn exported_trajectories_give_the_reported_ate() {
    let dir = tempfile::tempdir().unwrap();
    let (est, tru) = (dir.path().join("est.txt"), dir.path().join("true.txt"));
    let out = bin()
        .args(["explore", "--json", "-q", "--planner", "greedy", "--scene"])
        .arg(scene())
        .arg("--config")
        .arg(preset("odometry_drift"))
        .args(["--set", "sim.budget_s=60", "--trajectory"])
        .arg(&est)
        .arg("--trajectory-true")
        .arg(&tru)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let result: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let read = |p: &Path| -> Vec<Vec<f64>> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .filter(|l| !l.starts_with('#'))
            .map(|l| l.split(' ').map(|x| x.parse().unwrap()).collect())
            .collect()
    };
    let (e, t) = (read(&est), read(&tru));
    assert_eq!(e.len() as u64, result["steps"].as_u64().unwrap() + 1);
    assert_eq!(e.len(), t.len());
    let mut sum = 0.0;
    let mut max = 0.0f64;
    for (a, b) in e.iter().zip(&t) {
        assert_eq!(a[0], b[0], "timestamps pair up");
        let d2 = (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2);
        sum += d2;
        max = max.max(d2.sqrt());
    }
    let rmse = (sum / e.len() as f64).sqrt();
    assert!(rmse > 0.0);
    assert!((rmse - result["ate_rmse_m"].as_f64().unwrap()).abs() < 1e-9);
    assert!((max - result["ate_max_m"].as_f64().unwrap()).abs() < 1e-9);
}

/// A noisy run's log replays message for message (`replay --verify`), and its `/tf` carries the
/// true pose as `base_link_true` beside the estimate; they differ once the robot has moved.
#[test]
fn a_noisy_log_verifies_and_carries_the_true_pose() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.mcap");
    let out = bin()
        .args(["explore", "-q", "--planner", "greedy", "--scene"])
        .arg(scene())
        .arg("--config")
        .arg(preset("odometry_drift"))
        .args([
            "--set",
            "sim.budget_s=30",
            "--set",
            "noise.depth.model=\"kinect\"",
        ])
        .arg("--log")
        .arg(&log)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let v = bin()
        .arg("replay")
        .arg(&log)
        .arg("--verify")
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .unwrap();
    assert!(v.status.success(), "{}", stderr(&v));
    assert_eq!(
        String::from_utf8_lossy(&v.stdout).lines().last(),
        Some("identical")
    );
    let contents = tensorscout::log::reader::read_log(&log).unwrap();
    let mut differ = 0;
    let mut tfs = 0;
    for m in contents.topic("/tf") {
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        let frame = |child: &str| {
            v["transforms"]
                .as_array()
                .unwrap()
                .iter()
                .find(|t| t["child_frame_id"] == child)
                .unwrap_or_else(|| panic!("no {child} in /tf"))
                .clone()
        };
        let (est, tru) = (frame("base_link"), frame("base_link_true"));
        assert_eq!(tru["parent_frame_id"], "world");
        tfs += 1;
        differ += usize::from(est["translation"] != tru["translation"]);
    }
    assert!(tfs > 100 && differ > tfs / 2, "{differ} of {tfs}");
}

/// Map quality measures the map against the truth: with an exact pose and exact frames (motion
/// noise on with zero error, so that it is reported) nearly every occupied voxel is real and
/// hardly a free voxel is occupied; a pose estimate 0.3 m off (standard deviation) lowers precision and
/// recall and makes real obstacles read as free.
#[test]
fn map_quality_falls_with_pose_error() {
    let exact = Config::load(
        None,
        &[
            "sim.budget_s=60".into(),
            "noise.motion.enabled=true".into(),
            "noise.motion.alpha1=0".into(),
            "noise.motion.alpha2=0".into(),
            "noise.motion.alpha3=0".into(),
            "noise.motion.alpha4=0".into(),
        ],
    )
    .unwrap();
    let mut wrong = exact.clone();
    wrong.noise.pose.model = tensorscout::config::PoseModel::Localized;
    wrong.noise.pose.sigma_xy_m = 0.3;
    let a = result_json(&exact, PlannerKind::Greedy, 1);
    let b = result_json(&wrong, PlannerKind::Greedy, 1);
    let f = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap();
    assert_eq!(f(&a, "ate_rmse_m"), 0.0);
    assert!(f(&a, "map_precision") > 0.97, "{a}");
    // Not zero even so: a ray may pass through a voxel that a wall's surface only clips.
    assert!(f(&a, "free_but_occupied") < 0.02, "{a}");
    assert!(f(&b, "map_precision") < f(&a, "map_precision") - 0.1, "{b}");
    assert!(f(&b, "map_recall") < f(&a, "map_recall"), "{b}");
    assert!(
        f(&b, "free_but_occupied") > 2.0 * f(&a, "free_but_occupied"),
        "{b}"
    );
}
