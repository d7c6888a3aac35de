//! `summary.md` and `summary.json`: the batch in the shape of the THP paper's tables.
//!
//! Table 1: per scene and planner, explored volume ε, its ratio r_ε to the reference planner's ε on
//! the same scene, path length L, completeness and simulated time, as mean ± the half-width of the
//! Student-t 95 % confidence interval over seeds (successful runs only). Table 2: mean per-step stage
//! timings. Then the paired comparison against the reference planner over every (scene, seed) pair
//! that both ran successfully (same seed = same start), and one verdict line per planner that says
//! only what those intervals support.

use super::stats::{Better, MeanCi, PairedDiff};
use super::store::{BenchRow, RunStatus};
use crate::plan::PlannerKind;
use crate::sim::STAGES;
use serde::Serialize;
use std::collections::BTreeMap;

/// One scene × planner cell of the tables.
#[derive(Clone, Debug, Serialize)]
pub struct Cell {
    pub scene: String,
    pub planner: String,
    pub runs: usize,
    pub failed: usize,
    pub explored_volume_m3: MeanCi,
    /// Mean ε over mean ε of the reference planner on this scene; absent without a reference.
    pub r_epsilon: Option<f64>,
    pub path_length_m: MeanCi,
    pub completeness: MeanCi,
    pub sim_time_s: MeanCi,
    pub collisions: u64,
    /// Runs that ended `complete` with reachable frontiers left that border unseen observable space
    /// (`frontiers_left > 0`); `None` when a row predates the count.
    pub complete_with_frontiers_left: Option<usize>,
    /// Mean over runs of each stage's mean per-step wall time, ms.
    pub timings_ms: BTreeMap<String, f64>,
    /// A* queries per run.
    pub astar_calls: MeanCi,
    /// TSP time per planning step that solved one (THP, NBV-TSP), ms: mean over runs of each run's
    /// mean, p50 and p95; absent for planners without a TSP.
    pub tsp_ms: Option<[f64; 3]>,
}

/// One planner over the whole batch.
#[derive(Clone, Debug, Serialize)]
pub struct Verdict {
    pub planner: String,
    pub runs: usize,
    pub failed: usize,
    pub completeness: MeanCi,
    pub path_length_m: MeanCi,
}

#[derive(Clone, Debug, Serialize)]
pub struct Failure {
    pub scene: String,
    pub planner: String,
    pub seed: u64,
    pub error: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// The planner r_ε is relative to (None when no run of it succeeded).
    pub reference: Option<String>,
    pub cells: Vec<Cell>,
    pub verdicts: Vec<Verdict>,
    /// Each other planner against the reference, over matched (scene, seed) pairs.
    pub paired: Vec<Paired>,
    pub failures: Vec<Failure>,
}

/// One planner against the reference over the (scene, seed) pairs that both ran successfully.
#[derive(Clone, Debug, Serialize)]
pub struct Paired {
    pub planner: String,
    pub pairs: usize,
    pub path_length_m: PairedDiff,
    pub completeness: PairedDiff,
    pub sim_time_s: PairedDiff,
    /// Path each run needed to reach 90 % of the pair's smaller final ε (efficiency at equal
    /// coverage, THP Fig. 6).
    pub path_to_equal_coverage_m: PairedDiff,
}

/// Share of the pair's smaller final ε at which paths are compared ("equal coverage").
pub const EQUAL_COVERAGE_FRACTION: f64 = 0.9;

/// Path length at which a run's curve first reached explored volume `target` (linear between curve
/// samples); `None` if it never did.
pub fn path_to_volume(curve: &[crate::sim::CurveSample], target: f64) -> Option<f64> {
    let k = curve.iter().position(|c| c.explored_volume_m3 >= target)?;
    if k == 0 {
        return Some(curve[0].path_length_m);
    }
    let (a, b) = (&curve[k - 1], &curve[k]);
    let f = (target - a.explored_volume_m3) / (b.explored_volume_m3 - a.explored_volume_m3);
    Some(a.path_length_m + f * (b.path_length_m - a.path_length_m))
}

/// The paired comparison of `planner` against `reference` (labels) in `rows`.
fn paired(
    rows: &[BenchRow],
    label: &dyn Fn(&BenchRow) -> String,
    planner: &str,
    reference: &str,
) -> Paired {
    type Key = (String, u64);
    let ok = |want: &str| -> BTreeMap<Key, &crate::sim::RunResult> {
        rows.iter()
            .filter(|r| r.status == RunStatus::Ok && label(r) == want)
            .filter_map(|r| {
                let res = r.result.as_ref()?;
                Some(((r.key.scene_path.clone(), r.key.seed), res))
            })
            .collect()
    };
    let (mine, theirs) = (ok(planner), ok(reference));
    let matched: Vec<(&crate::sim::RunResult, &crate::sim::RunResult)> = mine
        .iter()
        .filter_map(|(k, a)| theirs.get(k).map(|b| (*a, *b)))
        .collect();
    let values = |f: &dyn Fn(&crate::sim::RunResult) -> f64| -> Vec<(f64, f64)> {
        matched.iter().map(|(a, b)| (f(a), f(b))).collect()
    };
    let equal_coverage: Vec<(f64, f64)> = matched
        .iter()
        .filter_map(|(a, b)| {
            let target = EQUAL_COVERAGE_FRACTION * a.explored_volume_m3.min(b.explored_volume_m3);
            Some((
                path_to_volume(&a.curve, target)?,
                path_to_volume(&b.curve, target)?,
            ))
        })
        .collect();
    let rel = |r: f64| 0.01 * r.abs();
    Paired {
        planner: planner.to_string(),
        pairs: matched.len(),
        path_length_m: PairedDiff::of(&values(&|r| r.path_length_m), Better::Lower, rel),
        completeness: PairedDiff::of(&values(&|r| r.completeness), Better::Higher, |_| 0.005),
        sim_time_s: PairedDiff::of(&values(&|r| r.sim_time_s), Better::Lower, rel),
        path_to_equal_coverage_m: PairedDiff::of(&equal_coverage, Better::Lower, rel),
    }
}

/// The scene's display name: its file stem.
pub fn scene_name(path: &str) -> String {
    std::path::Path::new(path)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.to_string())
}

/// The name a run is grouped and shown under: its planner, followed by `@` and the first 6 digits
/// of its config hash when `rows` mix several configs (e.g. merged batches run with different
/// `--set`), so that different configs are never averaged together.
pub fn run_labeller(rows: &[BenchRow]) -> impl Fn(&BenchRow) -> String {
    let first = rows.first().map(|r| r.key.config_hash.clone());
    let multi = rows
        .iter()
        .any(|r| Some(&r.key.config_hash) != first.as_ref());
    move |r: &BenchRow| {
        if multi {
            let h = &r.key.config_hash;
            format!("{}@{}", r.key.planner, &h[..h.len().min(6)])
        } else {
            r.key.planner.clone()
        }
    }
}

impl Summary {
    /// Builds the summary of `rows`. The reference planner is `reference`, else THP, else the first
    /// planner (by name) with a successful run.
    pub fn of(rows: &[BenchRow], reference: Option<PlannerKind>) -> Summary {
        let label = run_labeller(rows);
        let mut groups: BTreeMap<(String, String), Vec<&BenchRow>> = BTreeMap::new();
        for r in rows {
            groups
                .entry((r.key.scene_path.clone(), label(r)))
                .or_default()
                .push(r);
        }
        let ok_planners: Vec<String> = {
            let mut v: Vec<String> = rows
                .iter()
                .filter(|r| r.status == RunStatus::Ok)
                .map(&label)
                .collect();
            v.sort();
            v.dedup();
            v
        };
        let wanted = reference.unwrap_or(PlannerKind::Thp).name().to_string();
        // With several configs, the reference is the wanted planner's first config, in the default
        // profile if it ran (`thp`, `thp@…`), else in another (`thp/published`).
        let found = (ok_planners.iter())
            .find(|l| **l == wanted || l.starts_with(&format!("{wanted}@")))
            .or_else(|| (ok_planners.iter()).find(|l| l.starts_with(&format!("{wanted}/"))));
        let reference = if let Some(found) = found {
            Some(found.clone())
        } else if reference.is_none() {
            ok_planners.first().cloned()
        } else {
            None
        };

        let mut cells = Vec::new();
        for ((scene, planner), runs) in &groups {
            let ok: Vec<_> = runs
                .iter()
                .filter(|r| r.status == RunStatus::Ok)
                .filter_map(|r| r.result.as_ref())
                .collect();
            let col = |f: &dyn Fn(&crate::sim::RunResult) -> f64| {
                MeanCi::of(&ok.iter().map(|r| f(r)).collect::<Vec<_>>())
            };
            let timings_ms = STAGES
                .iter()
                .map(|s| {
                    let v = col(&|r| r.timings_ms.get(*s).map_or(0.0, |t| t.mean));
                    (s.to_string(), v.mean)
                })
                .collect();
            cells.push(Cell {
                scene: scene.clone(),
                planner: planner.clone(),
                runs: runs.len(),
                failed: runs.len() - ok.len(),
                explored_volume_m3: col(&|r| r.explored_volume_m3),
                r_epsilon: None,
                path_length_m: col(&|r| r.path_length_m),
                completeness: col(&|r| r.completeness),
                sim_time_s: col(&|r| r.sim_time_s),
                collisions: ok.iter().map(|r| r.collisions).sum(),
                complete_with_frontiers_left: ok
                    .iter()
                    .map(|r| {
                        r.frontiers_left.map(|n| {
                            usize::from(r.termination == crate::sim::Termination::Complete && n > 0)
                        })
                    })
                    .sum(),
                timings_ms,
                astar_calls: col(&|r| r.astar_calls as f64),
                tsp_ms: {
                    let tsp: Vec<_> = ok.iter().filter_map(|r| r.timings_ms.get("tsp")).collect();
                    (!tsp.is_empty()).then(|| {
                        let m = |f: &dyn Fn(&crate::sim::StageStats) -> f64| {
                            tsp.iter().map(|t| f(t)).sum::<f64>() / tsp.len() as f64
                        };
                        [m(&|t| t.mean), m(&|t| t.p50), m(&|t| t.p95)]
                    })
                },
            });
        }
        // r_ε: this cell's mean ε over the reference cell's on the same scene.
        let ref_eps: BTreeMap<String, f64> = cells
            .iter()
            .filter(|c| Some(&c.planner) == reference.as_ref() && c.runs > c.failed)
            .map(|c| (c.scene.clone(), c.explored_volume_m3.mean))
            .collect();
        for c in &mut cells {
            if c.runs > c.failed {
                c.r_epsilon = ref_eps
                    .get(&c.scene)
                    .filter(|&&e| e > 0.0)
                    .map(|e| c.explored_volume_m3.mean / e);
            }
        }

        let mut planners: Vec<&String> = groups.keys().map(|(_, p)| p).collect();
        planners.sort();
        planners.dedup();
        let verdicts = planners
            .into_iter()
            .map(|p| {
                let runs: Vec<&BenchRow> = rows.iter().filter(|r| &label(r) == p).collect();
                let ok: Vec<_> = runs
                    .iter()
                    .filter(|r| r.status == RunStatus::Ok)
                    .filter_map(|r| r.result.as_ref())
                    .collect();
                let mean = |f: &dyn Fn(&crate::sim::RunResult) -> f64| {
                    MeanCi::of(&ok.iter().map(|r| f(r)).collect::<Vec<_>>())
                };
                Verdict {
                    planner: p.clone(),
                    runs: runs.len(),
                    failed: runs.len() - ok.len(),
                    completeness: mean(&|r| r.completeness),
                    path_length_m: mean(&|r| r.path_length_m),
                }
            })
            .collect();
        let failures = rows
            .iter()
            .filter(|r| r.status == RunStatus::Failed)
            .map(|r| Failure {
                scene: r.key.scene_path.clone(),
                planner: label(r),
                seed: r.key.seed,
                error: r.error.clone().unwrap_or_default(),
            })
            .collect();
        let paired = match &reference {
            Some(r) => ok_planners
                .iter()
                .filter(|p| *p != r)
                .map(|p| paired(rows, &label, p, r))
                .collect(),
            None => Vec::new(),
        };
        Summary {
            reference,
            cells,
            verdicts,
            paired,
            failures,
        }
    }

    pub fn to_markdown(&self) -> String {
        let pm = |m: MeanCi, digits: usize| m.show(digits);
        let mut s = String::from("# Benchmark summary\n\n");
        let runs: usize = self.cells.iter().map(|c| c.runs).sum();
        let failed: usize = self.cells.iter().map(|c| c.failed).sum();
        s.push_str(&format!(
            "{runs} runs, {failed} failed. Mean ± half-width of the Student-t 95 % confidence interval over seeds (successful runs; no interval for a single run). Completeness is against the volume the camera could observe from the floor the robot can reach.\n\n"
        ));
        s.push_str("## Exploration (THP Table 1)\n\n");
        match &self.reference {
            Some(r) => s.push_str(&format!(
                "ε: explored volume; r_ε: ε relative to the reference planner **{r}** on the same scene; L: path length.\n\n"
            )),
            None => s.push_str("ε: explored volume; L: path length. r_ε: no successful run of the reference planner.\n\n"),
        }
        s.push_str("Complete, frontiers left: runs that ended `complete` with a frontier left in the reachable region that borders unseen observable space (`frontiers_left` > 0); — where a row was written before the count existed.\n\n");
        s.push_str("| scene | planner | runs | ε (m³) | r_ε | L (m) | completeness | sim time (s) | collisions | complete, frontiers left |\n");
        s.push_str("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
        for c in &self.cells {
            let ok = c.runs - c.failed;
            let runs = if c.failed > 0 {
                format!("{ok}/{} ({} failed)", c.runs, c.failed)
            } else {
                format!("{}", c.runs)
            };
            if ok == 0 {
                s.push_str(&format!(
                    "| {} | {} | {runs} | — | — | — | — | — | — | — |\n",
                    scene_name(&c.scene),
                    c.planner
                ));
                continue;
            }
            s.push_str(&format!(
                "| {} | {} | {runs} | {} | {} | {} | {} | {} | {} | {} |\n",
                scene_name(&c.scene),
                c.planner,
                pm(c.explored_volume_m3, 1),
                c.r_epsilon.map_or("—".into(), |r| format!("{r:.3}")),
                pm(c.path_length_m, 1),
                pm(c.completeness, 3),
                pm(c.sim_time_s, 0),
                c.collisions,
                c.complete_with_frontiers_left
                    .map_or("—".to_string(), |n| n.to_string())
            ));
        }
        s.push_str("\n## Stage timings (THP Table 2)\n\nMean wall time per simulation step, ms (mean over runs of each run's mean).\n\n| scene | planner |");
        for st in STAGES {
            s.push_str(&format!(" {st} |"));
        }
        s.push_str(" total |\n|---|---|");
        s.push_str(&"---:|".repeat(STAGES.len() + 1));
        s.push('\n');
        for c in self.cells.iter().filter(|c| c.runs > c.failed) {
            s.push_str(&format!("| {} | {} |", scene_name(&c.scene), c.planner));
            let mut total = 0.0;
            for st in STAGES {
                let v = c.timings_ms.get(st).copied().unwrap_or(0.0);
                total += v;
                s.push_str(&format!(" {v:.3} |"));
            }
            s.push_str(&format!(" {total:.3} |\n"));
        }
        if self.cells.iter().any(|c| c.tsp_ms.is_some()) {
            s.push_str("\n## TSP time per planning step (THP Fig. 8)\n\nWall time of the cost matrix and the solve, per planning step that solved a TSP, ms (mean over runs); A* queries per run.\n\n| scene | planner | mean | p50 | p95 | A* calls |\n|---|---|---:|---:|---:|---:|\n");
            for c in &self.cells {
                if let Some([mean, p50, p95]) = c.tsp_ms {
                    s.push_str(&format!(
                        "| {} | {} | {mean:.3} | {p50:.3} | {p95:.3} | {:.0} |\n",
                        scene_name(&c.scene),
                        c.planner,
                        c.astar_calls.mean
                    ));
                }
            }
        }
        if let (Some(reference), false) = (&self.reference, self.paired.is_empty()) {
            s.push_str(&format!(
                "\n## Paired comparison against {reference}\n\nOver the (scene, seed) pairs where both runs succeeded (the same seed starts both from the same pose). Δ = planner − {reference}: mean ± Student-t 95 % half-width. W/T/L: pairs the planner won, tied and lost (ties: L, time and path within 1 % of {reference}'s, completeness within 0.005). Equal coverage: the path each run needed to reach {:.0} % of the pair's smaller final ε.\n\n| planner | pairs | ΔL (m) | W/T/L | Δ completeness | W/T/L | Δ sim time (s) | W/T/L | Δ path to equal coverage (m) | W/T/L |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
                EQUAL_COVERAGE_FRACTION * 100.0
            ));
            let wtl = |d: &PairedDiff| format!("{}/{}/{}", d.wins, d.ties, d.losses);
            for p in &self.paired {
                s.push_str(&format!(
                    "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                    p.planner,
                    p.pairs,
                    p.path_length_m.diff.show(2),
                    wtl(&p.path_length_m),
                    p.completeness.diff.show(4),
                    wtl(&p.completeness),
                    p.sim_time_s.diff.show(1),
                    wtl(&p.sim_time_s),
                    p.path_to_equal_coverage_m.diff.show(2),
                    wtl(&p.path_to_equal_coverage_m),
                ));
            }
        }
        s.push_str("\n## Verdict\n\n");
        for v in &self.verdicts {
            if v.failed == v.runs {
                s.push_str(&format!(
                    "- **{}**: no successful run, {}/{} runs failed\n",
                    v.planner, v.failed, v.runs
                ));
                continue;
            }
            s.push_str(&format!(
                "- **{}**: completeness {}, L {} m, {}/{} runs failed",
                v.planner,
                v.completeness.show(3),
                v.path_length_m.show(1),
                v.failed,
                v.runs
            ));
            match (
                self.paired.iter().find(|p| p.planner == v.planner),
                &self.reference,
            ) {
                (Some(p), Some(r)) => s.push_str(&format!(
                    ". Against {r} over {} pairs: path {}; completeness {}; simulated time {}; path to equal coverage {}.\n",
                    p.pairs,
                    p.path_length_m.reading("shorter", "longer"),
                    p.completeness.reading("lower", "higher"),
                    p.sim_time_s.reading("shorter", "longer"),
                    p.path_to_equal_coverage_m.reading("shorter", "longer"),
                )),
                _ if self.reference.as_deref() == Some(v.planner.as_str()) => {
                    s.push_str(" (reference)\n")
                }
                _ => s.push('\n'),
            }
        }
        if !self.failures.is_empty() {
            s.push_str("\n## Failures\n\n");
            for f in &self.failures {
                s.push_str(&format!(
                    "- {} / {} / seed {}: {}\n",
                    scene_name(&f.scene),
                    f.planner,
                    f.seed,
                    f.error.replace('\n', " ")
                ));
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(planner: &str, config_hash: &str, eps: Option<f64>) -> BenchRow {
        let key = super::super::RunKey {
            scene_path: "scenes/a.obj".into(),
            scene_hash: "h".into(),
            planner: planner.into(),
            seed: 1,
            config_hash: config_hash.into(),
        };
        match eps {
            None => BenchRow::failed(key, "boom".into()),
            Some(e) => {
                let json = format!(
                    r#"{{"scene":"a","scene_hash":"h","planner":"{planner}","seed":1,
                    "spawn":{{"x":0,"y":0,"yaw":0}},"termination":"complete","completeness":0.5,
                    "explored_volume_m3":{e},"observable_volume_m3":10,"surface_coverage":0.5,
                    "path_length_m":3,"sim_time_s":10,"wall_time_s":1,"real_time_factor":10,
                    "collisions":0,"steps":100,"replans":1,"astar_calls":1,"timings_ms":{{}},
                    "version":"0","config_hash":"{config_hash}","curve":[]}}"#
                );
                BenchRow {
                    key,
                    status: super::super::RunStatus::Ok,
                    error: None,
                    result: Some(serde_json::from_str(&json).unwrap()),
                }
            }
        }
    }

    /// (planner label, r_ε) of every cell.
    fn ratios(s: &Summary) -> Vec<(&str, Option<f64>)> {
        s.cells
            .iter()
            .map(|c| (c.planner.as_str(), c.r_epsilon))
            .collect()
    }

    #[test]
    fn tsp_time_per_planning_step_is_averaged_over_runs() {
        let with_tsp = |mean: f64, p50: f64, p95: f64| {
            let mut r = row("thp", "c1", Some(8.0));
            let stats = crate::sim::StageStats {
                mean,
                p50,
                p95,
                max: p95,
            };
            let result = r.result.as_mut().unwrap();
            result.timings_ms.insert("tsp".into(), stats);
            result.astar_calls = 10;
            r
        };
        let rows = [
            with_tsp(1.0, 0.5, 3.0),
            with_tsp(3.0, 1.5, 5.0),
            row("greedy", "c1", Some(4.0)),
        ];
        let s = Summary::of(&rows, None);
        let thp = s.cells.iter().find(|c| c.planner == "thp").unwrap();
        assert_eq!(thp.tsp_ms, Some([2.0, 1.0, 4.0]));
        assert_eq!(thp.astar_calls.mean, 10.0);
        let greedy = s.cells.iter().find(|c| c.planner == "greedy").unwrap();
        assert_eq!(greedy.tsp_ms, None);
        let md = s.to_markdown();
        let section = md.split("## TSP time per planning step").nth(1).unwrap();
        let section = section.split("\n## ").next().unwrap();
        assert!(
            section.contains("| a | thp | 2.000 | 1.000 | 4.000 | 10 |"),
            "{md}"
        );
        assert!(!section.contains("greedy"), "{md}");
    }

    #[test]
    fn runs_complete_with_frontiers_left_are_counted_per_cell() {
        let with = |planner: &str, termination: crate::sim::Termination, frontiers_left: u64| {
            let mut r = row(planner, "c1", Some(8.0));
            let result = r.result.as_mut().unwrap();
            result.termination = termination;
            result.frontiers_left = Some(frontiers_left);
            r
        };
        use crate::sim::Termination::{Budget, Complete};
        // GREEDY: one row counted, one written before the count existed (no `frontiers_left`).
        let rows = [
            with("thp", Complete, 12),
            with("thp", Complete, 0),
            with("thp", Budget, 7),
            with("thp", Complete, 1),
            with("greedy", Complete, 3),
            row("greedy", "c1", Some(4.0)),
        ];
        let s = Summary::of(&rows, None);
        let count = |p: &str| {
            let c = s.cells.iter().find(|c| c.planner == p).unwrap();
            c.complete_with_frontiers_left
        };
        assert_eq!((count("thp"), count("greedy")), (Some(2), None));
        let md = s.to_markdown();
        assert!(
            md.contains("| collisions | complete, frontiers left |"),
            "{md}"
        );
        let thp = md
            .lines()
            .find(|l| l.starts_with("| a | thp | 4 |"))
            .unwrap();
        assert!(thp.ends_with("| 0 | 2 |"), "{thp}");
        let greedy = md
            .lines()
            .find(|l| l.starts_with("| a | greedy | 2 |"))
            .unwrap();
        assert!(greedy.ends_with("| 0 | — |"), "{greedy}");
    }

    #[test]
    fn r_epsilon_is_relative_to_the_reference() {
        let rows = [
            row("greedy", "c1", Some(4.0)),
            row("thp", "c1", Some(8.0)),
            row("nbv", "c1", None),
        ];
        let s = Summary::of(&rows, None);
        assert_eq!(s.reference.as_deref(), Some("thp"));
        let r = ratios(&s);
        assert_eq!(
            r,
            [("greedy", Some(0.5)), ("nbv", None), ("thp", Some(1.0))]
        );
        // One seed per planner: a pair, but no interval.
        let greedy = &s.paired[0];
        assert_eq!((greedy.planner.as_str(), greedy.pairs), ("greedy", 1));
        assert_eq!(greedy.path_length_m.diff.ci95, None);
        // An explicit reference with no successful run gives no ratios.
        let s = Summary::of(&rows, Some(PlannerKind::Nbv));
        assert_eq!(s.reference, None);
        assert!(s.cells.iter().all(|c| c.r_epsilon.is_none()));
        assert_eq!(s.failures.len(), 1);
        assert!(s
            .to_markdown()
            .contains("- **nbv**: no successful run, 1/1 runs failed"));
    }

    #[test]
    fn different_configs_are_kept_apart() {
        let rows = [
            row("greedy", "aaaaaaaa11", Some(4.0)),
            row("greedy", "bbbbbbbb22", Some(6.0)),
        ];
        let s = Summary::of(&rows, None);
        assert_eq!(s.reference.as_deref(), Some("greedy@aaaaaa"));
        let r = ratios(&s);
        assert_eq!(
            r,
            [("greedy@aaaaaa", Some(1.0)), ("greedy@bbbbbb", Some(1.5))]
        );
    }

    #[test]
    fn scene_names_are_stems() {
        assert_eq!(scene_name("scenes/office_large.obj"), "office_large");
    }
}
