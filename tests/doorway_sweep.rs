//! The doorway sweep: two rooms joined by one door (`scene::doorway`), its width swept across the
//! robot's inflated diameter, its jambs at every quarter-cell offset, for each kind of door, and
//! GREEDY, THP and NBV-TSP run on each. For every run either the ground truth says the far room is
//! reachable and the robot drives into it, or it says not and the run ends `complete`; no run ends
//! `complete` with frontiers left, and none collides. Heavy tier (see TESTING.md).

mod common;

use rayon::prelude::*;
use tensorscout::plan::PlannerKind;
use tensorscout::scene::doorway::{doorway, DoorKind};
use tensorscout::sim::{run, Termination, World};
use tensorscout::Config;

/// Door widths in centimetres: every centimetre from 60 to 80 for the thin wall, every other one
/// for the other kinds.
fn widths(kind: DoorKind) -> impl Iterator<Item = u32> {
    let step = if kind == DoorKind::Thin { 1 } else { 2 };
    (60..=80).step_by(step)
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn every_planner_passes_a_passable_door_and_ends_rightly_before_another() {
    let cfg = Config::default();
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("doorway-sweep");
    std::fs::create_dir_all(&dir).unwrap();
    let mut cases = Vec::new();
    for kind in DoorKind::ALL {
        for width in widths(kind) {
            for offset in [0.0, 0.025, 0.05, 0.075] {
                for planner in [PlannerKind::Greedy, PlannerKind::Thp, PlannerKind::Nbv] {
                    cases.push((kind, width, offset, planner));
                }
            }
        }
    }
    let outcomes: Vec<(bool, Option<String>)> = cases
        .par_iter()
        .map(|&(kind, width, offset, planner)| {
            let d = doorway(kind, width as f64 / 100.0, offset);
            let name = format!("{}_{width}_{}", kind.name(), (offset * 1000.0) as u32);
            let path = dir.join(format!("{name}.obj"));
            let s = d.spawn;
            let spawn = format!("{} {} {}", s.x, s.y, s.yaw);
            std::fs::write(&path, common::obj_text(&d.mesh, Some(&spawn))).unwrap();
            let scene = tensorscout::scene::load(&path, &cfg.scene).unwrap();
            let world = World::with_cache(&scene, &cfg, None, &common::cache()).unwrap();
            let out = run(&scene, world, &cfg, planner, &mut tensorscout::sim::NoObserver).unwrap();
            let r = &out.result;
            let grid = out.ground_truth.grid;
            let far = grid.index(grid.cell_of(d.far_room).unwrap());
            let passable = out.ground_truth.reachable(far);
            let entered = out.trajectory.iter().any(|p| p.x > d.far_room_x0 + 0.3);
            let left = r.frontiers_left.unwrap_or(0);
            let what = format!(
                "{name} {}: passable {passable}, entered {entered}, {:?} with {left} frontier cells left, {} collisions, completeness {:.3}",
                planner.name(),
                r.termination,
                r.collisions,
                r.completeness
            );
            let right = r.collisions == 0
                && !(r.termination == Termination::Complete && left > 0)
                && if passable {
                    entered
                } else {
                    r.termination == Termination::Complete
                };
            (passable, (!right).then_some(what))
        })
        .collect();
    let passable = outcomes.iter().filter(|(p, _)| *p).count();
    eprintln!(
        "doorway sweep: {} runs, {passable} through a door the ground truth passes",
        cases.len()
    );
    let failures: Vec<String> = outcomes.into_iter().filter_map(|(_, f)| f).collect();
    assert!(
        failures.is_empty(),
        "{} of {} runs went wrong:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
