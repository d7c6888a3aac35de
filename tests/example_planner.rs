//! The example planner (`examples/planner.rs`) builds against the public API and explores a shipped
//! scene: the "how to add a planner" recipe of ARCHITECTURE.md, checked.

#[allow(dead_code)]
#[path = "../examples/planner.rs"]
mod planner;

use std::path::Path;
use tensorscout::sim::Termination;

#[test]
fn the_example_planner_explores_a_shipped_scene() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/apartment_small.obj");
    let out = planner::explore(&path, 300.0).unwrap();
    let r = &out.result;
    assert_eq!(r.planner, "nearest-cell");
    assert_eq!(r.error, None);
    assert!(
        matches!(r.termination, Termination::Complete | Termination::Budget),
        "{:?}",
        r.termination
    );
    assert_eq!(r.collisions, 0);
    // It sees most of the apartment (GREEDY reaches 0.97 here).
    assert!(r.completeness > 0.8, "{}", r.completeness);
    // Same scene, same planner: the same run.
    let again = planner::explore(&path, 300.0).unwrap().result;
    assert_eq!(
        (again.steps, again.path_length_m, again.completeness),
        (r.steps, r.path_length_m, r.completeness)
    );
}
