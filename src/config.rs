//! The whole configuration tree.
//!
//! The defaults live in one place: `configs/default.toml`, embedded in the binary with a comment on
//! every key (`tensorscout config default` prints it verbatim). A user's config file and `--set`
//! overrides are merged over that tree key by key; a key that is not in the default tree is an error
//! naming its dotted path, and the merged tree is then deserialised with `deny_unknown_fields`.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The default config, with a comment on every key.
pub const DEFAULT_TOML: &str = include_str!("../configs/default.toml");

/// The `published` profile: the value that switches off each key of `[additions]`, and nothing
/// else.
pub const PUBLISHED_TOML: &str = include_str!("../configs/published.toml");

/// A finite number above zero: a length, duration or rate that must not vanish (the unit is in the
/// key's name). Parsed, not validated afterwards: a config that holds one has been checked, and the
/// error names the dotted key (`config key `camera.max_range_m` must be a positive number, got -1`).
/// It serialises as the plain number, so the TOML and `config_hash` are those of an `f64`.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd, Serialize, Deserialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct Positive(f64);

/// A finite number of at least zero (a length or amount that may be switched off with 0); see
/// [`Positive`].
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd, Serialize, Deserialize)]
#[serde(try_from = "f64", into = "f64")]
pub struct NonNegative(f64);

/// The start of every message a checked number's parse error carries: [`Config::load`] puts the
/// dotted key in front of it, as it does for the checks of [`Config::validate`].
const CHECK_PREFIX: &str = "must ";

impl Positive {
    /// The number, if it is finite and above zero; else the error `positive` names a key with.
    pub fn new(v: f64) -> std::result::Result<Positive, String> {
        if v.is_finite() && v > 0.0 {
            Ok(Positive(v))
        } else {
            Err(format!(
                "{CHECK_PREFIX}be a positive number, got {}",
                crate::util::short_number(v)
            ))
        }
    }

    pub fn get(self) -> f64 {
        self.0
    }
}

impl NonNegative {
    /// The number, if it is finite and at least zero; else the error `non_negative` names a key
    /// with.
    pub fn new(v: f64) -> std::result::Result<NonNegative, String> {
        if v.is_finite() && v >= 0.0 {
            Ok(NonNegative(v))
        } else {
            Err(format!(
                "{CHECK_PREFIX}be zero or positive, got {}",
                crate::util::short_number(v)
            ))
        }
    }

    pub fn get(self) -> f64 {
        self.0
    }
}

impl TryFrom<f64> for Positive {
    type Error = String;
    fn try_from(v: f64) -> std::result::Result<Self, String> {
        Positive::new(v)
    }
}

impl TryFrom<f64> for NonNegative {
    type Error = String;
    fn try_from(v: f64) -> std::result::Result<Self, String> {
        NonNegative::new(v)
    }
}

impl From<Positive> for f64 {
    fn from(v: Positive) -> f64 {
        v.0
    }
}

impl From<NonNegative> for f64 {
    fn from(v: NonNegative) -> f64 {
        v.0
    }
}

/// Shown as the plain number.
impl std::fmt::Display for Positive {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

/// Shown as the plain number.
impl std::fmt::Display for NonNegative {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub profile: Profile,
    pub seed: u64,
    pub sim: SimConfig,
    pub scene: SceneConfig,
    pub map: MapConfig,
    pub camera: CameraConfig,
    pub robot: RobotConfig,
    pub motion: MotionConfig,
    pub search: SearchConfig,
    pub greedy: GreedyConfig,
    pub field: FieldConfig,
    pub thp: ThpConfig,
    pub tensor: TensorConfig,
    pub nbv: NbvConfig,
    pub additions: Additions,
    pub log: LogConfig,
    pub metrics: MetricsConfig,
}

/// Which set of rules a run follows: a name for a set of config values, never a second code path.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// Each planner with tensorscout's additions (`[additions]`) as `configs/default.toml` sets them.
    Tensorscout,
    /// Each planner as its paper describes it: every key of `[additions]` switched off
    /// (`configs/published.toml`).
    Published,
}

impl Profile {
    /// The name used on the command line, in results and in bench labels.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Tensorscout => "tensorscout",
            Profile::Published => "published",
        }
    }
}

/// The rules no paper has: tensorscout's additions to the frontier planners, each a key here and
/// nowhere else, each with the value that switches it off (`configs/published.toml`, which the
/// `published` profile applies). See `configs/default.toml` for what each does and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Additions {
    pub look_from_on_top: bool,
    pub viewpoint_looks: u32,
    pub viewpoint_away_m: NonNegative,
    pub exact_arrival: bool,
    pub approach_attempts: u32,
    pub unreached_give_up_m: NonNegative,
    pub blind_zone_step_back: bool,
    pub blind_zone_look_first_m: NonNegative,
    pub distant_views: bool,
    pub volume_views: bool,
    pub volume_view_gain_cutoff_m3: NonNegative,
    pub volume_view_spacing_m: Positive,
    pub volume_view_tour: bool,
    pub reopen_max: u32,
    pub escape_tries: u32,
    pub escape_clearance_m: NonNegative,
    pub way_out_m: NonNegative,
    pub look_when_blocked: bool,
    pub advection_stall_s: NonNegative,
    pub nbv_frontier_views: bool,
}

/// How the ground truth of what can be observed is sampled (see `eval::observable`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetricsConfig {
    pub observable_spacing_m: f64,
    pub observable_yaws: usize,
}

/// Where a run starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SpawnMode {
    /// The scene's own spawn (or `--spawn X,Y[,YAW]`).
    Scene,
    /// A pose drawn from the run's seed over the reachable region of the scene's spawn.
    Random,
}

/// What `explore --log` writes and how often (see `src/log`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogConfig {
    pub depth_every_n: u64,
    pub map_every_s: f64,
    pub field: bool,
    pub zstd_level: u32,
    pub chunk_size_kb: u64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    pub dt_s: f64,
    pub budget_s: Positive,
    pub stuck_timeout_s: Positive,
    pub stuck_min_gain_m3: NonNegative,
    pub curve_interval_s: f64,
    pub initial_look_around: bool,
    pub spawn: SpawnMode,
    pub random_spawn_margin_m: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneConfig {
    pub wall_height_m: Positive,
    pub y_up: bool,
    pub unknown_as_free: bool,
    pub max_extent_m: Positive,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapConfig {
    pub voxel_m: f64,
    pub margin_m: f64,
    pub band_min_m: f64,
    pub band_max_m: f64,
    pub log_odds_hit: f32,
    pub log_odds_miss: f32,
    pub log_odds_min: f32,
    pub log_odds_max: f32,
    pub log_odds_occupied: f32,
    pub column_known_fraction: f64,
    pub inflation_margin_m: f64,
    pub proximity_band_m: f64,
    pub frontier_segment_max_m: f64,
    pub frontier_min_cells: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraConfig {
    pub hfov_deg: f64,
    pub vfov_deg: f64,
    pub min_range_m: NonNegative,
    pub max_range_m: Positive,
    pub width: usize,
    pub height: usize,
    pub mount_height_m: Positive,
    pub rate_hz: Positive,
    pub renderer: DepthRenderer,
}

/// How the depth camera computes its frames (see `src/sensor`). Both give the same depths along the
/// same pixel rays, up to silhouette pixels (`tests/raster_vs_raycast.rs` counts them).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DepthRenderer {
    /// Z-buffer rasterisation of the scene mesh (the fast default).
    Raster,
    /// One BVH ray per pixel (the reference).
    Raycast,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    pub radius_m: f64,
    pub height_m: f64,
    pub max_speed_mps: f64,
    pub max_turn_rate_rps: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionConfig {
    pub turn_in_place_rad: Positive,
    pub lookahead_m: Positive,
    pub goal_tolerance_m: f64,
    pub slow_clearance_m: NonNegative,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchConfig {
    pub unknown_is_free: bool,
    pub near_unknown_radius_m: f64,
    pub proximity_cost: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GreedyConfig {
    pub look_around_on_arrival: bool,
    pub view_distance_m: NonNegative,
}

/// The tensor field (THP Eq. 11, TENSOR §4 and §6); see `src/field/`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldConfig {
    pub d_s_m: f64,
    pub sigma_m: f64,
    pub decay: f64,
    pub tangent_radius_m: f64,
    pub min_tangent_anisotropy: f64,
    pub weight_cutoff: f64,
    pub path_strength: f64,
    pub keyframe_period_s: f64,
    pub substeps: usize,
    pub omega_s: f64,
    pub omega_t: f64,
    pub alpha: f64,
    pub timevary_radius_m: f64,
    pub timevary_max_iterations: usize,
    pub topology_sigma_factor: f64,
    pub topology_cell_factor: usize,
    pub track_radius_m: f64,
    pub min_clearance_m: f64,
    pub rk4_step_m: f64,
    pub separatrix_max_length_m: f64,
    pub arrive_radius_m: f64,
    pub stop_at_unknown: bool,
    pub cancel_pairs: bool,
    pub cancel_max_iterations: usize,
    pub move_wedges_into_corners: bool,
    pub move_trisectors_from_obstacles: bool,
    pub trisector_clearance_m: f64,
    pub max_move_m: f64,
}

/// How THP groups frontiers before its TSP (THP §3.4; Fig. 8 compares the three).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Grouping {
    /// Frontiers join their nearest anchor within `d_f` (THP Alg. 2): the TSP runs over anchors.
    Anchors,
    /// No grouping: the TSP runs over every frontier.
    None,
    /// K-means clusters of frontiers (Kulich et al. 2019): the TSP runs over cluster centres.
    Kmeans,
}

/// Where THP's open tour starts (room THP Alg. 1 leaves; see `plan::thp`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TourStart {
    /// At the robot: the TSP holds the robot's cell as its fixed start, so the first group is
    /// chosen with the whole tour in view.
    Robot,
    /// At the anchor nearest the robot by path cost (Alg. 1 read literally).
    NearestAnchor,
}

/// Between which cells of two THP tour nodes the TSP's path costs run (see `plan::thp::tour`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TourCosts {
    /// Between the nodes' positions (Eq. 6's dist(p_i, p_j) between anchors), each taken from its
    /// least-cost frontier instead where it does not lie on floor the robot can reach.
    Anchors,
    /// Between each node's least-cost frontier from the robot (which moves with the robot).
    Frontiers,
}

/// THP: anchors, online TSP, frontier grouping and splitting, advection (THP, Xi et al., CVM 2024, §3.3–3.5).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThpConfig {
    pub field_period_s: f64,
    pub extension: bool,
    pub grouping: Grouping,
    pub d_f_m: f64,
    pub d_g_m: f64,
    pub d_p_m: f64,
    pub kmeans_cluster_m: f64,
    pub exact_tsp_max_nodes: usize,
    pub cost_refresh_s: f64,
    pub cost_refresh_rows_max: usize,
    pub advection: bool,
    pub advect_length_m: f64,
    pub drift_m: f64,
    pub finish_group_first: bool,
    pub tour_start: TourStart,
    pub tour_costs: TourCosts,
    pub view_distance_m: f64,
}

/// TENSOR: time-varying field, advection, topology-graph routing (Xu et al., ACM TOG 2017, §4–6).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TensorConfig {
    pub min_info_gain: f64,
    pub gain_radius_m: f64,
    pub advect_substeps: usize,
    pub dock_radius_m: f64,
    pub wall_clearance_m: f64,
    pub look_spacing_m: f64,
    pub stall_timeout_s: f64,
    pub topological_control: bool,
    pub fallback: bool,
}

/// NBV-TSP: coverage sampling, heuristic gain, GA over a fixed-start open TSP (Meng et al., RA-L 2017).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NbvConfig {
    pub eta: f64,
    pub sample_radius_m: f64,
    pub max_viewpoints: usize,
    pub misses_per_m2: f64,
    pub min_misses: usize,
    pub gain_ray_stride: usize,
    pub visibility_length_m: f64,
    pub gain_cutoff_m3: f64,
    pub cover_min_visibility: f64,
    pub ga_population: usize,
    pub ga_group_size: usize,
    pub ga_generations: usize,
    pub ga_stall_generations: usize,
}

/// Fails unless `v` is a finite number above zero, naming `key`.
fn positive(key: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::usage(format!(
            "config key `{key}` must be a positive number, got {}",
            crate::util::short_number(v)
        )))
    }
}

/// Fails unless `v` is a finite number of at least zero, naming `key`.
fn non_negative(key: &str, v: f64) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(Error::usage(format!(
            "config key `{key}` must be zero or positive, got {}",
            crate::util::short_number(v)
        )))
    }
}

/// Fails unless `lo <= v <= hi` (a finite number), naming `key` and the bound. Bounds on values that
/// cost time or memory; each is stated in `configs/default.toml`'s comment for the key.
fn within(key: &str, v: f64, lo: f64, hi: f64) -> Result<()> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(Error::usage(format!(
            "config key `{key}` must lie in [{}, {}], got {}",
            crate::util::short_number(lo),
            crate::util::short_number(hi),
            crate::util::short_number(v)
        )))
    }
}

/// Fails unless the count `v` lies in `lo..=hi`, naming `key` and the bound.
fn count_within(key: &str, v: u64, lo: u64, hi: u64) -> Result<()> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(Error::usage(format!(
            "config key `{key}` must lie in {lo}..={hi}, got {v}"
        )))
    }
}

impl MapConfig {
    /// The `map` section's own checks.
    fn validate(&self) -> Result<()> {
        positive("map.voxel_m", self.voxel_m)?;
        within("map.voxel_m", self.voxel_m, 0.01, 1.0)?;
        non_negative("map.margin_m", self.margin_m)?;
        non_negative("map.band_min_m", self.band_min_m)?;
        positive("map.band_max_m", self.band_max_m)?;
        if self.band_max_m <= self.band_min_m + self.voxel_m {
            return Err(Error::usage(format!(
                "config key `map.band_max_m` ({}) must exceed `map.band_min_m` ({}) by more than one voxel",
                self.band_max_m, self.band_min_m
            )));
        }
        positive("map.log_odds_hit", self.log_odds_hit as f64)?;
        if self.log_odds_miss.is_nan() || self.log_odds_miss >= 0.0 {
            return Err(Error::usage(format!(
                "config key `map.log_odds_miss` must be negative, got {}",
                self.log_odds_miss
            )));
        }
        if !(self.log_odds_min < 0.0 && self.log_odds_max > 0.0) {
            return Err(Error::usage(
                "config keys `map.log_odds_min` and `map.log_odds_max` must be negative and positive",
            ));
        }
        if !(0.0..=1.0).contains(&self.column_known_fraction) {
            return Err(Error::usage(format!(
                "config key `map.column_known_fraction` must lie in [0, 1], got {}",
                self.column_known_fraction
            )));
        }
        non_negative("map.inflation_margin_m", self.inflation_margin_m)?;
        positive("map.frontier_segment_max_m", self.frontier_segment_max_m)?;
        non_negative("map.proximity_band_m", self.proximity_band_m)?;
        Ok(())
    }
}

impl ThpConfig {
    fn validate(&self) -> Result<()> {
        for (key, v) in [
            ("thp.field_period_s", self.field_period_s),
            ("thp.d_f_m", self.d_f_m),
            ("thp.d_g_m", self.d_g_m),
            ("thp.d_p_m", self.d_p_m),
            ("thp.kmeans_cluster_m", self.kmeans_cluster_m),
            ("thp.cost_refresh_s", self.cost_refresh_s),
            ("thp.advect_length_m", self.advect_length_m),
            ("thp.drift_m", self.drift_m),
        ] {
            positive(key, v)?;
        }
        non_negative("thp.view_distance_m", self.view_distance_m)?;
        within("thp.field_period_s", self.field_period_s, 0.01, 1e6)?;
        if !(1..=20).contains(&self.exact_tsp_max_nodes) {
            return Err(Error::usage(format!(
                "config key `thp.exact_tsp_max_nodes` must lie in 1..=20 (Held–Karp needs 2^n memory), got {}",
                self.exact_tsp_max_nodes
            )));
        }
        if self.cost_refresh_rows_max == 0 {
            return Err(Error::usage(
                "config key `thp.cost_refresh_rows_max` must be at least 1 (at 0 an old row would never be recomputed)",
            ));
        }
        Ok(())
    }
}

impl TensorConfig {
    fn validate(&self) -> Result<()> {
        non_negative("tensor.min_info_gain", self.min_info_gain)?;
        for (key, v) in [
            ("tensor.gain_radius_m", self.gain_radius_m),
            ("tensor.dock_radius_m", self.dock_radius_m),
            ("tensor.stall_timeout_s", self.stall_timeout_s),
        ] {
            positive(key, v)?;
        }
        non_negative("tensor.wall_clearance_m", self.wall_clearance_m)?;
        non_negative("tensor.look_spacing_m", self.look_spacing_m)?;
        count_within(
            "tensor.advect_substeps",
            self.advect_substeps as u64,
            1,
            1000,
        )?;
        Ok(())
    }
}

impl NbvConfig {
    fn validate(&self) -> Result<()> {
        non_negative("nbv.eta", self.eta)?;
        for (key, v) in [
            ("nbv.sample_radius_m", self.sample_radius_m),
            ("nbv.visibility_length_m", self.visibility_length_m),
        ] {
            positive(key, v)?;
        }
        non_negative("nbv.misses_per_m2", self.misses_per_m2)?;
        non_negative("nbv.gain_cutoff_m3", self.gain_cutoff_m3)?;
        if !(0.0..=1.0).contains(&self.cover_min_visibility) {
            return Err(Error::usage(format!(
                "config key `nbv.cover_min_visibility` must lie in [0, 1], got {}",
                self.cover_min_visibility
            )));
        }
        for (key, v) in [
            ("nbv.max_viewpoints", self.max_viewpoints),
            ("nbv.gain_ray_stride", self.gain_ray_stride),
            ("nbv.ga_population", self.ga_population),
            ("nbv.ga_group_size", self.ga_group_size),
        ] {
            if v == 0 {
                return Err(Error::usage(format!(
                    "config key `{key}` must be at least 1, got 0"
                )));
            }
        }
        for (key, v, lo, hi) in [
            ("nbv.max_viewpoints", self.max_viewpoints, 1, 10_000),
            ("nbv.gain_ray_stride", self.gain_ray_stride, 1, 4096),
            ("nbv.ga_population", self.ga_population, 1, 100_000),
            ("nbv.ga_group_size", self.ga_group_size, 1, 100_000),
            ("nbv.ga_generations", self.ga_generations, 0, 1_000_000),
            (
                "nbv.ga_stall_generations",
                self.ga_stall_generations,
                0,
                1_000_000,
            ),
            ("nbv.min_misses", self.min_misses, 0, 1_000_000_000),
        ] {
            count_within(key, v as u64, lo, hi)?;
        }
        if self.ga_group_size > self.ga_population {
            return Err(Error::usage(format!(
                "config key `nbv.ga_group_size` ({}) must not exceed `nbv.ga_population` ({})",
                self.ga_group_size, self.ga_population
            )));
        }
        Ok(())
    }
}

impl Default for Config {
    fn default() -> Self {
        // The embedded default is checked by a unit test, so this cannot fail in a released binary.
        Config::from_value(default_tree()).expect("configs/default.toml is a valid config")
    }
}

fn default_tree() -> toml::Table {
    DEFAULT_TOML
        .parse::<toml::Table>()
        .expect("configs/default.toml is valid TOML")
}

/// The defaults with `configs/published.toml` over them (`profile = "published"` included).
fn published_tree() -> toml::Table {
    let mut tree = default_tree();
    let published = PUBLISHED_TOML
        .parse::<toml::Table>()
        .expect("configs/published.toml is valid TOML");
    merge(&mut tree, published, "").expect("configs/published.toml sets only known keys");
    tree
}

/// The whole config of `profile` as TOML with a comment on every key, as `config default
/// --profile` prints it: `configs/default.toml` with the profile's values in place of the
/// defaults.
pub fn profile_toml(profile: Profile) -> String {
    if profile == Profile::Tensorscout {
        return DEFAULT_TOML.to_string();
    }
    let values = PUBLISHED_TOML
        .parse::<toml::Table>()
        .expect("configs/published.toml is valid TOML");
    let mut section: Option<&toml::Table> = Some(&values);
    let mut out = String::with_capacity(DEFAULT_TOML.len());
    for line in DEFAULT_TOML.lines() {
        let t = line.trim();
        if let Some(name) = t.strip_prefix('[').and_then(|n| n.strip_suffix(']')) {
            section = values.get(name).and_then(toml::Value::as_table);
        } else if let Some((key, _)) = t.split_once('=').filter(|_| !t.starts_with('#')) {
            if let Some(v) = section.and_then(|s| s.get(key.trim())) {
                out.push_str(&format!("{} = {v}\n", key.trim()));
                continue;
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// A user's TOML config file: a regular file of at most 16 MiB; text that is not UTF-8 (a binary
/// file given by mistake) is a usage error like any other unparsable config.
fn read_user_file(path: &Path) -> Result<toml::Table> {
    let bytes = crate::util::read_regular_file(path, 16 << 20)?;
    let text = String::from_utf8(bytes).map_err(|e| {
        Error::usage(format!(
            "{}: not a TOML config (not UTF-8 text at byte {})",
            path.display(),
            e.utf8_error().valid_up_to()
        ))
    })?;
    text.parse().map_err(|e: toml::de::Error| {
        Error::usage(format!("{}: {}", path.display(), one_line(&e.to_string())))
    })
}

impl Config {
    /// Builds a config from the defaults, an optional TOML file, and `key=value` overrides, in that
    /// order, then validates it. A bad key or value is a usage error naming the dotted key.
    ///
    /// ```
    /// use tensorscout::Config;
    /// let cfg = Config::load(None, &["map.voxel_m=0.05".to_string()]).unwrap();
    /// assert_eq!(cfg.map.voxel_m, 0.05);
    /// let e = Config::load(None, &["map.voxel_m=-1".to_string()]).unwrap_err();
    /// assert_eq!(e.exit_code(), 2);
    /// assert!(e.to_string().contains("map.voxel_m"));
    /// ```
    pub fn load(file: Option<&Path>, overrides: &[String]) -> Result<Config> {
        let user = file.map(read_user_file).transpose()?;
        // The file and the overrides set the profile like any key; its values go under them, so
        // that a key set explicitly wins over the profile's.
        let resolve = |mut tree: toml::Table| -> Result<toml::Table> {
            if let (Some(path), Some(user)) = (file, &user) {
                merge(&mut tree, user.clone(), "")
                    .map_err(|e| Error::usage(format!("{}: {e}", path.display())))?;
            }
            for item in overrides {
                apply_override(&mut tree, item)?;
            }
            Ok(tree)
        };
        let mut tree = resolve(default_tree())?;
        if tree.get("profile").and_then(toml::Value::as_str) == Some(Profile::Published.name()) {
            tree = resolve(published_tree())?;
        }
        let config = Config::from_value(tree)?;
        config.validate()?;
        Ok(config)
    }

    /// The defaults under `profile`, as `config default --profile` prints them.
    pub fn of_profile(profile: Profile) -> Config {
        let tree = match profile {
            Profile::Tensorscout => default_tree(),
            Profile::Published => published_tree(),
        };
        // Both embedded files are checked by unit tests, so this cannot fail in a released binary.
        Config::from_value(tree).expect("the embedded profiles are valid configs")
    }

    fn from_value(tree: toml::Table) -> Result<Config> {
        let de = toml::Value::Table(tree);
        serde_path_to_error::deserialize(de).map_err(|e| {
            let msg = one_line(&e.inner().to_string());
            if msg.starts_with(CHECK_PREFIX) {
                // A checked number's own message reads on from the key, as `validate`'s do
                // (without the parser's ` in `key`` tail: the key leads already).
                let own = msg.split(" in `").next().unwrap_or(&msg);
                return Error::usage(format!("config key `{}` {own}", e.path()));
            }
            Error::usage(format!("config key `{}`: {msg}", e.path()))
        })
    }

    /// The config as TOML (every key), as stored in logs and hashed into `config_hash`.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a config always serialises")
    }

    /// A stable 64-bit FNV-1a hash of the canonical TOML, as 16 hex digits.
    pub fn hash(&self) -> String {
        format!("{:016x}", crate::util::fnv1a64(self.to_toml().as_bytes()))
    }

    /// Rejects values that are of the right type but make no sense, naming the key. Each section
    /// checks its own keys (a check that relates a section to another takes the other value as an
    /// argument); [`Positive`] and [`NonNegative`] keys were checked when the tree was parsed. The
    /// order is that of the sections in the file, so that a config with several faults names the
    /// first one.
    pub fn validate(&self) -> Result<()> {
        self.sim.validate()?;
        self.metrics.validate(self.map.voxel_m)?;
        self.log.validate()?;
        self.scene.validate()?;
        self.map.validate()?;
        self.camera.validate()?;
        self.robot.validate(self.sim.dt_s)?;
        self.greedy.validate()?;
        self.search.validate()?;
        self.motion.validate()?;
        self.field.validate()?;
        self.thp.validate()?;
        self.tensor.validate()?;
        self.nbv.validate()?;
        self.additions.validate()?;
        Ok(())
    }
}

impl SimConfig {
    fn validate(&self) -> Result<()> {
        // Bounds on what costs time or memory (stated in configs/default.toml).
        within("sim.dt_s", self.dt_s, 0.001, 1.0)?;
        within("sim.budget_s", self.budget_s.get(), 0.0, 1e6)?;
        if self.dt_s > self.budget_s.get() {
            return Err(Error::usage(format!(
                "config key `sim.dt_s` ({}) must not exceed `sim.budget_s` ({}): the run would take no step",
                self.dt_s, self.budget_s.get()
            )));
        }
        within("sim.curve_interval_s", self.curve_interval_s, 0.01, 1e6)?;
        within(
            "sim.random_spawn_margin_m",
            self.random_spawn_margin_m,
            0.0,
            10.0,
        )?;
        Ok(())
    }
}

impl MetricsConfig {
    /// The observable set's sampling; its spacing may not be finer than the map's voxels
    /// (`voxel_m`).
    fn validate(&self, voxel_m: f64) -> Result<()> {
        within(
            "metrics.observable_spacing_m",
            self.observable_spacing_m,
            0.01,
            10.0,
        )?;
        if self.observable_spacing_m < voxel_m {
            return Err(Error::usage(format!(
                "config key `metrics.observable_spacing_m` ({}) must be at least `map.voxel_m` ({})",
                self.observable_spacing_m, voxel_m
            )));
        }
        if !(1..=64).contains(&self.observable_yaws) {
            return Err(Error::usage(format!(
                "config key `metrics.observable_yaws` must lie in 1..=64, got {}",
                self.observable_yaws
            )));
        }
        Ok(())
    }
}

impl LogConfig {
    fn validate(&self) -> Result<()> {
        within("log.map_every_s", self.map_every_s, 0.01, 1e6)?;
        if !(1..=19).contains(&self.zstd_level) {
            return Err(Error::usage(format!(
                "config key `log.zstd_level` must be 1..=19, got {}",
                self.zstd_level
            )));
        }
        count_within("log.chunk_size_kb", self.chunk_size_kb, 1, 65_536)
    }
}

impl SceneConfig {
    /// Both lengths are [`Positive`]: nothing is left to check.
    fn validate(&self) -> Result<()> {
        Ok(())
    }
}

impl CameraConfig {
    fn validate(&self) -> Result<()> {
        for (key, v) in [
            ("camera.hfov_deg", self.hfov_deg),
            ("camera.vfov_deg", self.vfov_deg),
        ] {
            if !(v > 0.0 && v < 180.0) {
                return Err(Error::usage(format!(
                    "config key `{key}` must lie in (0, 180), got {v}"
                )));
            }
        }
        within("camera.max_range_m", self.max_range_m.get(), 0.0, 100.0)?;
        if self.min_range_m.get() >= self.max_range_m.get() {
            return Err(Error::usage(
                "config key `camera.min_range_m` must be below `camera.max_range_m`",
            ));
        }
        count_within("camera.width", self.width as u64, 1, 2048)?;
        count_within("camera.height", self.height as u64, 1, 2048)?;
        within("camera.rate_hz", self.rate_hz.get(), 0.0, 1000.0)?;
        Ok(())
    }
}

impl RobotConfig {
    /// The robot's size and speeds, and the step `dt_s` they allow.
    fn validate(&self, dt_s: f64) -> Result<()> {
        positive("robot.radius_m", self.radius_m)?;
        positive("robot.height_m", self.height_m)?;
        positive("robot.max_speed_mps", self.max_speed_mps)?;
        positive("robot.max_turn_rate_rps", self.max_turn_rate_rps)?;
        // A step at full speed may not carry the robot further than its own radius: motion,
        // collision checks and sensing happen once per step, so a longer step could jump the disc
        // past a wall.
        if dt_s * self.max_speed_mps > self.radius_m * (1.0 + 1e-9) {
            return Err(Error::usage(format!(
                "config key `sim.dt_s` ({} s) is too large: at robot.max_speed_mps = {} a step would carry the robot more than its radius robot.radius_m = {} m (at most {} s)",
                dt_s,
                self.max_speed_mps,
                self.radius_m,
                crate::util::short_number(self.radius_m / self.max_speed_mps)
            )));
        }
        Ok(())
    }
}

impl GreedyConfig {
    /// `view_distance_m` is [`NonNegative`]: nothing is left to check.
    fn validate(&self) -> Result<()> {
        Ok(())
    }
}

impl Additions {
    /// Counts bounded by what is meaningful; the lengths are newtypes that check themselves.
    fn validate(&self) -> Result<()> {
        count_within(
            "additions.viewpoint_looks",
            u64::from(self.viewpoint_looks),
            0,
            255,
        )?;
        count_within(
            "additions.approach_attempts",
            u64::from(self.approach_attempts),
            1,
            1000,
        )?;
        count_within("additions.reopen_max", u64::from(self.reopen_max), 0, 255)?;
        count_within(
            "additions.escape_tries",
            u64::from(self.escape_tries),
            0,
            1000,
        )?;
        within("additions.way_out_m", self.way_out_m.get(), 0.0, 100.0)?;
        within(
            "additions.unreached_give_up_m",
            self.unreached_give_up_m.get(),
            0.0,
            100.0,
        )?;
        Ok(())
    }
}

impl SearchConfig {
    fn validate(&self) -> Result<()> {
        non_negative("search.proximity_cost", self.proximity_cost)?;
        non_negative("search.near_unknown_radius_m", self.near_unknown_radius_m)
    }
}

impl MotionConfig {
    fn validate(&self) -> Result<()> {
        positive("motion.goal_tolerance_m", self.goal_tolerance_m)
    }
}

impl FieldConfig {
    fn validate(&self) -> Result<()> {
        let f = self;
        for (key, v) in [
            ("field.d_s_m", f.d_s_m),
            ("field.sigma_m", f.sigma_m),
            ("field.decay", f.decay),
            ("field.tangent_radius_m", f.tangent_radius_m),
            ("field.keyframe_period_s", f.keyframe_period_s),
            ("field.omega_s", f.omega_s),
            ("field.omega_t", f.omega_t),
            ("field.alpha", f.alpha),
            ("field.timevary_radius_m", f.timevary_radius_m),
            ("field.topology_sigma_factor", f.topology_sigma_factor),
            ("field.rk4_step_m", f.rk4_step_m),
            ("field.arrive_radius_m", f.arrive_radius_m),
        ] {
            positive(key, v)?;
        }
        for (key, v) in [
            ("field.min_tangent_anisotropy", f.min_tangent_anisotropy),
            ("field.path_strength", f.path_strength),
            ("field.track_radius_m", f.track_radius_m),
            ("field.min_clearance_m", f.min_clearance_m),
            ("field.separatrix_max_length_m", f.separatrix_max_length_m),
            ("field.trisector_clearance_m", f.trisector_clearance_m),
            ("field.max_move_m", f.max_move_m),
        ] {
            non_negative(key, v)?;
        }
        if !(f.weight_cutoff > 0.0 && f.weight_cutoff < 1.0) {
            return Err(Error::usage(format!(
                "config key `field.weight_cutoff` must lie in (0, 1), got {}",
                f.weight_cutoff
            )));
        }
        within("field.d_s_m", f.d_s_m, 0.02, 10.0)?;
        within("field.sigma_m", f.sigma_m, 0.01, 10.0)?;
        within("field.rk4_step_m", f.rk4_step_m, 0.001, 1.0)?;
        within("field.keyframe_period_s", f.keyframe_period_s, 0.01, 1e6)?;
        within("field.timevary_radius_m", f.timevary_radius_m, 0.0, 50.0)?;
        within(
            "field.separatrix_max_length_m",
            f.separatrix_max_length_m,
            0.0,
            10_000.0,
        )?;
        count_within("field.substeps", f.substeps as u64, 1, 1000)?;
        count_within(
            "field.topology_cell_factor",
            f.topology_cell_factor as u64,
            1,
            16,
        )?;
        count_within(
            "field.timevary_max_iterations",
            f.timevary_max_iterations as u64,
            0,
            100_000,
        )?;
        count_within(
            "field.cancel_max_iterations",
            f.cancel_max_iterations as u64,
            0,
            100_000,
        )?;
        Ok(())
    }
}

/// First line of a possibly multi-line parser message, trimmed.
fn one_line(msg: &str) -> String {
    msg.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

/// Merges `user` over `base`; every key of `user` must exist in `base` (named by its dotted path).
fn merge(
    base: &mut toml::Table,
    user: toml::Table,
    prefix: &str,
) -> std::result::Result<(), String> {
    for (key, value) in user {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        // Keys are shown escaped: a key holding a newline must not break the one-line error.
        let shown = path.escape_debug();
        match (base.get_mut(&key), value) {
            (None, _) => return Err(format!("unknown config key `{shown}`")),
            (Some(toml::Value::Table(b)), toml::Value::Table(u)) => merge(b, u, &path)?,
            (Some(toml::Value::Table(_)), _) => {
                return Err(format!(
                    "config key `{shown}` is a section; set one of its keys instead"
                ))
            }
            (Some(slot), value) => *slot = value,
        }
    }
    Ok(())
}

/// Applies one `key=value` override; the value is parsed as TOML, or taken as a string if it is not.
fn apply_override(tree: &mut toml::Table, item: &str) -> Result<()> {
    let (key, raw) = item.split_once('=').ok_or_else(|| {
        Error::usage(format!(
            "--set `{}`: expected KEY=VALUE",
            item.escape_debug()
        ))
    })?;
    let key = key.trim();
    let raw = raw.trim();
    if key.is_empty() {
        return Err(Error::usage(format!(
            "--set `{}`: empty key",
            item.escape_debug()
        )));
    }
    if !key
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.')
    {
        return Err(Error::usage(format!(
            "--set `{}`: not a config key (dotted names of letters, digits and `_`)",
            key.escape_debug()
        )));
    }
    let value = format!("v = {raw}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(raw.to_string()));
    let mut user = toml::Table::new();
    let parts: Vec<&str> = key.split('.').collect();
    let mut slot = &mut user;
    for part in &parts[..parts.len() - 1] {
        slot = slot
            .entry(part.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .expect("just inserted a table");
    }
    slot.insert(parts[parts.len() - 1].to_string(), value);
    merge(tree, user, "").map_err(|e| Error::usage(format!("--set {key}: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_published_profile_switches_off_every_addition_and_nothing_else() {
        let published: toml::Table = PUBLISHED_TOML.parse().unwrap();
        let additions = default_tree()["additions"].as_table().unwrap().clone();
        let off = published["additions"].as_table().unwrap();
        // Only the profile's own name and `[additions]` keys.
        let top: Vec<&str> = published.keys().map(String::as_str).collect();
        assert_eq!(top, ["additions", "profile"]);
        // Every switch of `[additions]` is set; the keys left out are the parameters of a switch
        // ("Used with ..." in their comment), which the switch being off makes moot.
        let text = DEFAULT_TOML.split("[additions]").nth(1).unwrap();
        let text = text.split("\n[").next().unwrap();
        let mut comment = String::new();
        for line in text.lines() {
            if let Some(c) = line.strip_prefix('#') {
                comment.push_str(c);
            } else if let Some((key, _)) = line.split_once('=') {
                let key = key.trim();
                assert!(additions.contains_key(key));
                assert!(
                    comment.contains("Not in any paper")
                        || comment.contains("Used with")
                        || comment.contains("both profiles"),
                    "{key}: {comment}"
                );
                let is_switch = comment.contains("Not in any paper");
                assert_eq!(off.contains_key(key), is_switch, "{key}");
                if is_switch {
                    // The comment names the value the profile sets.
                    let want = format!("published: {}", off[key]);
                    assert!(comment.contains(&want), "{key}: comment lacks `{want}`");
                    assert_ne!(off[key], additions[key], "{key} is already off by default");
                }
                comment.clear();
            }
        }
        for key in off.keys() {
            assert!(additions.contains_key(key), "{key}");
        }
    }

    #[test]
    fn a_profile_is_a_set_of_values_and_explicit_keys_win() {
        let published = Config::load(None, &["profile=published".to_string()]).unwrap();
        assert_eq!(published, Config::of_profile(Profile::Published));
        assert_eq!(published.profile, Profile::Published);
        assert!(!published.additions.volume_views && published.additions.reopen_max == 0);
        // Apart from the profile's name and `[additions]`, the two profiles agree.
        let mut same = published.clone();
        same.profile = Profile::Tensorscout;
        same.additions = Config::default().additions;
        assert_eq!(same, Config::default());
        // A key set explicitly wins over the profile's value, in either order.
        for set in [
            ["profile=published", "additions.volume_views=true"],
            ["additions.volume_views=true", "profile=published"],
        ] {
            let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
            let cfg = Config::load(None, &set).unwrap();
            assert!(cfg.additions.volume_views && !cfg.additions.distant_views);
        }
        // The printed config of a profile is that profile.
        for p in [Profile::Tensorscout, Profile::Published] {
            let tree: toml::Table = profile_toml(p).parse().unwrap();
            assert_eq!(Config::from_value(tree).unwrap(), Config::of_profile(p));
        }
        let e = Config::load(None, &["profile=paper".to_string()]).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().contains("`profile`"), "{e}");
    }

    #[test]
    fn default_toml_parses_and_validates() {
        let c = Config::default();
        c.validate().unwrap();
        assert_eq!(c.map.voxel_m, 0.1);
        assert_eq!(c.camera.width, 80);
        assert_eq!(c.robot.radius_m, 0.25);
        assert_eq!(c.sim.budget_s.get(), 1800.0);
    }

    #[test]
    fn every_key_of_the_default_has_a_comment() {
        let mut previous = "";
        for line in DEFAULT_TOML.lines() {
            let t = line.trim();
            if !t.is_empty() && !t.starts_with('#') && !t.starts_with('[') {
                assert!(
                    previous.starts_with('#'),
                    "key line `{t}` has no comment above it"
                );
            }
            previous = t;
        }
    }

    #[test]
    fn round_trips_through_toml() {
        let c = Config::default();
        let back: Config = toml::from_str(&c.to_toml()).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn set_overrides_dotted_keys() {
        let c = Config::load(None, &["map.voxel_m=0.05".into(), "seed=7".into()]).unwrap();
        assert_eq!(c.map.voxel_m, 0.05);
        assert_eq!(c.seed, 7);
        assert_ne!(c.hash(), Config::default().hash());
    }

    #[test]
    fn unknown_key_is_named() {
        let e = Config::load(None, &["map.voxl_m=0.05".into()]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "--set map.voxl_m: unknown config key `map.voxl_m`"
        );
        assert_eq!(e.exit_code(), 2);
    }

    #[test]
    fn wrong_type_names_the_key() {
        let e = Config::load(None, &["camera.width=wide".into()]).unwrap_err();
        assert!(
            e.to_string().starts_with("config key `camera.width`"),
            "{e}"
        );
    }

    #[test]
    fn negative_resolution_is_rejected() {
        let e = Config::load(None, &["map.voxel_m=-0.1".into()]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "config key `map.voxel_m` must be a positive number, got -0.1"
        );
    }

    /// A checked number is refused while the tree is parsed, with the message the old check gave
    /// after it; a good one reads back as the plain number.
    #[test]
    fn checked_numbers_name_their_key() {
        for (set, msg) in [
            (
                "camera.max_range_m=-1",
                "config key `camera.max_range_m` must be a positive number, got -1",
            ),
            (
                "camera.min_range_m=-0.5",
                "config key `camera.min_range_m` must be zero or positive, got -0.5",
            ),
            (
                "sim.budget_s=0",
                "config key `sim.budget_s` must be a positive number, got 0",
            ),
            (
                "motion.lookahead_m=nan",
                "config key `motion.lookahead_m` must be a positive number, got NaN",
            ),
            (
                "greedy.view_distance_m=-inf",
                "config key `greedy.view_distance_m` must be zero or positive, got -inf",
            ),
            (
                "scene.max_extent_m=\"far\"",
                "config key `scene.max_extent_m`: invalid type: string \"far\", expected f64 in `scene.max_extent_m`",
            ),
        ] {
            let e = Config::load(None, &[set.into()]).unwrap_err();
            assert_eq!(e.to_string(), msg, "{set}");
            assert_eq!(e.exit_code(), 2);
        }
        let c = Config::load(None, &["camera.max_range_m=4".into()]).unwrap();
        assert_eq!(c.camera.max_range_m.get(), 4.0);
        assert!(c.to_toml().contains("\nmax_range_m = 4.0\n"));
        assert_eq!(
            Positive::new(0.0),
            Err("must be a positive number, got 0".into())
        );
        assert_eq!(NonNegative::new(0.0).map(NonNegative::get), Ok(0.0));
    }

    #[test]
    fn bad_field_cutoff_is_rejected() {
        let e = Config::load(None, &["field.weight_cutoff=2".into()]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "config key `field.weight_cutoff` must lie in (0, 1), got 2"
        );
        let e = Config::load(None, &["field.sigma_m=0".into()]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "config key `field.sigma_m` must be a positive number, got 0"
        );
        let e = Config::load(None, &["thp.cost_refresh_rows_max=0".into()]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "config key `thp.cost_refresh_rows_max` must be at least 1 (at 0 an old row would never be recomputed)"
        );
        assert_eq!(e.exit_code(), 2);
    }

    #[test]
    fn camera_size_bounded() {
        for (set, msg) in [
            (
                "camera.width=9223372036854775807",
                "config key `camera.width` must lie in 1..=2048, got 9223372036854775807",
            ),
            (
                "camera.height=100000",
                "config key `camera.height` must lie in 1..=2048, got 100000",
            ),
            (
                "camera.width=0",
                "config key `camera.width` must lie in 1..=2048, got 0",
            ),
        ] {
            let e = Config::load(None, &[set.into()]).unwrap_err();
            assert_eq!(e.to_string(), msg);
            assert_eq!(e.exit_code(), 2);
        }
    }

    #[test]
    fn costly_values_bounded() {
        for (set, msg) in [
            (
                "sim.dt_s=1e-300",
                "config key `sim.dt_s` must lie in [0.001, 1], got 1e-300",
            ),
            (
                "field.rk4_step_m=1e-9",
                "config key `field.rk4_step_m` must lie in [0.001, 1], got 1e-9",
            ),
            (
                "field.d_s_m=1e-6",
                "config key `field.d_s_m` must lie in [0.02, 10], got 1e-6",
            ),
            (
                "map.voxel_m=0.001",
                "config key `map.voxel_m` must lie in [0.01, 1], got 0.001",
            ),
            (
                "field.substeps=100000",
                "config key `field.substeps` must lie in 1..=1000, got 100000",
            ),
            (
                "nbv.ga_population=1000000000",
                "config key `nbv.ga_population` must lie in 1..=100000, got 1000000000",
            ),
            (
                "log.chunk_size_kb=100000000",
                "config key `log.chunk_size_kb` must lie in 1..=65536, got 100000000",
            ),
        ] {
            let e = Config::load(None, &[set.into()]).unwrap_err();
            assert_eq!(e.to_string(), msg);
            assert_eq!(e.exit_code(), 2);
        }
        // Every bound is stated in the default config's comment for its key.
        for key in [
            "dt_s",
            "rk4_step_m",
            "d_s_m",
            "voxel_m",
            "width",
            "height",
            "substeps",
        ] {
            let i = DEFAULT_TOML
                .find(&format!("\n{key} = "))
                .unwrap_or_else(|| panic!("{key}"));
            let comments: Vec<&str> = DEFAULT_TOML[..i]
                .lines()
                .rev()
                .take_while(|l| l.starts_with('#'))
                .collect();
            assert!(
                comments.iter().any(|l| l.starts_with("# Bound: ")),
                "{key}: {comments:?}"
            );
        }
    }

    #[test]
    fn dt_larger_than_budget_rejected() {
        let e = Config::load(None, &["sim.dt_s=100".into(), "sim.budget_s=20".into()]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "config key `sim.dt_s` must lie in [0.001, 1], got 100"
        );
        let e =
            Config::load(None, &["sim.dt_s=0.1".into(), "sim.budget_s=0.05".into()]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "config key `sim.dt_s` (0.1) must not exceed `sim.budget_s` (0.05): the run would take no step"
        );
        // Faster than one 0.1 m cell per step.
        let e = Config::load(None, &["sim.dt_s=0.5".into()]).unwrap_err();
        assert!(
            e.to_string().starts_with(
                "config key `sim.dt_s` (0.5 s) is too large: at robot.max_speed_mps = 1"
            ),
            "{e}"
        );
        assert_eq!(e.exit_code(), 2);
    }

    #[test]
    fn binary_config_is_a_usage_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.toml");
        std::fs::write(&path, [0x00, 0xff, 0xfe]).unwrap();
        let e = Config::load(Some(&path), &[]).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert_eq!(
            e.to_string(),
            format!(
                "{}: not a TOML config (not UTF-8 text at byte 1)",
                path.display()
            )
        );
    }

    #[test]
    fn unknown_key_in_file_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.toml");
        std::fs::write(&path, "[robot]\nradius_m = 0.3\nspeed = 2\n").unwrap();
        let e = Config::load(Some(&path), &[]).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("{}: unknown config key `robot.speed`", path.display())
        );
    }
}
