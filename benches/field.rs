//! Tensor field speed on a synthetic 20 × 20 m office at 0.1 m (see `src/field/synth.rs`):
//! incremental key-frame update, full recompute against the brute-force reference, degenerate points
//! plus topology, and the time-varying window solve; with one and two rayon threads.
//!
//! `cargo bench --bench field` (prints the p50 of a simulated run's key-frame updates to stderr).

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use nalgebra::Point2;
use std::hint::black_box;
use tensorscout::config::Config;
use tensorscout::field::{eval, synth, MaskInputs, SpaceTimeParams, TensorField};

/// The robot's key-frame positions along the office's corridors and into rooms.
fn route() -> Vec<Point2<f64>> {
    let mut r = Vec::new();
    for k in 0..=18 {
        r.push(Point2::new(1.0 + k as f64, 10.0));
    }
    for k in 0..=8 {
        r.push(Point2::new(10.0, 11.0 + k as f64));
    }
    for k in 0..=8 {
        r.push(Point2::new(10.0, 9.0 - k as f64));
    }
    r
}

/// Surface revealed after each key frame (everything within 5 m of the route so far).
fn reveals(layout: &synth::Layout) -> Vec<Vec<bool>> {
    let route = route();
    (1..=route.len())
        .map(|k| synth::reveal(layout, &route[..k], 5.0))
        .collect()
}

fn bench(c: &mut Criterion) {
    let cfg = Config::default().field;
    let layout = synth::office(0.1);
    let frames = reveals(&layout);
    let grid = layout.grid;
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
            for s in &frames {
                states.push(field.clone());
                let inputs = MaskInputs::new(&grid, s, s, None).unwrap();
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
                    let inputs = MaskInputs::new(&grid, &frames[k], &frames[k], None).unwrap();
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
                    Point2::new(10.0, 10.0),
                    cfg.timevary_radius_m,
                    &params,
                ))
            })
        });
        g.finish();
    }
    // Full recompute against the brute-force reference (single-threaded by construction), on the
    // same constraints (the whole office), in the same run.
    let (mut full, _) =
        tensorscout::field::field_report(&grid, &layout.surface, &layout.surface, &cfg).unwrap();
    let constraints = full.constraints();
    let kernel = eval::Kernel::new(cfg.sigma_m, cfg.decay, cfg.weight_cutoff);
    let cmp = tensorscout::field::max_orientation_difference_vs_reference(&mut full);
    eprintln!(
        "whole office: {} constraints, {} points; fast vs reference max orientation difference {:.2e} rad",
        constraints.len(),
        full.points().len(),
        cmp.max_orientation_difference_rad
    );
    let mut g = c.benchmark_group("field_full_office");
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
