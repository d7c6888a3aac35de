//! `tensorscout bench`: scenes × planners × seeds in parallel, and `bench merge` for shards.

use super::{note, ConfigArgs, ProfileArg};
use anyhow::Result;
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use tensorscout::bench::{self, BenchRow, BenchSpec, RunStatus, Shard};
use tensorscout::plan::PlannerKind;
use tensorscout::sim::ObservableCache;
use tensorscout::Error;

#[derive(Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BenchArgs {
    #[command(subcommand)]
    merge: Option<BenchCommand>,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Combine the results of several bench folders (e.g. shards) and write the summary and plots.
    Merge(MergeArgs),
}

#[derive(Args)]
struct MergeArgs {
    /// Bench output folders to combine.
    #[arg(required = true, value_name = "DIR")]
    dirs: Vec<PathBuf>,
    /// Folder for the combined results.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Planner that r_ε is relative to (default thp, else the first planner present).
    #[arg(long, value_enum)]
    reference: Option<PlannerKind>,
    /// Replace the results of an `--out` folder that already holds some.
    #[arg(long)]
    force: bool,
    /// When a run appears in several folders with different results, keep the first folder's
    /// instead of failing.
    #[arg(long)]
    keep_first: bool,
}

/// Largest `--seeds`, `--jobs` and number of runs in one batch (sanity bounds: a typo such as
/// `--seeds 1000000000` is refused instead of allocating its plan).
const MAX_SEEDS: u64 = 100_000;
const MAX_JOBS: usize = 1024;
const MAX_RUNS: usize = 1_000_000;

/// Files a bench folder holds besides `results.jsonl`.
const DERIVED: [&str; 5] = [
    "results.csv",
    "curves.csv",
    "summary.md",
    "summary.json",
    "plots",
];

/// Refuses an output folder that holds results (or files bench would overwrite) unless `force`,
/// or `resume` for a batch's own `results.jsonl`.
fn check_out(out: &std::path::Path, force: bool, resume: bool) -> tensorscout::Result<()> {
    if out.exists() && !out.is_dir() {
        return Err(Error::usage(format!(
            "--out {}: is a file, not a folder",
            out.display()
        )));
    }
    if force {
        return Ok(());
    }
    let jsonl = out.join(bench::RESULTS_JSONL);
    if jsonl.exists() {
        return if resume {
            Ok(())
        } else {
            Err(Error::usage(format!(
                "{} already exists; pass --resume to continue that batch, --force to replace it, or choose another --out",
                jsonl.display()
            )))
        };
    }
    if let Some(f) = DERIVED.iter().map(|f| out.join(f)).find(|p| p.exists()) {
        return Err(Error::usage(format!(
            "{} already exists and is not from a bench run here; pass --force to overwrite it or choose another --out",
            f.display()
        )));
    }
    Ok(())
}

#[derive(Args)]
struct RunArgs {
    /// Scene files, or folders whose scene files (.obj .ply .yaml .yml .json) are all used.
    #[arg(long, num_args = 1.., value_name = "DIR|FILE")]
    scenes: Vec<PathBuf>,
    /// Planners to compare, comma separated. A run that fails (bad scene, error) gives a failed row.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "thp,tensor,nbv,greedy"
    )]
    planners: Vec<PlannerKind>,
    /// Seeds per scene and planner: the config's `seed`, `seed+1`, … (1 to 100000). With more than
    /// one seed, each seed starts from its own random pose over the scene's reachable floor (the
    /// same pose for every planner, so runs pair up); see --scene-spawn.
    #[arg(long, default_value_t = 3)]
    seeds: u64,
    /// Start every run at the scene's own spawn, even with several seeds (then seeds vary only the
    /// planners' own random draws).
    #[arg(long)]
    scene_spawn: bool,
    #[command(flatten)]
    config: ConfigArgs,
    #[command(flatten)]
    profile: ProfileArg,
    /// Runs in parallel on one thread pool (default: the number of cores; at most 1024).
    #[arg(long)]
    jobs: Option<usize>,
    /// Output folder.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Write each run's MCAP log into DIR/logs/.
    #[arg(long)]
    log_runs: bool,
    /// Skip runs whose results are already in DIR/results.jsonl.
    #[arg(long)]
    resume: bool,
    /// Replace what an `--out` folder holds (results of another batch, or files of the same names).
    #[arg(long, conflicts_with = "resume")]
    force: bool,
    /// Run only the deterministic slice K of N (1-based), e.g. `--shard 2/8`.
    #[arg(long, value_name = "K/N")]
    shard: Option<String>,
    /// Planner that r_ε is relative to (default thp, else the first planner present).
    #[arg(long, value_enum)]
    reference: Option<PlannerKind>,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

/// Progress bar: done / failed / total and an ETA.
struct Bar {
    bar: ProgressBar,
    failed: AtomicUsize,
}

impl bench::Progress for Bar {
    fn start(&self, total: usize, skipped: usize) {
        self.bar.set_length(total as u64);
        self.bar.set_position(skipped as u64);
        // The ETA counts only the runs done in this process.
        self.bar.reset_eta();
    }

    fn finished(&self, row: &BenchRow) {
        if row.status == RunStatus::Failed {
            self.failed.fetch_add(1, Ordering::Relaxed);
        }
        self.bar
            .set_message(format!("{} failed", self.failed.load(Ordering::Relaxed)));
        self.bar.inc(1);
    }
}

pub fn run(args: BenchArgs) -> Result<()> {
    match args.merge {
        Some(BenchCommand::Merge(m)) => {
            check_out(&m.out, m.force, false)?;
            let (failed, notes) = bench::merge(&m.dirs, &m.out, m.reference, m.keep_first)?;
            for line in &notes {
                note!("{line}");
            }
            note!(
                "merged {} folders into {} ({failed} failed runs)",
                m.dirs.len(),
                m.out.display()
            );
            Ok(())
        }
        None => run_batch(args.run),
    }
}

fn run_batch(a: RunArgs) -> Result<()> {
    let out = a
        .out
        .ok_or_else(|| Error::usage("bench: --out DIR is required"))?;
    if a.scenes.is_empty() {
        return Err(Error::usage("bench: --scenes is required").into());
    }
    if !(1..=MAX_SEEDS).contains(&a.seeds) {
        return Err(Error::usage(format!("--seeds {}: expected 1 to {MAX_SEEDS}", a.seeds)).into());
    }
    let shard = a.shard.as_deref().map(str::parse::<Shard>).transpose()?;
    let jobs = match a.jobs {
        Some(j) if !(1..=MAX_JOBS).contains(&j) => {
            return Err(Error::usage(format!("--jobs {j}: expected 1 to {MAX_JOBS}")).into())
        }
        Some(j) => j,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    check_out(&out, a.force, a.resume)?;
    let mut config = a.config.load_with(&a.profile)?;
    bench::apply_spawn_rule(&mut config, a.seeds, a.scene_spawn);
    let spec = BenchSpec {
        scenes: bench::collect_scenes(&a.scenes)?,
        planners: a.planners,
        seeds: a.seeds,
        config,
        jobs,
        out,
        resume: a.resume,
        shard,
        reference: a.reference,
        log_runs: a.log_runs,
        cache: ObservableCache::user(),
    };
    let runs = spec.scenes.len() as u64 * spec.planners.len() as u64 * spec.seeds;
    if runs > MAX_RUNS as u64 {
        return Err(Error::usage(format!(
            "the batch has {runs} runs, more than {MAX_RUNS}; use fewer --seeds, scenes or planners"
        ))
        .into());
    }
    let total = bench::plan_runs(&spec).len();
    let show = !a.quiet && std::io::stderr().is_terminal();
    let bar = Bar {
        bar: if show {
            ProgressBar::new(total as u64)
        } else {
            ProgressBar::hidden()
        },
        failed: AtomicUsize::new(0),
    };
    bar.bar.set_style(
        ProgressStyle::with_template(
            "[{elapsed_precise}] {bar:30} {pos}/{len} runs, {msg}, ETA {eta}",
        )
        .expect("valid template"),
    );
    bar.bar.set_message("0 failed");
    if a.force {
        // Replace: the earlier rows go, so the batch starts afresh.
        let jsonl = spec.out.join(bench::RESULTS_JSONL);
        if jsonl.exists() {
            std::fs::remove_file(&jsonl).map_err(|e| Error::io(&jsonl, e))?;
        }
    }
    let report = bench::run_batch(&spec, &bar)?;
    bar.bar.finish_and_clear();
    for line in &report.notes {
        note!("{line}");
    }
    note!(
        "{} runs ({} skipped as already done, {} run now), {} failed; results in {}",
        report.total,
        report.skipped,
        report.ran,
        report.failed,
        spec.out.display()
    );
    Ok(())
}
