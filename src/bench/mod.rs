//! Batch benchmark: scenes × planners × seeds on one rayon pool, one row per run appended to
//! `results.jsonl` as it finishes (so an interrupted batch can resume), then tables, a summary and
//! plots rebuilt from those rows.
//!
//! Every derived file (`results.csv`, `curves.csv`, `summary.md`, `summary.json`, `plots/`) is a pure
//! function of the sorted rows, so a sharded batch merged with [`merge`] and an unsharded one give
//! the same files (apart from wall-clock fields).

pub(crate) mod plot;
pub(crate) mod stats;
pub(crate) mod store;
pub(crate) mod summary;

use crate::config::SpawnMode;
use crate::plan::PlannerKind;
use crate::sim::{self, ObservableCache, World};
use crate::{scene, Config, Error, Result};
pub use plot::SERIES_COLOURS;
use rayon::prelude::*;
use std::collections::BTreeSet;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
pub use store::{BenchRow, RunKey, RunStatus, RESULTS_JSONL};

/// Scene file extensions `--scenes DIR` picks up.
pub const SCENE_EXTENSIONS: [&str; 7] = ["obj", "ply", "gltf", "glb", "yaml", "yml", "json"];

/// One deterministic slice `K/N` (1-based `K`) of a batch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = Error;
    /// Parses `K/N` with 1 ≤ K ≤ N.
    fn from_str(s: &str) -> Result<Shard> {
        let bad = || Error::usage(format!("--shard `{s}`: expected K/N with 1 <= K <= N"));
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let index: usize = k.trim().parse().map_err(|_| bad())?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if index == 0 || count == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

/// What to run and where to put it.
pub struct BenchSpec {
    pub scenes: Vec<PathBuf>,
    pub planners: Vec<PlannerKind>,
    /// Number of seeds per scene and planner: `cfg.seed`, `cfg.seed + 1`, …
    pub seeds: u64,
    pub config: Config,
    /// Runs in parallel (the size of the one rayon pool).
    pub jobs: usize,
    pub out: PathBuf,
    pub resume: bool,
    pub shard: Option<Shard>,
    pub reference: Option<PlannerKind>,
    /// Write each run's MCAP log into `out/logs/`.
    pub log_runs: bool,
    /// Where observable sets are cached (see `eval::observable`).
    pub cache: ObservableCache,
}

/// The start rule of a batch: with more than one seed, each seed draws its own start (the same for
/// every planner, so runs pair up) unless `keep_scene_spawn`; with one seed, the config decides
/// (`sim.spawn`, the scene's own spawn by default).
pub fn apply_spawn_rule(cfg: &mut Config, seeds: u64, keep_scene_spawn: bool) {
    if keep_scene_spawn {
        cfg.sim.spawn = SpawnMode::Scene;
    } else if seeds > 1 {
        cfg.sim.spawn = SpawnMode::Random;
    }
}

/// One run to do.
#[derive(Clone, Debug)]
pub struct RunSpec {
    pub key: RunKey,
    pub scene_path: PathBuf,
    pub planner: PlannerKind,
}

/// Expands `--scenes` arguments: a folder gives its scene files (sorted, not recursive), a list
/// file (`.txt`) the scenes it names, any other file itself. Sorted and without duplicates.
pub fn collect_scenes(args: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = BTreeSet::new();
    for a in args {
        if a.is_dir() {
            let entries = std::fs::read_dir(a).map_err(|e| Error::io(a, e))?;
            for e in entries {
                let p = e.map_err(|e| Error::io(a, e))?.path();
                let ext = p
                    .extension()
                    .and_then(|e| e.to_str())
                    .map(str::to_ascii_lowercase);
                if p.is_file() && ext.is_some_and(|e| SCENE_EXTENSIONS.contains(&e.as_str())) {
                    out.insert(p);
                }
            }
        } else if is_scene_list(a) {
            out.extend(read_scene_list(a)?);
        } else {
            // A missing file is kept: it becomes a failed row, not an abort of the whole batch.
            out.insert(a.clone());
        }
    }
    if out.is_empty() {
        return Err(Error::usage("--scenes: no scene files found"));
    }
    Ok(out.into_iter().collect())
}

/// Whether `path` names a list of scenes (a `.txt` file) rather than a scene.
fn is_scene_list(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("txt"))
}

/// Largest scene list read, bytes: a list names scenes, one a line.
const SCENE_LIST_MAX_BYTES: u64 = 1 << 20;

/// The scenes a list file names: one path a line, relative to the list's folder; blank lines and
/// `#` comments are skipped. A named scene that does not exist is an error naming the list's line,
/// since a typo in a list would otherwise silently shrink the batch to a failed row.
fn read_scene_list(list: &Path) -> Result<Vec<PathBuf>> {
    let meta = std::fs::metadata(list).map_err(|e| Error::io(list, e))?;
    if !meta.is_file() || meta.len() > SCENE_LIST_MAX_BYTES {
        return Err(Error::usage(format!(
            "--scenes: {} is not a scene list (a regular text file of at most 1 MiB)",
            list.display()
        )));
    }
    let text = std::fs::read_to_string(list).map_err(|e| Error::io(list, e))?;
    let folder = list.parent().unwrap_or(Path::new(""));
    let mut scenes = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let entry = line.split('#').next().unwrap_or("").trim();
        if entry.is_empty() {
            continue;
        }
        let path = folder.join(entry);
        if !path.is_file() {
            return Err(Error::usage(format!(
                "--scenes: {}:{}: no scene file {}",
                list.display(),
                n + 1,
                path.display()
            )));
        }
        scenes.push(path);
    }
    if scenes.is_empty() {
        return Err(Error::usage(format!(
            "--scenes: {} names no scene",
            list.display()
        )));
    }
    Ok(scenes)
}

/// Every run of the batch, sorted by scene, planner and seed, then cut to the shard.
pub fn plan_runs(spec: &BenchSpec) -> Vec<RunSpec> {
    let config_hash = spec.config.hash();
    let mut planners = spec.planners.clone();
    planners.sort();
    planners.dedup();
    let mut runs = Vec::new();
    for path in &spec.scenes {
        // An unreadable file gets an empty hash; its runs fail with the read error.
        let scene_hash = std::fs::read(path)
            .map(|b| scene::content_hash(&b))
            .unwrap_or_default();
        for &planner in &planners {
            for i in 0..spec.seeds {
                runs.push(RunSpec {
                    key: RunKey {
                        scene_path: path.display().to_string(),
                        scene_hash: scene_hash.clone(),
                        planner: planner.label(&spec.config),
                        seed: spec.config.seed.wrapping_add(i),
                        config_hash: config_hash.clone(),
                    },
                    scene_path: path.clone(),
                    planner,
                });
            }
        }
    }
    runs.sort_by(|a, b| a.key.cmp(&b.key));
    if let Some(s) = spec.shard {
        runs = runs
            .into_iter()
            .enumerate()
            .filter(|(i, _)| i % s.count == s.index - 1)
            .map(|(_, r)| r)
            .collect();
    }
    runs
}

/// Runs one exploration; any error or panic becomes a failed row.
pub fn run_one(
    run: &RunSpec,
    base: &Config,
    log_dir: Option<&Path>,
    cache: &ObservableCache,
) -> BenchRow {
    let prepare = |cfg: &Config| run.planner.build(cfg).map(|_| ());
    run_row(
        &run.key,
        &run.scene_path,
        base,
        cache,
        prepare,
        |scene, world, cfg, ()| {
            let Some(dir) = log_dir else {
                return sim::run(scene, world, cfg, run.planner, &mut sim::NoObserver);
            };
            let path = dir.join(format!(
                "{}_{}_seed{}_{}.mcap",
                scene.name,
                run.planner.label(cfg).replace('/', "-"),
                run.key.seed,
                &run.key.config_hash
            ));
            let identity =
                crate::log::RunIdentity::new(&run.scene_path, scene, run.planner, cfg, None);
            let mut recorder = crate::log::Recorder::new(
                crate::log::RunLog::create(&path, &identity, &cfg.log)?,
                cfg,
                &scene.mesh,
                None,
            );
            let out = sim::run(scene, world, cfg, run.planner, &mut recorder);
            // The log is finished (summary section written) whatever the run's outcome.
            recorder.sink.close()?;
            out
        },
    )
}

/// The row of one run of a batch, for any planner: `base` with the run's seed is its config;
/// `prepare` builds (or checks) what the run needs before its scene is loaded, `drive` runs it on
/// the scene and its world. An error or a panic anywhere becomes a failed row, so the batch goes on.
pub fn run_row<P>(
    key: &RunKey,
    scene_path: &Path,
    base: &Config,
    cache: &ObservableCache,
    prepare: impl FnOnce(&Config) -> Result<P>,
    drive: impl FnOnce(&scene::Scene, World, &Config, P) -> Result<sim::RunOutput>,
) -> BenchRow {
    let outcome = catch_unwind(AssertUnwindSafe(|| -> Result<sim::RunOutput> {
        let mut cfg = base.clone();
        cfg.seed = key.seed;
        let prepared = prepare(&cfg)?;
        let scene = scene::load(scene_path, &cfg.scene)?;
        let world = World::with_cache(&scene, &cfg, None, cache)?;
        drive(&scene, world, &cfg, prepared)
    }));
    match outcome {
        Ok(Ok(out)) => BenchRow {
            key: key.clone(),
            status: if out.result.error.is_some() {
                RunStatus::Failed
            } else {
                RunStatus::Ok
            },
            error: out.result.error.clone(),
            result: Some(out.result),
        },
        Ok(Err(e)) => BenchRow::failed(key.clone(), e.to_string()),
        Err(panic) => BenchRow::failed(
            key.clone(),
            format!("panic: {}", crate::util::panic_message(&*panic)),
        ),
    }
}

/// Receives one call per finished run (for a progress bar).
pub trait Progress: Sync {
    /// Called once before the first run: runs in the batch and runs already done (`--resume`).
    fn start(&self, _total: usize, _skipped: usize) {}
    fn finished(&self, row: &BenchRow);
}

/// Progress that shows nothing.
pub struct NoProgress;
impl Progress for NoProgress {
    fn finished(&self, _row: &BenchRow) {}
}

/// What a batch did.
#[derive(Debug, Default)]
pub struct BatchReport {
    /// Runs in the batch (this shard).
    pub total: usize,
    /// Runs skipped because `--resume` found them.
    pub skipped: usize,
    /// Runs done now.
    pub ran: usize,
    /// Failed rows among all rows in DIR.
    pub failed: usize,
    /// Lines for the user (a damaged cache file that was recomputed, an unwritable cache).
    pub notes: Vec<String>,
}

/// Computes (or reads from the cache) each scene's observable set once before the runs, so that
/// parallel runs of one scene do not all compute it. A scene that fails to load is left to its runs,
/// which report the error in their rows; so is one whose preparation panics (each run then fails on
/// its own, as a `failed` row, instead of the panic ending the batch).
/// Answers the warnings to show once (a refused spawn line, a stale cache).
pub fn prepare_scenes<'a>(
    scenes: impl IntoIterator<Item = &'a PathBuf>,
    cfg: &Config,
    cache: &ObservableCache,
) -> Vec<String> {
    let scenes: BTreeSet<&PathBuf> = scenes.into_iter().collect();
    let mut notes = Vec::new();
    for path in scenes {
        let prepared = catch_unwind(AssertUnwindSafe(|| {
            let scene = scene::load(path, &cfg.scene).ok()?;
            let mut own = cfg.clone();
            // The set belongs to the scene's own spawn region, which random starts share; when
            // the file's spawn line is refused, random starts use the largest room's (said once).
            own.sim.spawn = SpawnMode::Scene;
            let world = World::with_cache(&scene, &own, None, cache)
                .or_else(|_| World::with_cache(&scene, cfg, None, cache))
                .ok()?;
            Some(
                world
                    .observable_source
                    .warning()
                    .into_iter()
                    .chain(world.spawn_warning)
                    .collect::<Vec<_>>(),
            )
        }));
        notes.extend(prepared.ok().flatten().into_iter().flatten());
    }
    notes
}

/// The runs still to do: all of them, or with `--resume` those not yet in `results.jsonl` (whose
/// truncated last line, if any, is dropped first).
pub fn pending_runs(spec: &BenchSpec) -> Result<Vec<RunSpec>> {
    let runs = plan_runs(spec);
    let jsonl = spec.out.join(store::RESULTS_JSONL);
    let existing = if jsonl.exists() {
        if !spec.resume {
            return Err(Error::usage(format!(
                "{} already exists; pass --resume to continue that batch or choose another --out",
                jsonl.display()
            )));
        }
        store::repair_jsonl(&jsonl)?
    } else {
        Vec::new()
    };
    let done: BTreeSet<&RunKey> = existing.iter().map(|r| &r.key).collect();
    Ok(runs
        .into_iter()
        .filter(|r| !done.contains(&r.key))
        .collect())
}

/// The lock file that keeps two bench processes from writing one folder at once.
pub const LOCK_FILE: &str = "bench.lock";

/// Guards a bench folder against a second process writing it at the same time (rows would be lost
/// when one rewrites `results.jsonl` under the other). The lock holds our process id; a lock whose
/// process is gone (after Ctrl-C) is taken over. Simplification: liveness is read from `/proc`, so
/// off Linux a leftover lock is always taken over, and check-then-write is not atomic.
struct DirLock {
    path: PathBuf,
}

impl DirLock {
    fn take(dir: &Path) -> Result<DirLock> {
        let path = dir.join(LOCK_FILE);
        if let Ok(text) = std::fs::read_to_string(&path) {
            if let Ok(pid) = text.trim().parse::<u32>() {
                if pid != std::process::id() && Path::new("/proc").join(pid.to_string()).exists() {
                    return Err(Error::usage(format!(
                        "{}: bench process {pid} is writing this folder; wait for it or choose another --out (delete the lock if that process is not a bench)",
                        path.display()
                    )));
                }
            }
        }
        std::fs::write(&path, std::process::id().to_string()).map_err(|e| Error::io(&path, e))?;
        Ok(DirLock { path })
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Runs the batch: writes each row to `results.jsonl` as it finishes, then every derived file.
pub fn run_batch(spec: &BenchSpec, progress: &dyn Progress) -> Result<BatchReport> {
    std::fs::create_dir_all(&spec.out).map_err(|e| Error::io(&spec.out, e))?;
    let _lock = DirLock::take(&spec.out)?;
    let log_dir = spec.log_runs.then(|| spec.out.join("logs"));
    if let Some(dir) = &log_dir {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let total = plan_runs(spec).len();
    let jsonl = spec.out.join(store::RESULTS_JSONL);
    // A cut last row is dropped by the resume (and its run done again): said, not silent.
    let cut_row = if spec.resume && jsonl.is_file() {
        store::cut_row_warning(&jsonl)?
    } else {
        None
    };
    let todo = pending_runs(spec)?;
    let skipped = total - todo.len();
    progress.start(total, skipped);
    let writer = Mutex::new(store::RowWriter::open_append(
        &spec.out.join(store::RESULTS_JSONL),
    )?);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(spec.jobs.max(1))
        .build()
        .map_err(|e| Error::Runtime(format!("cannot start the thread pool: {e}")))?;
    let mut notes: Vec<String> = cut_row.into_iter().collect();
    notes.extend(pool.install(|| {
        prepare_scenes(
            todo.iter().map(|r| &r.scene_path),
            &spec.config,
            &spec.cache,
        )
    }));
    // One pool: the runs and the ray casting inside each run share its threads, so the batch never
    // uses more than `jobs` threads.
    let write_errors: Vec<Error> = pool.install(|| {
        todo.par_iter()
            .filter_map(|run| {
                let row = run_one(run, &spec.config, log_dir.as_deref(), &spec.cache);
                let res = writer.lock().expect("writer lock").append(&row);
                progress.finished(&row);
                res.err()
            })
            .collect()
    });
    drop(writer);
    if let Some(e) = write_errors.into_iter().next() {
        return Err(e);
    }
    let failed = write_outputs(&spec.out, spec.reference)?;
    Ok(BatchReport {
        total,
        skipped,
        ran: total - skipped,
        failed,
        notes,
    })
}

/// Rebuilds `results.jsonl` (sorted) and every derived file in `dir` from its rows. Returns the
/// number of failed rows.
pub fn write_outputs(dir: &Path, reference: Option<PlannerKind>) -> Result<usize> {
    let rows = store::read_jsonl(&dir.join(store::RESULTS_JSONL))?;
    write_all_from_rows(dir, rows, reference)
}

fn write_all_from_rows(
    dir: &Path,
    mut rows: Vec<BenchRow>,
    reference: Option<PlannerKind>,
) -> Result<usize> {
    rows.sort_by(|a, b| a.key.cmp(&b.key));
    rows.dedup_by(|a, b| a.key == b.key);
    store::write_jsonl(&dir.join(store::RESULTS_JSONL), &rows)?;
    store::write_results_csv(&dir.join(store::RESULTS_CSV), &rows)?;
    store::write_curves_csv(&dir.join(store::CURVES_CSV), &rows)?;
    let summary = summary::Summary::of(&rows, reference);
    store::write_atomic(&dir.join("summary.md"), summary.to_markdown().as_bytes())?;
    let json = serde_json::to_string_pretty(&summary)
        .map_err(|e| Error::Runtime(format!("summary.json: {e}")))?;
    store::write_atomic(&dir.join("summary.json"), format!("{json}\n").as_bytes())?;
    plot::write_plots(&dir.join("plots"), &rows)?;
    Ok(rows
        .iter()
        .filter(|r| r.status == RunStatus::Failed)
        .count())
}

/// The row's result without its wall-clock fields, for comparing two runs of the same key.
fn comparable(row: &BenchRow) -> serde_json::Value {
    let mut v = serde_json::to_value(row).unwrap_or(serde_json::Value::Null);
    if let Some(r) = v.get_mut("result").and_then(|r| r.as_object_mut()) {
        for k in ["wall_time_s", "real_time_factor", "timings_ms"] {
            r.remove(k);
        }
    }
    v
}

/// The first run key present twice with results that differ (apart from wall-clock fields), and
/// how many keys differ so.
fn conflicts(rows: &[BenchRow]) -> Option<(RunKey, usize)> {
    let mut by_key: std::collections::BTreeMap<&RunKey, serde_json::Value> = Default::default();
    let mut first = None;
    let mut count = 0;
    let mut counted = BTreeSet::new();
    for r in rows {
        let v = comparable(r);
        match by_key.get(&r.key) {
            Some(prev) if *prev != v => {
                if counted.insert(&r.key) {
                    count += 1;
                    first.get_or_insert_with(|| r.key.clone());
                }
            }
            Some(_) => {}
            None => {
                by_key.insert(&r.key, v);
            }
        }
    }
    first.map(|k| (k, count))
}

/// Combines the rows of several batch folders (e.g. shards) into `out` and writes every derived file.
/// A run present in several folders with the same result is kept once; one with differing results
/// is an error naming it, unless `keep_first` (then the copy from the earliest folder is kept).
/// Returns the number of failed rows.
pub fn merge(
    dirs: &[PathBuf],
    out: &Path,
    reference: Option<PlannerKind>,
    keep_first: bool,
) -> Result<(usize, Vec<String>)> {
    let mut rows = Vec::new();
    let mut notes = Vec::new();
    for d in dirs {
        let path = d.join(store::RESULTS_JSONL);
        if !path.is_file() {
            return Err(Error::Runtime(format!(
                "{}: not found (is {} a bench output folder?)",
                path.display(),
                d.display()
            )));
        }
        notes.extend(store::cut_row_warning(&path)?);
        rows.extend(store::read_jsonl(&path)?);
    }
    if let Some((k, n)) = conflicts(&rows) {
        if !keep_first {
            return Err(Error::Runtime(format!(
                "{n} run(s) differ between the folders, e.g. {} {} seed {} (config {}); pass --keep-first to keep the first folder's",
                k.scene_path, k.planner, k.seed, k.config_hash
            )));
        }
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let _lock = DirLock::take(out)?;
    // The sort is stable, so the first folder's copy of a run comes first and is the one kept.
    Ok((write_all_from_rows(out, rows, reference)?, notes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shard_parsing() {
        assert_eq!(
            "2/3".parse::<Shard>().unwrap(),
            Shard { index: 2, count: 3 }
        );
        for bad in ["0/2", "3/2", "1", "a/b", "1/0"] {
            let e = bad.parse::<Shard>().unwrap_err().to_string();
            assert_eq!(e, format!("--shard `{bad}`: expected K/N with 1 <= K <= N"));
        }
    }

    fn spec(shard: Option<Shard>) -> BenchSpec {
        BenchSpec {
            scenes: vec!["b.obj".into(), "a.obj".into()],
            planners: vec![PlannerKind::Greedy, PlannerKind::Thp],
            seeds: 3,
            config: Config::default(),
            jobs: 1,
            out: "unused".into(),
            resume: false,
            shard,
            reference: None,
            log_runs: false,
            cache: ObservableCache::none(),
        }
    }

    #[test]
    fn shards_partition_the_sorted_runs() {
        let all = plan_runs(&spec(None));
        assert_eq!(all.len(), 2 * 2 * 3);
        let keys: Vec<_> = all.iter().map(|r| r.key.clone()).collect();
        let mut sorted = keys.clone();
        sorted.sort();
        assert_eq!(keys, sorted);
        assert_eq!(all[0].key.scene_path, "a.obj");
        let mut union: Vec<RunKey> = (1..=3)
            .flat_map(|k| plan_runs(&spec(Some(Shard { index: k, count: 3 }))))
            .map(|r| r.key)
            .collect();
        union.sort();
        assert_eq!(union, sorted);
    }

    #[test]
    fn a_live_lock_is_refused_a_stale_one_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let lock = dir.path().join(LOCK_FILE);
        // Process 1 (init) is alive on Linux.
        std::fs::write(&lock, "1").unwrap();
        if Path::new("/proc/1").exists() {
            let e = DirLock::take(dir.path()).err().unwrap().to_string();
            assert!(
                e.starts_with(&format!("{}: bench process 1 is writing", lock.display())),
                "{e}"
            );
        }
        // A process id that cannot exist (above Linux's pid_max).
        std::fs::write(&lock, "4294967295").unwrap();
        let taken = DirLock::take(dir.path()).unwrap();
        assert_eq!(
            std::fs::read_to_string(&lock).unwrap(),
            std::process::id().to_string()
        );
        drop(taken);
        assert!(!lock.exists());
    }

    fn row(seed: u64, error: &str) -> BenchRow {
        BenchRow::failed(
            RunKey {
                scene_path: "a.obj".into(),
                scene_hash: "h".into(),
                planner: "greedy".into(),
                seed,
                config_hash: "c".into(),
            },
            error.into(),
        )
    }

    #[test]
    fn bench_merge_reports_conflicting_results() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b, out) = (
            dir.path().join("a"),
            dir.path().join("b"),
            dir.path().join("out"),
        );
        for d in [&a, &b] {
            std::fs::create_dir(d).unwrap();
        }
        store::write_jsonl(&a.join(store::RESULTS_JSONL), &[row(1, "x"), row(2, "y")]).unwrap();
        // The same run twice with the same result is no conflict; seed 2 differs.
        store::write_jsonl(&b.join(store::RESULTS_JSONL), &[row(1, "x"), row(2, "z")]).unwrap();
        let e = merge(&[a.clone(), b.clone()], &out, None, false)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "1 run(s) differ between the folders, e.g. a.obj greedy seed 2 (config c); pass --keep-first to keep the first folder's"
        );
        assert!(!out.exists(), "nothing is written on a conflict");
        assert_eq!(merge(&[a, b], &out, None, true).unwrap(), (2, Vec::new()));
        let rows = store::read_jsonl(&out.join(store::RESULTS_JSONL)).unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[1].error.as_deref(), Some("y"));
    }

    #[test]
    fn missing_scene_is_a_failed_row() {
        let run = RunSpec {
            key: RunKey {
                scene_path: "/nonexistent/x.obj".into(),
                scene_hash: String::new(),
                planner: "greedy".into(),
                seed: 0,
                config_hash: String::new(),
            },
            scene_path: "/nonexistent/x.obj".into(),
            planner: PlannerKind::Greedy,
        };
        let row = run_one(&run, &Config::default(), None, &ObservableCache::none());
        assert_eq!(row.status, RunStatus::Failed);
        assert!(row.error.unwrap().starts_with("/nonexistent/x.obj"));
    }
}
