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

/// A connected patch of observable voxels that the run left unseen (columns 8-connected on the floor
/// plan): where the observable region still holds something, and how much.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UnseenPatch {
    /// Centroid of the patch's columns, metres.
    pub x: f64,
    pub y: f64,
    pub volume_m3: f64,
    /// Lowest and highest unseen voxel, metres above the floor (voxel bottoms and tops).
    pub z_min_m: f64,
    pub z_max_m: f64,
    /// Whether some column of the patch is reachable floor (else it lies over furniture, walls or
    /// floor the robot cannot stand on).
    pub over_reachable_floor: bool,
}

/// Patches reported per run, largest first.
pub const UNSEEN_PATCHES: usize = 5;

/// The largest patches of observable voxels that `map` does not know, largest first (at most
/// [`UNSEEN_PATCHES`]).
pub fn unseen_patches(gt: &GroundTruth, observable: &ObservableSet, map: &Map) -> Vec<UnseenPatch> {
    let grid = gt.grid;
    let cells = grid.cells();
    // Unseen voxels per column, with their layer range.
    let mut count = vec![0u32; cells];
    let mut layers = vec![(u32::MAX, 0u32); cells];
    for iz in gt.band_layers() {
        for c in 0..cells {
            let v = iz * cells + c;
            if observable.contains(v) && !map.is_voxel_known(v) {
                count[c] += 1;
                layers[c].0 = layers[c].0.min(iz as u32);
                layers[c].1 = layers[c].1.max(iz as u32);
            }
        }
    }
    let mut seen = vec![false; cells];
    let mut patches = Vec::new();
    for start in 0..cells {
        if count[start] == 0 || seen[start] {
            continue;
        }
        seen[start] = true;
        let mut stack = vec![start];
        let (mut n, mut sx, mut sy, mut lo, mut hi, mut reach) =
            (0u64, 0.0, 0.0, u32::MAX, 0, false);
        while let Some(i) = stack.pop() {
            let p = grid.center(grid.cell(i));
            n += count[i] as u64;
            sx += p.x * count[i] as f64;
            sy += p.y * count[i] as f64;
            lo = lo.min(layers[i].0);
            hi = hi.max(layers[i].1);
            reach |= gt.reachable(i);
            let c = grid.cell(i);
            for (dx, dy) in crate::grid::NEIGHBOURS_8 {
                if let Some(j) = grid.checked_index(crate::grid::Cell::new(c.x + dx, c.y + dy)) {
                    if count[j] > 0 && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        patches.push(UnseenPatch {
            x: sx / n as f64,
            y: sy / n as f64,
            volume_m3: n as f64 * grid.voxel_volume(),
            z_min_m: lo as f64 * grid.res,
            z_max_m: (hi + 1) as f64 * grid.res,
            over_reachable_floor: reach,
        });
    }
    patches.sort_by(|a, b| {
        b.volume_m3
            .total_cmp(&a.volume_m3)
            .then(a.x.total_cmp(&b.x))
            .then(a.y.total_cmp(&b.y))
    });
    patches.truncate(UNSEEN_PATCHES);
    patches
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
    /// The largest patches of the observable set left unseen at the end (see [`UnseenPatch`]).
    #[serde(default)]
    pub unseen_observable: Vec<UnseenPatch>,
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
