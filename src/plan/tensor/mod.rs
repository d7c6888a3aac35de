//! TENSOR: exploration guided by a time-varying tensor field (Xu et al., "Autonomous reconstruction of unknown indoor scenes guided by
//! time-varying tensor fields", ACM TOG 2017, §4–6).
//!
//! - **Field in time.** The planner owns a [`TensorField`] on the map's grid, updated every key
//!   frame (`field.keyframe_period_s`, 4 s). Between key frames the field moves from the previous
//!   key frame `T^{t-1}` to the new one `T^t` through the engine's space-time bi-harmonic
//!   interpolation (Eq. 4–5) on a window around the robot; outside the window, the point-wise linear
//!   interpolation the window's rim is fixed to. As in Alg. 1 the robot starts on the middle frame
//!   `T_{K/2}` at a key frame and reaches `T_K = T^t` at the next one.
//! - **Advection.** Every sub-step (`period / K`, 0.4 s) the pathline is traced through the
//!   time-varying field for `advect_substeps` (3) sub-steps at full speed, oriented by the robot's
//!   heading (the line field has no sign), cut at the first cell the shared cost rule forbids, and
//!   followed for one sub-step by the shared motion executor.
//! - **Wedges.** A pathline that ends at a wedge ends the path there (the executor slows down over
//!   a path's last half metre); there the robot stops and re-plans (and, when the wedge's branches
//!   offer no information, routes globally).
//! - **Trisectors.** A pathline that comes within `dock_radius_m` of a trisector and leaves it again
//!   (§6) is cut at its closest approach and ends at the trisector (docking); there the branch is
//!   chosen by routing over the minimum spanning tree rooted at the trisector (below).
//! - **Global routing (§4.2).** Edge cost `c(e) = 1 / Ī(e)`, `Ī` the length-weighted mean of the
//!   information gain `I(p)` along the edge. The graph is the topology graph's edges plus each node's
//!   open separatrices (leaves: lines into unknown space are where information is). Prim's tree is
//!   grown from the root (the docked trisector, the wedge, or the nearest node, reached by A* first
//!   when the robot is not on the graph); the target is the edge with `Ī ≥ min_info_gain` whose
//!   tree path from the root plus its own cost is cheapest, and the branch is the first hop on it.
//! - **Information gain.** `I(p) = min(1, n_f / n_side)`: `n_f` observable frontier cells (reachable,
//!   not given up) in the square of half-size `gain_radius_m` around `p`, `n_side` the cells along
//!   the square's side, so a frontier crossing the whole view square gives 1 and one frontier cell
//!   gives `res / (2 gain_radius_m)` (0.025 by default). The paper's `I` is the entropy a best view
//!   at `p` removes; frontier cells stand in for it (no TSDF, no view sampling here).
//! - **Safety (§6).** A body (the disc's edge) closer than `wall_clearance_m` to a known wall first
//!   moves away along the wall's normal when the known free space allows a gain of 0.1 m or more (at
//!   most once per key-frame period); a pathline into unknown space makes the robot look around
//!   before entering, at most once within `look_spacing_m` (the paper adds a look-at view to its
//!   arm-held camera; the camera here is fixed, so the robot turns).
//! - **Termination.** `Complete` when no accessible edge has `Ī ≥ min_info_gain` and no reachable,
//!   observable frontier is left. An edge is accessible when its nearer node is reachable and at
//!   least 90 % of its samples are outside every known obstacle's inflation (a contact test of the
//!   robot's body against the known scene; unknown cells pass, as in the paper).
//!
//! **States.** Two enums hold the planner's state, each changed in one place:
//! - [`Mode`], who drives the robot, changes only in [`Mode::next`] on an [`Event`]:
//!
//!   | mode | drives | `NoRoute` | `Stalled` (with `tensor.fallback`) | `LegReached` | `GainAgain`, `Arrived` |
//!   |---|---|---|---|---|---|
//!   | `Field` | advection, docking, routing, safety moves | `UntilGain` | `Leg` | — | — |
//!   | `UntilGain` | GREEDY | — | `LegThenUntilGain` | — | `Field` |
//!   | `Leg` | GREEDY | `LegThenUntilGain` | — | `Field` | — |
//!   | `LegThenUntilGain` | GREEDY | — | — | `UntilGain` | `Leg` |
//!
//!   `NoRoute`: routing offered no reachable node or no accessible edge with gain (without
//!   `tensor.fallback` the run then ends `complete` or `stuck`, see [`fallback`]). `Stalled`:
//!   advection saw nothing new twice in a row, or nothing new was seen in any mode for three stall
//!   timeouts; without `tensor.fallback` it changes nothing. `LegReached`: a GREEDY action reached
//!   its goal. `GainAgain`: checked at every planning step in `UntilGain`. `Arrived`: planning at a
//!   node (never met in `UntilGain` in practice, as every GREEDY mode plans with GREEDY).
//! - [`Current`], the action in progress and what it is for (`Advect`, `Dock`, `Route`, `Escape`,
//!   `Look`, `Fallback`), set where the action is chosen. When the action ends (`action_finished`,
//!   one `match`) it becomes what its end asks the next planning step to do first: `Arrived` at a
//!   node (a wedge reached, a trisector docked, a routed node reached), `Recover` (`Look`, then
//!   `StepClear`, when the executor refused to move at all), or `None`.
//!
//! A planning step ([`Tensor::next_action`]) takes, in this order: the `Recover` or `Arrived` that
//! `Current` holds; the long stall watchdog; the mode (a GREEDY mode plans with GREEDY; `UntilGain`
//! first checks the graph); the advection stall watchdog (routing from the nearest node); the wall
//! escape; advection. Beside the two enums the planner keeps memory, not modes: the node just
//! handled (`ignore`), a heading for the next pathline (`heading_override`), the watchdogs' clocks,
//! the refusal count, and `outdated`, which `is_outdated` hands to the `action_finished` call that
//! follows it.
//!
//! The parts: [`following`] (advection, wedge stops, docking, planning after an arrival),
//! [`routing`] (information gain, the routing graph, Prim's tree, the target edge), [`safety`] (wall
//! escape, stepping clear) and [`fallback`] (the termination rule, or the GREEDY hand-over); this
//! file holds the planner's state, the field in time and the planning step that ties them together.
//!
//! Deviations, each to keep the comparison fair or the run finite:
//! - **Fallback (option `tensor.fallback`, off by default).** Off, the paper's termination rule
//!   holds: when the graph offers nothing while a reachable, observable frontier remains, the method
//!   has failed and the run ends `stuck` (counted as `stuck_no_route`). On (results labelled
//!   `tensor+greedy`): when the graph offers nothing (no node reachable or no edge with gain) while
//!   frontiers remain reachable, the robot drives to the nearest frontier with A* (the GREEDY planner,
//!   embedded, so that its give-up rules for unobservable frontiers are shared); it advects again
//!   as soon as an edge has gain. One GREEDY leg (until it reaches its goal) is also driven when
//!   advection twice in a row reveals nothing for `stall_timeout_s`, or when nothing new has been
//!   seen for three times that in any mode (routes that lead nowhere). Observed: the pathlines
//!   follow wall tangents, so around a free-standing table or a room-centre wedge the field is a
//!   closed loop and the robot circles it; trisectors sit at doorways, which pathlines rarely pass
//!   within the docking radius. Without these hand-overs, early versions of this planner ended
//!   `stuck` on `apartment_small` and `apartment_loop`. The counters
//!   `fallback_plans` and `stalls` say how often it happened.
//! - **Pinned by the guard.** When the shared executor refuses to move at all (its guard counts
//!   never-seen cells beside the robot as hazards), the robot first looks around, then steps straight
//!   away from the nearest hazard, before the failure is counted; otherwise one pinned spot would
//!   make the fallback give up every frontier in a row.
//! - **Out of scope.** The camera stays fixed and forward-facing: the arm trajectory optimisation of
//!   §5 (Eq. 7–9, view selection, Gurobi) is not implemented. Moving a wedge inward after a
//!   round trip (Fig. 9b) is not implemented either; the wedge's branches are routed away from
//!   instead once they offer no gain.

use super::greedy::Greedy;
use super::{path_length, Action, FieldPlanner, Plan, PlanContext, Planner};
use crate::config::{Config, FieldConfig, GreedyConfig, TensorConfig};
use crate::field::advect::{trace, StopConditions, StopReason};
use crate::field::{
    biharmonic_window, DegenerateKind, FieldGrid, SpaceTimeParams, TensorField, TimeVaryingField,
};
use crate::grid::{Cell, GridSpec};
use crate::map::Map;
use crate::{Pose2, Result};
use nalgebra::{Point2, Vector2};
use std::collections::BTreeMap;

mod fallback;
mod following;
mod routing;
mod safety;

use routing::RouteEdge;
#[cfg(test)]
use routing::{leaving_heading, min_spanning_tree, select_target, GainMap};

/// Gain floor in `c(e) = 1 / max(Ī, GAIN_FLOOR)`: edges without gain keep a finite cost, so the
/// tree spans every reachable node.
const GAIN_FLOOR: f64 = 1e-3;
/// The planner's name in results with the GREEDY hand-over on (`tensor.fallback`).
pub const FALLBACK_LABEL: &str = "tensor+greedy";
/// Fraction of an edge's samples that must pass the contact test for the edge to be accessible.
const ACCESSIBLE_FRACTION: f64 = 0.9;
/// A node is snapped to a reachable cell within this distance, metres.
const SNAP_M: f64 = 0.5;
/// Newly known cells that count as progress for the stall watchdog.
const PROGRESS_CELLS: usize = 5;
/// Shortest pathline worth following beyond the goal tolerance, metres; shorter means advection is
/// blocked here.
const MIN_ADVANCE_M: f64 = 0.15;
/// Failed approaches after which a node is no longer routed to.
const MAX_NODE_FAILURES: u32 = 2;
/// Conjugate-gradient tolerance of the space-time solve (relative residual).
const SPACE_TIME_TOLERANCE: f64 = 1e-6;

/// What the routing step decided.
enum Routed {
    /// The robot is at the entry node: leave it along this heading.
    Leave { heading: f64, node_id: u64 },
    /// Drive there first.
    Go(Action),
    /// No accessible edge with gain (or no reachable node).
    Nothing,
}

/// Why the robot is where it is, when it arrives.
#[derive(Clone, Copy, Debug, PartialEq)]
enum ArrivalKind {
    Wedge,
    Dock,
    Route { heading: Option<f64> },
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Arrival {
    id: u64,
    kind: ArrivalKind,
}

/// A move out of a spot where the executor's guard refused to move at all.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Recovery {
    /// Look around (which shows the never-seen cells the guard counts as hazards).
    Look,
    /// Step straight away from the nearest hazard.
    StepClear,
}

/// The action in progress and what it is for; once an action has ended, what its end asks the next
/// planning step to do first (`Arrived`, `Recover`), else `None`.
#[derive(Clone, Debug, PartialEq)]
enum Current {
    None,
    /// At a node: plan there next (set when an action ends there, or for a look in the node's own
    /// cell, which the arrival outlives).
    Arrived(Arrival),
    /// The executor refused to move: this recovery next.
    Recover(Recovery),
    Advect {
        started_s: f64,
        cells: Vec<usize>,
        wedge: Option<(u64, Point2<f64>)>,
    },
    Dock {
        id: u64,
        pos: Point2<f64>,
        cells: Vec<usize>,
    },
    Route {
        id: u64,
        pos: Point2<f64>,
        heading: Option<f64>,
        cells: Vec<usize>,
    },
    Escape,
    Look,
    Fallback,
}

/// Who drives the robot; see the module doc's states. It changes only in [`Mode::next`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    /// The field drives: advection, docking, routing over the topology graph, safety moves.
    Field,
    /// GREEDY drives until the routing graph offers an accessible edge with gain again.
    UntilGain,
    /// GREEDY drives until one of its legs reaches its goal; then the field again.
    Leg,
    /// GREEDY drives until one of its legs reaches its goal; then until the graph offers gain.
    LegThenUntilGain,
}

/// What changes the [`Mode`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Event {
    /// Routing offered nothing: no reachable node, or no accessible edge with gain.
    NoRoute,
    /// Nothing new seen for long: advection stalled twice in a row, or nothing new in any mode for
    /// three stall timeouts.
    Stalled,
    /// A GREEDY leg reached its goal.
    LegReached,
    /// The routing graph offers an accessible edge with gain again.
    GainAgain,
    /// The robot arrived at a node (and plans there).
    Arrived,
}

impl Mode {
    /// The transition table. `hand_over` is `tensor.fallback`: without it a stall starts no GREEDY
    /// leg (and `NoRoute` ends the run in [`Tensor::fallback`], whatever the mode).
    fn next(self, event: Event, hand_over: bool) -> Mode {
        use Mode::*;
        match (event, self) {
            (Event::NoRoute, Field | UntilGain) => UntilGain,
            (Event::NoRoute, Leg | LegThenUntilGain) => LegThenUntilGain,
            (Event::Stalled, m) if !hand_over => m,
            (Event::Stalled, Field | Leg) => Leg,
            (Event::Stalled, UntilGain | LegThenUntilGain) => LegThenUntilGain,
            (Event::LegReached, Leg) => Field,
            (Event::LegReached, LegThenUntilGain) => UntilGain,
            (Event::LegReached, m @ (Field | UntilGain)) => m,
            (Event::GainAgain | Event::Arrived, UntilGain) => Field,
            (Event::GainAgain | Event::Arrived, LegThenUntilGain) => Leg,
            (Event::GainAgain | Event::Arrived, m @ (Field | Leg)) => m,
        }
    }
}

/// A degenerate point usable now: on a traversable cell.
#[derive(Clone, Copy, Debug)]
struct Node {
    id: u64,
    kind: DegenerateKind,
    pos: Point2<f64>,
}

/// The routing graph of one decision: reachable nodes, their snapped cells, edges with gains, and
/// the robot's distance field they were snapped with.
struct RoutingGraph {
    nodes: Vec<Node>,
    cells: Vec<usize>,
    edges: Vec<RouteEdge>,
    df: super::search::DistanceField,
}

/// Deterministic counters (see [`Planner::stats`]).
#[derive(Clone, Debug, Default)]
struct Stats {
    key_frames: u64,
    retraces: u64,
    window_solves: u64,
    wedge_stops: u64,
    trisector_dockings: u64,
    branch_choices: u64,
    mst_routes: u64,
    fallback_plans: u64,
    /// Runs ended `stuck` because routing offered no edge with gain while frontiers remained
    /// reachable and the GREEDY hand-over is off (0 or 1).
    stuck_no_route: u64,
    stalls: u64,
    looks: u64,
    wall_escapes: u64,
    unblocks: u64,
    cancelled_pairs: u64,
    moved_points: u64,
}

/// The TENSOR planner.
pub struct Tensor {
    cfg: TensorConfig,
    field_cfg: FieldConfig,
    /// `additions.field_range_m`.
    field_range_m: f64,
    field: Option<TensorField>,
    /// The planning field of the previous key frame (`None` before the second one).
    prev: Option<FieldGrid>,
    key_time_s: f64,
    next_key_s: f64,
    window: Option<TimeVaryingField>,
    window_center: Point2<f64>,
    greedy: Greedy,
    mode: Mode,
    current: Current,
    /// Heading for the next pathline instead of the robot's (a chosen branch).
    heading_override: Option<f64>,
    /// A node just handled: ignored by docking and pathline stops until the robot has left it.
    ignore: Option<(u64, Point2<f64>)>,
    known_cells: usize,
    last_progress_s: f64,
    /// Last time anything new was seen, in any mode.
    last_any_progress_s: f64,
    stalls_in_a_row: u32,
    looks_at: Vec<Point2<f64>>,
    last_escape_s: f64,
    node_failures: BTreeMap<u64, u32>,
    route_target: Option<Point2<f64>>,
    max_speed: f64,
    /// The last action was an advection step (the stall watchdog runs while this holds).
    advecting: bool,
    /// `is_outdated` ended the last action (as opposed to the executor reporting it blocked): what
    /// `is_outdated` tells the `action_finished` call that follows it.
    outdated: bool,
    /// Where the last action started.
    action_start: Point2<f64>,
    /// Where the executor refused to move, and how often in a row.
    refusal: Option<(Point2<f64>, u32)>,
    stats: Stats,
}

/// What TENSOR reads of the config: its own section, the field, GREEDY's section (the hand-over),
/// and the robot's top speed (advection's pathlines run at full speed between field updates, which
/// see no [`PlanContext`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TensorParams {
    pub tensor: TensorConfig,
    pub field: FieldConfig,
    pub greedy: GreedyConfig,
    /// How the GREEDY hand-over gives frontiers up (`[additions]`).
    pub visit_rules: crate::plan::VisitRules,
    /// `additions.field_range_m`.
    pub field_range_m: f64,
    /// `robot.max_speed_mps`.
    pub max_speed_mps: f64,
}

impl From<&Config> for TensorParams {
    fn from(cfg: &Config) -> TensorParams {
        TensorParams {
            tensor: cfg.tensor.clone(),
            field: cfg.field.clone(),
            greedy: cfg.greedy.clone(),
            visit_rules: (&cfg.additions).into(),
            field_range_m: cfg.additions.field_range_m.get(),
            max_speed_mps: cfg.robot.max_speed_mps,
        }
    }
}

impl Tensor {
    pub fn new(cfg: &TensorParams) -> Self {
        let mut field_cfg = cfg.field.clone();
        if cfg.tensor.topological_control {
            field_cfg.cancel_pairs = true;
            field_cfg.move_wedges_into_corners = true;
            field_cfg.move_trisectors_from_obstacles = true;
        }
        Tensor {
            cfg: cfg.tensor.clone(),
            field_cfg,
            field_range_m: cfg.field_range_m,
            field: None,
            prev: None,
            key_time_s: 0.0,
            next_key_s: 0.0,
            window: None,
            window_center: Point2::origin(),
            // TENSOR's hand-over keeps GREEDY as published: no volume views.
            greedy: Greedy::new(&cfg.greedy, cfg.visit_rules, None),
            mode: Mode::Field,
            current: Current::None,
            heading_override: None,
            ignore: None,
            known_cells: 0,
            last_progress_s: 0.0,
            last_any_progress_s: 0.0,
            stalls_in_a_row: 0,
            looks_at: Vec::new(),
            last_escape_s: f64::NEG_INFINITY,
            node_failures: BTreeMap::new(),
            route_target: None,
            max_speed: cfg.max_speed_mps,
            advecting: false,
            outdated: false,
            action_start: Point2::origin(),
            refusal: None,
            stats: Stats::default(),
        }
    }

    /// Sub-step duration, seconds (key-frame period / K).
    fn substep_s(&self) -> f64 {
        self.field_cfg.keyframe_period_s / self.field_cfg.substeps.max(1) as f64
    }

    /// Field time τ ∈ [0, 1] between the previous key frame (0) and the last one (1) at time `t`:
    /// from the middle frame at a key frame to the last at the next key frame (Alg. 1).
    fn tau(&self, t: f64) -> f64 {
        let k = self.field_cfg.substeps.max(1);
        let m = (k / 2) as f64 / k as f64;
        (m + (1.0 - m) * (t - self.key_time_s) / self.field_cfg.keyframe_period_s).clamp(0.0, 1.0)
    }

    /// `(a, b)` of the time-varying field at `p` and time `t`.
    fn sample(&self, p: Point2<f64>, t: f64) -> Option<[f64; 2]> {
        let cur = self.field.as_ref()?.field();
        let Some(prev) = &self.prev else {
            return cur.sample(p).map(|s| [s.a, s.b]);
        };
        let tau = self.tau(t);
        if let Some(v) = self.window.as_ref().and_then(|w| w.sample(p, tau)) {
            return Some(v);
        }
        let (a, b) = (prev.sample(p)?, cur.sample(p)?);
        Some([a.a * (1.0 - tau) + b.a * tau, a.b * (1.0 - tau) + b.b * tau])
    }

    /// The pathline from `start` at time `t0` through the time-varying field, leaving along the
    /// field direction nearest `heading` (local orientation, §4.2); `v` maps arc length to time.
    fn trace_pathline(
        &self,
        start: Point2<f64>,
        heading: f64,
        t0: f64,
        len: f64,
        v: f64,
        stop: &StopConditions,
    ) -> (Vec<Point2<f64>>, StopReason) {
        trace(
            |p, s| self.sample(p, t0 + s / v),
            start,
            heading,
            len,
            self.field_cfg.rk4_step_m,
            stop,
        )
    }

    /// Length of one traced pathline: `advect_substeps` sub-steps at full speed.
    fn pathline_length(&self, max_speed: f64) -> f64 {
        self.cfg.advect_substeps as f64 * self.substep_s() * max_speed
    }

    fn note_progress(&mut self, ctx: &PlanContext) {
        let known = ctx
            .map
            .cell_states()
            .iter()
            .filter(|s| **s != crate::map::CellState::Unknown)
            .count();
        if known >= self.known_cells + PROGRESS_CELLS {
            self.known_cells = known;
            self.last_progress_s = ctx.time_s;
            self.last_any_progress_s = ctx.time_s;
            self.stalls_in_a_row = 0;
        }
    }

    /// Solves the space-time window around where the next pathline will run, when it is stale.
    fn refresh_window(&mut self, pose: Pose2, max_speed: f64) {
        let (Some(prev), Some(field)) = (&self.prev, &self.field) else {
            return;
        };
        let len = self.pathline_length(max_speed);
        let ahead = pose.position() + Vector2::new(pose.yaw.cos(), pose.yaw.sin()) * (0.5 * len);
        let r = self.field_cfg.timevary_radius_m;
        if self.window.is_some() && (ahead - self.window_center).norm() <= 0.5 * r {
            return;
        }
        let params = SpaceTimeParams {
            substeps: self.field_cfg.substeps.max(1),
            omega_s: self.field_cfg.omega_s,
            omega_t: self.field_cfg.omega_t,
            alpha: self.field_cfg.alpha,
            max_iterations: self.field_cfg.timevary_max_iterations,
            tolerance: SPACE_TIME_TOLERANCE,
        };
        self.window = biharmonic_window(prev, field.field(), ahead, r, &params);
        self.window_center = ahead;
        self.stats.window_solves += 1;
    }
}

/// Cells a path passes through after its first point (for the blockage check), without repeats.
fn path_cells(grid: &GridSpec, path: &[Point2<f64>]) -> Vec<usize> {
    let mut out: Vec<usize> = Vec::new();
    for p in path.iter().skip(1) {
        if let Some(c) = grid.cell_of(*p) {
            let i = grid.index(c);
            if out.last() != Some(&i) {
                out.push(i);
            }
        }
    }
    out
}

impl Tensor {
    /// Changes the mode on `event` (see [`Mode::next`]).
    fn transition(&mut self, event: Event) {
        self.mode = self.mode.next(event, self.cfg.fallback);
    }

    /// The next action (see [`Planner::plan`]): what the last action's end asked for, then the
    /// watchdogs, then the mode's own step.
    fn next_action(&mut self, ctx: &mut PlanContext) -> Result<Action> {
        self.action_start = ctx.pose.position();
        if self.field.is_none() {
            return Ok(Action::LookAround);
        }
        let mut arrival = None;
        match self.current {
            Current::Recover(Recovery::Look) => {
                self.looks_at.push(ctx.pose.position());
                self.stats.looks += 1;
                self.current = Current::Look;
                return Ok(Action::LookAround);
            }
            Current::Recover(Recovery::StepClear) => {
                self.current = Current::None;
                if let Some(a) = self.step_clear(ctx) {
                    return Ok(a);
                }
            }
            Current::Arrived(a) => {
                self.current = Current::None;
                arrival = Some(a);
            }
            _ => {}
        }
        self.note_progress(ctx);
        if let Some(arrival) = arrival {
            self.transition(Event::Arrived);
            return self.plan_at(ctx, arrival, 0);
        }
        if ctx.time_s - self.last_any_progress_s >= 3.0 * self.cfg.stall_timeout_s {
            // Nothing new for long whatever the mode (routes that lead nowhere reset the advection
            // watchdog): one GREEDY leg, if the hand-over is on.
            self.stats.stalls += 1;
            self.last_any_progress_s = ctx.time_s;
            self.transition(Event::Stalled);
        }
        let mode = self.mode;
        match mode {
            Mode::Leg | Mode::LegThenUntilGain => return self.fallback(ctx),
            Mode::UntilGain if self.graph_has_gain(ctx) => self.transition(Event::GainAgain),
            Mode::UntilGain => return self.fallback(ctx),
            Mode::Field => {}
        }
        if ctx.time_s - self.last_progress_s >= self.cfg.stall_timeout_s {
            self.stats.stalls += 1;
            self.stalls_in_a_row += 1;
            self.last_progress_s = ctx.time_s;
            if self.stalls_in_a_row >= 2 {
                // Twice nothing new: one full GREEDY leg, to its frontier, before advecting again (if
                // the hand-over is on).
                self.stalls_in_a_row = 0;
                self.transition(Event::Stalled);
            }
            match self.route(ctx, None) {
                Routed::Leave { heading, node_id } => {
                    self.heading_override = Some(heading);
                    self.ignore = Some((node_id, ctx.pose.position()));
                }
                Routed::Go(a) => return Ok(a),
                Routed::Nothing => {
                    self.transition(Event::NoRoute);
                    return self.fallback(ctx);
                }
            }
        }
        if let Some(a) = self.wall_escape(ctx) {
            return Ok(a);
        }
        self.advect(ctx, 0)
    }
}

impl Planner for Tensor {
    fn name(&self) -> &'static str {
        if self.cfg.fallback {
            FALLBACK_LABEL
        } else {
            "tensor"
        }
    }

    fn plan(&mut self, ctx: &mut PlanContext) -> Result<Plan> {
        let action = self.next_action(ctx)?;
        Ok(Plan::new(
            action,
            self.route_target.into_iter().collect(),
            None,
        ))
    }

    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool {
        let blocked = |cells: &[usize]| cells.iter().any(|&i| !ctx.passable(i));
        self.outdated = match &self.current {
            Current::Advect {
                started_s, cells, ..
            } => ctx.time_s - started_s >= self.substep_s() - 1e-9 || blocked(cells),
            Current::Dock { cells, .. } | Current::Route { cells, .. } => blocked(cells),
            Current::Fallback => self.greedy.is_outdated(ctx, action),
            Current::None
            | Current::Arrived(_)
            | Current::Recover(_)
            | Current::Escape
            | Current::Look => false,
        };
        self.outdated
    }

    fn action_finished(&mut self, ctx: &PlanContext, reached: bool) {
        let robot = ctx.pose.position();
        let near = |pos: Point2<f64>, r: f64| (pos - robot).norm() <= r;
        // The executor's guard refused to move at all (unseen cells beside the robot count as
        // hazards): look around once here, which shows them, before counting a failure.
        let was_outdated = std::mem::take(&mut self.outdated);
        let refused = !reached && !was_outdated && (robot - self.action_start).norm() < 0.05;
        if refused {
            if self.refusal.is_none_or(|(p, _)| (p - robot).norm() > 0.3) {
                self.refusal = Some((robot, 0));
            }
            let n = self.refusal.as_mut().map_or(0, |r| {
                r.1 += 1;
                r.1
            });
            // First a look, then a step away from the hazard; after that, failures count (the
            // fallback's give-up rule) every other time, so one pinned spot cannot give up every
            // frontier in a row.
            if n == 1 || n.is_multiple_of(2) {
                self.current = Current::Recover(if n == 1 {
                    Recovery::Look
                } else {
                    Recovery::StepClear
                });
                return;
            }
        }
        let arrived = |id, kind| Current::Arrived(Arrival { id, kind });
        self.current = match std::mem::replace(&mut self.current, Current::None) {
            Current::Advect {
                wedge: Some((id, pos)),
                ..
            } if near(
                pos,
                self.field_cfg.arrive_radius_m + ctx.cfg.motion.goal_tolerance_m,
            ) =>
            {
                arrived(id, ArrivalKind::Wedge)
            }
            Current::Dock { id, pos, .. } if reached || near(pos, self.cfg.dock_radius_m) => {
                arrived(id, ArrivalKind::Dock)
            }
            Current::Route {
                id, pos, heading, ..
            } if reached || near(pos, self.cfg.dock_radius_m) => {
                arrived(id, ArrivalKind::Route { heading })
            }
            Current::Dock { id, .. } | Current::Route { id, .. } => {
                *self.node_failures.entry(id).or_default() += 1;
                Current::None
            }
            Current::Fallback => {
                if reached {
                    self.transition(Event::LegReached);
                }
                self.greedy.action_finished(ctx, reached);
                Current::None
            }
            // What the end of an earlier action asked for still stands (a look in a node's own
            // cell keeps its arrival).
            pending @ (Current::Arrived(_) | Current::Recover(_)) => pending,
            Current::None | Current::Advect { .. } | Current::Escape | Current::Look => {
                Current::None
            }
        };
    }

    fn field_planner(&mut self) -> Option<&mut dyn FieldPlanner> {
        Some(self)
    }

    fn stats(&self) -> BTreeMap<String, f64> {
        self.stats_map()
    }
}

impl FieldPlanner for Tensor {
    fn update_field(&mut self, map: &Map, pose: Pose2, time_s: f64) -> Result<()> {
        let (cfg, range_m) = (&self.field_cfg, self.field_range_m);
        let field = self
            .field
            .get_or_insert_with(|| TensorField::new(*map.grid(), cfg).with_range(range_m));
        if time_s + 1e-9 >= self.next_key_s {
            let before = (self.stats.key_frames > 0).then(|| field.field().clone());
            field.update(map)?;
            let c = field.control_counts();
            self.stats.cancelled_pairs += c.cancelled_pairs as u64;
            self.stats.moved_points += (c.moved_wedges + c.moved_trisectors) as u64;
            self.stats.key_frames += 1;
            self.prev = before;
            self.key_time_s = time_s;
            self.next_key_s = self.stats.key_frames as f64 * self.field_cfg.keyframe_period_s;
            self.window = None;
        }
        // The window matters only to advection, which re-traces every sub-step.
        if matches!(
            self.current,
            Current::Advect { .. } | Current::None | Current::Arrived(_) | Current::Recover(_)
        ) {
            self.refresh_window(pose, self.max_speed);
        }
        Ok(())
    }

    fn field(&self) -> Option<&TensorField> {
        self.field.as_ref()
    }
}

impl Tensor {
    /// The run statistics under their `planner_stats` keys (see [`Planner::stats`]).
    fn stats_map(&self) -> BTreeMap<String, f64> {
        let s = &self.stats;
        [
            ("key_frames", s.key_frames),
            ("retraces", s.retraces),
            ("window_solves", s.window_solves),
            ("wedge_stops", s.wedge_stops),
            ("trisector_dockings", s.trisector_dockings),
            ("branch_choices", s.branch_choices),
            ("mst_routes", s.mst_routes),
            ("fallback_plans", s.fallback_plans),
            ("stuck_no_route", s.stuck_no_route),
            ("stalls", s.stalls),
            ("looks", s.looks),
            ("wall_escapes", s.wall_escapes),
            ("unblocks", s.unblocks),
            ("cancelled_pairs", s.cancelled_pairs),
            ("moved_points", s.moved_points),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v as f64))
        .collect()
    }
}

#[cfg(test)]
mod tests;
