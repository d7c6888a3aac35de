//! The `published` profile runs each frontier planner without the rules no paper has: the planner
//! statistics of every addition are zero (or absent, which `planner_stats` means by zero), the
//! result names its profile, and the run is still safe (no collision). The command line takes
//! `--profile` and prints the profile's config.

mod common;

use std::path::Path;
use std::process::Command;
use tensorscout::config::Profile;
use tensorscout::plan::PlannerKind;
use tensorscout::Config;

fn stat(r: &tensorscout::sim::RunResult, key: &str) -> f64 {
    r.planner_stats.get(key).copied().unwrap_or(0.0)
}

/// The counters of the additions GREEDY and THP share.
const SHARED: [&str; 7] = [
    "viewpoint_looks",
    "reopened",
    "volume_views",
    "distant_views",
    "path_m_blind_zone",
    "path_m_distant_view",
    "path_m_volume_view",
];

/// The counters of the additions, per planner: what the published profile must leave at zero.
fn addition_stats(planner: PlannerKind) -> Vec<&'static str> {
    match planner {
        PlannerKind::Greedy => SHARED.to_vec(),
        PlannerKind::Thp => [
            &SHARED[..],
            &[
                "path_m_escape",
                "escapes",
                "looks_when_blocked",
                "advection_stalls",
            ],
        ]
        .concat(),
        PlannerKind::Nbv => vec![
            "viewpoint_looks",
            "reopened",
            "distant_views",
            "anchor_tries",
        ],
        PlannerKind::Tensor => Vec::new(),
    }
}

#[test]
fn published_frontier_planners_use_no_addition() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/apartment_small.obj");
    let published = Config::of_profile(Profile::Published);
    for planner in [PlannerKind::Greedy, PlannerKind::Thp, PlannerKind::Nbv] {
        let r = common::explore(&scene, &published, planner);
        assert_eq!(r.profile, "published");
        assert_eq!(r.collisions, 0, "{}", planner.name());
        for key in addition_stats(planner) {
            assert_eq!(
                stat(&r, key),
                0.0,
                "{} {key}: {:?}",
                planner.name(),
                r.planner_stats
            );
        }
    }
    // The default profile does use them on the same scene (else the test above proves nothing).
    let r = common::explore(&scene, &Config::default(), PlannerKind::Greedy);
    assert_eq!(r.profile, "tensorscout");
    let used: f64 = addition_stats(PlannerKind::Greedy)
        .iter()
        .map(|k| stat(&r, k))
        .sum();
    assert!(used > 0.0, "{:?}", r.planner_stats);
}

fn tensorscout(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tensorscout"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn config_default_prints_each_profile() {
    let default = tensorscout(&["config", "default"]);
    assert!(default.status.success());
    let text = String::from_utf8(default.stdout).unwrap();
    assert_eq!(text, tensorscout::config::DEFAULT_TOML);
    let published = tensorscout(&["config", "default", "--profile", "published"]);
    assert!(published.status.success());
    let text = String::from_utf8(published.stdout).unwrap();
    assert!(text.contains("profile = \"published\"\n"));
    assert!(text.contains("\nvolume_views = false\n"));
    assert!(text.contains("\nreopen_max = 0\n"));
    // Every comment is kept: the two differ only in values.
    assert_eq!(
        text.lines().count(),
        tensorscout::config::DEFAULT_TOML.lines().count()
    );
    let bad = tensorscout(&["config", "default", "--profile", "paper"]);
    assert_eq!(bad.status.code(), Some(2));
    let err = String::from_utf8(bad.stderr).unwrap();
    assert!(err.contains("paper") && err.contains("published"), "{err}");
}

#[test]
fn explore_names_its_profile_in_the_result() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/apartment_small.obj");
    let out = tensorscout(&[
        "explore",
        "--scene",
        scene.to_str().unwrap(),
        "--planner",
        "greedy",
        "--profile",
        "published",
        "--set",
        "sim.budget_s=5",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["profile"], "published");
    assert_eq!(v["planner"], "greedy");
}
