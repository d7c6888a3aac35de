//! GREEDY explores every shipped scene to the end: complete, nearly all the explorable volume and
//! surface observed, and never a collision. THP, NBV-TSP and TENSOR with its GREEDY hand-over finish
//! every shipped scene without a collision, an error or a stall, and THP reaches completeness 0.95 on
//! each. TENSOR as published never collides, and a run of it that ends `stuck` says why. Every planner finishes a sample of
//! real plans (TENSOR with its hand-over). All heavy tier (see TESTING.md).

mod common;

use tensorscout::plan::PlannerKind;
use tensorscout::sim::Termination;
use tensorscout::Config;

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn greedy_completes_every_shipped_scene() {
    let cfg = Config::default();
    let mut failures = Vec::new();
    for path in common::shipped_scenes() {
        let r = &common::explore(&path, &cfg, PlannerKind::Greedy);
        // The observable set is sampled tightly: under 1 % of what the run saw lies outside it.
        let ok = r.termination == Termination::Complete
            && r.completeness >= 0.95
            && r.surface_coverage >= 0.90
            && r.explored_outside_observable_fraction < 0.01
            && r.collisions == 0;
        if !ok {
            failures.push(format!(
                "{}: {} completeness {:.3} surface {:.3} outside {:.4} collisions {}",
                r.scene,
                r.termination.as_str(),
                r.completeness,
                r.surface_coverage,
                r.explored_outside_observable_fraction,
                r.collisions
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Every scene with `planner`: the run must end `complete` or `budget` (never `stuck` or `error`)
/// with no collision and at least `min_completeness`; returns one line per violation.
fn finishes_every_scene(planner: PlannerKind, min_completeness: f64) -> Vec<String> {
    finishes_every_scene_with(&Config::default(), planner, min_completeness)
}

/// [`finishes_every_scene`] under `cfg`.
fn finishes_every_scene_with(
    cfg: &Config,
    planner: PlannerKind,
    min_completeness: f64,
) -> Vec<String> {
    finishes(
        &common::shipped_scenes(),
        cfg,
        planner,
        min_completeness,
        false,
    )
}

/// [`finishes_every_scene_with`] over the scenes at `paths`; with `stuck_ok` a run may also end
/// `stuck` (the other conditions still hold).
fn finishes(
    paths: &[std::path::PathBuf],
    cfg: &Config,
    planner: PlannerKind,
    min_completeness: f64,
    stuck_ok: bool,
) -> Vec<String> {
    let cfg = cfg.clone();
    let mut failures = Vec::new();
    for path in paths {
        let r = &common::explore(path, &cfg, planner);
        let finished = matches!(r.termination, Termination::Complete | Termination::Budget)
            || (stuck_ok && r.termination == Termination::Stuck);
        if !finished || r.collisions != 0 || r.completeness < min_completeness {
            failures.push(format!(
                "{} {}: {} completeness {:.3} collisions {}",
                planner.name(),
                r.scene,
                r.termination.as_str(),
                r.completeness,
                r.collisions
            ));
        }
        // A planner that splits its path by goal (`path_m_*`) accounts for all of it, up to the
        // last step's motion, which no planner call sees.
        let split: Vec<f64> = r
            .planner_stats
            .iter()
            .filter(|(k, _)| k.starts_with("path_m_"))
            .map(|(_, v)| *v)
            .collect();
        let unsplit = r.path_length_m - split.iter().sum::<f64>();
        if !split.is_empty() && !(-1e-6..=0.1).contains(&unsplit) {
            failures.push(format!(
                "{} {}: path {:.3} m, {:.3} m of it outside the path_m_* split",
                planner.name(),
                r.scene,
                r.path_length_m,
                unsplit
            ));
        }
    }
    failures
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn thp_finishes_every_shipped_scene() {
    let failures = finishes_every_scene(PlannerKind::Thp, 0.95);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn tensor_with_its_greedy_fallback_finishes_every_shipped_scene() {
    let mut cfg = Config::default();
    cfg.tensor.fallback = true;
    let failures = finishes_every_scene_with(&cfg, PlannerKind::Tensor, 0.0);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Without the hand-over (the default), TENSOR may fail where the method fails, but only as
/// `complete`, `budget` or `stuck`, never by a collision, and a `stuck` run carries its cause: the
/// routing graph had no edge with gain (`stuck_no_route`), or nothing new was seen for
/// `sim.stuck_timeout_s`.
#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn tensor_as_published_reports_why_it_stops() {
    let cfg = Config::default();
    assert!(
        !cfg.tensor.fallback,
        "the GREEDY hand-over is off by default"
    );
    let mut failures = Vec::new();
    for path in common::shipped_scenes() {
        let r = &common::explore(&path, &cfg, PlannerKind::Tensor);
        assert_eq!(r.planner, "tensor");
        assert_eq!(
            r.planner_stats.get("fallback_plans"),
            Some(&0.0),
            "{}",
            r.scene
        );
        let no_route = r
            .planner_stats
            .get("stuck_no_route")
            .copied()
            .unwrap_or(0.0);
        let cause_ok = match r.termination {
            Termination::Stuck => no_route == 1.0 || saw_nothing_new_at_the_end(r, &cfg),
            Termination::Complete | Termination::Budget => no_route == 0.0,
            _ => false,
        };
        if !cause_ok || r.collisions != 0 {
            failures.push(format!(
                "{}: {} stuck_no_route {no_route} collisions {}",
                r.scene,
                r.termination.as_str(),
                r.collisions
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Whether the run's explored volume grew by less than `sim.stuck_min_gain_m3` over its last
/// `sim.stuck_timeout_s`, read from its curve: the stuck rule's own condition, checked on what the
/// run recorded.
fn saw_nothing_new_at_the_end(r: &tensorscout::sim::RunResult, cfg: &Config) -> bool {
    let since = r.sim_time_s - cfg.sim.stuck_timeout_s.get();
    let (Some(before), Some(last)) = (
        // The first sample from `since` on: explored volume never shrinks, so from there to the end
        // it grew by no more than since the last gain the stuck rule counted.
        r.curve.iter().find(|c| c.t_s >= since - 1e-9),
        r.curve.last(),
    ) else {
        return false;
    };
    last.explored_volume_m3 - before.explored_volume_m3 < cfg.sim.stuck_min_gain_m3.get() + 1e-9
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn nbv_finishes_every_shipped_scene() {
    let failures = finishes_every_scene(PlannerKind::Nbv, 0.0);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Every planner on a sample of real apartment plans (`common::sample_plans`, each from its own
/// start): no error, no collision, and at least 0.70 of the observable volume seen. GREEDY, the
/// lowest, sees 0.74 on plan_165cad143c: its spawn room is closed by a door too narrow to pass, and
/// what it leaves is the top of the height band over the room's far side, which no frontier shows
/// (it saw 0.85 while a frontier it has since learnt to resolve from a viewpoint drew it across the
/// room). A run may end `stuck` here: real plans can hold frontiers a planner cannot reach or see
/// (THP once ended `stuck` on plan_115c3a7a64 at 0.93).
#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn every_planner_finishes_a_sample_of_real_plans() {
    let plans = common::sample_plans();
    let mut failures = Vec::new();
    for planner in [
        PlannerKind::Thp,
        PlannerKind::Tensor,
        PlannerKind::Nbv,
        PlannerKind::Greedy,
    ] {
        let mut cfg = Config::default();
        // TENSOR with its GREEDY hand-over: as published it may end `stuck` where the method fails.
        cfg.tensor.fallback = planner == PlannerKind::Tensor;
        failures.extend(finishes(&plans, &cfg, planner, 0.70, true));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
