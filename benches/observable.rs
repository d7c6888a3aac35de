//! The observable set of a scene (`eval::observable`): the ground truth's ray sampling over the
//! reachable region, for a small and the largest shipped scene and a real plan whose views through
//! narrow gaps are sampled again finer, without the disk cache.
use criterion::{criterion_group, criterion_main, Criterion};
use std::path::Path;
use std::time::Duration;
use tensorscout::eval::GroundTruth;
use tensorscout::eval::{ObservableParams, ObservableSet};
use tensorscout::scene;
use tensorscout::sensor::{DepthCamera, MeshBvh};
use tensorscout::Config;

fn observable(c: &mut Criterion) {
    let cfg = Config::default();
    let mut g = c.benchmark_group("observable_set");
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(30));
    for name in [
        "apartment_small",
        "office_large",
        "floorplans/plan_7fdb16a896",
    ] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.obj"));
        let scene = scene::load(&path, &cfg.scene).unwrap();
        let gt = GroundTruth::build(&scene.mesh, scene.spawn, &cfg).unwrap();
        let bvh = MeshBvh::new(&scene.mesh).unwrap();
        let camera = DepthCamera::new(&cfg.camera);
        let params = ObservableParams::from_config(&cfg.metrics);
        g.bench_function(name, |b| {
            b.iter(|| ObservableSet::compute(&gt, &bvh, &camera, &params))
        });
    }
    g.finish();
}

criterion_group!(benches, observable);
criterion_main!(benches);
