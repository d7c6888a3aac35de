//! TSP solvers on random Euclidean instances (uniform points in a 10 m square, fixed start 0):
//! the heuristic on 30 nodes (target ≤ 1 ms), Held–Karp on 12 nodes, the GA (NBV-TSP defaults) on
//! 30 nodes.
//!
//! `cargo bench --bench tsp`

use criterion::{criterion_group, criterion_main, Criterion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;
use tensorscout::plan::tsp::{self, CostMatrix, GaParams};
use tensorscout::Config;

fn euclidean(n: usize, seed: u64) -> CostMatrix {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let pts: Vec<(f64, f64)> = (0..n)
        .map(|_| (rng.random_range(0.0..10.0), rng.random_range(0.0..10.0)))
        .collect();
    CostMatrix::from_fn(n, |i, j| {
        ((pts[i].0 - pts[j].0).powi(2) + (pts[i].1 - pts[j].1).powi(2)).sqrt()
    })
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("tsp");
    let m30 = euclidean(30, 1);
    g.bench_function("heuristic_30", |b| {
        b.iter(|| tsp::heuristic(black_box(&m30), 0))
    });
    let m12 = euclidean(12, 2);
    g.bench_function("held_karp_12", |b| {
        b.iter(|| tsp::held_karp(black_box(&m12), 0))
    });
    let nbv = Config::default().nbv;
    let p = GaParams {
        population: nbv.ga_population,
        group_size: nbv.ga_group_size,
        generations: nbv.ga_generations,
        stall_generations: nbv.ga_stall_generations,
    };
    g.sample_size(20);
    g.bench_function("genetic_30", |b| {
        b.iter(|| tsp::genetic(black_box(&m30), 0, &p, &mut ChaCha8Rng::seed_from_u64(3)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
