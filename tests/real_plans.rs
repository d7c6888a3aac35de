//! GREEDY, THP and NBV-TSP on real furnished apartment plans (`scenes/floorplans/`) that each of them
//! once called done with most of the apartment unentered: `plan_2b11efc201`, whose only way out of
//! the start room is a 0.66 m door that the map's inflation closed by a millimetre (GREEDY ended
//! `complete` at 0.116), and `plan_ca76724070`, where the same happened at a 0.6 m door (0.485).
//! Each run must end `complete` with no collision and at least 0.90 of the observable volume seen;
//! a failure lists what the observable region still holds unseen, and where.

mod common;

use std::path::{Path, PathBuf};
use tensorscout::plan::PlannerKind;
use tensorscout::sim::Termination;
use tensorscout::Config;

const PLANS: [&str; 2] = ["plan_2b11efc201", "plan_ca76724070"];

/// The mesh of the real plan `name` in `scenes/floorplans/`.
fn plan(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/floorplans")
        .join(format!("{name}.obj"))
}

/// The default config, starting at the random pose drawn from `seed`.
fn random_start(seed: u64) -> Config {
    let mut cfg = Config {
        seed,
        ..Config::default()
    };
    cfg.sim.spawn = tensorscout::config::SpawnMode::Random;
    cfg
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn frontier_planners_enter_every_room_behind_narrow_doors() {
    let cfg = Config::default();
    let mut failures = Vec::new();
    for name in PLANS {
        let path = plan(name);
        for planner in [PlannerKind::Greedy, PlannerKind::Thp, PlannerKind::Nbv] {
            let r = &common::explore(&path, &cfg, planner);
            if r.termination != Termination::Complete || r.collisions != 0 || r.completeness < 0.90
            {
                let unseen: Vec<String> = r
                    .unseen_observable
                    .iter()
                    .map(|p| {
                        format!(
                            "{:.2} m³ at ({:.1}, {:.1}){}",
                            p.volume_m3,
                            p.x,
                            p.y,
                            if p.over_reachable_floor {
                                " over reachable floor"
                            } else {
                                ""
                            }
                        )
                    })
                    .collect();
                failures.push(format!(
                    "{name} {}: {} completeness {:.3} collisions {}; unseen: {}",
                    planner.name(),
                    r.termination.as_str(),
                    r.completeness,
                    r.collisions,
                    unseen.join(", ")
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Random starts (by seed) on real plans where GREEDY once ended `complete` with an observable
/// frontier left: a second approach that the motion guard stopped short beside never-seen floor
/// counted as a failed attempt, and two of them gave the frontier up. GREEDY must now end `complete`
/// with no reachable frontier that borders unseen observable space (`frontiers_left` 0).
const LEFT_FRONTIERS_BEFORE: [(&str, u64); 3] = [
    ("plan_8d536c12be", 1),
    ("plan_7851b31025", 2),
    ("plan_25b5cec7e3", 2),
];

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn greedy_leaves_no_observable_frontier_where_the_guard_stopped_it_short() {
    let mut failures = Vec::new();
    for (name, seed) in LEFT_FRONTIERS_BEFORE {
        let r = common::explore(&plan(name), &random_start(seed), PlannerKind::Greedy);
        if r.termination != Termination::Complete || r.frontiers_left != Some(0) {
            let groups: Vec<String> = r
                .frontier_groups_left
                .iter()
                .map(|g| format!("{} cells at ({:.2}, {:.2})", g.cells, g.x, g.y))
                .collect();
            failures.push(format!(
                "{name} seed {seed}: {} with {:?} frontier cells left: {}",
                r.termination.as_str(),
                r.frontiers_left,
                groups.join(", ")
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The random start (seed 2) of `plan_6ede154d56` where THP ended `stuck`: the robot stopped in a
/// 0.557 m gap at exactly the guard's clearance from one side, and the back-off, turning onto its
/// heading while moving, lost a fraction of a millimetre on every step and was refused every step.
/// THP must end `complete` there, with no collision.
#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn thp_leaves_the_gap_it_once_stayed_stuck_in() {
    let r = common::explore(&plan("plan_6ede154d56"), &random_start(2), PlannerKind::Thp);
    assert_eq!(
        (r.termination, r.collisions),
        (Termination::Complete, 0),
        "ended {} at {:.3} after {:.1} m",
        r.termination.as_str(),
        r.completeness,
        r.path_length_m
    );
}
