//! Scenario tests of `tensorscout bench`: determinism across `--jobs`, shards merged, resume after an
//! interruption, failed rows, and the output files. Short runs (`sim.budget_s=30`) on two small
//! shipped scenes keep them fast.

mod common;

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn scene(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .display()
        .to_string()
}

/// Runs `bench` on the standard small batch plus `extra` args, into `out`.
fn bench(out: &Path, extra: &[&str]) -> Output {
    let a = scene("apartment_small.obj");
    let b = scene("office_small.obj");
    let out_s = out.display().to_string();
    let mut args = vec![
        "bench",
        "--scenes",
        &a,
        &b,
        "--planners",
        "greedy",
        "--seeds",
        "2",
        "--set",
        "sim.budget_s=30",
        "--out",
        &out_s,
        "--quiet",
    ];
    args.extend_from_slice(extra);
    Command::new(env!("CARGO_BIN_EXE_tensorscout"))
        .env("TENSORSCOUT_CACHE_DIR", common::cache_dir())
        .args(&args)
        .output()
        .unwrap()
}

fn assert_ok(o: &Output) {
    assert!(
        o.status.success(),
        "bench failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The rows of `results.jsonl` without wall-clock fields.
fn rows(dir: &Path) -> Vec<Value> {
    std::fs::read_to_string(dir.join("results.jsonl"))
        .unwrap()
        .lines()
        .map(|l| {
            let mut v: Value = serde_json::from_str(l).unwrap();
            if let Some(r) = v.get_mut("result").and_then(Value::as_object_mut) {
                for k in ["wall_time_s", "real_time_factor", "timings_ms"] {
                    assert!(r.remove(k).is_some(), "missing {k}");
                }
            }
            v
        })
        .collect()
}

fn read(dir: &Path, name: &str) -> String {
    std::fs::read_to_string(dir.join(name)).unwrap()
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

#[test]
fn same_rows_whatever_the_jobs_and_outputs_parse() {
    let t = tmp();
    let (one, two) = (t.path().join("one"), t.path().join("two"));
    assert_ok(&bench(&one, &["--jobs", "1"]));
    assert_ok(&bench(&two, &["--jobs", "2"]));
    let r = rows(&one);
    assert_eq!(r.len(), 4);
    assert_eq!(r, rows(&two));
    assert_eq!(read(&one, "curves.csv"), read(&two, "curves.csv"));
    // Sorted by scene, planner, seed; every run succeeded with a full result.
    let keys: Vec<(String, u64)> = r
        .iter()
        .map(|v| {
            assert_eq!(v["status"], "ok");
            assert!(v["result"]["completeness"].as_f64().unwrap() > 0.0);
            (
                v["scene_path"].as_str().unwrap().to_string(),
                v["seed"].as_u64().unwrap(),
            )
        })
        .collect();
    let mut sorted = keys.clone();
    sorted.sort();
    assert_eq!(keys, sorted);

    // results.csv: a header and one line per run, every line with the header's column count.
    let csv = read(&one, "results.csv");
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 5);
    let cols = lines[0].split(',').count();
    assert!(lines[0].contains("completeness") && lines[0].contains("timings_ms_plan_p95"));
    assert!(lines.iter().all(|l| l.split(',').count() == cols));
    // curves.csv: one sample per simulated second (0..=30) per run.
    assert_eq!(read(&one, "curves.csv").lines().count(), 1 + 4 * 31);
    let summary: Value = serde_json::from_str(&read(&one, "summary.json")).unwrap();
    assert_eq!(summary["reference"], "greedy");
    assert_eq!(summary["cells"].as_array().unwrap().len(), 2);
    assert_eq!(summary["cells"][0]["r_epsilon"], 1.0);
    let md = read(&one, "summary.md");
    assert!(md.contains("| apartment_small | greedy | 2 |"), "{md}");
    assert!(md.contains("- **greedy**: completeness"), "{md}");
    for stem in ["apartment_small", "office_small"] {
        for kind in ["volume_vs_path", "completeness_vs_time"] {
            let png = one.join("plots").join(format!("{stem}_{kind}.png"));
            let img = image::open(&png).unwrap();
            assert_eq!((img.width(), img.height()), (900, 600));
        }
    }
}

#[test]
fn shards_merged_equal_the_whole_batch() {
    let t = tmp();
    let p = |n: &str| t.path().join(n);
    assert_ok(&bench(&p("all"), &["--jobs", "2"]));
    assert_ok(&bench(&p("s1"), &["--shard", "1/2"]));
    assert_ok(&bench(&p("s2"), &["--shard", "2/2"]));
    assert_eq!(rows(&p("s1")).len(), 2);
    let o = Command::new(env!("CARGO_BIN_EXE_tensorscout"))
        .env("TENSORSCOUT_CACHE_DIR", common::cache_dir())
        .args(["bench", "merge"])
        .args([p("s1"), p("s2")])
        .arg("--out")
        .arg(p("merged"))
        .output()
        .unwrap();
    assert_ok(&o);
    assert_eq!(rows(&p("merged")), rows(&p("all")));
    assert_eq!(
        read(&p("merged"), "curves.csv"),
        read(&p("all"), "curves.csv")
    );
    assert!(p("merged")
        .join("plots/office_small_volume_vs_path.png")
        .is_file());
}

#[test]
fn resume_after_an_interruption_gives_the_same_rows() {
    let t = tmp();
    let (whole, cut) = (t.path().join("whole"), t.path().join("cut"));
    assert_ok(&bench(&whole, &[]));
    // An interrupted batch: one complete row and half of the next.
    std::fs::create_dir(&cut).unwrap();
    let text = read(&whole, "results.jsonl");
    let mut lines = text.lines();
    let first = lines.next().unwrap();
    let second = lines.next().unwrap();
    std::fs::write(
        cut.join("results.jsonl"),
        format!("{first}\n{}", &second[..second.len() / 2]),
    )
    .unwrap();

    // Without --resume an existing batch is refused (usage error).
    let o = bench(&cut, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("pass --resume"));

    let o = bench(&cut, &["--resume"]);
    assert_ok(&o);
    assert!(
        String::from_utf8_lossy(&o.stderr)
            .contains("4 runs (1 skipped as already done, 3 run now)"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(rows(&cut), rows(&whole));
    // The first row was kept as it was, wall-clock fields included.
    assert_eq!(read(&cut, "results.jsonl").lines().next(), Some(first));
}

#[test]
fn a_bad_scene_is_a_failed_row_for_every_planner() {
    let t = tmp();
    let bad: PathBuf = t.path().join("broken.obj");
    std::fs::write(&bad, "v 0 0 0\nf 1 2 3\n").unwrap();
    let out = t.path().join("out");
    let bad_s = bad.display().to_string();
    let o = Command::new(env!("CARGO_BIN_EXE_tensorscout"))
        .env("TENSORSCOUT_CACHE_DIR", common::cache_dir())
        .args([
            "bench",
            "--scenes",
            &bad_s,
            "--planners",
            "greedy,tensor",
            "--seeds",
            "1",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_ok(&o);
    let r = rows(&out);
    assert_eq!(r.len(), 2);
    assert!(r.iter().all(|v| v["status"] == "failed"));
    for v in &r {
        assert!(v["error"].as_str().unwrap().starts_with(&bad_s), "{v}");
    }
    let md = read(&out, "summary.md");
    assert!(
        md.contains("- **tensor**: no successful run, 1/1 runs failed"),
        "{md}"
    );
}

#[test]
fn bad_flags_are_usage_errors() {
    let t = tmp();
    for (extra, needle) in [
        (&["--shard", "3/2"][..], "--shard `3/2`: expected K/N"),
        (&["--jobs", "0"][..], "--jobs 0"),
    ] {
        let o = bench(&t.path().join("x"), extra);
        assert_eq!(o.status.code(), Some(2), "{extra:?}");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(needle),
            "{extra:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

#[test]
fn log_runs_writes_one_verifiable_log_per_run() {
    let t = tmp();
    let out = t.path().join("logged");
    let o = bench(&out, &["--log-runs"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut logs: Vec<_> = std::fs::read_dir(out.join("logs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    logs.sort();
    let rows = std::fs::read_to_string(out.join("results.jsonl")).unwrap();
    assert_eq!(logs.len(), rows.lines().count());
    for log in logs {
        let r = Command::new(env!("CARGO_BIN_EXE_tensorscout"))
            .env("TENSORSCOUT_CACHE_DIR", common::cache_dir())
            .args(["replay", log.to_str().unwrap(), "--verify"])
            .output()
            .unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        assert!(String::from_utf8_lossy(&r.stdout).contains("identical"));
    }
}

/// With several seeds each seed draws its own start, the same for every planner; the summary has
/// confidence intervals and the paired comparison; rows do not depend on the observable-set cache
/// (a cold cache and a warm one give the same rows); `--scene-spawn` keeps the scene's spawn.
#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn seeds_pair_starts_across_planners() {
    let t = tmp();
    let a = scene("apartment_small.obj");
    let run = |out: &Path, cache: &Path, extra: &[&str]| {
        let out_s = out.display().to_string();
        let mut args = vec![
            "bench",
            "--scenes",
            &a,
            "--planners",
            "thp,greedy",
            "--seeds",
            "3",
            "--set",
            "sim.budget_s=20",
            "--out",
            &out_s,
            "--quiet",
        ];
        args.extend_from_slice(extra);
        Command::new(env!("CARGO_BIN_EXE_tensorscout"))
            .env("TENSORSCOUT_CACHE_DIR", cache)
            .args(&args)
            .output()
            .unwrap()
    };
    let cold = t.path().join("cache");
    let (first, second) = (t.path().join("first"), t.path().join("second"));
    assert_ok(&run(&first, &cold, &[]));
    assert!(cold.join("observable").read_dir().unwrap().count() == 1);
    assert_ok(&run(&second, &cold, &[]));
    assert_eq!(rows(&first), rows(&second));
    let r = rows(&first);
    assert_eq!(r.len(), 6);
    let start = |planner: &str, seed: u64| {
        r.iter()
            .find(|v| v["planner"] == planner && v["seed"] == seed)
            .map(|v| v["result"]["spawn"].clone())
            .unwrap()
    };
    let starts: Vec<Value> = (1..=3).map(|s| start("greedy", s)).collect();
    for (i, s) in starts.iter().enumerate() {
        assert_eq!(*s, start("thp", i as u64 + 1));
        assert!(starts.iter().filter(|o| *o == s).count() == 1, "{starts:?}");
    }
    let md = read(&first, "summary.md");
    assert!(md.contains("Student-t 95 %"), "{md}");
    assert!(
        md.contains("## Paired comparison against thp") && md.contains("| greedy | 3 |"),
        "{md}"
    );
    assert!(md.contains("Against thp over 3 pairs: path "), "{md}");
    // --scene-spawn: every run starts at the scene's own spawn.
    let kept = t.path().join("kept");
    assert_ok(&run(&kept, &cold, &["--scene-spawn"]));
    let k = rows(&kept);
    assert!(k
        .iter()
        .all(|v| v["result"]["spawn"] == k[0]["result"]["spawn"]));
}
