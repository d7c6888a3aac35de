//! The tensor field on every shipped scene, fully observed: the fast evaluator agrees with the f64
//! brute-force reference, and the degenerate points are few and clear of walls.

mod common;

use common::shipped_scenes;
use tensorscout::eval::GroundTruth;
use tensorscout::field;
use tensorscout::scene;
use tensorscout::Config;

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn field_on_shipped_scenes_matches_reference_and_has_few_clear_points() {
    let cfg = Config::default();
    for path in shipped_scenes() {
        let scene = scene::load(&path, &cfg.scene).unwrap();
        let gt = GroundTruth::build(&scene.mesh, scene.spawn, &cfg).unwrap();
        let surface = gt.surface_columns();
        let (mut f, _) =
            field::full_field(&gt.grid, &surface, gt.obstacle_columns(), &cfg.field).unwrap();
        let cmp = field::max_orientation_difference_vs_reference(&mut f);
        assert!(
            cmp.max_orientation_difference_rad < 1e-6,
            "{}: fast field differs from the reference by {} rad",
            scene.name,
            cmp.max_orientation_difference_rad
        );
        let area_m2 = gt.region_cells() as f64 * gt.grid.cell_area();
        let points = f.graph().nodes.len();
        assert!(points >= 1, "{}: no degenerate point", scene.name);
        assert!(
            (points as f64) <= area_m2 / 6.0,
            "{}: {points} degenerate points for {area_m2:.0} m²",
            scene.name
        );
        for p in &f.graph().nodes {
            let cell = gt.grid.cell_at(p.x, p.y);
            let idx = gt.grid.checked_index(cell).expect("point inside the grid");
            assert!(
                gt.clearance_m(idx) as f64 >= cfg.robot.radius_m,
                "{}: point {} at ({:.2}, {:.2}) is {:.2} m from a wall",
                scene.name,
                p.id,
                p.x,
                p.y,
                gt.clearance_m(idx)
            );
        }
    }
}
