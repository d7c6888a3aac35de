//! Whole GREEDY explorations of the largest shipped scene: simulated steps per second. With the
//! default `dt` of 0.1 s, the real-time factor is the reported element rate divided by 10.
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::path::Path;
use std::time::Duration;
use tensorscout::plan::PlannerKind;
use tensorscout::sim::{self, World};
use tensorscout::{scene, Config};

fn explore(c: &mut Criterion) {
    let cfg = Config::default();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/office_large.obj");
    let scene = scene::load(&path, &cfg.scene).unwrap();
    let run = || {
        let world = World::with_cache(&scene, &cfg, None, &bench_cache()).unwrap();
        sim::run(
            &scene,
            world,
            &cfg,
            PlannerKind::Greedy,
            &mut sim::NoObserver,
        )
        .unwrap()
    };
    // The run is deterministic: measure its length once for the throughput.
    let steps = run().result.steps;
    let mut g = c.benchmark_group("explore_office_large");
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(60));
    g.throughput(Throughput::Elements(steps));
    g.bench_function("greedy", |b| b.iter(run));
    g.finish();
}

criterion_group!(benches, explore);
criterion_main!(benches);

/// The observable set is computed once and read back from a cache under the build's temporary
/// folder: the bench measures the run, not the ground truth.
fn bench_cache() -> tensorscout::sim::ObservableCache {
    tensorscout::sim::ObservableCache::at(
        std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("tensorscout-cache/observable"),
    )
}
