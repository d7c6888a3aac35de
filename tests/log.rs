//! Run logs end to end: write, replay, verify, damaged files, interruption, and an independent read
//! with the Python `mcap` package when it is installed.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_tensorscout"));
    c.env("TENSORSCOUT_CACHE_DIR", common::cache_dir());
    c
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Copies a shipped scene into `dir` (so a test can edit it) and returns its path.
fn scene_copy(dir: &Path, name: &str) -> PathBuf {
    let src = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    let dst = dir.join(name);
    std::fs::copy(src, &dst).unwrap();
    dst
}

/// Runs a short logged exploration; small chunks so that truncation tests see several.
fn explore_logged(scene: &Path, log: &Path, extra: &[&str]) -> Output {
    bin()
        .args(["explore", "--scene"])
        .arg(scene)
        .arg("--log")
        .arg(log)
        .args([
            "--json",
            "-q",
            "--set",
            "sim.budget_s=40",
            "--set",
            "log.chunk_size_kb=32",
        ])
        .args(extra)
        .output()
        .unwrap()
}

fn replay(log: &Path, extra: &[&str]) -> Output {
    bin().arg("replay").arg(log).args(extra).output().unwrap()
}

fn json(o: &Output) -> serde_json::Value {
    serde_json::from_str(&stdout(o)).unwrap_or_else(|e| panic!("{e}: {}", stdout(o)))
}

#[test]
fn log_replays_verifies_and_is_never_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_copy(dir.path(), "apartment_small.obj");
    let log = dir.path().join("run.mcap");
    // With the field topics on, so that they are verified and read by Python too.
    let run = explore_logged(&scene, &log, &["--set", "log.field=true"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let result = json(&run);

    let summary = replay(&log, &["--json"]);
    assert!(summary.status.success(), "{}", stderr(&summary));
    let s = json(&summary);
    let id = &s["identity"];
    assert_eq!(id["planner"], "thp", "explore defaults to THP");
    assert_eq!(id["seed"], 1);
    assert_eq!(id["scene_hash"], result["scene_hash"]);
    assert_eq!(id["config_hash"], result["config_hash"]);
    assert_eq!(s["result"]["completeness"], result["completeness"]);
    assert_eq!(s["complete"], true);
    assert_eq!(s["chunks_lost"], 0);
    // One pose per step and the start pose; one metrics message per step; the last milestone is
    // the end of the run.
    let steps = result["steps"].as_u64().unwrap();
    assert_eq!(s["messages"]["/robot/pose"], steps + 1);
    assert_eq!(s["messages"]["/metrics"], steps);
    assert_eq!(
        s["messages"]["/plan/path"],
        s["messages"]["/plan/frontiers"]
    );
    assert_eq!(s["messages"]["/plan/tour"], s["messages"]["/plan/path"]);
    let ms = s["milestones"].as_array().unwrap();
    assert_eq!(ms.len(), 4);
    assert_eq!(ms[3]["completeness"], result["completeness"]);
    assert_eq!(ms[3]["path_length_m"], result["path_length_m"]);

    // The re-run matches message for message, with one or two threads.
    for threads in ["1", "2"] {
        let v = bin()
            .arg("replay")
            .arg(&log)
            .arg("--verify")
            .env("RAYON_NUM_THREADS", threads)
            .output()
            .unwrap();
        assert!(v.status.success(), "{}", stderr(&v));
        assert_eq!(stdout(&v).lines().last(), Some("identical"));
    }

    // An existing log is not overwritten without --force.
    let again = explore_logged(&scene, &log, &[]);
    assert_eq!(again.status.code(), Some(1));
    assert!(
        stderr(&again).contains("pass --force"),
        "{}",
        stderr(&again)
    );
    let field = ["--set", "log.field=true"];
    assert!(
        explore_logged(&scene, &log, &["--force", field[0], field[1]])
            .status
            .success()
    );

    // An edited scene is caught by its content hash.
    let mut text = std::fs::read_to_string(&scene).unwrap();
    text.push_str("v 0 0 0\n");
    std::fs::write(&scene, text).unwrap();
    let v = replay(&log, &["--verify"]);
    assert_eq!(v.status.code(), Some(1));
    assert!(stderr(&v).contains("content hash"), "{}", stderr(&v));
    assert!(
        stderr(&v).contains("differs from the logged"),
        "{}",
        stderr(&v)
    );

    python_check(&log, &s["messages"]);

    // Pictures: one frame per 10 s of the run, the start included (the first key frame is the
    // first depth frame's, at t = 0), and an overview.
    let pics = dir.path().join("pics");
    let r = replay(&log, &["--render", pics.to_str().unwrap(), "--every", "10"]);
    assert!(r.status.success(), "{}", stderr(&r));
    let sim_time = result["sim_time_s"].as_f64().unwrap();
    let frames = std::fs::read_dir(&pics)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with("frame_")
        })
        .count();
    assert_eq!(frames, (sim_time / 10.0).floor() as usize + 1);
    assert!(pics.join("overview.png").is_file());
}

/// Decodes every message with the PyPI `mcap` reader and compares counts per topic (skipped, with
/// a note, when Python or the package is missing).
fn python_check(log: &Path, counts: &serde_json::Value) {
    if !python_has(&["mcap"]) {
        eprintln!("note: python3 with the `mcap` package not found; independent check skipped");
        return;
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/check_mcap.py");
    let o = Command::new("python3")
        .arg(script)
        .arg(log)
        .arg(counts.to_string())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
}

/// Whether python3 can import every module in `modules`; without them a check is skipped with a
/// note, unless `TENSORSCOUT_REQUIRE_PYTHON` is set (as `.ci/run` does), when that is a failure.
fn python_has(modules: &[&str]) -> bool {
    let ok = Command::new("python3")
        .args(["-c", &format!("import {}", modules.join(", "))])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok && std::env::var_os("TENSORSCOUT_REQUIRE_PYTHON").is_some() {
        panic!(
            "python3 with {modules:?} is required (TENSORSCOUT_REQUIRE_PYTHON is set): pip install {}",
            modules.join(" ")
        );
    }
    ok
}

/// The vendored official schema file of `foxglove.NAME`.
fn official_schema(name: &str) -> Vec<u8> {
    let file = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/foxglove-schemas")
        .join(format!("{}.json", name.trim_start_matches("foxglove.")));
    std::fs::read(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()))
}

/// A default-rate log of `planner` holds `/tf`, the field topics, the scene mesh and the robot; each
/// `foxglove.*` channel's schema is the official file byte for byte; and every message validates
/// against it (Python `jsonschema`, stopping at the first error).
fn check_official_schemas(planner: &str) {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_copy(dir.path(), "apartment_small.obj");
    let log = dir.path().join("run.mcap");
    let run = explore_logged(&scene, &log, &["--planner", planner]);
    assert!(run.status.success(), "{}", stderr(&run));

    let bytes = std::fs::read(&log).unwrap();
    let mut topics = std::collections::BTreeMap::new();
    let mut scene_msg = None;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m
            .channel
            .schema
            .as_ref()
            .expect("every channel has a schema");
        if schema.name.starts_with("foxglove.") {
            assert_eq!(schema.encoding, "jsonschema");
            assert!(
                schema.data.as_ref() == official_schema(&schema.name).as_slice(),
                "{}: the schema {} in the log is not the official file",
                m.channel.topic,
                schema.name
            );
        }
        if m.channel.topic == "/scene" {
            scene_msg = Some(serde_json::from_slice::<serde_json::Value>(&m.data).unwrap());
        }
        *topics.entry(m.channel.topic.clone()).or_insert(0u64) += 1;
    }
    for t in [
        "/tf",
        "/field/tensor",
        "/field/degenerate",
        "/field/topology",
    ] {
        assert!(
            topics.get(t).copied().unwrap_or(0) > 0,
            "{planner}: no {t} in {topics:?}"
        );
    }
    assert_eq!(topics["/scene"], 1);
    assert_eq!(topics["/tf"], topics["/robot/pose"]);
    assert_eq!(topics["/camera/calibration"], topics["/camera/depth"]);
    let entity = &scene_msg.unwrap()["entities"][0];
    assert_eq!(entity["id"], "scene_mesh");
    let tri = &entity["triangles"][0];
    assert!(tri["indices"].as_array().unwrap().len() >= 3);
    assert_eq!(tri["indices"].as_array().unwrap().len() % 3, 0);

    if !python_has(&["mcap", "jsonschema"]) {
        eprintln!(
            "note: SKIPPED the jsonschema validation of the {planner} log: python3 with the \
             `mcap` and `jsonschema` packages not found (pip install mcap jsonschema)"
        );
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let o = Command::new("python3")
        .arg(root.join("tests/python/check_schemas.py"))
        .arg(&log)
        .arg(root.join("assets/foxglove-schemas"))
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{planner}: {}{}",
        stdout(&o),
        stderr(&o)
    );
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn thp_log_has_official_schemas_and_every_message_validates() {
    check_official_schemas("thp");
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn tensor_log_has_official_schemas_and_every_message_validates() {
    check_official_schemas("tensor");
}

#[test]
fn truncated_log_replays_complete_chunks_and_reports_the_loss() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_copy(dir.path(), "apartment_small.obj");
    let log = dir.path().join("run.mcap");
    assert!(explore_logged(&scene, &log, &[]).status.success());
    let bytes = std::fs::read(&log).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();

    let full = json(&replay(&log, &["--json"]));
    let o = replay(&cut, &["--json"]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(err.contains("damaged log"), "{err}");
    assert!(err.contains("chunks lost"), "{err}");
    let s = json(&o);
    assert_eq!(s["complete"], false);
    assert!(s["chunks_read"].as_u64().unwrap() >= 2, "{s}");
    assert!(s["chunks_lost"].as_u64().unwrap() >= 1, "{s}");
    let poses = s["messages"]["/robot/pose"].as_u64().unwrap();
    assert!(poses > 0 && poses < full["messages"]["/robot/pose"].as_u64().unwrap());
    assert!(s["result"].is_null());

    // Garbage is not a log at all.
    let junk = dir.path().join("junk.mcap");
    std::fs::write(&junk, b"not an mcap file").unwrap();
    let o = replay(&junk, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("not an MCAP file"), "{}", stderr(&o));
}

#[test]
fn interrupted_log_verifies_up_to_its_end() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_copy(dir.path(), "office_large.obj");
    let log = dir.path().join("run.mcap");
    let child = bin()
        .args(["explore", "--scene"])
        .arg(&scene)
        .arg("--log")
        .arg(&log)
        .args(["--json", "-q", "--set", "sim.budget_s=100000"])
        .args(["--set", "sim.stuck_timeout_s=100000"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The log file exists once the signal handlers are installed.
    while !log.exists() {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    std::thread::sleep(std::time::Duration::from_millis(300));
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    // Exit 130 after SIGINT, with the result printed and the log finished.
    assert_eq!(out.status.code(), Some(130), "{}", stderr(&out));
    let result = json(&out);
    assert_eq!(result["termination"], "interrupted");
    let s = replay(&log, &["--json"]);
    assert!(s.status.success(), "{}", stderr(&s));
    let s = json(&s);
    assert_eq!(s["complete"], true);
    assert_eq!(s["result"]["termination"], "interrupted");
    // A pose for the start and one per step; none when the signal landed before the first step
    // (a loaded machine can take longer than the sleep above to get there).
    let steps = result["steps"].as_u64().unwrap();
    let poses = s["messages"]["/robot/pose"].as_u64().unwrap_or(0);
    assert_eq!(poses, if steps == 0 { 0 } else { steps + 1 });
    // The re-run stops where the interrupted run stopped, and says so.
    let v = replay(&log, &["--verify"]);
    assert!(v.status.success(), "{}", stderr(&v));
    let line = stdout(&v).lines().last().unwrap_or_default().to_string();
    let t: f64 = line
        .strip_prefix("identical up to t = ")
        .and_then(|r| r.strip_suffix(" s (the run was interrupted there)"))
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert_eq!(t, result["sim_time_s"].as_f64().unwrap());
}

#[test]
fn bad_log_config_is_a_usage_error() {
    let o = bin()
        .args([
            "explore",
            "--scene",
            "nowhere.obj",
            "--set",
            "log.zstd_level=0",
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("config key `log.zstd_level` must lie in 1..=19, got 0"),
        "{}",
        stderr(&o)
    );
}

/// How logged depth frames compare with frames re-rendered at a logged pose.
#[derive(Debug, Default)]
struct Agreement {
    frames: usize,
    pixels: usize,
    /// Pixels off by more than 1 mm next to a depth jump (an object's outline).
    silhouette_off: usize,
    /// Pixels off by more than 1 mm anywhere else.
    off: usize,
}

/// Whether pixel `i` of a `w`-wide depth image borders a jump of more than 10 cm (or a pixel with
/// or without a return where it has the other): where the outline of an object falls.
fn on_silhouette(depth: &[f32], w: usize, i: usize) -> bool {
    let (x, y, h) = ((i % w) as i64, (i / w) as i64, (depth.len() / w) as i64);
    let d = depth[i];
    (-1..=1).any(|dy| {
        (-1..=1).any(|dx| {
            let (nx, ny) = (x + dx, y + dy);
            (0..w as i64).contains(&nx) && (0..h).contains(&ny) && {
                let n = depth[(ny * w as i64 + nx) as usize];
                (n == 0.0) != (d == 0.0) || (n - d).abs() > 0.1
            }
        })
    })
}

/// Re-renders every `/camera/depth` frame of `log` with the library's renderer (the one the run's
/// config names) at the `/tf` pose stamped `lag_steps` steps before the frame (0: the same stamp),
/// and counts the pixels that differ by more than 1 mm. Also checks that every message's own
/// stamps equal its log time.
fn rerender_depth(log: &Path, lag_steps: u64) -> Agreement {
    use tensorscout::config::DepthRenderer;
    use tensorscout::sensor::{DepthCamera, DepthFrame, MeshBvh, MeshRaster};
    let contents = tensorscout::log::read_log(log).unwrap();
    let id = contents.identity.as_ref().unwrap();
    let cfg: tensorscout::Config = toml::from_str(&id.config_toml).unwrap();
    let scene = tensorscout::scene::load(Path::new(&id.scene_path), &cfg.scene).unwrap();
    let dt_ns = (cfg.sim.dt_s * 1e9).round() as u64;

    // Every `timestamp` in a message (headers, transforms, entities) is its log time.
    fn stamps(v: &serde_json::Value, out: &mut Vec<u64>) {
        match v {
            serde_json::Value::Object(m) => {
                if let Some(t) = m.get("timestamp") {
                    out.push(
                        t["sec"].as_u64().unwrap() * 1_000_000_000 + t["nsec"].as_u64().unwrap(),
                    );
                }
                m.values().for_each(|c| stamps(c, out));
            }
            serde_json::Value::Array(a) => a.iter().for_each(|c| stamps(c, out)),
            _ => {}
        }
    }
    let mut poses = std::collections::BTreeMap::new();
    for m in &contents.messages {
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        let mut found = Vec::new();
        stamps(&v, &mut found);
        assert!(
            found.iter().all(|&t| t == m.log_time_ns),
            "{} at {} ns carries stamps {found:?}",
            m.topic,
            m.log_time_ns
        );
        if m.topic == "/tf" {
            let tfs = v["transforms"].as_array().unwrap();
            let base = tfs
                .iter()
                .find(|t| t["child_frame_id"] == "base_link")
                .unwrap();
            let cam = tfs
                .iter()
                .find(|t| t["child_frame_id"] == "camera")
                .unwrap();
            assert_eq!(cam["parent_frame_id"], "base_link");
            assert_eq!(
                cam["translation"]["z"].as_f64().unwrap(),
                cfg.camera.mount_height_m.get()
            );
            let (t, q) = (&base["translation"], &base["rotation"]);
            let f = |v: &serde_json::Value| v.as_f64().unwrap();
            assert_eq!((f(&t["z"]), f(&q["x"]), f(&q["y"])), (0.0, 0.0, 0.0));
            let yaw = 2.0 * f(&q["z"]).atan2(f(&q["w"]));
            poses.insert(
                m.log_time_ns,
                tensorscout::Pose2::new(f(&t["x"]), f(&t["y"]), yaw),
            );
        }
    }

    // Each map key frame has the pose it was integrated at (what `replay --render` draws with it).
    for m in contents.topic("/map/grid") {
        assert!(
            poses.contains_key(&m.log_time_ns),
            "no /tf at the grid of {} ns",
            m.log_time_ns
        );
    }

    let camera = DepthCamera::new(&cfg.camera);
    let raster = MeshRaster::new(&scene.mesh).unwrap();
    let bvh = MeshBvh::new(&scene.mesh).unwrap();
    let mut frame = DepthFrame::default();
    let mut a = Agreement::default();
    for m in contents.topic("/camera/depth") {
        let Some(at) = m.log_time_ns.checked_sub(lag_steps * dt_ns) else {
            continue;
        };
        let pose = *poses.get(&at).unwrap_or_else(|| {
            panic!(
                "no /tf stamped {at} ns for the frame at {} ns",
                m.log_time_ns
            )
        });
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        let bytes = tensorscout::util::base64_decode(v["data"].as_str().unwrap()).unwrap();
        assert_eq!(v["encoding"], "16UC1");
        let logged: Vec<f32> = bytes
            .chunks_exact(2)
            .map(|c| f32::from(u16::from_le_bytes([c[0], c[1]])) / 1000.0)
            .collect();
        match cfg.camera.renderer {
            DepthRenderer::Raster => camera.render_into(&raster, pose, &mut frame),
            DepthRenderer::Raycast => camera.capture_into(&bvh, pose, &mut frame),
        }
        let again = frame.depth_image();
        assert_eq!(logged.len(), again.len());
        for (i, (l, r)) in logged.iter().zip(&again).enumerate() {
            if (l - r).abs() > 1e-3 {
                if on_silhouette(&logged, frame.width, i) || on_silhouette(&again, frame.width, i) {
                    a.silhouette_off += 1;
                } else {
                    a.off += 1;
                }
            }
        }
        a.frames += 1;
        a.pixels += logged.len();
    }
    a
}

/// A logged run with every depth frame on `/camera/depth`.
fn explore_every_frame(scene: &Path, log: &Path, extra: &[&str]) {
    let run = bin()
        .args(["explore", "--scene"])
        .arg(scene)
        .arg("--log")
        .arg(log)
        .args(["--json", "-q", "--set", "log.depth_every_n=1"])
        .args(extra)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", stderr(&run));
}

/// Each depth frame shows what the camera sees from the `/tf` pose of its own stamp: re-rendered
/// there, every pixel off a silhouette agrees within 1 mm. Paired with the pose one step earlier
/// (the stamping this guards against) a moving robot's frames disagree, so the check has teeth.
#[test]
fn depth_frames_match_the_pose_of_their_stamp() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_copy(dir.path(), "apartment_small.obj");
    let log = dir.path().join("run.mcap");
    explore_every_frame(&scene, &log, &["--set", "sim.budget_s=20"]);
    let same = rerender_depth(&log, 0);
    eprintln!("same stamp: {same:?}");
    assert_eq!(same.frames, 200, "{same:?}");
    assert_eq!(same.off, 0, "{same:?}");
    assert!(same.silhouette_off * 10_000 <= same.pixels, "{same:?}");
    let earlier = rerender_depth(&log, 1);
    eprintln!("one step earlier: {earlier:?}");
    assert!(earlier.off * 20 > earlier.pixels, "{earlier:?}");
}

/// The same on every frame of a whole GREEDY run of the largest shipped scene.
#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn depth_frames_match_the_pose_of_their_stamp_on_office_large() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_copy(dir.path(), "office_large.obj");
    let log = dir.path().join("run.mcap");
    explore_every_frame(
        &scene,
        &log,
        &["--planner", "greedy", "--set", "log.field=false"],
    );
    let a = rerender_depth(&log, 0);
    eprintln!("{a:?}");
    assert!(a.frames > 1000, "{a:?}");
    assert_eq!(a.off, 0, "{a:?}");
    assert!(a.silhouette_off * 10_000 <= a.pixels, "{a:?}");
}
