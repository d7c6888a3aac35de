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
    pub noise: NoiseConfig,
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
    pub field_range_m: NonNegative,
}

/// How the ground truth of what can be observed is sampled (see `eval::observable`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetricsConfig {
    pub observable_spacing_m: f64,
    pub observable_yaws: usize,
}

/// Sensor and odometry error (see `sensor::noise` and `sim::odometry`); all off by default, and
/// with all off a run is the same, bit for bit, as without the section.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseConfig {
    pub depth: DepthNoiseConfig,
    pub pose: PoseNoiseConfig,
    pub motion: MotionNoiseConfig,
}

impl NoiseConfig {
    /// Whether the robot's pose can differ from the commanded or believed one (actuation noise or a
    /// pose estimate): the runs that report pose error and log the true pose beside the estimate.
    pub fn pose_is_noisy(&self) -> bool {
        self.motion.enabled || self.pose.model != PoseModel::None
    }

    /// Whether any noise is on: the runs that report map quality against the ground truth.
    pub fn any(&self) -> bool {
        self.depth.model != DepthNoiseModel::None || self.pose_is_noisy()
    }
}

/// The depth camera's error model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DepthNoiseModel {
    /// Exact depth.
    None,
    /// Structured light (Kinect v1): axial error growing with (z − z₀)², after Nguyen, Izadi and
    /// Lovell 2012.
    Kinect,
    /// Active stereo (RealSense D400): Gaussian disparity error, depth error z² · σ_d / (f · B),
    /// and quantised disparity.
    Stereo,
}

/// `[noise.depth]`: what each key means is in `configs/default.toml` and `sensor::noise`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DepthNoiseConfig {
    pub model: DepthNoiseModel,
    pub axial_base_m: f64,
    pub axial_quadratic_per_m: f64,
    pub axial_offset_m: f64,
    pub axial_angle_m: f64,
    pub lateral_px: f64,
    pub lateral_angle_px: f64,
    pub focal_px: f64,
    pub baseline_m: f64,
    pub subpixel_px: f64,
    pub disparity_step_px: f64,
    pub dropout: f64,
    pub grazing_dropout: f64,
    pub grazing_start_deg: f64,
    pub edge_dropout: f64,
    pub edge_jump: f64,
}

/// How the robot knows its pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PoseModel {
    /// The true pose.
    None,
    /// Dead reckoning: the measured motion of each step, with the odometry motion model's error,
    /// added up; the error grows without bound.
    Odometry,
    /// A localisation system's estimate: the truth plus an error that wanders and is pulled back
    /// (an Ornstein–Uhlenbeck process) with a set standard deviation and time constant.
    Localized,
}

/// `[noise.pose]`: the robot's pose estimate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseNoiseConfig {
    pub model: PoseModel,
    pub alpha1: f64,
    pub alpha2: f64,
    pub alpha3: f64,
    pub alpha4: f64,
    pub sigma_xy_m: f64,
    pub sigma_yaw_rad: f64,
    pub time_constant_s: f64,
}

/// `[noise.motion]`: the executed motion differs from the commanded one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionNoiseConfig {
    pub enabled: bool,
    pub alpha1: f64,
    pub alpha2: f64,
    pub alpha3: f64,
    pub alpha4: f64,
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

/// How a number key's bound reads: an interval of reals or a range of counts.
#[derive(Clone, Copy, Debug)]
enum Span {
    /// `[lo, hi]`.
    Closed,
    /// `(lo, hi]`.
    AboveTo,
    /// `[lo, hi)`.
    FromBelow,
    /// `(lo, hi)`.
    Open,
    /// Whole numbers `lo..=hi`.
    Count,
}

/// The bound of one number key: what is physically meaningful for it and what keeps a run's time
/// and memory in reason. `configs/default.toml` states each in the key's comment (`# Bound: …`, the
/// same text the error gives; a unit test holds the two together).
#[derive(Clone, Copy, Debug)]
struct Bound {
    key: &'static str,
    lo: f64,
    hi: f64,
    span: Span,
}

const fn b(key: &'static str, span: Span, lo: f64, hi: f64) -> Bound {
    Bound { key, lo, hi, span }
}

use Span::{AboveTo, Closed, Count, FromBelow, Open};

/// Every number key of the tree, in the order of `configs/default.toml`.
const BOUNDS: &[Bound] = &[
    b("seed", Count, 0.0, 9_223_372_036_854_775_807.0),
    b("sim.dt_s", Closed, 0.001, 1.0),
    b("sim.budget_s", AboveTo, 0.0, 1e6),
    b("sim.stuck_timeout_s", AboveTo, 0.0, 1e6),
    b("sim.stuck_min_gain_m3", Closed, 0.0, 1000.0),
    b("sim.curve_interval_s", Closed, 0.01, 1e6),
    b("sim.random_spawn_margin_m", Closed, 0.0, 10.0),
    b("scene.wall_height_m", AboveTo, 0.0, 100.0),
    b("scene.max_extent_m", AboveTo, 0.0, 10_000.0),
    b("map.voxel_m", Closed, 0.01, 1.0),
    b("map.margin_m", Closed, 0.0, 10.0),
    b("map.band_min_m", Closed, 0.0, 10.0),
    b("map.band_max_m", AboveTo, 0.0, 10.0),
    b("map.log_odds_hit", AboveTo, 0.0, 100.0),
    b("map.log_odds_miss", FromBelow, -100.0, 0.0),
    b("map.log_odds_min", FromBelow, -100.0, 0.0),
    b("map.log_odds_max", AboveTo, 0.0, 100.0),
    b("map.log_odds_occupied", Closed, -100.0, 100.0),
    b("map.column_known_fraction", Closed, 0.0, 1.0),
    b("map.inflation_margin_m", Closed, 0.0, 2.0),
    b("map.proximity_band_m", Closed, 0.0, 2.0),
    b("map.frontier_segment_max_m", AboveTo, 0.0, 100.0),
    b("map.frontier_min_cells", Count, 0.0, 100_000.0),
    b("camera.hfov_deg", Open, 0.0, 180.0),
    b("camera.vfov_deg", Open, 0.0, 180.0),
    b("camera.min_range_m", Closed, 0.0, 100.0),
    b("camera.max_range_m", AboveTo, 0.0, 100.0),
    b("camera.width", Count, 1.0, 2048.0),
    b("camera.height", Count, 1.0, 2048.0),
    b("camera.mount_height_m", AboveTo, 0.0, 10.0),
    b("camera.rate_hz", AboveTo, 0.0, 1000.0),
    b("robot.radius_m", AboveTo, 0.0, 5.0),
    b("robot.height_m", AboveTo, 0.0, 10.0),
    b("robot.max_speed_mps", AboveTo, 0.0, 10.0),
    b("robot.max_turn_rate_rps", AboveTo, 0.0, 20.0),
    b(
        "motion.turn_in_place_rad",
        AboveTo,
        0.0,
        std::f64::consts::PI,
    ),
    b("motion.lookahead_m", AboveTo, 0.0, 100.0),
    b("motion.goal_tolerance_m", AboveTo, 0.0, 10.0),
    b("motion.slow_clearance_m", Closed, 0.0, 10.0),
    b("search.near_unknown_radius_m", Closed, 0.0, 10.0),
    b("search.proximity_cost", Closed, 0.0, 1e6),
    b("greedy.view_distance_m", Closed, 0.0, 100.0),
    b("field.d_s_m", Closed, 0.02, 10.0),
    b("field.sigma_m", Closed, 0.01, 10.0),
    b("field.decay", AboveTo, 0.0, 100.0),
    b("field.tangent_radius_m", AboveTo, 0.0, 5.0),
    b("field.min_tangent_anisotropy", Closed, 0.0, 1.0),
    b("field.weight_cutoff", Open, 0.0, 1.0),
    b("field.path_strength", Closed, 0.0, 1e6),
    b("field.keyframe_period_s", Closed, 0.01, 1e6),
    b("field.substeps", Count, 1.0, 1000.0),
    b("field.omega_s", AboveTo, 0.0, 1e6),
    b("field.omega_t", AboveTo, 0.0, 1e6),
    b("field.alpha", AboveTo, 0.0, 1e9),
    b("field.timevary_radius_m", AboveTo, 0.0, 50.0),
    b("field.timevary_max_iterations", Count, 0.0, 100_000.0),
    b("field.topology_sigma_factor", AboveTo, 0.0, 100.0),
    b("field.topology_cell_factor", Count, 1.0, 16.0),
    b("field.track_radius_m", Closed, 0.0, 10.0),
    b("field.min_clearance_m", Closed, 0.0, 10.0),
    b("field.rk4_step_m", Closed, 0.001, 1.0),
    b("field.separatrix_max_length_m", Closed, 0.0, 10_000.0),
    b("field.arrive_radius_m", AboveTo, 0.0, 10.0),
    b("field.cancel_max_iterations", Count, 0.0, 100_000.0),
    b("field.trisector_clearance_m", Closed, 0.0, 10.0),
    b("field.max_move_m", Closed, 0.0, 100.0),
    b("thp.field_period_s", Closed, 0.01, 1e6),
    b("thp.d_f_m", AboveTo, 0.0, 100.0),
    b("thp.d_g_m", AboveTo, 0.0, 100.0),
    b("thp.d_p_m", AboveTo, 0.0, 100.0),
    b("thp.kmeans_cluster_m", AboveTo, 0.0, 100.0),
    b("thp.exact_tsp_max_nodes", Count, 1.0, 20.0),
    b("thp.cost_refresh_s", AboveTo, 0.0, 1e6),
    b("thp.cost_refresh_rows_max", Count, 1.0, 10_000.0),
    b("thp.advect_length_m", AboveTo, 0.0, 100.0),
    b("thp.drift_m", AboveTo, 0.0, 100.0),
    b("thp.view_distance_m", Closed, 0.0, 100.0),
    b("tensor.min_info_gain", Closed, 0.0, 1.0),
    b("tensor.gain_radius_m", AboveTo, 0.0, 50.0),
    b("tensor.advect_substeps", Count, 1.0, 1000.0),
    b("tensor.dock_radius_m", AboveTo, 0.0, 10.0),
    b("tensor.wall_clearance_m", Closed, 0.0, 10.0),
    b("tensor.look_spacing_m", Closed, 0.0, 100.0),
    b("tensor.stall_timeout_s", AboveTo, 0.0, 1e6),
    b("nbv.eta", Closed, 0.0, 10.0),
    b("nbv.sample_radius_m", AboveTo, 0.0, 50.0),
    b("nbv.max_viewpoints", Count, 1.0, 10_000.0),
    b("nbv.misses_per_m2", Closed, 0.0, 1000.0),
    b("nbv.min_misses", Count, 0.0, 1e7),
    b("nbv.gain_ray_stride", Count, 1.0, 4096.0),
    b("nbv.visibility_length_m", AboveTo, 0.0, 10.0),
    b("nbv.gain_cutoff_m3", Closed, 0.0, 1e6),
    b("nbv.cover_min_visibility", Closed, 0.0, 1.0),
    b("nbv.ga_population", Count, 1.0, 100_000.0),
    b("nbv.ga_group_size", Count, 1.0, 100_000.0),
    b("nbv.ga_generations", Count, 0.0, 1e6),
    b("nbv.ga_stall_generations", Count, 0.0, 1e6),
    b("additions.viewpoint_looks", Count, 0.0, 255.0),
    b("additions.viewpoint_away_m", Closed, 0.0, 100.0),
    b("additions.approach_attempts", Count, 1.0, 1000.0),
    b("additions.unreached_give_up_m", Closed, 0.0, 100.0),
    b("additions.blind_zone_look_first_m", Closed, 0.0, 1e6),
    b("additions.volume_view_gain_cutoff_m3", Closed, 0.0, 1e6),
    b("additions.volume_view_spacing_m", AboveTo, 0.0, 100.0),
    b("additions.reopen_max", Count, 0.0, 255.0),
    b("additions.escape_tries", Count, 0.0, 1000.0),
    b("additions.escape_clearance_m", Closed, 0.0, 10.0),
    b("additions.way_out_m", Closed, 0.0, 100.0),
    b("additions.advection_stall_s", Closed, 0.0, 1e6),
    b("additions.field_range_m", Closed, 0.0, 1000.0),
    b("log.depth_every_n", Count, 0.0, 1e6),
    b("log.map_every_s", Closed, 0.01, 1e6),
    b("log.zstd_level", Count, 1.0, 19.0),
    b("log.chunk_size_kb", Count, 1.0, 65_536.0),
    b("metrics.observable_spacing_m", Closed, 0.01, 10.0),
    b("metrics.observable_yaws", Count, 1.0, 64.0),
    b("noise.depth.axial_base_m", Closed, 0.0, 1.0),
    b("noise.depth.axial_quadratic_per_m", Closed, 0.0, 1.0),
    b("noise.depth.axial_offset_m", Closed, 0.0, 10.0),
    b("noise.depth.axial_angle_m", Closed, 0.0, 1.0),
    b("noise.depth.lateral_px", Closed, 0.0, 100.0),
    b("noise.depth.lateral_angle_px", Closed, 0.0, 100.0),
    b("noise.depth.focal_px", AboveTo, 0.0, 100_000.0),
    b("noise.depth.baseline_m", AboveTo, 0.0, 10.0),
    b("noise.depth.subpixel_px", Closed, 0.0, 100.0),
    b("noise.depth.disparity_step_px", Closed, 0.0, 100.0),
    b("noise.depth.dropout", Closed, 0.0, 1.0),
    b("noise.depth.grazing_dropout", Closed, 0.0, 1.0),
    b("noise.depth.grazing_start_deg", FromBelow, 0.0, 90.0),
    b("noise.depth.edge_dropout", Closed, 0.0, 1.0),
    b("noise.depth.edge_jump", AboveTo, 0.0, 100.0),
    b("noise.pose.alpha1", Closed, 0.0, 1.0),
    b("noise.pose.alpha2", Closed, 0.0, 1.0),
    b("noise.pose.alpha3", Closed, 0.0, 1.0),
    b("noise.pose.alpha4", Closed, 0.0, 1.0),
    b("noise.pose.sigma_xy_m", Closed, 0.0, 10.0),
    b("noise.pose.sigma_yaw_rad", Closed, 0.0, 1.0),
    b("noise.pose.time_constant_s", AboveTo, 0.0, 1e6),
    b("noise.motion.alpha1", Closed, 0.0, 1.0),
    b("noise.motion.alpha2", Closed, 0.0, 1.0),
    b("noise.motion.alpha3", Closed, 0.0, 1.0),
    b("noise.motion.alpha4", Closed, 0.0, 1.0),
];

impl Bound {
    /// The bound as the comment and the error state it: `[0.01, 1]`, `(0, 5]`, `1..=2048`.
    fn text(&self) -> String {
        let (lo, hi) = (
            crate::util::short_number(self.lo),
            crate::util::short_number(self.hi),
        );
        match self.span {
            Closed => format!("[{lo}, {hi}]"),
            AboveTo => format!("({lo}, {hi}]"),
            FromBelow => format!("[{lo}, {hi})"),
            Open => format!("({lo}, {hi})"),
            Count => format!("{}..={}", self.lo as i64, self.hi as i64),
        }
    }

    fn holds(&self, v: f64) -> bool {
        let (lo_ok, hi_ok) = match self.span {
            Closed | Count => (v >= self.lo, v <= self.hi),
            AboveTo => (v > self.lo, v <= self.hi),
            FromBelow => (v >= self.lo, v < self.hi),
            Open => (v > self.lo, v < self.hi),
        };
        lo_ok && hi_ok
    }

    /// Fails unless `v` lies in the bound, with the one-line error naming the key: a positive or
    /// non-negative key refused for its sign says so, as the checked numbers ([`Positive`],
    /// [`NonNegative`]) do.
    fn check(&self, value: &toml::Value) -> Result<()> {
        let (v, got) = match value {
            toml::Value::Integer(i) => (*i as f64, i.to_string()),
            toml::Value::Float(f) => (*f, crate::util::short_number(*f)),
            _ => return Ok(()),
        };
        if self.holds(v) {
            return Ok(());
        }
        let msg = match self.span {
            AboveTo if self.lo == 0.0 && (v.is_nan() || v <= 0.0) => {
                format!("must be a positive number, got {got}")
            }
            Closed if self.lo == 0.0 && (v.is_nan() || v < 0.0) => {
                format!("must be zero or positive, got {got}")
            }
            _ => format!("must lie in {}, got {got}", self.text()),
        };
        Err(Error::usage(format!("config key `{}` {msg}", self.key)))
    }
}

/// The value at dotted `key` of a config tree (sections may nest: `noise.depth.dropout`).
fn value_at<'a>(tree: &'a toml::Table, key: &str) -> Option<&'a toml::Value> {
    let mut parts = key.split('.');
    let mut value = tree.get(parts.next()?)?;
    for part in parts {
        value = value.as_table()?.get(part)?;
    }
    Some(value)
}

impl MapConfig {
    /// What relates the `map` keys to each other (each key's own bound is in [`BOUNDS`]).
    fn validate(&self) -> Result<()> {
        // The band takes the voxel layers whose centres lie in it; at or below half a voxel it
        // would take the floor's own layer, and every floor cell would be an obstacle.
        if self.band_min_m <= self.voxel_m / 2.0 {
            return Err(Error::usage(format!(
                "config key `map.band_min_m` ({}) must exceed half of `map.voxel_m` ({}), or the floor itself counts as an obstacle",
                self.band_min_m, self.voxel_m
            )));
        }
        if self.band_max_m <= self.band_min_m + self.voxel_m {
            return Err(Error::usage(format!(
                "config key `map.band_max_m` ({}) must exceed `map.band_min_m` ({}) by more than one voxel",
                self.band_max_m, self.band_min_m
            )));
        }
        if !(self.log_odds_min..self.log_odds_max).contains(&self.log_odds_occupied) {
            return Err(Error::usage(format!(
                "config key `map.log_odds_occupied` ({}) must lie in [`map.log_odds_min`, `map.log_odds_max`) ({}, {})",
                self.log_odds_occupied, self.log_odds_min, self.log_odds_max
            )));
        }
        Ok(())
    }
}

impl NbvConfig {
    fn validate(&self) -> Result<()> {
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

/// The dotted keys of `tree` whose values are numbers, in the order of the tree: the keys
/// [`BOUNDS`] must cover, and the ones a sweep over bad values walks.
pub fn number_keys(tree: &toml::Table) -> Vec<String> {
    fn walk(table: &toml::Table, prefix: &str, out: &mut Vec<String>) {
        for (k, v) in table {
            let key = format!("{prefix}{k}");
            match v {
                toml::Value::Table(t) => walk(t, &format!("{key}."), out),
                toml::Value::Integer(_) | toml::Value::Float(_) => out.push(key),
                _ => {}
            }
        }
    }
    let mut out = Vec::new();
    walk(tree, "", &mut out);
    out
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

    /// Rejects values that are of the right type but make no sense, naming the key: first each
    /// number against its bound ([`BOUNDS`], in the order of the file, so that a config with several
    /// faults names the first one), then what relates keys to each other.
    pub fn validate(&self) -> Result<()> {
        let seed = &BOUNDS[0];
        if self.seed > seed.hi as u64 {
            return Err(Error::usage(format!(
                "config key `seed` must lie in {}, got {}",
                seed.text(),
                self.seed
            )));
        }
        let tree = toml::Table::try_from(self).expect("a config with a bounded seed serialises");
        for bound in BOUNDS {
            if let Some(v) = value_at(&tree, bound.key) {
                bound.check(v)?;
            }
        }
        self.sim.validate()?;
        self.metrics.validate(self.map.voxel_m)?;
        self.map.validate()?;
        self.camera.validate()?;
        self.robot.validate(self.sim.dt_s)?;
        self.nbv.validate()?;
        Ok(())
    }
}

impl SimConfig {
    fn validate(&self) -> Result<()> {
        if self.dt_s > self.budget_s.get() {
            return Err(Error::usage(format!(
                "config key `sim.dt_s` ({}) must not exceed `sim.budget_s` ({}): the run would take no step",
                self.dt_s, self.budget_s.get()
            )));
        }
        Ok(())
    }
}

impl MetricsConfig {
    /// The observable set's spacing may not be finer than the map's voxels (`voxel_m`).
    fn validate(&self, voxel_m: f64) -> Result<()> {
        if self.observable_spacing_m < voxel_m {
            return Err(Error::usage(format!(
                "config key `metrics.observable_spacing_m` ({}) must be at least `map.voxel_m` ({})",
                self.observable_spacing_m, voxel_m
            )));
        }
        Ok(())
    }
}

impl CameraConfig {
    fn validate(&self) -> Result<()> {
        if self.min_range_m.get() >= self.max_range_m.get() {
            return Err(Error::usage(
                "config key `camera.min_range_m` must be below `camera.max_range_m`",
            ));
        }
        Ok(())
    }
}

impl RobotConfig {
    /// The robot's size and speeds, and the step `dt_s` they allow.
    fn validate(&self, dt_s: f64) -> Result<()> {
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
        .and_then(|mut t| t.remove("v"));
    // A whole number beyond TOML's 64-bit integers would otherwise be taken as a string.
    if value.is_none() && raw.parse::<i128>().is_ok() {
        let within = BOUNDS.iter().find(|b| b.key == key).map_or(
            "[-9223372036854775808, 9223372036854775807]".to_string(),
            Bound::text,
        );
        return Err(Error::usage(format!(
            "config key `{key}` must lie in {within}, got {raw}"
        )));
    }
    let value = value.unwrap_or_else(|| toml::Value::String(raw.to_string()));
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
            "config key `map.voxel_m` must lie in [0.01, 1], got -0.1"
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
            "config key `field.sigma_m` must lie in [0.01, 10], got 0"
        );
        let e = Config::load(None, &["thp.cost_refresh_rows_max=0".into()]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "config key `thp.cost_refresh_rows_max` must lie in 1..=10000, got 0"
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
    }

    /// Every number key has a bound, stated in its comment in `configs/default.toml` as the error
    /// states it; both profiles' defaults lie within.
    #[test]
    fn every_number_key_is_bounded_and_says_so() {
        let mut keys = number_keys(&default_tree());
        let mut bounded: Vec<String> = BOUNDS.iter().map(|b| b.key.to_string()).collect();
        keys.sort();
        bounded.sort();
        assert_eq!(keys, bounded);
        let lines: Vec<&str> = DEFAULT_TOML.lines().collect();
        let mut section = String::new();
        for (i, line) in lines.iter().enumerate() {
            if let Some(s) = line.strip_prefix('[').and_then(|s| s.strip_suffix(']')) {
                section = format!("{s}.");
                continue;
            }
            let Some((name, _)) = line.split_once(" = ").filter(|_| !line.starts_with('#')) else {
                continue;
            };
            let key = format!("{section}{name}");
            let Some(bound) = BOUNDS.iter().find(|b| b.key == key) else {
                continue;
            };
            let stated = format!("# Bound: {}", bound.text());
            let comment = lines[..i].iter().rev().take_while(|l| l.starts_with('#'));
            assert!(
                comment.clone().any(|l| l.starts_with(&stated)),
                "{key}: no `{stated}` line in its comment"
            );
        }
        for profile in [Profile::Tensorscout, Profile::Published] {
            Config::of_profile(profile).validate().unwrap();
        }
    }

    /// Each number key refuses what lies outside its bound with a one-line usage error naming it,
    /// and each of 0, -1, NaN, ±inf and 1e308 is either refused so or accepted.
    #[test]
    fn every_number_key_refuses_what_lies_outside() {
        for bound in BOUNDS {
            let key = bound.key;
            for raw in ["0", "-1", "nan", "inf", "-inf", "1e308", "1e20", "-1e308"] {
                match Config::load(None, &[format!("{key}={raw}")]) {
                    Ok(c) => {
                        let tree = toml::Table::try_from(&c).unwrap();
                        let v = value_at(&tree, key).unwrap();
                        assert!(bound.check(v).is_ok(), "{key}={raw} accepted as {v}");
                    }
                    Err(e) => {
                        let msg = e.to_string();
                        assert_eq!(e.exit_code(), 2, "{key}={raw}: {msg}");
                        assert!(!msg.contains('\n'), "{key}={raw}: {msg}");
                        assert!(
                            msg.contains(&format!("`{key}`")) || msg.contains(key),
                            "{key}={raw}: {msg}"
                        );
                    }
                }
            }
            let beyond = if matches!(bound.span, Count) {
                format!("{}", (bound.hi as i64).saturating_add(1))
            } else {
                format!("{:e}", bound.hi * 2.0 + 1.0)
            };
            if key != "seed" {
                let e = Config::load(None, &[format!("{key}={beyond}")]).unwrap_err();
                assert_eq!(
                    e.to_string(),
                    format!("config key `{key}` must lie in {}, got {}", bound.text(), {
                        let v: f64 = beyond.parse().unwrap();
                        if matches!(bound.span, Count) {
                            beyond.clone()
                        } else {
                            crate::util::short_number(v)
                        }
                    }),
                );
            }
        }
        let e = Config::load(None, &["seed=18446744073709551615".into()]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "config key `seed` must lie in 0..=9223372036854775807, got 18446744073709551615"
        );
        let e = Config::load(None, &["map.log_odds_occupied=nan".into()]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "config key `map.log_odds_occupied` must lie in [-100, 100], got NaN"
        );
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
