//! The THP planning stage (grouping + TSP + A* + path constraints, plus the advected pathline it
//! answers with) on the largest shipped scene, one planning step at a time.
//!
//! A THP run of `office_large` with the default config is recorded first: at every
//! `SAMPLE_EVERY`-th planning step the planner's state and the map are saved. Criterion then times
//! `Thp::plan` from each saved state (on a fresh clone, so every iteration does the same work). At
//! the end the bench prints p50 and p95 over the sampled steps of Criterion's per-step medians,
//! for all sampled steps and for the steps that solved a TSP.
use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;
use tensorscout::map::Map;
use tensorscout::plan::search::Search;
use tensorscout::plan::thp::{Thp, ThpParams};
use tensorscout::plan::{Action, FieldPlanner, Plan, PlanContext, PlanParams, Planner};
use tensorscout::sim::{self, Simulation, World};
use tensorscout::{scene, Config, Pose2, Result};

/// Every this many planning steps of the recorded run, one is saved and timed.
const SAMPLE_EVERY: usize = 4;
const GROUP: &str = "thp_plan_office_large";

/// One saved planning step.
struct Snapshot {
    step: usize,
    thp: Thp,
    map: Map,
    pose: Pose2,
    time_s: f64,
}

/// A THP planner that saves its state and the map before every `SAMPLE_EVERY`-th plan.
struct Recorder {
    thp: Thp,
    plans: usize,
    saved: Vec<Snapshot>,
}

impl Planner for Recorder {
    fn name(&self) -> &'static str {
        self.thp.name()
    }
    fn plan(&mut self, ctx: &mut PlanContext) -> Result<Plan> {
        if self.plans.is_multiple_of(SAMPLE_EVERY) {
            self.saved.push(Snapshot {
                step: self.plans,
                thp: self.thp.clone(),
                map: ctx.map.clone(),
                pose: ctx.pose,
                time_s: ctx.time_s,
            });
        }
        self.plans += 1;
        self.thp.plan(ctx)
    }
    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool {
        self.thp.is_outdated(ctx, action)
    }
    fn action_finished(&mut self, ctx: &PlanContext, reached: bool) {
        self.thp.action_finished(ctx, reached)
    }
    fn field_planner(&mut self) -> Option<&mut dyn FieldPlanner> {
        self.thp.field_planner()
    }
    fn stats(&self) -> BTreeMap<String, f64> {
        self.thp.stats()
    }
}

/// Runs one planning step from a saved state; returns whether it solved a TSP.
fn replay(cfg: &Config, snap: &Snapshot, thp: &mut Thp, search: &mut Search) -> bool {
    let mut ctx = PlanContext {
        map: &snap.map,
        pose: snap.pose,
        time_s: snap.time_s,
        cfg: &PlanParams::from(cfg),
        search,
    };
    let plan = thp.plan(&mut ctx).expect("a saved step plans again");
    plan.report.tsp_ms.is_some()
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    let k = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted[k.min(sorted.len() - 1)]
}

/// Criterion's median for one benchmark of the group, in ms, from its saved estimates.
fn criterion_median_ms(id: &str) -> Option<f64> {
    let root = std::env::var("CARGO_TARGET_DIR").unwrap_or_else(|_| "target".into());
    let path = Path::new(&root)
        .join("criterion")
        .join(GROUP)
        .join(id)
        .join("new/estimates.json");
    let text = std::fs::read_to_string(path).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    Some(v["median"]["point_estimate"].as_f64()? / 1e6)
}

fn thp_plan(c: &mut Criterion) {
    let cfg = Config::default();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/office_large.obj");
    let scene = scene::load(&path, &cfg.scene).unwrap();
    let world = World::with_cache(&scene, &cfg, None, &bench_cache()).unwrap();
    let mut recorder = Recorder {
        thp: Thp::new(&ThpParams::from(&cfg)),
        plans: 0,
        saved: Vec::new(),
    };
    let out = Simulation::with_planner(&scene, world, &cfg, Box::new(&mut recorder))
        .run_to_end(&mut sim::NoObserver);
    eprintln!(
        "recorded run: {:?}, completeness {:.3}, {} planning steps, {} saved",
        out.result.termination,
        out.result.completeness,
        recorder.plans,
        recorder.saved.len()
    );
    let grid = *out.map.grid();
    let mut search = Search::new(&grid);
    let mut g = c.benchmark_group(GROUP);
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(300));
    g.measurement_time(Duration::from_secs(1));
    let mut solves_tsp = Vec::new();
    for snap in &recorder.saved {
        solves_tsp.push(replay(&cfg, snap, &mut snap.thp.clone(), &mut search));
        g.bench_function(format!("step_{:04}", snap.step), |b| {
            b.iter_batched(
                || snap.thp.clone(),
                // The planner is returned, so Criterion drops it outside the timing.
                |mut thp| {
                    replay(&cfg, snap, &mut thp, &mut search);
                    thp
                },
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();

    let mut all = Vec::new();
    let mut tsp = Vec::new();
    for (snap, solved) in recorder.saved.iter().zip(&solves_tsp) {
        let Some(ms) = criterion_median_ms(&format!("step_{:04}", snap.step)) else {
            continue;
        };
        all.push(ms);
        if *solved {
            tsp.push(ms);
        }
    }
    for (label, v) in [
        ("all sampled steps", &mut all),
        ("steps that solved a TSP", &mut tsp),
    ] {
        if v.is_empty() {
            continue;
        }
        v.sort_by(f64::total_cmp);
        eprintln!(
            "THP planning step, {label} ({}): p50 {:.3} ms, p95 {:.3} ms, max {:.3} ms",
            v.len(),
            percentile(v, 0.5),
            percentile(v, 0.95),
            v[v.len() - 1]
        );
    }
}

criterion_group!(benches, thp_plan);
criterion_main!(benches);

/// The observable set is computed once and read back from a cache under the build's temporary
/// folder: the bench measures the run, not the ground truth.
fn bench_cache() -> tensorscout::sim::ObservableCache {
    tensorscout::sim::ObservableCache::at(
        std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("tensorscout-cache/observable"),
    )
}
