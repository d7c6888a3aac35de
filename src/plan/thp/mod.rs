//! THP: tensor-field-driven hierarchical path planning (Xi, Zhu, Duan, Yi, Zheng, He, Xu, "THP:
//! Tensor-field-driven hierarchical path planning for autonomous scene exploration with depth
//! sensors", Computational Visual Media 2024, §3.3–3.5).
//!
//! Three levels, each re-using the shared map, field, searches and motion executor:
//!
//! 1. **Anchors and the online TSP (§3.3, Alg. 1, Eq. 5–6; [`tour::Tour`]).** Anchors are the
//!    tracked degenerate points of the field (recomputed every `thp.field_period_s`), kept at their last position once
//!    their point disappears, and visited for good once their frontier group is empty. `P*` is the set
//!    of anchors new since the last solve; while it is empty the robot follows the tour, otherwise the
//!    fixed-start open TSP is re-solved (Alg. 1 breaks its loop). Where the tour starts is room the
//!    paper leaves (`thp.tour_start`, [`tour`]): Alg. 1 says "the anchor nearest the robot", which
//!    can lie behind the robot while the rest of the tour lies ahead; `"robot"` makes the robot's own
//!    cell the fixed start, so the first group is the one the whole tour favours. The paper's reading
//!    is the default: on real plans the robot start drove slightly farther (docs/experiments.md). Costs
//!    are path costs under the shared search cost rule between the nodes' anchors (Eq. 6's
//!    dist(p_i, p_j); `thp.tour_costs`), an anchor off the reachable floor replaced by its group's
//!    least-cost frontier. They come from one Dijkstra per node
//!    ([`super::search::Search::costs_to_targets`]) rather than pairwise A*, each row kept while its node keeps its
//!    access cell and searched again once `thp.cost_refresh_s` old, at most
//!    `thp.cost_refresh_rows_max` at one solve and only for the pairs no younger row holds (the
//!    paper leaves caching open; [`tour::CostRows`]). Exact Held–Karp up to
//!    `thp.exact_tsp_max_nodes`, the heuristic above ([`super::tsp::solve`]).
//! 2. **Frontier grouping and splitting (§3.4, Alg. 2, Eq. 7–9; [`grouping::Anchors`]).** Frontier
//!    positions are the centroids of the map's frontier segments (at most `map.frontier_segment_max_m`, 1 m, long). Each
//!    joins its nearest unvisited anchor within `d_f`; the rest become anchors. Groups are split by
//!    Eq. 9 under the reading documented at [`grouping::split_group`]. Groups are visited in tour order, the
//!    frontiers of a group in path order (least path cost from the robot first).
//! 3. **A* and advection (§3.5, Eq. 10–11).** A* runs to the next goal; its path is sampled at `d_s`
//!    into constraint points that change the planning field within σ of the path. The robot then moves
//!    along pathlines of that field (`thp.advect_length_m` at a time), oriented toward the goal. A* is
//!    re-run only when the goal changes, the path is blocked by a newly seen obstacle, or the robot
//!    or its pathline strays more than `thp.drift_m` from the path.
//!
//! Frontiers are visited with the rules GREEDY shares ([`super::frontier`]). Under the
//! `published` profile that is the paper's "done after the robot has looked at it": the robot stops
//! `thp.view_distance_m` short of the frontier, turns once to look, and a frontier the look left
//! open is done; so is one the robot failed to reach. The run is complete when no anchor and no
//! reachable frontier is left. A frontier approached once stays a member of its group even inside
//! the camera's blind zone around the robot, so its second approach (default profile) comes while
//! the robot is there ([`Thp::frontiers`] says why).
//!
//! What a *visited* anchor is (room the paper leaves): one whose group holds no frontier in a plan.
//!
//! Control state: [`mode::Mode`] (idle, driving to a goal, blocked), with every change of it in
//! `mode.rs`.
//!
//! Mechanisms the paper does not have, each a key of `[additions]` that the `published` profile
//! switches off (`configs/default.toml` says why each exists and what it measured):
//! - the frontier rules shared with GREEDY: `look_from_on_top`, `viewpoint_looks`,
//!   `exact_arrival`, `approach_attempts` above 1;
//! - `blind_zone_step_back`: a frontier in the camera's blind zone around the robot is looked at,
//!   by a step back, before the robot drives to the tour's next goal ([`blind_zone_first`]). The
//!   step back is kept until it is reached, seen or blocked, through new anchors too (the tour is
//!   re-solved after it): re-chosen at every segment end, two such frontiers whose viewpoints lay
//!   beside each other held the robot between them without a look until the run was `stuck`;
//! - the end-of-run sequence shared with GREEDY ([`super::frontier::end_of_run`]):
//!   `distant_views`, `volume_views` (counted as `volume_views`) and `reopen_max`; with
//!   `volume_view_tour` THP visits the views in the order of a fixed-start open TSP from the robot
//!   over the open views, thinned to one per metre and solved again at every view
//!   ([`Thp::next_volume_view`]), as Alg. 1 orders anchors;
//! - `escape_tries`: when frontiers are left but none is reachable, or no cell around the robot
//!   may be entered, the robot squeezes out through inflated cells only beside its own trail
//!   ([`goals::Trail`]), back the way it came in (`escapes`); a target is given up after that many
//!   tries (`escapes_given_up`);
//! - `look_when_blocked`: an attempt that could not move the robot at all (the motion guard refused
//!   every move, typically in a doorway beside never-seen cells) is followed by a look around
//!   before the next goal (`looks_when_blocked`); so is an escape or a volume view that could not;
//! - `advection_stall_s`: when advection has not brought the robot farther along its A* path for
//!   that long, the robot follows the A* path itself to that goal (`advection_stalls`);
//! - `field_range_m`: the field has no value farther than that from every surface constraint
//!   (`crate::field`, "A bounded range"), shared with TENSOR.
//!
//! Readings where the paper leaves room, in `[thp]` and the same in both profiles:
//! `thp.finish_group_first` (off) and `thp.tour_start` (see [`tour`]), `thp.tour_costs`.
//!
//! Statistics: besides the counters of each stage, `path_m_*` split the path by why the robot was
//! driving (see `PathLedger`), and `groups_left_unfinished` / `returns_to_unfinished` count tour
//! goals that left a group with frontiers left and came back to one. `tour_starts_not_nearest_group`
//! and `tour_start_extra_m` count the tours whose first group the robot does not reach at least cost
//! (an anchor near the robot whose frontiers are not), one cause of THP's longer legs on real plans.
//!
//! Ablations (`[thp]`): `extension = false` keeps only the degenerate points of the first key frame
//! (Table 3); `grouping = "none" | "kmeans"` replaces anchor groups by single frontiers or k-means
//! clusters, re-solving the TSP at every goal choice (Fig. 8); `advection = false` follows the A*
//! path itself.

use super::frontier::{
    blind_zone_first, blind_zone_viewpoint, distant_view, end_of_run, follow_to, Ending,
    FrontierVisits, Visit,
};
use super::frontier::{VolumeView, VolumeViewParams, VolumeViews};
use super::search::DistanceField;
use super::{path_length, Action, Count, FieldPlanner, Plan, PlanContext, PlanParams, Planner};
use crate::config::{Additions, Config, FieldConfig, Grouping, ThpConfig};
use crate::field::{StopReason, TensorField};
use crate::grid::GridSpec;
use crate::map::Map;
use crate::plan;
use crate::{Pose2, Result};
use nalgebra::Point2;
use std::collections::{BTreeMap, BTreeSet};

/// An attempt that moved the robot less than this did not move it at all (`Mode::Blocked`), metres.
const BLOCKED_MOVE_M: f64 = 0.05;

mod following;
mod goals;
mod grouping;
mod ledger;
mod mode;
mod tour;

use following::*;
use goals::Choice;
use grouping::{kmeans_nodes, on_floor, Anchors, Frontier, Node};
use ledger::*;
use mode::Mode;
use tour::{costs_from, open_tour_from, Tour, TourInputs};

/// The THP planner. Cloneable, so that a bench can replay one planning step from a saved state.
#[derive(Clone)]
pub struct Thp {
    cfg: ThpConfig,
    /// The rules no paper has (`[additions]`; the module doc lists THP's).
    rules: Additions,
    near_unknown_m: f64,
    goal_tolerance_m: f64,
    radius_m: f64,
    key_frames: KeyFrames,
    /// The anchors and the grouping of frontiers around them (Alg. 2).
    anchors: Anchors,
    /// The online tour over the groups (Alg. 1).
    tour: Tour,
    visits: FrontierVisits,
    mode: Mode,
    /// Where the robot was when the action in flight began.
    action_from: Point2<f64>,
    /// Buffers of the planning step's cell costs and the robot's distance field, kept between steps.
    step_costs: plan::StepCosts,
    flood: DistanceField,
    stats: ThpStats,
    ledger: PathLedger,
    escapes: goals::Escapes,
    /// Views of the unknown volume before `Complete`, if on (not in the paper; see the module doc).
    volume_views: Option<VolumeViews>,
}

/// The tensor field THP plans in, computed again at each key frame (every `thp.field_period_s`).
#[derive(Clone)]
struct KeyFrames {
    cfg: FieldConfig,
    /// `additions.field_range_m`.
    range_m: f64,
    field: Option<TensorField>,
    next_s: f64,
}

impl KeyFrames {
    /// Updates the field from `map` if a key frame is due at `time_s`. Returns `None` if none was
    /// due, else whether it was the first.
    fn update(&mut self, map: &Map, time_s: f64, period_s: f64) -> Result<Option<bool>> {
        if time_s + 1e-9 < self.next_s {
            return Ok(None);
        }
        let first = self.field.is_none();
        let field = self.field.get_or_insert_with(|| {
            let mut f = TensorField::new(*map.grid(), &self.cfg).with_range(self.range_m);
            // THP reads the planning field only along its pathlines (`pathline_computing`).
            f.set_lazy_planning_field(true);
            f
        });
        field.update(map)?;
        self.next_s = time_s + period_s;
        Ok(Some(first))
    }
}

/// What THP takes from the config: its own section, the field's, and the shared planning parameters
/// (the blind-zone radius of the searches, the robot's radius, the executor's goal tolerance).
#[derive(Clone, Debug, PartialEq)]
pub struct ThpParams {
    pub thp: ThpConfig,
    pub field: FieldConfig,
    pub plan: PlanParams,
    /// Views of the unknown volume before `Complete` (`volume_views`; not in the paper).
    pub volume_views: VolumeViewParams,
}

impl From<&Config> for ThpParams {
    fn from(cfg: &Config) -> ThpParams {
        ThpParams {
            thp: cfg.thp.clone(),
            field: cfg.field.clone(),
            plan: PlanParams::from(cfg),
            volume_views: cfg.into(),
        }
    }
}

/// THP's run statistics (`planner_stats`, under the field names).
#[derive(Clone, Debug, Default)]
struct ThpStats {
    key_frames: Count,
    escapes: Count,
    escapes_given_up: Count,
    astar_new_goal: Count,
    astar_same_goal: Count,
    advected_segments: Count,
    advection_stops_at_points: Count,
    advection_fallbacks: Count,
    advection_stalls: Count,
    looks_when_blocked: Count,
    distant_views: Count,
    groups_left_unfinished: Count,
    returns_to_unfinished: Count,
    /// Metres driven per goal kind (`path_m_*`), indexed by [`GoalKind`].
    path_m: [Count; 9],
}

impl Thp {
    pub fn new(params: &ThpParams) -> Self {
        Thp {
            cfg: params.thp.clone(),
            rules: params.plan.additions.clone(),
            near_unknown_m: params.plan.search.near_unknown_radius_m,
            goal_tolerance_m: params.plan.motion.goal_tolerance_m,
            radius_m: params.plan.robot.radius_m,
            key_frames: KeyFrames {
                cfg: params.field.clone(),
                range_m: params.plan.additions.field_range_m.get(),
                field: None,
                next_s: 0.0,
            },
            anchors: Anchors::default(),
            tour: Tour::default(),
            visits: FrontierVisits::new((&params.plan.additions).into()),
            mode: Mode::Idle,
            action_from: Point2::origin(),
            step_costs: super::StepCosts::default(),
            flood: DistanceField::default(),
            stats: ThpStats::default(),
            ledger: PathLedger::default(),
            escapes: goals::Escapes::default(),
            volume_views: VolumeViews::new(&params.volume_views),
        }
    }
}

impl FieldPlanner for Thp {
    fn update_field(&mut self, map: &Map, _pose: Pose2, time_s: f64) -> Result<()> {
        let Some(first) = self
            .key_frames
            .update(map, time_s, self.cfg.field_period_s)?
        else {
            return Ok(());
        };
        self.stats.key_frames.add(1.0);
        // Eq. 5: the key frame's degenerate points become anchors; new ones break the tour loop
        // (Alg. 1) and the next plan re-solves.
        let field = self.key_frames.field.as_ref().expect("updated above");
        let points: Vec<(u64, Point2<f64>)> =
            field.points().iter().map(|p| (p.id, p.pos())).collect();
        let grid = map.grid();
        // Table 3's ablation (`thp.extension = false`) routes over the first key frame's points.
        let take_new = self.cfg.extension || first;
        (self.anchors).take_points(&points, |p| on_floor(map, grid, p), take_new);
        Ok(())
    }

    fn field(&self) -> Option<&TensorField> {
        self.key_frames.field.as_ref()
    }
}

impl Thp {
    /// The next action (see [`Planner::plan`]).
    fn next_action(&mut self, ctx: &mut PlanContext) -> Result<Action> {
        self.note_position(ctx.pose.position());
        self.escapes
            .trail
            .visit(ctx.map.grid(), ctx.pose.position());
        self.visits.ensure(ctx.map.grid());
        self.tour.take_solve_ms();
        if self.mode.unblock() {
            self.stats.looks_when_blocked.add(1.0);
            return Ok(Action::LookAround);
        }
        // A goal stays until it is reached, seen or blocked. A drive to a viewpoint (a near view)
        // whose path went bad is chosen again, since its A* path ends at the viewpoint, not at the
        // aim. A goal outside the tour (a step back for the blind zone, a look through a gap)
        // stays through new anchors too; the tour is re-solved once it is done. Re-chosen at every
        // segment end, two blind-zone frontiers whose viewpoints lie beside each other sent the
        // robot back and forth between them without a look until the run was stuck.
        let keep_goal = self.mode.goal().is_some_and(|g| {
            g.visit.is_open(ctx.map)
                && !g.final_segment
                && (!g.visit.near_view || !self.path_invalid(ctx, g))
                && (!self.anchors.has_new() || g.tour_node.is_none())
        });
        if !keep_goal {
            if let Choice::Act(action) = self.choose_goal(ctx)? {
                return Ok(action);
            }
        }
        let Some(goal) = self.mode.goal() else {
            // `Choice::Drive` leaves a goal to drive to; turn in place should it not.
            return Ok(Action::LookAround);
        };
        if self.path_invalid(ctx, goal) {
            let goal = goal.clone();
            // Same goal, but the path is blocked or left behind: re-run A* to it.
            let grid = *ctx.map.grid();
            let robot = ctx.pose.position();
            let (map, search_cfg) = (ctx.map, &ctx.cfg.search);
            let start = plan::search_source(map, search_cfg, robot, self.radius_m);
            if start.is_some() {
                self.stats.astar_same_goal.add(1.0);
            }
            let path = start.and_then(|s| {
                ctx.search.astar(
                    &grid,
                    |i| plan::step_cost(map, search_cfg, robot, i),
                    s,
                    goal.visit.aim,
                )
            });
            let Some(path) = path else {
                self.visits.finished_in(ctx, &goal.visit, false);
                self.mode.stop();
                return Ok(Action::LookAround);
            };
            let cells = self
                .visits
                .cut_short(&grid, &path.cells, goal.visit.aim, self.cfg.view_distance_m)
                .to_vec();
            self.set_goal(ctx, goal.visit, goal.tour_node, &cells);
        }
        Ok(self.next_segment(ctx))
    }
}

impl Planner for Thp {
    fn name(&self) -> &'static str {
        "thp"
    }

    fn plan(&mut self, ctx: &mut PlanContext) -> Result<Plan> {
        let action = self.next_action(ctx)?;
        self.action_from = ctx.pose.position();
        Ok(Plan::new(
            action,
            self.tour.points().to_vec(),
            self.tour.take_solve_ms(),
        ))
    }

    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool {
        self.note_position(ctx.pose.position());
        self.escapes
            .trail
            .visit(ctx.map.grid(), ctx.pose.position());
        if !matches!(action, Action::Follow { .. }) {
            return false;
        }
        let Some(goal) = self.mode.goal_mut() else {
            return false;
        };
        if !goal.visit.is_open(ctx.map) {
            // Observed on the way: done (§3.4).
            self.mode.interrupt();
            return true;
        }
        if self.anchors.has_new() && goal.tour_node.is_some() {
            // Alg. 1: new anchors break the loop and the TSP is re-solved.
            self.mode.interrupt();
            return true;
        }
        if goal.path_cells.iter().any(|&i| !ctx.passable(i)) {
            // Blocked by a newly seen obstacle: A* is re-run to the same goal (not a failed attempt;
            // a goal A* cannot reach any more is given up in `plan`).
            goal.stale = true;
            self.mode.interrupt();
            return true;
        }
        false
    }

    fn action_finished(&mut self, ctx: &PlanContext, reached: bool) {
        // Without `additions.look_when_blocked`, every attempt counts as having moved the robot.
        let moved = !self.rules.look_when_blocked
            || (ctx.pose.position() - self.action_from).norm() >= BLOCKED_MOVE_M;
        if let Some((visit, reached)) = self
            .mode
            .action_ended(reached, moved, |visit| visit.is_open(ctx.map))
        {
            self.visits.finished_in(ctx, &visit, reached);
        }
    }

    fn field_planner(&mut self) -> Option<&mut dyn FieldPlanner> {
        Some(self)
    }

    fn stats(&self) -> BTreeMap<String, f64> {
        let s = &self.stats;
        super::counted(
            [
                ("key_frames", s.key_frames),
                ("escapes", s.escapes),
                ("escapes_given_up", s.escapes_given_up),
                ("astar_new_goal", s.astar_new_goal),
                ("astar_same_goal", s.astar_same_goal),
                ("advected_segments", s.advected_segments),
                ("advection_stops_at_points", s.advection_stops_at_points),
                ("advection_fallbacks", s.advection_fallbacks),
                ("advection_stalls", s.advection_stalls),
                ("looks_when_blocked", s.looks_when_blocked),
                ("distant_views", s.distant_views),
                ("volume_views", VolumeViews::taken(&self.volume_views)),
                ("groups_left_unfinished", s.groups_left_unfinished),
                ("returns_to_unfinished", s.returns_to_unfinished),
            ]
            .into_iter()
            .chain(self.anchors.stats())
            .chain(self.tour.stats())
            .chain(self.visits.stats())
            .chain(GoalKind::ALL.map(|k| (k.key(), s.path_m[k as usize]))),
        )
    }
}
