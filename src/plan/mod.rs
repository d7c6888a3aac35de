//! Planners and the searches they share.
//!
//! Every planner reads the same [`Map`] (and, for the tensor-field planners, the same field) through
//! a [`PlanContext`] and answers with an [`Action`]; the simulator's one motion executor carries it
//! out, so that comparisons between planners are fair.

pub(crate) mod frontier;
pub(crate) mod greedy;
pub(crate) mod nbv;
pub mod search;
pub(crate) mod tensor;
pub mod thp;
pub mod tsp;
pub(crate) mod view_gain;

use crate::config::{Additions, CameraConfig, Config, MotionConfig, RobotConfig, SearchConfig};
use crate::field::TensorField;
use crate::grid::{Cell, CellRect};
use crate::map::Map;
use crate::{Pose2, Result};
pub use frontier::VisitRules;
use nalgebra::Point2;
use search::Search;
use std::collections::BTreeMap;

/// What a planner sees: read-only views of the map and the robot, the configuration every planner
/// shares, plus a reusable search workspace.
pub struct PlanContext<'a> {
    pub map: &'a Map,
    pub pose: Pose2,
    pub time_s: f64,
    pub cfg: &'a PlanParams,
    pub search: &'a mut Search,
}

/// The configuration every planner shares, read through [`PlanContext::cfg`]: the shared cost rule
/// (`search`), the robot's body and speeds, and how the motion executor follows a path (its goal
/// tolerance). A planner's own section goes to its constructor instead.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanParams {
    pub search: SearchConfig,
    pub robot: RobotConfig,
    pub motion: MotionConfig,
    pub camera: CameraConfig,
    /// The rules no paper has, each with its switch (`[additions]`).
    pub additions: Additions,
}

impl From<&Config> for PlanParams {
    fn from(cfg: &Config) -> PlanParams {
        PlanParams {
            search: cfg.search.clone(),
            robot: cfg.robot.clone(),
            motion: cfg.motion.clone(),
            camera: cfg.camera.clone(),
            additions: cfg.additions.clone(),
        }
    }
}

impl PlanContext<'_> {
    /// The search cost of entering a cell now (see [`step_cost`]).
    pub fn step_cost(&self, cell: usize) -> Option<f32> {
        step_cost(self.map, &self.cfg.search, self.pose.position(), cell)
    }

    /// Whether the robot may enter a cell now.
    pub fn passable(&self, cell: usize) -> bool {
        self.step_cost(cell).is_some()
    }
}

/// The cost rule every search uses (see [`search`]): a cell may be entered if it is traversable, or
/// unknown and clear of every known obstacle's inflation when searches are optimistic or when it
/// lies within `near_unknown_radius_m` of the robot (the camera's blind zone around its own wheels).
/// Entering costs 1 per metre, plus `proximity_cost` near a known obstacle.
pub fn step_cost(map: &Map, cfg: &SearchConfig, robot: Point2<f64>, cell: usize) -> Option<f32> {
    let grid = map.grid();
    cost_rule(map, cfg, cell, || {
        near_robot(cfg, robot, grid.center(grid.cell(cell)))
    })
}

/// [`step_cost`] given whether the cell lies near the robot (asked only when it matters).
#[inline]
fn cost_rule(
    map: &Map,
    cfg: &SearchConfig,
    cell: usize,
    near_robot: impl FnOnce() -> bool,
) -> Option<f32> {
    let enterable = map.is_traversable(cell)
        || (map.is_unknown(cell)
            && !map.is_inflated(cell)
            && (cfg.unknown_is_free || near_robot()));
    enterable.then(|| {
        if map.is_near_obstacle(cell) {
            1.0 + cfg.proximity_cost as f32
        } else {
            1.0
        }
    })
}

/// Whether `p` lies within `near_unknown_radius_m` of the robot.
#[inline]
fn near_robot(cfg: &SearchConfig, robot: Point2<f64>, p: Point2<f64>) -> bool {
    (p - robot).norm_squared() <= cfg.near_unknown_radius_m * cfg.near_unknown_radius_m
}

/// [`step_cost`] of every cell, for a planning step that runs several searches from one robot
/// position: one evaluation per cell instead of one per neighbour visit of every search.
#[derive(Clone, Default)]
pub struct StepCosts {
    costs: Vec<f32>,
    /// Every cell ever given a finite cost lies in it; the cells outside hold infinity.
    filled: CellRect,
}

impl StepCosts {
    pub fn new(map: &Map, cfg: &SearchConfig, robot: Point2<f64>) -> Self {
        let mut costs = StepCosts::default();
        costs.refill(map, cfg, robot);
        costs
    }

    /// Re-evaluates every cell for a new map and robot position, reusing the buffer. Only cells a
    /// search could enter are evaluated: those the map has touched and those near the robot (all of
    /// them when unknown space counts as free); the rest stay infinite. Walks row by row, so a
    /// cell's centre comes without an index division.
    pub fn refill(&mut self, map: &Map, cfg: &SearchConfig, robot: Point2<f64>) {
        let grid = map.grid();
        if self.costs.len() != grid.cells() {
            self.costs = vec![f32::INFINITY; grid.cells()];
            self.filled = CellRect::EMPTY;
        }
        let enterable = if cfg.unknown_is_free {
            CellRect::all(grid)
        } else {
            let near = CellRect::around(grid, robot, cfg.near_unknown_radius_m + grid.res);
            map.touched().union(near)
        };
        // The cells filled before are evaluated again: a cost may have become infinite.
        self.filled = self.filled.union(enterable);
        for (c, cell) in self.filled.cells(grid) {
            let cost = cost_rule(map, cfg, cell, || near_robot(cfg, robot, grid.center(c)));
            self.costs[cell] = cost.unwrap_or(f32::INFINITY);
        }
    }

    /// The cost of entering `cell`, as [`step_cost`] gives it.
    pub fn get(&self, cell: usize) -> Option<f32> {
        let c = self.costs[cell];
        c.is_finite().then_some(c)
    }
}

/// The cell searches start from: the robot's own cell, unless the robot stands where no neighbour
/// may be entered (pushed into an obstacle's inflation band, e.g. in a door barely wider than the
/// robot); then the nearest enterable cell within `2·radius`, which the motion executor drives to
/// first. `None` off the grid or with nothing enterable nearby.
pub fn search_source(
    map: &Map,
    cfg: &SearchConfig,
    robot: Point2<f64>,
    radius: f64,
) -> Option<usize> {
    let grid = map.grid();
    let here = grid.cell_of(robot)?;
    let open = |c: Cell| {
        grid.checked_index(c)
            .is_some_and(|i| step_cost(map, cfg, robot, i).is_some())
    };
    if crate::grid::NEIGHBOURS_8
        .iter()
        .any(|&(dx, dy)| open(Cell::new(here.x + dx, here.y + dy)))
    {
        return Some(grid.index(here));
    }
    let reach = (2.0 * radius / grid.res).ceil() as i32;
    let mut best: Option<(f64, usize)> = None;
    for dy in -reach..=reach {
        for dx in -reach..=reach {
            let c = Cell::new(here.x + dx, here.y + dy);
            if !open(c) {
                continue;
            }
            let i = grid.index(c);
            let d = (grid.center(c) - robot).norm();
            if d <= 2.0 * radius && best.is_none_or(|b| (d, i) < b) {
                best = Some((d, i));
            }
        }
    }
    best.map(|b| b.1)
}

/// A way out for a robot trapped in a pocket of the map: the cells reachable under [`step_cost`]
/// (`reachable`) hold no goal, because the robot entered through unknown space (its blind zone) a
/// door that the obstacles seen since have inflated shut. The escape search also enters inflated
/// cells that are physically clear (at least `robot.radius_m + clear_margin_m` from every known
/// obstacle surface), at three times the cost, and leads to the nearest of `targets` outside the
/// pocket: the open frontier cells, or, for a robot with no enterable cell around it at all, the
/// enterable cells nearby (THP's `way_out`). Only the inflated cells for which `may_squeeze` holds
/// are entered (THP: the cells beside the robot's own trail, the way it came in). Returns world
/// points from the robot.
pub fn escape_path(
    ctx: &mut PlanContext,
    source: usize,
    reachable: &search::DistanceField,
    targets: &[usize],
    clear_margin_m: f64,
    may_squeeze: impl Fn(usize) -> bool,
) -> Option<Vec<Point2<f64>>> {
    let (map, cfg, robot) = (ctx.map, &ctx.cfg.search, ctx.pose.position());
    let grid = *map.grid();
    let clear = ctx.cfg.robot.radius_m + clear_margin_m;
    let relaxed = |i: usize| {
        step_cost(map, cfg, robot, i).or_else(|| {
            (map.is_inflated(i) && !map.is_obstacle(i) && !map.is_unknown(i) && may_squeeze(i) && {
                let p = grid.center(grid.cell(i));
                map.nearest_obstacle_point(p, clear).is_none()
            })
            .then_some(3.0 * (1.0 + cfg.proximity_cost as f32))
        })
    };
    let df = ctx
        .search
        .distance_field(&grid, relaxed, source, f32::INFINITY);
    let target = targets
        .iter()
        .copied()
        .filter(|&i| reachable.cost_to(i).is_none())
        .filter_map(|i| df.cost_to(i).map(|c| (c, i)))
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))?;
    let path = df.path_to(&grid, target.1)?;
    Some(path.cells.iter().map(|c| grid.center(*c)).collect())
}

/// Length of a polyline, metres.
pub fn path_length(line: &[Point2<f64>]) -> f64 {
    line.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

/// How near the end of its path a robot following an `exact_arrival` action stops, metres.
pub const EXACT_ARRIVAL_M: f64 = 0.02;

/// What the robot should do next.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// Follow `path` (world points, the first near the robot) to its end; then, if `look_on_arrival`,
    /// turn once in place.
    ///
    /// The robot counts as arrived within `motion.goal_tolerance_m` of the end. With `exact_arrival`
    /// it drives on to within [`EXACT_ARRIVAL_M`] where its disc stays over seen floor (no Unknown
    /// cell under it): for a viewpoint chosen to see one voxel, 0.2 m off the cell centre is often
    /// out of sight of it, and the frontier was given up with the voxel unseen.
    Follow {
        path: Vec<Point2<f64>>,
        look_on_arrival: bool,
        exact_arrival: bool,
    },
    /// Turn once in place where the robot stands.
    LookAround,
    /// Nothing reachable is left to explore.
    Complete,
    /// The planner's method has no way to go on although it has not covered what it can reach (for
    /// TENSOR without its GREEDY fallback: no routing edge with gain while frontiers remain). The run
    /// ends `stuck` at once, and the planner counts the cause in its statistics.
    Stuck,
}

/// A planner: turns what is known into the next action.
///
/// The core is four methods; what only some planners do comes as optional capabilities
/// ([`Planner::field_planner`]) and run statistics ([`Planner::stats`]), both defaulted. See
/// `ARCHITECTURE.md` ("How to add a planner") and `examples/planner.rs`.
///
/// ```
/// use tensorscout::plan::{Action, Plan, PlanContext, Planner};
///
/// /// Turns in place once, then declares the exploration complete.
/// struct LookOnce(bool);
///
/// impl Planner for LookOnce {
///     fn name(&self) -> &'static str {
///         "look-once"
///     }
///     fn plan(&mut self, _ctx: &mut PlanContext) -> tensorscout::Result<Plan> {
///         let done = std::mem::replace(&mut self.0, true);
///         Ok(if done { Action::Complete } else { Action::LookAround }.into())
///     }
///     fn is_outdated(&mut self, _ctx: &PlanContext, _action: &Action) -> bool {
///         false
///     }
///     fn action_finished(&mut self, _ctx: &PlanContext, _reached: bool) {}
/// }
/// # let _ = LookOnce(false);
/// ```
pub trait Planner {
    /// The name used on the command line and in results.
    fn name(&self) -> &'static str;

    /// Chooses the next action, with what the planning step reports. Called when the previous
    /// action is done, blocked or outdated. An error ends the run with termination `error`.
    fn plan(&mut self, ctx: &mut PlanContext) -> Result<Plan>;

    /// Whether the action in progress should be abandoned for a new plan (checked every step).
    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool;

    /// Told when the action ended: reached (`true`) or blocked/abandoned (`false`).
    fn action_finished(&mut self, ctx: &PlanContext, reached: bool);

    /// Capability of the planners steered by a tensor field (THP, TENSOR): the simulation updates
    /// their field in the field stage of every step. `None` for planners without one.
    fn field_planner(&mut self) -> Option<&mut dyn FieldPlanner> {
        None
    }

    /// The planner's deterministic run statistics (`planner_stats` in the result), such as TSP
    /// solves or anchors visited: each planner keeps them typed ([`Count`] counters or plain
    /// fields) and writes them under their JSON keys here. Asked once, when the run ends, as field
    /// updates and finished actions count too.
    fn stats(&self) -> BTreeMap<String, f64> {
        BTreeMap::new()
    }
}

/// The capability of a planner steered by a tensor field.
pub trait FieldPlanner {
    /// The field stage of a step, before planning: update the field at the planner's key frames.
    fn update_field(&mut self, map: &Map, pose: Pose2, time_s: f64) -> Result<()>;

    /// The tensor field the planner steers by, once it has one (logged with `log.field`).
    fn field(&self) -> Option<&TensorField>;
}

/// A planning step's answer: the next action and what the step reports.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub action: Action,
    pub report: PlanReport,
}

impl Plan {
    /// A plan with its tour and TSP time (see [`PlanReport`]).
    pub fn new(action: Action, tour: Vec<Point2<f64>>, tsp_ms: Option<f64>) -> Plan {
        Plan {
            action,
            report: PlanReport { tour, tsp_ms },
        }
    }
}

impl From<Action> for Plan {
    /// A plan that reports nothing beyond its action.
    fn from(action: Action) -> Plan {
        Plan {
            action,
            report: PlanReport::default(),
        }
    }
}

/// What a planning step reports besides its action.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlanReport {
    /// The planned visiting order of goals (world points, next goal first), for logs and
    /// pictures; empty for planners without one.
    pub tour: Vec<Point2<f64>>,
    /// Wall milliseconds spent solving TSPs in this step, if one was solved (THP Fig. 8 plots it
    /// per planning step). Not deterministic: reported with the stage timings.
    pub tsp_ms: Option<f64>,
}

/// The distance the robot moved between the planner's calls, for splitting its path by goal
/// (`path_m_*` in `planner_stats`). The planners see the robot once a step (`plan` or
/// `is_outdated`), so the sum of the parts is the path driven.
#[derive(Clone, Copy, Debug, Default)]
pub struct Odometer {
    last: Option<Point2<f64>>,
}

impl Odometer {
    /// The distance from the position at the last call to `p` (0 on the first call).
    pub fn advance(&mut self, p: Point2<f64>) -> f64 {
        self.last.replace(p).map_or(0.0, |q| (p - q).norm())
    }
}

/// One counter of a planner's typed statistics. It enters `planner_stats` once counted: a counter
/// never touched in a run is left out of the result.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Count(Option<f64>);

impl Count {
    /// Adds `by`.
    pub fn add(&mut self, by: f64) {
        self.0 = Some(self.0.unwrap_or(0.0) + by);
    }

    /// Raises the counter to `v` if it is below (a running maximum).
    pub fn raise_to(&mut self, v: f64) {
        self.0 = Some(self.0.unwrap_or(0.0).max(v));
    }

    /// The value, if counted.
    pub fn get(self) -> Option<f64> {
        self.0
    }
}

/// `planner_stats` from named counters: the counted ones, under their names.
pub fn counted<'a>(counters: impl IntoIterator<Item = (&'a str, Count)>) -> BTreeMap<String, f64> {
    counters
        .into_iter()
        .filter_map(|(k, c)| c.get().map(|v| (k.to_string(), v)))
        .collect()
}

/// A planner borrowed from its owner is a planner too (benches keep the planner they wrap, to read
/// what it recorded after the run).
impl<P: Planner + ?Sized> Planner for &mut P {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn plan(&mut self, ctx: &mut PlanContext) -> Result<Plan> {
        (**self).plan(ctx)
    }
    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool {
        (**self).is_outdated(ctx, action)
    }
    fn action_finished(&mut self, ctx: &PlanContext, reached: bool) {
        (**self).action_finished(ctx, reached)
    }
    fn field_planner(&mut self) -> Option<&mut dyn FieldPlanner> {
        (**self).field_planner()
    }
    fn stats(&self) -> BTreeMap<String, f64> {
        (**self).stats()
    }
}

/// The planners a run can use.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, clap::ValueEnum, serde::Serialize,
)]
#[serde(rename_all = "lowercase")]
pub enum PlannerKind {
    /// Tensor-field-driven hierarchical planning (THP).
    Thp,
    /// Time-varying tensor-field exploration (TENSOR).
    Tensor,
    /// Two-stage next-best-view planning with a TSP (NBV-TSP).
    Nbv,
    /// Nearest frontier (Yamauchi 1997).
    Greedy,
}

impl PlannerKind {
    /// The name used on the command line and in results.
    pub fn name(self) -> &'static str {
        match self {
            PlannerKind::Thp => "thp",
            PlannerKind::Tensor => "tensor",
            PlannerKind::Nbv => "nbv",
            PlannerKind::Greedy => "greedy",
        }
    }

    /// The name results and bench tables carry under `cfg`: the command-line name, except that TENSOR
    /// with its GREEDY hand-over on is `tensor+greedy`, and a run under the `published` profile has
    /// `/published` after its name (`greedy/published`), so that rows of different rules are never
    /// averaged together. A bare name is the default profile.
    pub fn label(self, cfg: &Config) -> String {
        let name = match self {
            PlannerKind::Tensor if cfg.tensor.fallback => tensor::FALLBACK_LABEL,
            _ => self.name(),
        };
        match cfg.profile {
            crate::config::Profile::Tensorscout => name.to_string(),
            profile => format!("{name}/{}", profile.name()),
        }
    }

    /// A fresh planner of this kind. Every built-in planner is `Send`, so that a simulation can move
    /// to another thread (the Python bindings' vector environment steps simulations on a pool).
    pub fn build(self, cfg: &Config) -> Result<Box<dyn Planner + Send>> {
        match self {
            PlannerKind::Greedy => Ok(Box::new(greedy::Greedy::new(
                &cfg.greedy,
                (&cfg.additions).into(),
                frontier::VolumeViews::new(&cfg.into()),
            ))),
            PlannerKind::Thp => Ok(Box::new(thp::Thp::new(&thp::ThpParams::from(cfg)))),
            PlannerKind::Tensor => Ok(Box::new(tensor::Tensor::new(&cfg.into()))),
            PlannerKind::Nbv => Ok(Box::new(nbv::Nbv::new(&cfg.into()))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridSpec;
    use crate::map::testing::seen_from;
    use crate::scene::TriMesh;
    use crate::sensor::raycast::testing::push_box;
    use crate::sensor::raycast::MeshBvh;

    /// The per-step table of costs agrees with the cost rule cell by cell, for pessimistic and
    /// optimistic searches, on a map that holds every kind of cell.
    #[test]
    fn step_costs_agree_with_the_cost_rule() {
        let mut cfg = Config::default();
        let grid = GridSpec::covering(
            Point2::new(-4.0, -4.0),
            Point2::new(4.0, 4.0),
            cfg.map.band_max_m,
            cfg.map.voxel_m,
        );
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [-9.0, -9.0, -0.1], [9.0, 9.0, 0.0]);
        push_box(&mut mesh, [2.0, -0.5, 0.0], [2.5, 0.5, 1.0]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let robot = Point2::new(0.0, 0.0);
        let map = seen_from(grid, &cfg, &bvh, [Pose2::new(robot.x, robot.y, 0.0)]);
        for unknown_is_free in [false, true] {
            cfg.search.unknown_is_free = unknown_is_free;
            let table = StepCosts::new(&map, &cfg.search, robot);
            let mut kinds = BTreeMap::new();
            let mut unknown_enterable = [0, 0];
            for cell in 0..grid.cells() {
                let expected = step_cost(&map, &cfg.search, robot, cell);
                assert_eq!(table.get(cell), expected, "cell {cell}");
                *kinds.entry(format!("{expected:?}")).or_insert(0) += 1;
                if map.is_unknown(cell) && !map.is_inflated(cell) {
                    unknown_enterable[usize::from(expected.is_some())] += 1;
                }
            }
            // Blocked, plain and near-obstacle cells all occur; pessimistic searches enter unknown
            // cells (clear of inflation) only in the blind zone around the robot.
            assert_eq!(kinds.len(), 3, "{kinds:?}");
            assert!(unknown_enterable[1] > 0, "{unknown_enterable:?}");
            assert_eq!(
                unknown_enterable[0] > 0,
                !unknown_is_free,
                "{unknown_enterable:?}"
            );
        }
    }

    /// One table, refilled as the map grows, the robot moves into never-seen space and the rule
    /// turns optimistic and back, agrees with the cost rule cell by cell each time.
    #[test]
    fn a_refilled_table_agrees_with_the_cost_rule() {
        let mut cfg = Config::default();
        let grid = GridSpec::covering(
            Point2::new(-10.0, -10.0),
            Point2::new(10.0, 10.0),
            cfg.map.band_max_m,
            cfg.map.voxel_m,
        );
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [-19.0, -19.0, -0.1], [19.0, 19.0, 0.0]);
        push_box(&mut mesh, [2.0, -0.5, 0.0], [2.5, 0.5, 1.0]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let mut table = StepCosts::default();
        let mut poses = Vec::new();
        let steps = [
            (0.0, 0.0, false),
            (-3.0, 1.0, false),
            (-3.0, 1.0, true),
            (8.0, -8.0, false),
        ];
        for (k, &(x, y, unknown_is_free)) in steps.iter().enumerate() {
            poses.push(Pose2::new(x, y, k as f64 * 2.0));
            let map = seen_from(grid, &cfg, &bvh, poses.iter().copied());
            assert_ne!(map.touched(), CellRect::all(&grid), "step {k}");
            let robot = Point2::new(x, y);
            cfg.search.unknown_is_free = unknown_is_free;
            table.refill(&map, &cfg.search, robot);
            let mut enterable = 0;
            for cell in 0..grid.cells() {
                let expected = step_cost(&map, &cfg.search, robot, cell);
                assert_eq!(table.get(cell), expected, "step {k} cell {cell}");
                enterable += usize::from(expected.is_some());
            }
            assert!(enterable > 0, "step {k}");
        }
    }
}
