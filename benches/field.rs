//! Tensor field speed at 0.1 m on the largest shipped scene (`scenes/office_large.obj`): incremental
//! key-frame updates on the map layers of a real GREEDY run (one key frame every 4 s of simulated
//! time), a full recompute against the brute-force reference on the fully observed scene, degenerate
//! points plus topology, and the time-varying window solve; with one and two rayon threads.
//!
//! `cargo bench --bench field` (prints the p50 of the run's key-frame updates to stderr).

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use std::hint::black_box;
use std::path::Path;
use tensorscout::config::Config;
use tensorscout::eval::GroundTruth;
use tensorscout::field::{eval, MaskInputs, SpaceTimeParams, TensorField};
use tensorscout::plan::PlannerKind;
use tensorscout::scene;
use tensorscout::sim::{self, Observer, StepView, World};
use tensorscout::GridSpec;

/// The map's surface and obstacle layers at every key frame of a GREEDY run.
struct KeyFrames {
    every_steps: u64,
    surface: Vec<Vec<bool>>,
    obstacle: Vec<Vec<bool>>,
}

impl Observer for KeyFrames {
    fn on_step(&mut self, view: &StepView) {
        if view.step.is_multiple_of(self.every_steps) {
            self.surface.push(view.map.surface_cells().to_vec());
            let grid = view.map.grid();
            self.obstacle
                .push((0..grid.cells()).map(|i| view.map.is_obstacle(i)).collect());
        }
    }
}

/// The shipped scene's grid, its fully observed surface and obstacle layers, and a run's key frames.
fn office_large(cfg: &Config) -> (GridSpec, Vec<bool>, Vec<bool>, KeyFrames) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/office_large.obj");
    let scene = scene::load(&path, &cfg.scene).unwrap();
    let gt = GroundTruth::build(&scene.mesh, scene.spawn, cfg).unwrap();
    let mut frames = KeyFrames {
        every_steps: (cfg.field.keyframe_period_s / cfg.sim.dt_s).round() as u64,
        surface: Vec::new(),
        obstacle: Vec::new(),
    };
    let world = World::with_cache(&scene, cfg, None, &bench_cache()).unwrap();
    sim::run(&scene, world, cfg, PlannerKind::Greedy, &mut frames).unwrap();
    (
        gt.grid,
        gt.surface_columns(),
        gt.obstacle_columns().to_vec(),
        frames,
    )
}

fn bench(c: &mut Criterion) {
    let full_cfg = Config::default();
    let cfg = full_cfg.field.clone();
    let (grid, full_surface, full_obstacle, keyframes) = office_large(&full_cfg);
    let frames = &keyframes.surface;
    let obstacles = &keyframes.obstacle;
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        // A whole simulated run, timed per key frame (p50 printed, not asserted).
        let (field, states) = pool.install(|| {
            let mut field = TensorField::new(grid, &cfg);
            let mut states = Vec::new();
            let mut times = Vec::new();
            let mut topo_times = Vec::new();
            for (s, o) in frames.iter().zip(obstacles) {
                states.push(field.clone());
                let inputs = MaskInputs::new(&grid, s, o, None).unwrap();
                let t = std::time::Instant::now();
                field.update_field(&inputs).unwrap();
                times.push(t.elapsed().as_secs_f64() * 1e3);
                let t = std::time::Instant::now();
                field.compute_topology();
                topo_times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            let p = |v: &mut Vec<f64>, q: usize| {
                v.sort_by(f64::total_cmp);
                v[(v.len() * q / 100).min(v.len() - 1)]
            };
            eprintln!(
                "threads {threads}: {} key frames; field update p50 {:.2} ms, p95 {:.2} ms, max {:.2} ms; \
                 topology p50 {:.2} ms, max {:.2} ms; {} constraints, {} points",
                times.len(),
                p(&mut times, 50),
                p(&mut times, 95),
                p(&mut times, 100),
                p(&mut topo_times, 50),
                p(&mut topo_times, 100),
                field.surface_constraint_count(),
                field.points().len()
            );
            (field, states)
        });
        let mut g = c.benchmark_group(format!("field_t{threads}"));
        g.sample_size(20);
        let mut k = 0usize;
        g.bench_function("incremental_keyframe", |b| {
            b.iter_batched(
                || {
                    k = (k + 1) % frames.len();
                    (states[k].clone(), k)
                },
                |(mut f, k)| {
                    let inputs = MaskInputs::new(&grid, &frames[k], &obstacles[k], None).unwrap();
                    pool.install(|| black_box(f.update_field(&inputs).unwrap()))
                },
                BatchSize::LargeInput,
            )
        });
        let mut full = field.clone();
        g.bench_function("full_recompute_planning_field", |b| {
            b.iter(|| pool.install(|| black_box(full.recompute_planning_field())))
        });
        g.bench_function("degenerate_points_and_topology", |b| {
            b.iter(|| {
                pool.install(|| full.compute_topology());
                black_box(full.points().len())
            })
        });
        let before = states[states.len() / 2].field().clone();
        let params = SpaceTimeParams {
            substeps: cfg.substeps,
            omega_s: cfg.omega_s,
            omega_t: cfg.omega_t,
            alpha: cfg.alpha,
            max_iterations: cfg.timevary_max_iterations,
            tolerance: 1e-6,
        };
        g.bench_function("timevary_window", |b| {
            b.iter(|| {
                black_box(tensorscout::field::biharmonic_window(
                    &before,
                    field.field(),
                    grid.center(grid.cell(grid.cells() / 2 + grid.nx / 2)),
                    cfg.timevary_radius_m,
                    &params,
                ))
            })
        });
        g.finish();
    }
    // Full recompute against the brute-force reference (single-threaded by construction), on the
    // same constraints (the fully observed scene), in the same run.
    let (mut full, _) =
        tensorscout::field::full_field(&grid, &full_surface, &full_obstacle, &cfg).unwrap();
    let constraints = full.constraints();
    let kernel = eval::Kernel::new(cfg.sigma_m, cfg.decay, cfg.weight_cutoff);
    let cmp = tensorscout::field::max_orientation_difference_vs_reference(&mut full);
    eprintln!(
        "office_large fully observed: {} constraints, {} points; fast vs reference max orientation difference {:.2e} rad",
        constraints.len(),
        full.points().len(),
        cmp.max_orientation_difference_rad
    );
    let mut g = c.benchmark_group("field_full_office_large");
    g.sample_size(10);
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        g.bench_function(format!("fast_full_recompute_t{threads}"), |b| {
            b.iter(|| pool.install(|| black_box(full.recompute_planning_field())))
        });
        g.bench_function(format!("degenerate_points_and_topology_t{threads}"), |b| {
            b.iter(|| {
                pool.install(|| full.compute_topology());
                black_box(full.points().len())
            })
        });
    }
    g.bench_function("reference_full_grid", |b| {
        b.iter(|| black_box(eval::reference_grid(&constraints, &grid, &kernel)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

/// The observable set is computed once and read back from a cache under the build's temporary
/// folder: the bench measures the run, not the ground truth.
fn bench_cache() -> tensorscout::sim::ObservableCache {
    tensorscout::sim::ObservableCache::at(
        std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("tensorscout-cache/observable"),
    )
}
