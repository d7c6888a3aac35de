//! Whole runs give the same results with one and two threads (rendering, integration, the field and
//! the planners' parallel loops included): everything but the wall-clock fields.

use std::path::Path;
use tensorscout::config::{Config, DepthRenderer};
use tensorscout::plan::PlannerKind;
use tensorscout::sim::{run, NoObserver, World};

fn result_json(
    scene: &str,
    planner: PlannerKind,
    renderer: DepthRenderer,
    threads: usize,
) -> serde_json::Value {
    let mut cfg = Config::default();
    cfg.camera.renderer = renderer;
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(scene);
    let scene = tensorscout::scene::load(&path, &cfg.scene).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let out = pool.install(|| {
        let world = World::new(&scene, &cfg, None).unwrap();
        run(&scene, world, &cfg, planner, &mut NoObserver).unwrap()
    });
    let mut v = serde_json::to_value(&out.result).unwrap();
    let o = v.as_object_mut().unwrap();
    for k in ["wall_time_s", "real_time_factor", "timings_ms"] {
        o.remove(k);
    }
    v
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn thp_and_greedy_runs_do_not_depend_on_the_thread_count() {
    for (planner, renderer) in [
        (PlannerKind::Thp, DepthRenderer::Raster),
        (PlannerKind::Greedy, DepthRenderer::Raster),
        (PlannerKind::Thp, DepthRenderer::Raycast),
    ] {
        let one = result_json("apartment_small.obj", planner, renderer, 1);
        assert!(one["steps"].as_u64().unwrap() > 100);
        assert_eq!(
            one,
            result_json("apartment_small.obj", planner, renderer, 2),
            "{planner:?} {renderer:?}"
        );
    }
}
