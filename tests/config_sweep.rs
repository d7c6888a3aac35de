//! Every number key of `tensorscout config default`, set to 0, -1, NaN, inf and 1e308 in turn, either
//! is refused with a one-line usage error (exit 2) or gives a clean run (exit 0, one JSON result),
//! within a memory limit and a time limit: no panic, abort, out-of-memory or hang.

mod common;

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// Address space a run may take (`ulimit -v`, KiB): a run of the test room needs a few hundred MB.
const MEMORY_LIMIT_KIB: u64 = 3 << 20;
/// Wall-clock limit of one run of 5 simulated seconds (generous: the machine may be busy).
const TIME_LIMIT: Duration = Duration::from_secs(60);

/// The planner whose run reads the key's section (GREEDY for the shared sections).
fn planner_for(key: &str) -> &'static str {
    match key.split('.').next().unwrap_or("") {
        "thp" | "additions" => "thp",
        "tensor" | "field" => "tensor",
        "nbv" => "nbv",
        _ => "greedy",
    }
}

/// Runs `explore` with `set` under the limits; returns (exit code, stdout, stderr).
fn run_limited(scene: &Path, dir: &Path, key: &str, set: &str) -> (Option<i32>, String, String) {
    let log = dir.join("sweep.mcap");
    let _ = std::fs::remove_file(&log);
    let mut cmd = Command::new("sh");
    cmd.arg("-c")
        .arg(format!(
            "ulimit -v {MEMORY_LIMIT_KIB} && exec \"$0\" \"$@\""
        ))
        .arg(env!("CARGO_BIN_EXE_tensorscout"))
        .env("TENSORSCOUT_CACHE_DIR", common::cache_dir())
        .args(["explore", "-q", "--json", "--planner", planner_for(key)])
        .arg("--scene")
        .arg(scene)
        // The key's own value comes last, so `sim.budget_s` itself is swept too.
        .args(["--set", "sim.budget_s=5", "--set", set])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped());
    if key.starts_with("log.") {
        cmd.arg("--log").arg(&log);
    }
    let mut child = cmd.spawn().expect("sh runs");
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed() > TIME_LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("`--set {set}` ran past {TIME_LIMIT:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let o = child.wait_with_output().unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn every_number_key_through_absurd_values() {
    let out = Command::new(env!("CARGO_BIN_EXE_tensorscout"))
        .args(["config", "default"])
        .output()
        .unwrap();
    let tree: toml::Table = String::from_utf8(out.stdout).unwrap().parse().unwrap();
    let keys = tensorscout::config::number_keys(&tree);
    assert!(keys.len() > 100, "{} number keys", keys.len());
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("room.obj");
    std::fs::write(&scene, common::room_obj(None)).unwrap();
    let mut clean = 0;
    for key in &keys {
        for value in ["0", "-1", "nan", "inf", "1e308"] {
            let set = format!("{key}={value}");
            let (code, stdout, stderr) = run_limited(&scene, dir.path(), key, &set);
            match code {
                Some(0) => {
                    let result: serde_json::Value = serde_json::from_str(stdout.trim())
                        .unwrap_or_else(|e| {
                            panic!("`--set {set}`: no JSON result ({e}): {stdout}")
                        });
                    assert!(result["termination"].is_string(), "`--set {set}`: {stdout}");
                    clean += 1;
                }
                Some(2) => {
                    assert_eq!(
                        stderr.trim_end().lines().count(),
                        1,
                        "`--set {set}`: not one line: {stderr}"
                    );
                    assert!(stderr.contains(key.as_str()), "`--set {set}`: {stderr}");
                }
                other => panic!("`--set {set}` ended with {other:?}: {stderr}"),
            }
            assert!(!stderr.contains("panicked"), "`--set {set}`: {stderr}");
        }
    }
    // Zero is meaningful for many keys (switches, margins): the sweep ran real explorations too.
    assert!(clean > 20, "only {clean} clean runs");
}
