//! The long fuzz run: seeded mutations of valid inputs for every loader and parser (see
//! `tests/fuzz/mod.rs`), counting panics, aborts (the process killed by an allocation failure or
//! any signal) and hangs.
//!
//! ```sh
//! cargo run --release --example fuzz -- --cases 100000 --format all [--seed 17] [--out DIR]
//! ```
//!
//! The cases run in a child process of this program (limited to 4 GiB of address space with
//! `ulimit -v`, so that a runaway allocation fails fast instead of swapping the machine); the child
//! reports each case on its stderr, so when it dies the supervisor knows which case killed it,
//! saves that input to `--out` (default `target/fuzz-crashes`), and starts a new child after it. A
//! case that runs longer than 30 s is a hang: the child is killed and the case saved. Exit code 1
//! when anything panicked, aborted or hung.

#[path = "../tests/fuzz/mod.rs"]
mod fuzz;

use fuzz::{case_input, run_case, seeds, Format, Outcome};
use std::collections::BTreeMap;
use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::process::{Command, ExitCode, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const HANG_AFTER: Duration = Duration::from_secs(30);
const MEMORY_LIMIT_KB: u64 = 4 << 20;

fn usage() -> ExitCode {
    eprintln!("usage: fuzz [--cases N] [--format all|obj|ply|pgm|yaml|houseexpo|toml|set|mcap|glb|gltf[,...]] [--seed S] [--out DIR]");
    ExitCode::from(2)
}

/// Worker mode: run cases `start..start+count`, one line per case on stderr: `@i` before it and
/// `i outcome` after it (stderr is unbuffered, so nothing is lost when the process dies).
fn worker(format: Format, start: u64, count: u64, seed: u64) -> ExitCode {
    // Panics are counted by the supervisor; `FUZZ_TRACE=1` keeps their messages and backtraces on
    // stderr to debug one case (`fuzz --worker FORMAT CASE 1 SEED`).
    if std::env::var_os("FUZZ_TRACE").is_none() {
        std::panic::set_hook(Box::new(|_| {}));
    }
    let seeds = seeds(format);
    let dir = tempfile::tempdir().expect("temp dir");
    let mut err = std::io::stderr().lock();
    for i in start..start + count {
        let _ = writeln!(err, "@{i}");
        let input = case_input(seed, format, i, &seeds);
        let line = match run_case(format, &input, dir.path()) {
            Outcome::Accepted => format!("{i} accepted"),
            Outcome::Rejected(k) => format!("{i} {k}"),
            Outcome::Panicked(m) => format!("{i} panic {}", m.replace('\n', " ")),
        };
        let _ = writeln!(err, "{line}");
    }
    ExitCode::SUCCESS
}

#[derive(Default)]
struct Counts {
    cases: u64,
    outcomes: BTreeMap<String, u64>,
    panics: Vec<(u64, String)>,
    aborts: Vec<(u64, String)>,
    hangs: Vec<u64>,
}

/// Runs `cases` cases of `format` in supervised children.
fn supervise(format: Format, cases: u64, seed: u64, out: &std::path::Path) -> Counts {
    let exe = std::env::current_exe().expect("own path");
    let mut counts = Counts::default();
    let all_seeds = seeds(format);
    let save = |i: u64, what: &str| {
        let _ = std::fs::create_dir_all(out);
        let p = out.join(format!("{}_{what}_case{i}.bin", format.name()));
        let _ = std::fs::write(&p, case_input(seed, format, i, &all_seeds));
        p
    };
    let mut start = 0;
    while start < cases {
        let mut child = Command::new("sh")
            .arg("-c")
            .arg(format!("ulimit -v {MEMORY_LIMIT_KB} && exec \"$0\" \"$@\""))
            .arg(&exe)
            .args([
                "--worker",
                format.name(),
                &start.to_string(),
                &(cases - start).to_string(),
                &seed.to_string(),
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("worker starts");
        let current = Arc::new(AtomicU64::new(start));
        let progress = Arc::new(Mutex::new(Instant::now()));
        let lines = Arc::new(Mutex::new(Vec::<String>::new()));
        let reader = {
            let (current, progress, lines) = (current.clone(), progress.clone(), lines.clone());
            let stderr = child.stderr.take().expect("piped");
            std::thread::spawn(move || {
                for line in std::io::BufReader::new(stderr).lines() {
                    let Ok(line) = line else { break };
                    if let Some(i) = line.strip_prefix('@') {
                        if let Ok(i) = i.parse() {
                            current.store(i, Ordering::SeqCst);
                            *progress.lock().unwrap() = Instant::now();
                        }
                    } else {
                        lines.lock().unwrap().push(line);
                    }
                }
            })
        };
        let status = loop {
            if let Some(status) = child.try_wait().expect("wait") {
                break Some(status);
            }
            if progress.lock().unwrap().elapsed() > HANG_AFTER {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            std::thread::sleep(Duration::from_millis(50));
        };
        let _ = reader.join();
        let mut last_done = None;
        for line in lines.lock().unwrap().drain(..) {
            let mut parts = line.splitn(3, ' ');
            let (Some(i), Some(kind)) = (parts.next(), parts.next()) else {
                continue;
            };
            let Ok(i) = i.parse::<u64>() else { continue };
            last_done = Some(i);
            counts.cases += 1;
            if kind == "panic" {
                let msg = parts.next().unwrap_or("").to_string();
                save(i, "panic");
                counts.panics.push((i, msg));
            } else {
                *counts.outcomes.entry(kind.to_string()).or_default() += 1;
            }
        }
        let next = last_done.map_or(start, |i| i + 1);
        match status {
            Some(s) if s.success() => break,
            Some(s) => {
                // The case that was running when the child died.
                let i = current.load(Ordering::SeqCst).max(next);
                counts.cases += 1;
                let p = save(i, "abort");
                counts
                    .aborts
                    .push((i, format!("{s} (input {})", p.display())));
                start = i + 1;
            }
            None => {
                let i = current.load(Ordering::SeqCst).max(next);
                counts.cases += 1;
                save(i, "hang");
                counts.hangs.push(i);
                start = i + 1;
            }
        }
    }
    counts
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("--worker") {
        let (Some(f), Some(start), Some(count), Some(seed)) = (
            args.get(1).and_then(|s| Format::parse(s)),
            args.get(2).and_then(|s| s.parse().ok()),
            args.get(3).and_then(|s| s.parse().ok()),
            args.get(4).and_then(|s| s.parse().ok()),
        ) else {
            return usage();
        };
        return worker(f, start, count, seed);
    }
    let mut cases = 10_000u64;
    let mut formats = Format::ALL.to_vec();
    let mut seed = 17u64;
    let mut out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/fuzz-crashes");
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let Some(v) = it.next() else { return usage() };
        match a.as_str() {
            "--cases" => match v.parse() {
                Ok(n) => cases = n,
                Err(_) => return usage(),
            },
            "--seed" => match v.parse() {
                Ok(n) => seed = n,
                Err(_) => return usage(),
            },
            "--out" => out = PathBuf::from(v),
            "--format" if v == "all" => formats = Format::ALL.to_vec(),
            "--format" => {
                let parsed: Option<Vec<Format>> = v.split(',').map(Format::parse).collect();
                match parsed {
                    Some(f) => formats = f,
                    None => return usage(),
                }
            }
            _ => return usage(),
        }
    }
    let mut bad = false;
    println!(
        "| format | cases | accepted | rejected (by kind) | panics | aborts | hangs | seconds |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for f in formats {
        let t0 = Instant::now();
        let c = supervise(f, cases, seed, &out);
        let rejected: Vec<String> = c
            .outcomes
            .iter()
            .filter(|(k, _)| k.as_str() != "accepted")
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {:.0} |",
            f.name(),
            c.cases,
            c.outcomes.get("accepted").copied().unwrap_or(0),
            rejected.join(", "),
            c.panics.len(),
            c.aborts.len(),
            c.hangs.len(),
            t0.elapsed().as_secs_f64()
        );
        for (i, m) in &c.panics {
            eprintln!("{} case {i}: panic: {m}", f.name());
        }
        for (i, m) in &c.aborts {
            eprintln!("{} case {i}: abort: {m}", f.name());
        }
        for i in &c.hangs {
            eprintln!(
                "{} case {i}: hang (over {} s)",
                f.name(),
                HANG_AFTER.as_secs()
            );
        }
        bad |= !(c.panics.is_empty() && c.aborts.is_empty() && c.hangs.is_empty());
    }
    if bad {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}
