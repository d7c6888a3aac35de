//! `tensorscout.bench(...)`: the batch `tensorscout bench` runs, with Python planners beside the
//! built-in ones, writing the same folder (rows in `results.jsonl`, then every derived file through
//! `bench::write_outputs`).
//!
//! The runs are driven here rather than by `bench::run_batch`, whose runs know only built-in
//! planners and cannot be stopped midway: each run here builds its planner (built-in, or a fresh
//! instance of the Python class), and stops at the next step when Ctrl-C arrives. Each row is made by
//! `bench::run_row`, as the command line's are (the same config, seed, scene, world and step loop),
//! so it equals the command line's; `tests/test_bench.py` checks it.

use crate::config;
use crate::errors::{guard, usage, IntoPy};
use crate::planner::{planner_name, Pending, PyPlanner};
use crate::simulation::{planner_kind, SIGNAL_CHECK};
use pyo3::prelude::*;
use pyo3::types::PyList;
use rayon::prelude::*;
use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Mutex};
use tensorscout::bench::{self as batch, BenchRow, BenchSpec, RunKey, RESULTS_JSONL};
use tensorscout::plan::{Planner, PlannerKind};
use tensorscout::sim::{ObservableCache, Observer, Simulation};
use tensorscout::{scene, Config};

/// The command line's limits (`bench --seeds`, `--jobs`).
const MAX_SEEDS: u64 = 100_000;
const MAX_JOBS: usize = 1024;

/// What plans a run.
enum Who {
    Builtin(PlannerKind),
    /// A Python class or zero-argument factory, called once per run.
    Python(Py<PyAny>, String),
}

struct Job {
    key: RunKey,
    scene: PathBuf,
    who: usize,
}

/// Stops a run at its next step once the batch is interrupted.
struct StopFlag<'a>(&'a AtomicBool);

impl Observer for StopFlag<'_> {
    fn stop_requested(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// One run's row (as `bench::run_row` makes it for the command line); `None` when it was
/// interrupted (such a row is not kept).
fn run_job(job: &Job, who: &Who, base: &Config, stop: &AtomicBool) -> Option<BenchRow> {
    let prepare = |cfg: &Config| -> tensorscout::Result<Box<dyn Planner + Send>> {
        match who {
            Who::Builtin(k) => k.build(cfg),
            Who::Python(factory, name) => Python::attach(|py| {
                factory
                    .bind(py)
                    .call0()
                    .map(|obj| {
                        Box::new(PyPlanner::new(obj.unbind(), name, Pending::default()))
                            as Box<dyn Planner + Send>
                    })
                    .map_err(|e| {
                        tensorscout::Error::Runtime(format!(
                            "python planner {name} could not be created: {}",
                            e.value(py)
                        ))
                    })
            }),
        }
    };
    let row =
        batch::run_row(
            &job.key,
            &job.scene,
            base,
            &ObservableCache::user(),
            prepare,
            |scene, world, cfg, planner| {
                Ok(Simulation::with_planner(scene, world, cfg, planner)
                    .run_to_end(&mut StopFlag(stop)))
            },
        );
    let interrupted = row
        .result
        .as_ref()
        .is_some_and(|r| r.termination == tensorscout::sim::Termination::Interrupted);
    (!interrupted).then_some(row)
}

/// The keys already in `results.jsonl` (for `resume`).
fn done_keys(path: &Path) -> BTreeSet<RunKey> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str::<BenchRow>(l).ok())
        .map(|r| r.key)
        .collect()
}

#[pyfunction]
#[pyo3(signature = (scenes, planners, seeds, out, config, jobs, reference, scene_spawn, resume, force))]
#[allow(clippy::too_many_arguments)]
pub fn bench<'py>(
    py: Python<'py>,
    scenes: Vec<PathBuf>,
    planners: Vec<Bound<'py, PyAny>>,
    seeds: u64,
    out: PathBuf,
    config: Option<Bound<'py, PyAny>>,
    jobs: Option<usize>,
    reference: Option<String>,
    scene_spawn: bool,
    resume: bool,
    force: bool,
) -> PyResult<Bound<'py, PyList>> {
    guard(py, || {
        if !(1..=MAX_SEEDS).contains(&seeds) {
            return Err(usage(
                py,
                format!("--seeds {seeds}: expected 1 to {MAX_SEEDS}"),
            ));
        }
        let jobs = match jobs {
            Some(j) if !(1..=MAX_JOBS).contains(&j) => {
                return Err(usage(py, format!("--jobs {j}: expected 1 to {MAX_JOBS}")))
            }
            Some(j) => j,
            None => std::thread::available_parallelism().map_or(1, |n| n.get()),
        };
        if planners.is_empty() {
            return Err(usage(py, "planners: expected at least one"));
        }
        let mut cfg = config::load(py, config.as_ref(), &[], None)?;
        batch::apply_spawn_rule(&mut cfg, seeds, scene_spawn);
        let reference = reference.map(|r| planner_kind(py, &r)).transpose()?;
        let mut who = Vec::new();
        for p in &planners {
            who.push(match p.extract::<String>() {
                Ok(name) => Who::Builtin(planner_kind(py, &name)?),
                Err(_) if p.is_callable() => Who::Python(p.clone().unbind(), planner_name(p)?),
                Err(_) => {
                    return Err(usage(
                        py,
                        "planners: expected built-in names and Python planner classes or factories",
                    ))
                }
            });
        }
        let jsonl = out.join(RESULTS_JSONL);
        if force && jsonl.exists() {
            std::fs::remove_file(&jsonl)
                .map_err(|e| tensorscout::Error::io(&jsonl, e))
                .py_err(py)?;
        }
        let spec = BenchSpec {
            scenes: batch::collect_scenes(&scenes).py_err(py)?,
            planners: Vec::new(),
            seeds,
            config: cfg.clone(),
            jobs,
            out: out.clone(),
            resume,
            shard: None,
            reference,
            log_runs: false,
            cache: ObservableCache::user(),
        };
        // Refuses an existing batch without `resume`, as the command line does.
        batch::pending_runs(&spec).py_err(py)?;
        let done = done_keys(&jsonl);
        let config_hash = cfg.hash();
        let mut todo = Vec::new();
        for path in &spec.scenes {
            let scene_hash = std::fs::read(path)
                .map(|b| scene::content_hash(&b))
                .unwrap_or_default();
            for (i, w) in who.iter().enumerate() {
                let label = match w {
                    Who::Builtin(k) => k.label(&cfg),
                    Who::Python(_, name) => name.clone(),
                };
                for s in 0..seeds {
                    let key = RunKey {
                        scene_path: path.display().to_string(),
                        scene_hash: scene_hash.clone(),
                        planner: label.clone(),
                        seed: cfg.seed.wrapping_add(s),
                        config_hash: config_hash.clone(),
                    };
                    if !done.contains(&key) {
                        todo.push(Job {
                            key,
                            scene: path.clone(),
                            who: i,
                        });
                    }
                }
            }
        }
        todo.sort_by(|a, b| a.key.cmp(&b.key));
        todo.dedup_by(|a, b| a.key == b.key);
        std::fs::create_dir_all(&out)
            .map_err(|e| tensorscout::Error::io(&out, e))
            .py_err(py)?;
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&jsonl)
            .map_err(|e| tensorscout::Error::io(&jsonl, e))
            .py_err(py)?;
        let writer = Mutex::new(file);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(jobs)
            .build()
            .map_err(|e| usage(py, format!("cannot start the thread pool: {e}")))?;
        let stop = AtomicBool::new(false);
        let scenes_used: BTreeSet<&PathBuf> = todo.iter().map(|j| &j.scene).collect();
        // The batch runs on its own thread, so that this one can wait without the GIL (Python
        // planners take it in the workers) and still answer Ctrl-C promptly.
        let interrupted = std::thread::scope(|s| -> PyResult<Option<PyErr>> {
            let (done_tx, done_rx) = mpsc::channel::<tensorscout::Result<()>>();
            let (todo, who, cfg, writer, stop, pool, jsonl) =
                (&todo, &who, &cfg, &writer, &stop, &pool, &jsonl);
            s.spawn(move || {
                let r = pool.install(|| {
                    let _ = batch::prepare_scenes(scenes_used, cfg, &ObservableCache::user());
                    todo.par_iter()
                        .map(|job| -> tensorscout::Result<()> {
                            if stop.load(Ordering::Relaxed) {
                                return Ok(());
                            }
                            let Some(row) = run_job(job, &who[job.who], cfg, stop) else {
                                return Ok(());
                            };
                            let line = serde_json::to_string(&row)
                                .map_err(|e| tensorscout::Error::Runtime(e.to_string()))?;
                            let mut f = writer.lock().expect("writer");
                            writeln!(f, "{line}")
                                .and_then(|_| f.flush())
                                .map_err(|e| tensorscout::Error::io(jsonl, e))
                        })
                        .collect::<tensorscout::Result<Vec<()>>>()
                        .map(|_| ())
                });
                let _ = done_tx.send(r);
            });
            // In a mutex, so that the wait can leave the GIL (a receiver is not `Sync`).
            let done_rx = Mutex::new(done_rx);
            let mut interrupt = None;
            loop {
                let rx = &done_rx;
                let got = py.detach(move || rx.lock().expect("rx").recv_timeout(SIGNAL_CHECK));
                match got {
                    Ok(r) => {
                        r.py_err(py)?;
                        return Ok(interrupt);
                    }
                    Err(mpsc::RecvTimeoutError::Disconnected) => return Ok(interrupt),
                    Err(mpsc::RecvTimeoutError::Timeout) => {}
                }
                if interrupt.is_none() {
                    if let Err(e) = py.check_signals() {
                        stop.store(true, Ordering::Relaxed);
                        interrupt = Some(e);
                    }
                }
            }
        })?;
        if let Some(e) = interrupted {
            // The finished rows are in results.jsonl; `resume=True` continues the batch.
            return Err(e);
        }
        let r = reference;
        py.detach(|| batch::write_outputs(&out, r)).py_err(py)?;
        let rows = PyList::empty(py);
        let json = py.import("json")?;
        let text = std::fs::read_to_string(&jsonl)
            .map_err(|e| tensorscout::Error::io(&jsonl, e))
            .py_err(py)?;
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            rows.append(json.call_method1("loads", (line,))?)?;
        }
        Ok(rows)
    })
}
