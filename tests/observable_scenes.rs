//! The observable set on shipped scenes and real floor plans: the pose sampling has converged
//! (halving the spacing changes the volume by under 1 %), and what GREEDY explores lies inside it
//! (under 1 % outside).

mod common;

use std::path::Path;
use tensorscout::eval::GroundTruth;
use tensorscout::eval::{ObservableParams, ObservableSet};
use tensorscout::plan::PlannerKind;
use tensorscout::scene;
use tensorscout::sensor::{DepthCamera, MeshBvh};
use tensorscout::sim::{self, World};
use tensorscout::Config;

fn scene_path(rel: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(rel)
}

/// The last two are where GREEDY's views through gaps too narrow to pass fell outside the set before
/// the sampling was refined around such views (2.23 % and 1.09 %).
const PLANS: [&str; 5] = [
    "floorplans/plan_84f878cff1.obj",
    "floorplans/plan_88d1cfc9f3.obj",
    "floorplans/plan_807c123f55.obj",
    "floorplans/plan_7fdb16a896.obj",
    "floorplans/plan_f86b9b439a.obj",
];

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn halving_the_spacing_changes_the_volume_by_under_one_percent() {
    let cfg = Config::default();
    let mut report = Vec::new();
    for rel in ["apartment_small.obj", "office_small.obj"]
        .into_iter()
        .chain(PLANS)
    {
        let s = scene::load(&scene_path(rel), &cfg.scene).unwrap();
        let gt = GroundTruth::build(&s.mesh, s.spawn, &cfg).unwrap();
        let bvh = MeshBvh::new(&s.mesh).unwrap();
        let camera = DepthCamera::new(&cfg.camera);
        let volume = |spacing: f64| {
            let mut p = ObservableParams::from_config(&cfg.metrics);
            p.spacing_m = spacing;
            ObservableSet::compute(&gt, &bvh, &camera, &p).volume_m3()
        };
        let (coarse, fine) = (
            volume(cfg.metrics.observable_spacing_m),
            volume(0.5 * cfg.metrics.observable_spacing_m),
        );
        let change = (fine - coarse).abs() / fine;
        report.push(format!(
            "{rel}: {coarse:.2} vs {fine:.2} m³ ({:.2} %)",
            100.0 * change
        ));
        assert!(change < 0.01, "{}", report.join("\n"));
    }
    eprintln!("{}", report.join("\n"));
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn greedy_explores_inside_the_observable_set_on_real_plans() {
    let cfg = Config::default();
    for rel in PLANS {
        let s = scene::load(&scene_path(rel), &cfg.scene).unwrap();
        let world = World::with_cache(&s, &cfg, None, &common::cache()).unwrap();
        let out = sim::run(&s, world, &cfg, PlannerKind::Greedy, &mut sim::NoObserver).unwrap();
        let r = &out.result;
        assert!(
            r.explored_outside_observable_fraction < 0.01 && r.collisions == 0,
            "{rel}: outside {:.4}, collisions {}",
            r.explored_outside_observable_fraction,
            r.collisions
        );
        assert!(r.observable_volume_m3 > 0.0 && r.reachable_area_m2 > 0.0);
    }
}
