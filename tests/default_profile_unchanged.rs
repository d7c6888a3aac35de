//! The default profile's results are stored: every planner on every shipped scene (its own start)
//! and on the sample of real plans (two random starts each) must give the same result as recorded in
//! `tests/data/default_profile_results.tsv`, compared as a hash of the result without its wall-clock
//! fields. A change to any planner, rule, map or metric that moves a default result fails here, so
//! that it is made on purpose: re-record with `TENSORSCOUT_BLESS=1 cargo test --test
//! default_profile_unchanged -- --ignored` and say in the commit why the results moved.
//!
//! Left out of the hash: `wall_time_s`, `real_time_factor` and `timings_ms` (wall clock), `version`
//! and `config_hash` (they name the build and the config's text, not what the run did) and
//! `profile` (always the default here). `planner_stats` keys listed in [`STATS_ADDED`] are left out
//! too: counters added after the results were recorded, which a run under the default profile may
//! report without having done anything differently. Heavy tier (see TESTING.md).

mod common;

use rayon::prelude::*;
use std::path::{Path, PathBuf};
use tensorscout::config::SpawnMode;
use tensorscout::plan::PlannerKind;
use tensorscout::Config;

/// Counters added to `planner_stats` since the results were recorded.
const STATS_ADDED: &[&str] = &["viewpoint_looks", "reopened"];

/// The stored hashes, one line per run: planner, scene file name, start, hash.
fn results_file() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/default_profile_results.tsv")
}

/// One run of the table: a scene, a start ("scene" or the seed of a random start) and a planner.
struct Case {
    scene: PathBuf,
    start: Option<u64>,
    planner: PlannerKind,
}

impl Case {
    fn key(&self) -> String {
        let start = self
            .start
            .map_or("scene".to_string(), |s| format!("random{s}"));
        let name = self.scene.file_name().unwrap().to_string_lossy();
        format!("{}\t{name}\t{start}", self.planner.name())
    }

    /// The hash of the run's result without the fields the module doc names.
    fn run(&self) -> String {
        let mut cfg = Config::default();
        if let Some(seed) = self.start {
            cfg.seed = seed;
            cfg.sim.spawn = SpawnMode::Random;
        }
        let result = common::explore(&self.scene, &cfg, self.planner);
        let mut value = serde_json::to_value(&result).unwrap();
        let object = value.as_object_mut().unwrap();
        for key in [
            "wall_time_s",
            "real_time_factor",
            "timings_ms",
            "version",
            "config_hash",
            "profile",
        ] {
            object.remove(key);
        }
        if let Some(stats) = object
            .get_mut("planner_stats")
            .and_then(|s| s.as_object_mut())
        {
            for key in STATS_ADDED {
                stats.remove(*key);
            }
        }
        let text = serde_json::to_string(&value).unwrap();
        format!("{:016x}", tensorscout::util::fnv1a64(text.as_bytes()))
    }
}

fn cases() -> Vec<Case> {
    let planners = [
        PlannerKind::Thp,
        PlannerKind::Tensor,
        PlannerKind::Nbv,
        PlannerKind::Greedy,
    ];
    let mut cases = Vec::new();
    for planner in planners {
        for scene in common::shipped_scenes() {
            cases.push(Case {
                scene,
                start: None,
                planner,
            });
        }
        for scene in common::sample_plans() {
            for seed in [1, 2] {
                cases.push(Case {
                    scene: scene.clone(),
                    start: Some(seed),
                    planner,
                });
            }
        }
    }
    cases
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn default_profile_gives_the_recorded_results() {
    let cases = cases();
    let got: Vec<(String, String)> = cases.par_iter().map(|c| (c.key(), c.run())).collect();
    let text: String = got.iter().map(|(k, h)| format!("{k}\t{h}\n")).collect();
    if std::env::var_os("TENSORSCOUT_BLESS").is_some() {
        std::fs::write(results_file(), text).unwrap();
        return;
    }
    let stored = std::fs::read_to_string(results_file()).unwrap();
    let stored: std::collections::BTreeMap<&str, &str> =
        stored.lines().filter_map(|l| l.rsplit_once('\t')).collect();
    let mut changed = Vec::new();
    for (key, hash) in &got {
        match stored.get(key.as_str()) {
            Some(h) if h == hash => {}
            Some(h) => changed.push(format!("{key}: recorded {h}, now {hash}")),
            None => changed.push(format!("{key}: not recorded")),
        }
    }
    assert_eq!(stored.len(), got.len(), "the table has other runs");
    assert!(
        changed.is_empty(),
        "{} of {} default results changed:\n{}",
        changed.len(),
        got.len(),
        changed.join("\n")
    );
}
