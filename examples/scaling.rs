//! Measures how a run's cost grows with the building's size: for generated offices of growing floor
//! area, the time and peak memory of generating the scene, of computing its observable set (empty
//! cache) and of a THP and a GREEDY run, with the run's stage timings (sense, map, field, plan, TSP).
//! It writes `scaling.json` (every figure), `scaling.md` (the tables of BENCHMARKS.md, "Scaling with
//! scene area") and `scaling.png` (ms a step, total and per stage, against area, log-log).
//!
//! ```text
//! cargo build --release
//! cargo run --release --example scaling -- [OUT_DIR] [--areas 100,400,...] [--threads T] [--budget S]
//! ```
//!
//! Every child runs under GNU time (`/usr/bin/time -f %M`) for its peak RSS. A step that fails or
//! times out is recorded with its error and the script goes on. Wall times drift on a shared VM from
//! hour to hour: compare ratios within one run of this script, not figures across runs.

use plotters::prelude::*;
use serde_json::{json, Value};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use tensorscout::bench::SERIES_COLOURS;

const PLANNERS: [&str; 2] = ["thp", "greedy"];

/// How a run's cost grows with the building's size.
///
/// For each area A it generates an office (`scene generate --style office --seed 1 --area A`),
/// computes its observable set with an empty cache (`scene info`), and runs THP and GREEDY on it
/// (`explore --set sim.budget_s=S --json --quiet`, RAYON_NUM_THREADS=T), each child under GNU time
/// for its wall time and peak RSS. It writes OUT_DIR/scaling.json, scaling.md and scaling.png (ms a
/// step, total and per stage, against area, log-log); the scenes and their cache go in
/// OUT_DIR/scenes.
///
/// The default areas took 9 minutes on an idle 2-vCPU VM (2026-12): the 40,000 m² office's
/// observable set (about 200 s) and THP run (about 125 s) are most of it; its children peaked at
/// 1.5 GB. Failed steps (a timeout; an area the generator refuses) are recorded in the outputs and
/// listed on stderr; they do not stop the script.
#[derive(clap::Parser)]
#[command(name = "scaling")]
struct Options {
    /// Output folder.
    #[arg(default_value = "results/scaling")]
    out: PathBuf,
    /// Floor areas, m², comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [100u32, 400, 1600, 6400, 10000, 40000],
          value_parser = clap::value_parser!(u32).range(1..))]
    areas: Vec<u32>,
    /// The tensorscout binary [default: this checkout's target/release/tensorscout].
    #[arg(long, value_name = "PATH")]
    bin: Option<PathBuf>,
    /// RAYON_NUM_THREADS of the explore runs.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    threads: u32,
    /// Simulated seconds a run (sim.budget_s).
    #[arg(long, default_value_t = 600.0, value_parser = positive)]
    budget: f64,
    /// Wall seconds after which a child is killed and its step failed.
    #[arg(long, default_value_t = 900.0, value_parser = positive)]
    timeout: f64,
}

fn positive(v: &str) -> Result<f64, String> {
    match v.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("`{v}` is not a positive number")),
    }
}

/// What one child process did: its wall time, peak RSS (KiB, from GNU time) and output.
struct Child {
    wall_s: f64,
    peak_kib: Option<u64>,
    stdout: String,
    /// The child's own stderr, GNU time's line removed.
    stderr: String,
    ok: bool,
    /// Why it failed: the exit status or the timeout, and the child's last stderr line.
    error: Option<String>,
}

/// Runs `bin args` under `/usr/bin/time -f %M` with `envs`, killing it after `timeout` seconds.
fn run_child(bin: &Path, args: &[String], envs: &[(&str, String)], timeout: f64) -> Child {
    let start = Instant::now();
    let mut cmd = Command::new("/usr/bin/time");
    cmd.arg("-f")
        .arg("%M")
        .arg(bin)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    for (k, v) in envs {
        cmd.env(k, v);
    }
    let mut child = match cmd.spawn() {
        Ok(c) => c,
        Err(e) => {
            return Child {
                wall_s: 0.0,
                peak_kib: None,
                stdout: String::new(),
                stderr: String::new(),
                ok: false,
                error: Some(format!("could not start /usr/bin/time: {e}")),
            }
        }
    };
    // Both pipes are drained on threads, so that a chatty child cannot block on a full pipe.
    let drain = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut s = String::new();
            let _ = r.read_to_string(&mut s);
            s
        })
    };
    let out = drain(Box::new(child.stdout.take().expect("piped stdout")));
    let err = drain(Box::new(child.stderr.take().expect("piped stderr")));
    let mut timed_out = false;
    let status = loop {
        match child.try_wait() {
            Ok(Some(s)) => break Some(s),
            Ok(None) if start.elapsed().as_secs_f64() > timeout && !timed_out => {
                timed_out = true;
                // GNU time waits for its child: kill the child (tensorscout) and time reports.
                let pid = child.id();
                let kids = std::fs::read_to_string(format!("/proc/{pid}/task/{pid}/children"))
                    .unwrap_or_default();
                for k in kids.split_whitespace() {
                    let _ = Command::new("kill").args(["-KILL", k]).status();
                }
                if kids.trim().is_empty() {
                    let _ = child.kill();
                }
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(50)),
            Err(_) => break None,
        }
    };
    let wall_s = start.elapsed().as_secs_f64();
    let stdout = out.join().unwrap_or_default();
    let mut stderr = err.join().unwrap_or_default();
    // GNU time's `%M` is the last line of stderr.
    let mut peak_kib = None;
    let trimmed = stderr.trim_end().to_string();
    if let Some((head, last)) = trimmed.rsplit_once('\n').or(Some(("", trimmed.as_str()))) {
        if let Ok(k) = last.trim().parse::<u64>() {
            peak_kib = Some(k);
            stderr = head.to_string();
        }
    }
    let ok = !timed_out && status.is_some_and(|s| s.success());
    let error = (!ok).then(|| {
        let last = stderr
            .lines()
            .rev()
            .map(str::trim)
            .find(|l| !l.is_empty() && !l.starts_with("Command "))
            .unwrap_or("");
        let why = if timed_out {
            format!("killed after the {timeout:.0} s timeout")
        } else {
            match status.and_then(|s| s.code()) {
                Some(c) => format!("exit status {c}"),
                None => "killed by a signal".to_string(),
            }
        };
        if last.is_empty() {
            why
        } else {
            format!("{why}: {last}")
        }
    });
    Child {
        wall_s,
        peak_kib,
        stdout,
        stderr,
        ok,
        error,
    }
}

/// Prints `label ...` to stderr, runs the child, and ends the line with how it went.
fn step(label: &str, bin: &Path, args: &[String], envs: &[(&str, String)], timeout: f64) -> Child {
    eprint!("{label} ... ");
    let c = run_child(bin, args, envs, timeout);
    match &c.error {
        None => eprintln!("done in {:.1} s", c.wall_s),
        Some(e) => eprintln!("FAILED after {:.1} s: {e}", c.wall_s),
    }
    c
}

/// The mean of stage `name` in a run's `timings_ms`, if the run has it.
fn stage(timings: &Value, name: &str) -> Option<f64> {
    timings.get(name)?.get("mean")?.as_f64()
}

/// Does `planner` keep a tensor field (the others' field stage is the empty check, about 0 ms)?
fn has_field(planner: &str) -> bool {
    matches!(planner, "thp" | "tensor")
}

/// One explore run's record from its JSON result.
fn run_record(area: u32, planner: &str, c: &Child) -> Value {
    let mut rec = json!({
        "area_m2": area,
        "planner": planner.to_uppercase(),
        "ok": c.ok,
        "error": c.error,
        "process_wall_s": c.wall_s,
        "peak_rss_kib": c.peak_kib,
    });
    if !c.ok {
        return rec;
    }
    let r: Value = match serde_json::from_str(&c.stdout) {
        Ok(v) => v,
        Err(e) => {
            rec["ok"] = json!(false);
            rec["error"] = json!(format!("the run's JSON did not parse: {e}"));
            return rec;
        }
    };
    let steps = r["steps"].as_f64().unwrap_or(f64::NAN);
    let wall = r["wall_time_s"].as_f64().unwrap_or(f64::NAN);
    let t = &r["timings_ms"];
    let m = rec.as_object_mut().expect("an object");
    m.insert("steps".into(), r["steps"].clone());
    m.insert("termination".into(), r["termination"].clone());
    m.insert("completeness".into(), r["completeness"].clone());
    m.insert("real_time_factor".into(), r["real_time_factor"].clone());
    m.insert("sim_time_s".into(), r["sim_time_s"].clone());
    m.insert("run_wall_s".into(), r["wall_time_s"].clone());
    m.insert("ms_per_step".into(), json!(wall * 1000.0 / steps));
    m.insert("explored_volume_m3".into(), r["explored_volume_m3"].clone());
    for s in ["sense", "map", "field", "plan", "tsp"] {
        m.insert(format!("{s}_ms_mean"), json!(stage(t, s)));
    }
    m.insert(
        "tsp_solves".into(),
        r["planner_stats"]
            .get("tsp_solves")
            .cloned()
            .unwrap_or(Value::Null),
    );
    m.insert("timings_ms".into(), t.clone());
    rec
}

/// A scene step's record (generate or observable).
fn step_record(c: &Child) -> Value {
    json!({
        "ok": c.ok,
        "error": c.error,
        "wall_s": c.wall_s,
        "peak_rss_kib": c.peak_kib,
    })
}

fn skipped(why: &str) -> Value {
    json!({ "ok": false, "error": format!("skipped: {why}") })
}

/// Whether a record is one of [`skipped`]'s.
fn is_skipped(rec: &Value) -> bool {
    rec["error"]
        .as_str()
        .is_some_and(|e| e.starts_with("skipped"))
}

/// `1600` as `1,600`.
fn thousands(n: u32) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, ch) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(ch);
    }
    out
}

/// An axis label short enough for neighbouring areas (6,400 and 10,000) not to overlap: `6.4k`.
fn short_area(a: f64) -> String {
    if a >= 1000.0 {
        format!("{}k", (a / 100.0).round() / 10.0)
    } else {
        format!("{a:.0}")
    }
}

/// UTC date and time of `t` as `YYYY-MM-DD HH:MM UTC` (days to civil date: H. Hinnant's algorithm).
fn utc(t: std::time::SystemTime) -> String {
    let secs = t
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0);
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02} UTC",
        rem / 3600,
        rem % 3600 / 60
    )
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "?".into())
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "?".into())
}

/// The checkout's commit, with `+dirty` when the work tree has changes.
fn git_commit() -> String {
    let git = |args: &[&str]| {
        Command::new("git")
            .args(args)
            .stderr(Stdio::null())
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    match git(&["rev-parse", "--short", "HEAD"]) {
        Some(c) => match git(&["status", "--porcelain", "--untracked-files=no"]) {
            Some(s) if !s.is_empty() => format!("{c}+dirty"),
            _ => c,
        },
        None => "?".into(),
    }
}

fn mib(v: &Value) -> String {
    v.as_f64()
        .map(|k| format!("{:.0}", k / 1024.0))
        .unwrap_or_else(|| "–".into())
}

fn num(v: &Value, digits: usize) -> String {
    v.as_f64()
        .map(|x| format!("{x:.digits$}"))
        .unwrap_or_else(|| "–".into())
}

/// Every failed or skipped step, one line each, in the order they ran.
fn failures(doc: &Value) -> Vec<String> {
    let mut out = Vec::new();
    let runs = doc["runs"].as_array().cloned().unwrap_or_default();
    for sc in doc["scenes"].as_array().cloned().unwrap_or_default() {
        let area = &sc["area_m2"];
        for (what, v) in [
            ("generate", &sc["generate"]),
            ("observable set", &sc["observable"]),
        ] {
            if v["ok"] != json!(true) {
                let e = v["error"].as_str().unwrap_or("?");
                out.push(format!("office_{area}, {what}: {e}"));
            }
        }
        for r in runs
            .iter()
            .filter(|r| &r["area_m2"] == area && r["ok"] != json!(true))
        {
            let e = r["error"].as_str().unwrap_or("?");
            out.push(format!(
                "office_{area}, {} run: {e}",
                r["planner"].as_str().unwrap_or("?")
            ));
        }
    }
    out
}

fn markdown(doc: &Value) -> String {
    let meta = &doc["meta"];
    let mut s = String::new();
    s.push_str("# Scaling with scene area\n\n");
    s.push_str(&format!(
        "Generated offices (seed 1), build `{}`, {} to {}, {} ({} CPUs), load average (1, 5, 15 min) \
         {} at the start and {} at the end; runs with RAYON_NUM_THREADS={}, sim.budget_s={}; \
         observable sets computed with an empty cache, on all cores.\n\n",
        meta["commit"].as_str().unwrap_or("?"),
        meta["started"].as_str().unwrap_or("?"),
        meta["finished"].as_str().unwrap_or("?"),
        meta["cpu"].as_str().unwrap_or("?"),
        meta["cpus"],
        meta["load_start"].as_str().unwrap_or("?"),
        meta["load_end"].as_str().unwrap_or("?"),
        meta["threads"],
        meta["budget_s"],
    ));
    s.push_str(&format!(
        "```sh\n{}\n```\n\n",
        meta["command"].as_str().unwrap_or("")
    ));
    s.push_str("| area m² | planner | steps | ms a step | real time | sense / map / field / plan ms | TSP ms a solve | peak RSS MB | completeness |\n");
    s.push_str("|---:|---|---:|---:|---:|---|---:|---:|---:|\n");
    let runs = doc["runs"].as_array().cloned().unwrap_or_default();
    for p in PLANNERS {
        for r in runs
            .iter()
            .filter(|r| r["planner"].as_str() == Some(&p.to_uppercase()))
        {
            let area = thousands(r["area_m2"].as_u64().unwrap_or(0) as u32);
            let name = r["planner"].as_str().unwrap_or("?");
            if r["ok"] != json!(true) {
                let what = if is_skipped(r) { "skipped" } else { "failed" };
                s.push_str(&format!(
                    "| {area} | {name} | {what} | | | | | {} | |\n",
                    mib(&r["peak_rss_kib"])
                ));
                continue;
            }
            let field = if has_field(p) {
                num(&r["field_ms_mean"], 2)
            } else {
                "–".into()
            };
            s.push_str(&format!(
                "| {area} | {name} | {} | {} | {}× | {} / {} / {field} / {} | {} | {} | {} |\n",
                r["steps"],
                num(&r["ms_per_step"], 2),
                num(&r["real_time_factor"], 0),
                num(&r["sense_ms_mean"], 2),
                num(&r["map_ms_mean"], 2),
                num(&r["plan_ms_mean"], 2),
                num(&r["tsp_ms_mean"], 1),
                mib(&r["peak_rss_kib"]),
                num(&r["completeness"], 3),
            ));
        }
    }
    s.push_str("\n| area m² | generate s | generate peak RSS MB | observable set s | observable set peak RSS MB | camera positions |\n");
    s.push_str("|---:|---:|---:|---:|---:|---:|\n");
    for sc in doc["scenes"].as_array().cloned().unwrap_or_default() {
        let area = sc["area_m2"].as_u64().unwrap_or(0) as u32;
        let cell = |v: &Value| -> (String, String) {
            if v["ok"] == json!(true) {
                (num(&v["wall_s"], 1), mib(&v["peak_rss_kib"]))
            } else if is_skipped(v) {
                ("skipped".into(), "–".into())
            } else {
                ("failed".into(), mib(&v["peak_rss_kib"]))
            }
        };
        let (gs, gm) = cell(&sc["generate"]);
        let (os, om) = cell(&sc["observable"]);
        s.push_str(&format!(
            "| {} | {gs} | {gm} | {os} | {om} | {} |\n",
            thousands(area),
            num(&sc["observable"]["positions"], 0),
        ));
    }
    s.push_str(
        "\nms a step: the run's wall time (loading excluded) over its steps; stage figures are means \
         a step, TSP a solve. GREEDY keeps no field (–). MB = 2^20 bytes (GNU time's peak RSS in \
         KiB / 1024). Wall times drift on a shared VM: read ratios within one run of the script.\n",
    );
    let failures = failures(doc);
    if !failures.is_empty() {
        s.push_str("\nFailed or skipped:\n\n");
        for f in &failures {
            s.push_str(&format!("- {f}\n"));
        }
    }
    s
}

/// A stage's name and its (area, ms) points.
type Line<'a> = (&'a str, Vec<(f64, f64)>);

/// Two panels, THP and GREEDY, on the same log-log axes: ms a step against area, the total (black)
/// and each stage's mean a step.
fn draw(out: &Path, doc: &Value) -> Result<(), Box<dyn std::error::Error>> {
    let runs = doc["runs"].as_array().cloned().unwrap_or_default();
    let series = |p: &str, key: &str| -> Vec<(f64, f64)> {
        runs.iter()
            .filter(|r| r["ok"] == json!(true) && r["planner"].as_str() == Some(&p.to_uppercase()))
            .filter_map(|r| Some((r["area_m2"].as_f64()?, r[key].as_f64()?)))
            .filter(|&(_, v)| v > 0.0)
            .collect()
    };
    let stages: [(&str, &str); 5] = [
        ("total", "ms_per_step"),
        ("sense", "sense_ms_mean"),
        ("map", "map_ms_mean"),
        ("field", "field_ms_mean"),
        ("plan", "plan_ms_mean"),
    ];
    let lines: Vec<(&str, Vec<Line>)> = PLANNERS
        .iter()
        .map(|&p| {
            let ls = stages
                .iter()
                .filter(|(s, _)| *s != "field" || has_field(p))
                .map(|&(s, k)| (s, series(p, k)))
                .collect();
            (p, ls)
        })
        .collect();
    let all: Vec<(f64, f64)> = lines
        .iter()
        .flat_map(|(_, ls)| ls.iter().flat_map(|(_, v)| v.iter().copied()))
        .collect();
    if all.is_empty() {
        return Err("no successful run to plot".into());
    }
    let mut areas: Vec<f64> = all.iter().map(|p| p.0).collect();
    areas.sort_by(f64::total_cmp);
    areas.dedup();
    let (x0, x1) = (areas[0] / 1.5, areas[areas.len() - 1] * 1.5);
    // Whole decades (a hair wider, so that both end decades keep their labels).
    let decade = |v: f64, up: bool| {
        let e = v.log10();
        10f64.powf(if up { e.ceil() } else { e.floor() })
    };
    let y0 = decade(all.iter().map(|p| p.1).fold(f64::MAX, f64::min), false) / 1.001;
    let y1 = decade(all.iter().map(|p| p.1).fold(0.0, f64::max), true) * 1.001;

    tensorscout::render::register_font();
    let (w, h) = (1400u32, 620u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let panels = root.split_evenly((1, 2));
        for (panel, (p, ls)) in panels.iter().zip(&lines) {
            let mut chart = ChartBuilder::on(panel)
                .caption(
                    format!("{}: ms a step against area", p.to_uppercase()),
                    ("sans-serif", 26),
                )
                .margin(16)
                .x_label_area_size(50)
                .y_label_area_size(70)
                .build_cartesian_2d(
                    (x0..x1).log_scale().with_key_points(areas.clone()),
                    (y0..y1).log_scale(),
                )?;
            chart
                .configure_mesh()
                .x_label_formatter(&|x| short_area(*x))
                .y_label_formatter(&|y| {
                    if *y >= 1.0 {
                        format!("{y:.0}")
                    } else {
                        format!("{y:.3}")
                            .trim_end_matches('0')
                            .trim_end_matches('.')
                            .to_string()
                    }
                })
                .x_desc("floor area, m² (log)")
                .y_desc("ms a step (log)")
                .label_style(("sans-serif", 18))
                .axis_desc_style(("sans-serif", 20))
                .draw()?;
            for (s, pts) in ls {
                if pts.is_empty() {
                    continue;
                }
                // A stage keeps its colour in both panels.
                let i = stages.iter().position(|(n, _)| n == s).unwrap_or(0);
                let colour = match i {
                    0 => BLACK,
                    i => SERIES_COLOURS[(i - 1) % SERIES_COLOURS.len()],
                };
                let width = if *s == "total" { 4 } else { 2 };
                chart
                    .draw_series(LineSeries::new(
                        pts.iter().copied(),
                        colour.stroke_width(width),
                    ))?
                    .label(*s)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(width))
                    });
                chart.draw_series(
                    pts.iter()
                        .map(|&(x, y)| Circle::new((x, y), 4, colour.filled())),
                )?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .label_font(("sans-serif", 18))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()?;
        }
        root.present()?;
    }
    image::RgbImage::from_raw(w, h, buf)
        .ok_or("bad image buffer")?
        .save(out)?;
    Ok(())
}

/// Writes the JSON, the Markdown and the PNG (after every area, so that an interrupted run keeps
/// what it measured). Answers why the PNG could not be drawn, if it could not.
fn write_outputs(out: &Path, doc: &Value) -> Option<String> {
    let json_path = out.join("scaling.json");
    let text = serde_json::to_string_pretty(doc).expect("JSON");
    if let Err(e) = std::fs::write(&json_path, text + "\n") {
        eprintln!("scaling: {}: {e}", json_path.display());
        std::process::exit(1);
    }
    let md_path = out.join("scaling.md");
    if let Err(e) = std::fs::write(&md_path, markdown(doc)) {
        eprintln!("scaling: {}: {e}", md_path.display());
        std::process::exit(1);
    }
    let png_path = out.join("scaling.png");
    match draw(&png_path, doc) {
        Ok(()) => None,
        Err(e) => {
            // No stale picture from an earlier run beside these tables.
            let _ = std::fs::remove_file(&png_path);
            Some(format!("{}: {e}", png_path.display()))
        }
    }
}

fn main() {
    let o = <Options as clap::Parser>::parse();
    let bin = o.bin.clone().unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("target/release/tensorscout")
    });
    if !bin.is_file() {
        eprintln!(
            "scaling: {} does not exist: run `cargo build --release` first (or pass --bin PATH)",
            bin.display()
        );
        std::process::exit(1);
    }
    let gnu_time_ok = Command::new("/usr/bin/time")
        .args(["-f", "%M", "true"])
        .stdout(Stdio::null())
        .output()
        .is_ok_and(|r| {
            r.status.success()
                && String::from_utf8_lossy(&r.stderr)
                    .trim()
                    .parse::<u64>()
                    .is_ok()
        });
    if !gnu_time_ok {
        eprintln!("scaling: GNU time (/usr/bin/time with -f) is needed for the peak RSS: install it (apt-get install time)");
        std::process::exit(1);
    }
    let scenes = o.out.join("scenes");
    if let Err(e) = std::fs::create_dir_all(&scenes) {
        eprintln!("scaling: {}: {e}", scenes.display());
        std::process::exit(1);
    }
    let bin = std::fs::canonicalize(&bin).unwrap_or(bin);
    let areas: Vec<String> = o.areas.iter().map(u32::to_string).collect();
    let mut doc = json!({
        "meta": {
            "command": format!(
                "cargo run --release --example scaling -- {} --areas {} --threads {} --budget {} --timeout {}",
                o.out.display(), areas.join(","), o.threads, o.budget, o.timeout
            ),
            "bin": bin.display().to_string(),
            "commit": git_commit(),
            "started": utc(std::time::SystemTime::now()),
            "finished": Value::Null,
            "cpu": cpu_model(),
            "cpus": std::thread::available_parallelism().map(|n| n.get()).unwrap_or(0),
            "load_start": load_average(),
            "load_end": Value::Null,
            "threads": o.threads,
            "budget_s": o.budget,
            "timeout_s": o.timeout,
        },
        "scenes": [],
        "runs": [],
    });
    eprintln!(
        "scaling: areas {} m², THP and GREEDY, {} s budget, {} thread(s); load average {}",
        areas.join(", "),
        o.budget,
        o.threads,
        doc["meta"]["load_start"].as_str().unwrap_or("?")
    );
    let mut failed = 0usize;
    let mut png_error = None;
    for &area in &o.areas {
        let name = format!("office_{area}");
        let obj = scenes.join(format!("{name}.obj"));
        let obj_s = obj.display().to_string();
        // One cache folder an area, emptied first: `scene info` computes the set, the runs read it.
        let cache = scenes.join("cache").join(area.to_string());
        let _ = std::fs::remove_dir_all(&cache);
        let cache_env = ("TENSORSCOUT_CACHE_DIR", cache.display().to_string());
        let mut scene = json!({ "area_m2": area, "scene": obj_s });

        let g = step(
            &format!("{name}: generate"),
            &bin,
            &[
                "scene",
                "generate",
                "--style",
                "office",
                "--seed",
                "1",
                "--area",
                &area.to_string(),
                "-o",
                &obj_s,
                "--force",
            ]
            .map(String::from),
            &[],
            o.timeout,
        );
        scene["generate"] = step_record(&g);
        if g.ok {
            let i = step(
                &format!("{name}: observable set"),
                &bin,
                &["scene", "info", &obj_s, "--json"].map(String::from),
                std::slice::from_ref(&cache_env),
                o.timeout,
            );
            let mut rec = step_record(&i);
            if let Ok(info) = serde_json::from_str::<Value>(&i.stdout) {
                rec["positions"] = info["observable_positions"].clone();
                rec["observable_volume_m3"] = info["observable_volume_m3"].clone();
                rec["reachable_area_m2"] = info["reachable_area_m2"].clone();
                rec["triangles"] = info["triangles"].clone();
                rec["grid"] = info["grid"].clone();
            } else if i.ok {
                rec["ok"] = json!(false);
                rec["error"] = json!("the scene info JSON did not parse");
            }
            if !i.stderr.trim().is_empty() {
                rec["stderr"] = json!(i.stderr.trim());
            }
            scene["observable"] = rec;
        } else {
            scene["observable"] = skipped("generate failed");
        }
        let scene_ok = scene["observable"]["ok"] == json!(true);
        failed += usize::from(!g.ok) + usize::from(g.ok && !scene_ok);
        doc["scenes"].as_array_mut().expect("array").push(scene);

        for p in PLANNERS {
            let label = format!("{name}: {} run", p.to_uppercase());
            let rec = if scene_ok {
                let c = step(
                    &label,
                    &bin,
                    &[
                        "explore",
                        "--scene",
                        &obj_s,
                        "--planner",
                        p,
                        "--set",
                        &format!("sim.budget_s={}", o.budget),
                        "--json",
                        "--quiet",
                    ]
                    .map(String::from),
                    &[
                        cache_env.clone(),
                        ("RAYON_NUM_THREADS", o.threads.to_string()),
                    ],
                    o.timeout,
                );
                run_record(area, p, &c)
            } else {
                eprintln!("{label} ... skipped (no scene or no observable set)");
                let mut r = skipped("no scene or no observable set");
                r["area_m2"] = json!(area);
                r["planner"] = json!(p.to_uppercase());
                r
            };
            failed += usize::from(rec["ok"] != json!(true));
            doc["runs"].as_array_mut().expect("array").push(rec);
        }
        doc["meta"]["finished"] = json!(utc(std::time::SystemTime::now()));
        doc["meta"]["load_end"] = json!(load_average());
        png_error = write_outputs(&o.out, &doc);
    }
    let out = o.out.display();
    match png_error {
        None => eprintln!("scaling: wrote {out}/scaling.json, scaling.md and scaling.png"),
        Some(e) => eprintln!("scaling: wrote {out}/scaling.json and scaling.md; no PNG: {e}"),
    }
    eprintln!(
        "scaling: load average {}{}",
        doc["meta"]["load_end"].as_str().unwrap_or("?"),
        if failed > 0 {
            format!("; {failed} step(s) failed or were skipped (listed in scaling.md)")
        } else {
            String::new()
        }
    );
}
