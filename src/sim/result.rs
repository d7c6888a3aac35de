//! What a run gives: how it ended, its stage timings, the exploration curve and the whole result
//! (`RunResult`, what `explore --json` prints). The metrics in it are the evaluation layer's
//! ([`crate::eval`]).

use crate::eval::{FrontierGroup, UnseenPatch};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// How a run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Termination {
    /// Nothing reachable is left to explore.
    Complete,
    /// The simulated-time budget was spent.
    Budget,
    /// No progress for `sim.stuck_timeout_s`.
    Stuck,
    /// The run failed; see `error`.
    Error,
    /// Stopped early on request (SIGINT/SIGTERM); the results cover the steps run so far.
    Interrupted,
}

impl Termination {
    pub fn as_str(self) -> &'static str {
        match self {
            Termination::Complete => "complete",
            Termination::Budget => "budget",
            Termination::Stuck => "stuck",
            Termination::Error => "error",
            Termination::Interrupted => "interrupted",
        }
    }
}

/// Summary statistics of one stage's per-step wall time, milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StageStats {
    pub mean: f64,
    pub p50: f64,
    pub p95: f64,
    pub max: f64,
}

impl StageStats {
    /// Mean, nearest-rank percentiles and maximum of `samples` (all zero when empty).
    pub fn of(samples: &[f64]) -> Self {
        if samples.is_empty() {
            return StageStats::default();
        }
        let mut s = samples.to_vec();
        s.sort_by(f64::total_cmp);
        let rank = |q: f64| s[((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1];
        StageStats {
            mean: s.iter().sum::<f64>() / s.len() as f64,
            p50: rank(0.5),
            p95: rank(0.95),
            max: s[s.len() - 1],
        }
    }
}

/// The stages timed every step, in data-flow order.
pub const STAGES: [&str; 5] = ["sense", "map", "field", "plan", "motion"];

/// Per-step wall times of each stage, milliseconds.
#[derive(Default)]
pub struct StageTimes {
    samples: [Vec<f64>; 5],
    /// TSP solve time of each planning step that solved one (part of the plan stage).
    tsp: Vec<f64>,
}

impl StageTimes {
    /// Records `ms` for stage number `stage` (an index into [`STAGES`]).
    pub fn record(&mut self, stage: usize, ms: f64) {
        self.samples[stage].push(ms);
    }

    /// Records the TSP time of one planning step.
    pub fn record_tsp(&mut self, ms: f64) {
        self.tsp.push(ms);
    }

    /// Statistics per stage, plus `tsp` (per planning step that solved a TSP) when there was one.
    pub fn summary(&self) -> BTreeMap<String, StageStats> {
        let mut out: BTreeMap<String, StageStats> = STAGES
            .iter()
            .zip(&self.samples)
            .map(|(name, s)| (name.to_string(), StageStats::of(s)))
            .collect();
        if !self.tsp.is_empty() {
            out.insert("tsp".to_string(), StageStats::of(&self.tsp));
        }
        out
    }
}

/// One sample of the exploration curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurveSample {
    pub t_s: f64,
    pub path_length_m: f64,
    pub explored_volume_m3: f64,
    pub completeness: f64,
}

/// The profile of a result row written before profiles existed: the only rules there were.
fn default_profile_name() -> String {
    crate::config::Profile::Tensorscout.name().to_string()
}

/// Everything `explore --json` prints.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunResult {
    pub scene: String,
    pub scene_hash: String,
    pub planner: String,
    /// The config's `profile` (`tensorscout` or `published`); `tensorscout` in a row written before
    /// profiles existed.
    #[serde(default = "default_profile_name")]
    pub profile: String,
    pub seed: u64,
    pub spawn: crate::Pose2,
    pub termination: Termination,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub error: Option<String>,
    /// Known observable voxels ÷ observable voxels.
    pub completeness: f64,
    /// ε: known voxels in the height band, m³.
    pub explored_volume_m3: f64,
    /// The voxels the camera could observe from the reachable region, m³: completeness's ceiling.
    #[serde(default)]
    pub observable_volume_m3: f64,
    /// Floor area the robot can reach from its start, m².
    #[serde(default)]
    pub reachable_area_m2: f64,
    /// Share of the explored voxels outside the observable set (sampling misses; should be ≈ 0).
    #[serde(default)]
    pub explored_outside_observable_fraction: f64,
    pub surface_coverage: f64,
    /// The largest patches of the observable set left unseen at the end (see [`UnseenPatch`]).
    #[serde(default)]
    pub unseen_observable: Vec<UnseenPatch>,
    /// Frontier cells left at the end that lie in the reachable region and border an Unknown cell
    /// whose column holds unseen observable voxels (see [`crate::eval::frontiers_left`]); `None` in a row
    /// written before the count existed (not zero: an old batch resumed must not read as clean).
    #[serde(default)]
    pub frontiers_left: Option<u64>,
    /// The largest 8-connected groups of those cells (see [`FrontierGroup`]).
    #[serde(default)]
    pub frontier_groups_left: Vec<FrontierGroup>,
    pub path_length_m: f64,
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    pub real_time_factor: f64,
    pub collisions: u64,
    pub steps: u64,
    pub replans: u64,
    pub astar_calls: u64,
    /// Deterministic counters of the planner (TSP solves, anchors visited, …); empty for GREEDY.
    #[serde(default)]
    pub planner_stats: BTreeMap<String, f64>,
    pub timings_ms: BTreeMap<String, StageStats>,
    pub version: String,
    pub config_hash: String,
    pub curve: Vec<CurveSample>,
    /// With any `[noise]` on: share of the map's occupied band voxels with a truly occupied voxel
    /// within one voxel (see [`crate::eval::MapQuality`]). Absent in noise-free runs.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub map_precision: Option<f64>,
    /// With any `[noise]` on: share of the observable surface voxels with an occupied map voxel
    /// within one voxel.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub map_recall: Option<f64>,
    /// With any `[noise]` on: share of the map's known-free band voxels that are truly occupied.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub free_but_occupied: Option<f64>,
    /// With pose or motion noise on: the absolute trajectory error of the estimated against the
    /// true trajectory (position, no alignment), root mean square, metres.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub ate_rmse_m: Option<f64>,
    /// With pose or motion noise on: the largest position error of the estimate, metres.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub ate_max_m: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_stats_known_answer() {
        let s: Vec<f64> = (1..=100).map(f64::from).collect();
        let st = StageStats::of(&s);
        assert_eq!(st.mean, 50.5);
        assert_eq!(st.p50, 50.0);
        assert_eq!(st.p95, 95.0);
        assert_eq!(st.max, 100.0);
        assert_eq!(StageStats::of(&[]), StageStats::default());
        assert_eq!(StageStats::of(&[3.0]).p95, 3.0);
    }

    #[test]
    fn termination_names() {
        assert_eq!(
            serde_json::to_string(&Termination::Budget).unwrap(),
            "\"budget\""
        );
        assert_eq!(Termination::Stuck.as_str(), "stuck");
        assert_eq!(
            serde_json::to_string(&Termination::Interrupted).unwrap(),
            "\"interrupted\""
        );
    }
}
