//! Run metrics as DESIGN.md defines them: explored volume and completeness (counted incrementally
//! from the voxels each frame makes known), surface coverage, path length, collisions, stage timings
//! and the per-second curve samples.

use crate::map::Map;
use crate::scene::GroundTruth;
use crate::sim::observable::ObservableSet;
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

/// Explored volume and completeness, counted incrementally: a voxel counts once, when it first
/// becomes known, if it lies in the height band (ε); it also counts towards completeness if it is
/// observable (see [`ObservableSet`]).
pub struct ExploredVolume {
    known_in_band: u64,
    known_observable: u64,
    observable_voxels: u64,
    voxel_volume: f64,
    band: std::ops::Range<usize>,
}

impl ExploredVolume {
    pub fn new(gt: &GroundTruth, observable: &ObservableSet) -> Self {
        ExploredVolume {
            known_in_band: 0,
            known_observable: 0,
            observable_voxels: observable.voxels() as u64,
            voxel_volume: gt.grid.voxel_volume(),
            band: gt.band_layers(),
        }
    }

    /// Counts the voxels a frame made known.
    pub fn add(&mut self, gt: &GroundTruth, observable: &ObservableSet, newly_known: &[u32]) {
        for &v in newly_known {
            let (_, layer) = gt.grid.voxel_parts(v as usize);
            if self.band.contains(&layer) {
                self.known_in_band += 1;
                self.known_observable += observable.contains(v as usize) as u64;
            }
        }
    }

    /// ε: known voxels in the height band, m³.
    pub fn volume_m3(&self) -> f64 {
        self.known_in_band as f64 * self.voxel_volume
    }

    /// Known observable voxels over all observable voxels (0 when nothing is observable).
    pub fn completeness(&self) -> f64 {
        if self.observable_voxels == 0 {
            0.0
        } else {
            self.known_observable as f64 / self.observable_voxels as f64
        }
    }

    /// Share of the known band voxels that the observable set does not hold: how much the sampling
    /// of the observable set missed (0 when nothing is known).
    pub fn outside_observable_fraction(&self) -> f64 {
        if self.known_in_band == 0 {
            0.0
        } else {
            (self.known_in_band - self.known_observable) as f64 / self.known_in_band as f64
        }
    }
}

/// Observed surface voxels (known in the map) over the observable surface voxels.
pub fn surface_coverage(observable: &ObservableSet, map: &Map) -> f64 {
    let surface = observable.surface_voxels();
    if surface.is_empty() {
        return 0.0;
    }
    let seen = surface
        .iter()
        .filter(|&&v| map.is_voxel_known(v as usize))
        .count();
    seen as f64 / surface.len() as f64
}

/// Everything `explore --json` prints.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunResult {
    pub scene: String,
    pub scene_hash: String,
    pub planner: String,
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
