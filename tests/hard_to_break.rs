//! Regression tests of the defects found by trying to break the command line as a careless or
//! hostile user would: closed and full outputs, lost files, special files, absurd values, signals,
//! and misleading messages. Each test is named after the defect it guards against.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

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

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The exit code and exactly one line on stderr containing `needle`, no panic.
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

/// Runs a short logged exploration of `scene` into `log`.
fn explore_logged(scene: &Path, log: &Path, cwd: &Path) -> Output {
    bin()
        .current_dir(cwd)
        .args(["explore", "--planner", "greedy", "-q", "--json", "--scene"])
        .arg(scene)
        .arg("--log")
        .arg(log)
        .args(["--set", "sim.budget_s=8"])
        .output()
        .unwrap()
}

/// Waits for a child with a deadline; kills it (by its own pid) and fails past it.
fn wait_with_deadline(mut child: std::process::Child, limit: Duration) -> Output {
    let t0 = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return child.wait_with_output().unwrap();
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            panic!("the process did not end within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn closed_stdout_ends_quietly() {
    for args in [&["config", "default"][..], &["explore", "--help"][..]] {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let o = bin()
            .args(args)
            .stdout(writer)
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        if args[0] == "config" {
            assert_eq!(stderr(&o), "", "{args:?}");
        }
    }
}

#[test]
fn full_stdout_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    for args in [
        vec!["config".to_string(), "default".to_string()],
        vec![
            "scene".into(),
            "info".into(),
            scene.display().to_string(),
            "--json".into(),
        ],
    ] {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let o = bin().args(&args).stdout(full).output().unwrap();
        assert_fails(&o, 1, "stdout: No space left on device");
    }
}

#[test]
fn png_and_log_on_one_path_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    let p = dir.path().join("out.png");
    let o = bin()
        .args(["explore", "--scene"])
        .arg(&scene)
        .arg("--png")
        .arg(&p)
        .arg("--log")
        .arg(dir.path().join(".").join("out.png"))
        .output()
        .unwrap();
    assert_fails(&o, 2, "--png and --log name the same file");
    assert!(!p.exists());
    // An output onto the scene itself is refused too, even with --force.
    let o = bin()
        .args(["explore", "--force", "--scene"])
        .arg(&scene)
        .arg("--log")
        .arg(&scene)
        .output()
        .unwrap();
    assert_fails(&o, 2, "--log and --scene name the same file");
    assert_eq!(
        std::fs::read_to_string(&scene).unwrap(),
        common::room_obj(None)
    );
}

#[test]
fn png_problems_found_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    // An extension the PNG writer cannot write: a usage error before anything runs.
    let o = bin()
        .args(["explore", "--scene"])
        .arg(&scene)
        .arg("--png")
        .arg(dir.path().join("run.jpg"))
        .output()
        .unwrap();
    assert_fails(&o, 2, "run.jpg: the output must be a .png file");
    // A folder nobody can write in (even root cannot create files in /proc).
    let t0 = Instant::now();
    let o = bin()
        .args(["explore", "--scene"])
        .arg(&scene)
        .args(["--png", "/proc/run.png"])
        .output()
        .unwrap();
    assert_fails(&o, 1, "cannot write in folder /proc");
    assert!(stdout(&o).is_empty(), "the run must not start");
    let _ = t0;
}

/// One `results.jsonl` row of a failed run of seed `seed`.
fn failed_row(seed: u64) -> String {
    format!(
        "{{\"scene_path\":\"a.obj\",\"scene_hash\":\"h\",\"planner\":\"greedy\",\"seed\":{seed},\"config_hash\":\"c\",\"status\":\"failed\",\"error\":\"x\",\"result\":null}}\n"
    )
}

#[test]
fn bench_merge_refuses_existing_out() {
    let dir = tempfile::tempdir().unwrap();
    let row = failed_row;
    let a = dir.path().join("a");
    let out = dir.path().join("out");
    std::fs::create_dir(&a).unwrap();
    std::fs::create_dir(&out).unwrap();
    std::fs::write(a.join("results.jsonl"), row(1)).unwrap();
    let six: String = (10..16).map(row).collect();
    std::fs::write(out.join("results.jsonl"), &six).unwrap();
    let o = bin()
        .args(["bench", "merge"])
        .arg(&a)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_fails(&o, 2, "results.jsonl already exists");
    assert_eq!(
        std::fs::read_to_string(out.join("results.jsonl")).unwrap(),
        six
    );
    let o = bin()
        .args(["bench", "merge"])
        .arg(&a)
        .arg("--out")
        .arg(&out)
        .arg("--force")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(out.join("results.jsonl")).unwrap(),
        row(1)
    );
}

#[test]
fn bench_merge_reports_conflicts_on_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let row = |err: &str| {
        format!(
            "{{\"scene_path\":\"a.obj\",\"scene_hash\":\"h\",\"planner\":\"greedy\",\"seed\":1,\"config_hash\":\"c\",\"status\":\"failed\",\"error\":\"{err}\",\"result\":null}}\n"
        )
    };
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for (d, e) in [(&a, "x"), (&b, "y")] {
        std::fs::create_dir(d).unwrap();
        std::fs::write(d.join("results.jsonl"), row(e)).unwrap();
    }
    let out = dir.path().join("out");
    let o = bin()
        .args(["bench", "merge"])
        .arg(&a)
        .arg(&b)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_fails(&o, 1, "1 run(s) differ between the folders");
    let o = bin()
        .args(["bench", "merge", "--keep-first"])
        .arg(&a)
        .arg(&b)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn bench_out_with_user_files_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    write(&out, "summary.md", "my own notes\n");
    let o = bin()
        .args(["bench", "--planners", "greedy", "--seeds", "1", "--scenes"])
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_fails(
        &o,
        2,
        "summary.md already exists and is not from a bench run",
    );
    assert_eq!(
        std::fs::read_to_string(out.join("summary.md")).unwrap(),
        "my own notes\n"
    );
}

#[test]
fn special_files_as_scenes_refused() {
    let dir = tempfile::tempdir().unwrap();
    let z = dir.path().join("z.obj");
    std::os::unix::fs::symlink("/dev/zero", &z).unwrap();
    let child = bin()
        .args(["scene", "info"])
        .arg(&z)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let o = wait_with_deadline(child, Duration::from_secs(20));
    assert_fails(&o, 1, "not a regular file");
    let fifo = dir.path().join("f.obj");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let child = bin()
        .args(["scene", "info"])
        .arg(&fifo)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let o = wait_with_deadline(child, Duration::from_secs(20));
    assert_fails(&o, 1, "not a regular file");
    // A FIFO as the config or the log is refused the same way.
    let child = bin()
        .args(["config", "default"])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let _ = wait_with_deadline(child, Duration::from_secs(20));
    let child = bin()
        .arg("replay")
        .arg(&fifo)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let o = wait_with_deadline(child, Duration::from_secs(20));
    assert_fails(&o, 1, "not a regular file");
}

#[test]
fn costly_flag_values_are_bounded() {
    let o = run(&[
        "bench",
        "--scenes",
        "x.obj",
        "--seeds",
        "1000000000",
        "--out",
        "/nonexistent/o",
    ]);
    assert_fails(&o, 2, "--seeds 1000000000: expected 1 to 100000");
    let o = run(&[
        "bench",
        "--scenes",
        "x.obj",
        "--jobs",
        "100000",
        "--out",
        "/nonexistent/o",
    ]);
    assert_fails(&o, 2, "--jobs 100000: expected 1 to 1024");
    let o = run(&[
        "replay",
        "x.mcap",
        "--render",
        "/nonexistent/d",
        "--every",
        "1e-9",
    ]);
    assert_fails(&o, 2, "--every must lie in [0.1, 1e6] seconds, got 1e-9");
    for (set, key) in [
        ("sim.dt_s=1e-300", "sim.dt_s"),
        ("field.rk4_step_m=1e-9", "field.rk4_step_m"),
        ("field.d_s_m=1e-6", "field.d_s_m"),
        ("camera.width=9223372036854775807", "camera.width"),
        ("camera.height=100000", "camera.height"),
    ] {
        let o = run(&["explore", "--scene", "x.obj", "--set", set]);
        assert_fails(&o, 2, &format!("config key `{key}` must lie in"));
    }
}

#[test]
fn negative_option_values_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    let o = bin()
        .args(["explore", "--scene"])
        .arg(&scene)
        .args(["--spawn", "-50,2"])
        .output()
        .unwrap();
    assert_fails(&o, 2, "spawn (-50, 2) is outside the scene bounds");
    let out = dir.path().join("x.obj");
    let o = bin()
        .args([
            "scene", "generate", "--style", "office", "--area", "-5", "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert_fails(&o, 2, "-5");
    assert!(
        !stderr(&o).contains("unexpected argument"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn clap_errors_are_one_line() {
    for args in [
        &["explore", "--bogus"][..],
        &["explore"][..],
        &["bench", "--seeds", "many"][..],
        &["nosuchcommand"][..],
        &[][..],
    ] {
        let o = run(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        let err = stderr(&o);
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(err.starts_with("error: "), "{err}");
    }
    // Help still prints in full and succeeds.
    let o = run(&["explore", "--help"]);
    assert!(o.status.success());
    assert!(stdout(&o).lines().count() > 10);
}

fn send(child: &std::process::Child, signal: &str) {
    let ok = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
}

#[test]
fn interrupted_runs_exit_129_130_or_143() {
    let dir = tempfile::tempdir().unwrap();
    // A large scene, so that the runs are still going when the signal comes.
    let scene = dir.path().join("office_large.obj");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/office_large.obj"),
        &scene,
    )
    .unwrap();
    let long = [
        "--set",
        "sim.budget_s=100000",
        "--set",
        "sim.stuck_timeout_s=100000",
        "--set",
        "sim.initial_look_around=false",
    ];
    for (signal, code) in [("-INT", 130), ("-TERM", 143), ("-HUP", 129)] {
        // An unlogged run stops cleanly and prints its (interrupted) result.
        let child = bin()
            .args(["explore", "--json", "-q", "--planner", "greedy", "--scene"])
            .arg(&scene)
            .args(long)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(1500));
        send(&child, signal);
        let o = wait_with_deadline(child, Duration::from_secs(60));
        assert_eq!(o.status.code(), Some(code), "{signal}: {}", stderr(&o));
        if !stdout(&o).is_empty() {
            let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
            assert_eq!(v["termination"], "interrupted");
        }
    }
    // A bench batch too.
    let child = bin()
        .args([
            "bench",
            "-q",
            "--planners",
            "greedy",
            "--seeds",
            "1",
            "--scenes",
        ])
        .arg(&scene)
        .arg("--out")
        .arg(dir.path().join("b"))
        .args(long)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    send(&child, "-INT");
    let o = wait_with_deadline(child, Duration::from_secs(60));
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
}

#[test]
fn verify_finds_a_moved_scene_from_any_folder() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    std::fs::create_dir(&a).unwrap();
    write(&a, "room.obj", &common::room_obj(None));
    // The scene path is stored as given (relative to the working folder `a`).
    let o = explore_logged(Path::new("room.obj"), Path::new("run.mcap"), &a);
    assert!(o.status.success(), "{}", stderr(&o));
    // From another folder: found by the absolute path stored with it.
    let o = bin()
        .current_dir(dir.path())
        .args(["replay", "a/run.mcap", "--verify"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).ends_with("identical\n"), "{}", stdout(&o));
    // Scene and log moved together (renamed scene): found by its hash next to the log.
    let b = dir.path().join("b");
    std::fs::create_dir(&b).unwrap();
    std::fs::rename(a.join("run.mcap"), b.join("run.mcap")).unwrap();
    std::fs::rename(a.join("room.obj"), b.join("renamed.obj")).unwrap();
    let o = bin()
        .current_dir(dir.path())
        .args(["replay", "b/run.mcap", "--verify"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).ends_with("identical\n"), "{}", stdout(&o));
}

/// The top-level records of an MCAP file: (opcode, start, end).
fn records(bytes: &[u8]) -> Vec<(u8, usize, usize)> {
    let mut out = Vec::new();
    let mut pos = 8;
    while pos + 9 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        out.push((bytes[pos], pos, pos + 9 + len));
        pos += 9 + len;
    }
    out
}

#[test]
fn log_without_identity_is_a_loss() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", &common::room_obj(None));
    let o = explore_logged(Path::new("room.obj"), Path::new("run.mcap"), dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(dir.path().join("run.mcap")).unwrap();
    // Remove the metadata records (0x0C) and their index (0x0D), keeping the rest byte for byte.
    let mut stripped = bytes[..8].to_vec();
    let recs = records(&bytes);
    let mut end = 8;
    for (op, a, b) in recs {
        if op != 0x0C && op != 0x0D {
            stripped.extend_from_slice(&bytes[a..b]);
        }
        end = b;
    }
    stripped.extend_from_slice(&bytes[end..]);
    let p = dir.path().join("stripped.mcap");
    std::fs::write(&p, &stripped).unwrap();
    let o = bin().arg("replay").arg(&p).arg("--json").output().unwrap();
    assert_fails(&o, 1, "the run identity metadata is missing");
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["complete"], false);
}

#[test]
fn damaged_record_outside_chunks_resyncs() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", &common::room_obj(None));
    let o = bin()
        .current_dir(dir.path())
        .args([
            "explore",
            "--planner",
            "greedy",
            "-q",
            "--scene",
            "room.obj",
            "--log",
            "run.mcap",
            "--set",
            "sim.budget_s=20",
            "--set",
            "log.chunk_size_kb=8",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(dir.path().join("run.mcap")).unwrap();
    let recs = records(&bytes);
    let chunks = recs.iter().filter(|r| r.0 == 0x06).count();
    assert!(chunks >= 4, "{chunks} chunks");
    // Damage the header of a message index that follows the first chunk (outside any chunk).
    let (_, at, _) = *recs
        .iter()
        .skip_while(|r| r.0 != 0x06)
        .find(|r| r.0 == 0x07)
        .expect("a message index after a chunk");
    let mut damaged = bytes.clone();
    damaged[at + 3] ^= 0x40; // its length field
    let p = dir.path().join("damaged.mcap");
    std::fs::write(&p, &damaged).unwrap();
    let o = bin().arg("replay").arg(&p).arg("--json").output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    // Every chunk is still read, and the summary that follows too: nothing was lost.
    assert_eq!(v["chunks_read"], chunks as u64, "{v}");
    assert_eq!(v["chunks_lost"], 0);
    assert_eq!(v["messages_lost"], 0);
    assert!(
        stderr(&o).contains("damaged record at byte"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn replay_render_refuses_a_folder_with_frames() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", &common::room_obj(None));
    let o = explore_logged(Path::new("room.obj"), Path::new("run.mcap"), dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    write(&frames, "frame_0099.png", "stale");
    let log = dir.path().join("run.mcap");
    let o = bin()
        .arg("replay")
        .arg(&log)
        .arg("--render")
        .arg(&frames)
        .output()
        .unwrap();
    assert_fails(&o, 2, "the folder is not empty; pass --force");
    assert_eq!(
        std::fs::read_to_string(frames.join("frame_0099.png")).unwrap(),
        "stale"
    );
    let o = bin()
        .arg("replay")
        .arg(&log)
        .arg("--render")
        .arg(&frames)
        .arg("--force")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!frames.join("frame_0099.png").exists(), "stale frame left");
    assert!(frames.join("overview.png").exists());
}

#[test]
fn misleading_messages_fixed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A folder and a file without extension.
    let o = bin().args(["scene", "info"]).arg(d).output().unwrap();
    assert_fails(&o, 2, "is a folder, not a scene file");
    let noext = write(d, "room", &common::room_obj(None));
    let o = bin().args(["scene", "info"]).arg(&noext).output().unwrap();
    assert_fails(&o, 2, "the scene file has no extension");
    // A HouseExpo coordinate of 1e300 prints a short number.
    let plan = write(
        d,
        "plan.json",
        "{\"verts\": [[0, 0], [1e300, 0], [0, 5]], \"room_num\": 1}",
    );
    let o = bin().args(["scene", "info"]).arg(&plan).output().unwrap();
    assert_fails(&o, 1, "plan extent 1.000e300 m exceeds");
    assert!(stderr(&o).len() < 300, "{}", stderr(&o));
    // A spawn line inside a wall names the file.
    let walled = write(d, "walled.obj", &common::room_obj(Some("0.05 2 0")));
    let o = bin().args(["scene", "info"]).arg(&walled).output().unwrap();
    assert_fails(
        &o,
        2,
        &format!(
            "{}: the file's `tensorscout spawn` line: spawn (0.05, 2)",
            walled.display()
        ),
    );
    // A binary config is a usage error like a bad text one.
    let bin_cfg = d.join("c.toml");
    std::fs::write(&bin_cfg, [0xff, 0xfe, 0x00, 0x01]).unwrap();
    let o = bin()
        .args(["explore", "--scene", "x.obj", "--config"])
        .arg(&bin_cfg)
        .output()
        .unwrap();
    assert_fails(&o, 2, "not a TOML config (not UTF-8 text");
}

#[test]
fn bad_mesh_data_warned_or_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Faces with fewer than 3 vertices: a one-line warning naming the file and line.
    let mut text = common::room_obj(None);
    text.push_str("f 1 2\n");
    let short = write(d, "short.obj", &text);
    let o = bin().args(["scene", "info"]).arg(&short).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("1 face(s) with fewer than 3 vertices skipped (first on line"),
        "{}",
        stderr(&o)
    );
    // Zero-area triangles only: refused.
    let flat = write(
        d,
        "zero.obj",
        "v 0 0 0\nv 1 1 1\nv 2 2 2\nv 0 0 0\nf 1 2 3\nf 1 2 4\n",
    );
    let o = bin().args(["scene", "info"]).arg(&flat).output().unwrap();
    assert_fails(&o, 1, "every triangle has zero area");
    // An open mesh (one wall): the automatic spawn is in the open, and the user is told.
    let open = write(
        d,
        "open.obj",
        "v 0 0 0\nv 4 0 0\nv 4 0 2\nv 0 0 2\nv 0 3 0\nv 4 3 0\nf 1 2 3 4\nf 1 2 6 5\n",
    );
    let o = bin().args(["scene", "info"]).arg(&open).output().unwrap();
    assert!(
        stderr(&o).contains("is not enclosed (an open mesh?)"),
        "{}",
        stderr(&o)
    );
}

/// Every output flag of `explore`, with `--force`, against every input (the scene, the config, the
/// map image a ROS map names), spelled directly, as a symbolic link and as a hard link: refused
/// with exit 2, and no input changes. A link given as an output is refused even when it dangles,
/// and nothing is created at its target.
#[test]
fn outputs_never_replace_inputs() {
    use std::os::unix::fs::symlink;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    // The scene is `room.yaml`, naming the image `map.pgm` beside it.
    let yaml = write(
        d,
        "room.yaml",
        &std::fs::read_to_string(data.join("map.yaml")).unwrap(),
    );
    let image = d.join("map.pgm");
    std::fs::copy(data.join("map.pgm"), &image).unwrap();
    let config = write(d, "c.toml", "[sim]\nbudget_s = 5.0\n");
    let inputs = [&yaml, &image, &config];
    let before: Vec<Vec<u8>> = inputs.iter().map(|p| std::fs::read(p).unwrap()).collect();
    let explore = |out_flag: &str, out: &Path| {
        bin()
            .args(["explore", "-q", "--force", "--planner", "greedy", "--scene"])
            .arg(&yaml)
            .arg("--config")
            .arg(&config)
            .arg(out_flag)
            .arg(out)
            .output()
            .unwrap()
    };
    for (n, input) in inputs.iter().enumerate() {
        let sym = d.join(format!("sym{n}.png"));
        symlink(input, &sym).unwrap();
        let hard = d.join(format!("hard{n}.png"));
        std::fs::hard_link(input, &hard).unwrap();
        for flag in ["--log", "--trajectory", "--png"] {
            let mut spellings = vec![sym.clone(), hard.clone()];
            if flag != "--png" {
                spellings.push(input.to_path_buf());
                spellings.push(d.join(".").join(input.file_name().unwrap()));
            }
            for out in &spellings {
                let o = explore(flag, out);
                let err = stderr(&o);
                assert_eq!(o.status.code(), Some(2), "{flag} {}: {err}", out.display());
                assert_eq!(err.trim_end().lines().count(), 1, "{err}");
                assert!(
                    err.contains("name the same file") || err.contains("symbolic link"),
                    "{flag} {}: {err}",
                    out.display()
                );
            }
        }
    }
    // --map-out of the scene's folder would write map.pgm, the scene's image.
    let o = explore("--map-out", d);
    assert_fails(
        &o,
        2,
        "--map-out and a file the scene reads name the same file",
    );
    // A YAML reached through a link: --map-out of its folder would write its real file.
    let other = tempfile::tempdir().unwrap();
    let real = other.path().join("map.yaml");
    std::fs::write(
        &real,
        std::fs::read_to_string(&yaml)
            .unwrap()
            .replace("map.pgm", "img.pgm"),
    )
    .unwrap();
    std::fs::copy(&image, other.path().join("img.pgm")).unwrap();
    let alias = other.path().join("alias.yaml");
    symlink(&real, &alias).unwrap();
    let real_before = std::fs::read(&real).unwrap();
    let o = bin()
        .args(["explore", "-q", "--force", "--scene"])
        .arg(&alias)
        .arg("--map-out")
        .arg(other.path())
        .output()
        .unwrap();
    assert_fails(&o, 2, "--map-out and --scene name the same file");
    assert_eq!(std::fs::read(&real).unwrap(), real_before);
    for (p, b) in inputs.iter().zip(&before) {
        assert_eq!(&std::fs::read(p).unwrap(), b, "{} changed", p.display());
    }
    // A dangling link as an output is refused; its target is not created.
    let target = d.join("nowhere.mcap");
    let dangling = d.join("dangling.mcap");
    symlink(&target, &dangling).unwrap();
    let o = explore("--log", &dangling);
    assert_fails(&o, 2, "is a symbolic link");
    assert!(!target.exists());
}

/// A glTF buffer is read only from the folder of the `.gltf` (or below it), only from a regular
/// file, and never past the scene size limit; the refusal quotes nothing read from the file.
#[test]
fn gltf_buffers_stay_beside_the_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("scene");
    std::fs::create_dir(&d).unwrap();
    std::fs::write(dir.path().join("x.bin"), [0u8; 64]).unwrap();
    std::os::unix::fs::symlink(dir.path().join("x.bin"), d.join("link.bin")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.bin")).unwrap();
    let fifo = Command::new("mkfifo")
        .arg(d.join("fifo.bin"))
        .status()
        .unwrap();
    assert!(fifo.success());
    for (uri, needle) in [
        ("../x.bin", "lies outside the folder of the .gltf"),
        ("/etc/passwd", "lies outside the folder of the .gltf"),
        ("/dev/zero", "lies outside the folder of the .gltf"),
        ("%2E%2E/x.bin", "lies outside the folder of the .gltf"),
        ("link.bin", "lies outside the folder of the .gltf"),
        ("zero.bin", "lies outside the folder of the .gltf"),
        ("fifo.bin", "not a regular file"),
    ] {
        let doc = serde_json::json!({
            "asset": {"version": "2.0"},
            "buffers": [{"uri": uri, "byteLength": 64}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                "min": [0, 0, 0], "max": [1, 1, 1]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"mesh": 0}],
        });
        let path = d.join("s.gltf");
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        let o = bin().args(["scene", "info"]).arg(&path).output().unwrap();
        assert_fails(&o, 1, needle);
    }
}

/// A node graph whose nodes each list the next twice describes 2^40 instances in a few hundred
/// bytes: it is refused at the instance bound, not expanded.
#[test]
fn gltf_node_graph_expansion_is_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let bin_data: Vec<u8> = [[0f32, 0., 0.], [1., 0., 0.], [0., 0., 1.]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        tensorscout::util::base64_encode(&bin_data)
    );
    let mut nodes: Vec<serde_json::Value> = (0..40)
        .map(|i| serde_json::json!({"mesh": 0, "children": [i + 1, i + 1]}))
        .collect();
    nodes.push(serde_json::json!({"mesh": 0}));
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "buffers": [{"uri": uri, "byteLength": 36}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
            "min": [0, 0, 0], "max": [1, 0, 1]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": nodes,
    });
    let path = dir.path().join("shared.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let child = bin()
        .args(["scene", "info"])
        .arg(&path)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let o = wait_with_deadline(child, Duration::from_secs(60));
    assert_fails(&o, 1, "more than 100000 node instances");
}

/// A shard whose `results.jsonl` was cut mid-row merges without that row, and says so.
#[test]
fn bench_merge_of_a_cut_shard_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let row = failed_row;
    let a = dir.path().join("a");
    std::fs::create_dir(&a).unwrap();
    let whole = format!("{}{}", row(1), row(2));
    std::fs::write(a.join("results.jsonl"), &whole[..whole.len() - 20]).unwrap();
    let out = dir.path().join("out");
    let o = bin()
        .args(["bench", "merge"])
        .arg(&a)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("the last row was cut mid-line") && err.contains("a/results.jsonl"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("results.jsonl")).unwrap(),
        row(1)
    );
}

/// A scene without a spawn line whose roomiest floor cell is too tight for the robot (a 6 × 0.4 m
/// room) is refused, as an explicit spawn there is, instead of a run in collision.
#[test]
fn automatic_spawn_must_fit_the_robot() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(
        dir.path(),
        "narrow.obj",
        &common::walled_room_obj(6.2, 0.6, None),
    );
    let o = bin()
        .args(["explore", "-q", "--json", "--scene"])
        .arg(&scene)
        .args(["--set", "sim.budget_s=5"])
        .output()
        .unwrap();
    assert_fails(&o, 1, "the automatic spawn");
    assert!(
        stderr(&o).contains("the robot fits nowhere"),
        "{}",
        stderr(&o)
    );
    assert!(stdout(&o).is_empty());
}

/// Random starts do not use the file's spawn line: one inside a wall is warned about once, and the
/// starts are drawn over the largest room.
#[test]
fn random_start_ignores_a_bad_file_spawn() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(Some("0.05 2 0")));
    let o = bin()
        .args(["explore", "-q", "--json", "--spawn", "random", "--scene"])
        .arg(&scene)
        .args(["--set", "sim.budget_s=5"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let warnings = stderr(&o).matches("warning:").count();
    assert_eq!(warnings, 1, "{}", stderr(&o));
    assert!(stderr(&o).contains("tensorscout spawn"), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["collisions"], 0, "{r}");
    // A bench with several seeds: every run starts, none fails.
    let out = dir.path().join("b");
    let o = bin()
        .args([
            "bench",
            "-q",
            "--planners",
            "greedy",
            "--seeds",
            "2",
            "--scenes",
        ])
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .args(["--set", "sim.budget_s=5"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        stderr(&o).matches("tensorscout spawn").count(),
        1,
        "{}",
        stderr(&o)
    );
    let rows = std::fs::read_to_string(out.join("results.jsonl")).unwrap();
    assert_eq!(rows.lines().count(), 2);
    assert!(!rows.contains("\"failed\""), "{rows}");
}

/// `replay --verify` re-runs the config's seed, so a log whose seed metadata was edited is not
/// called identical: the mismatch is the verdict.
#[test]
fn verify_covers_the_seed_it_reports() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "room.obj", &common::room_obj(None));
    let path = dir.path().join("run.mcap");
    let o = explore_logged(&scene, &path, dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&path).unwrap();
    let mut log = tensorscout::log::reader::read_log_bytes(&bytes).unwrap();
    let id = log.identity.as_mut().expect("the fixture has an identity");
    id.seed = id.seed.wrapping_add(1);
    let e = tensorscout::log::replay::verify(&log, None).unwrap_err();
    assert!(e.to_string().contains("seed metadata"), "{e}");
}

/// Bytes that are not UTF-8 in an OBJ are named by line, not "read error".
#[test]
fn non_utf8_obj_names_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.obj");
    std::fs::write(&p, b"v 0 0 0\nv 1 0 0\nv 0 1 \xff\xfe\nf 1 2 3\n").unwrap();
    let o = run(&["scene", "info", p.to_str().unwrap()]);
    assert_fails(&o, 1, "line 3: not UTF-8 text (byte 22)");
}
