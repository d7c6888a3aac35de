//! THP: tensor-field-driven hierarchical path planning (seed 000, §3.3–3.5).
//!
//! Three levels, each re-using the shared map, field, searches and motion executor:
//!
//! 1. **Anchors and the online TSP (§3.3, Alg. 1, Eq. 5–6).** Anchors are the tracked degenerate
//!    points of the field (recomputed every `thp.field_period_s`), kept at their last position once
//!    their point disappears, and visited for good once their frontier group is empty. `P*` is the set
//!    of anchors new since the last solve; while it is empty the robot follows the tour, otherwise the
//!    fixed-start open TSP is re-solved from the anchor nearest the robot by path cost (Alg. 1 breaks
//!    its loop). Costs are path costs under the shared search cost rule, one Dijkstra per node
//!    ([`Search::costs_to_targets`]) rather than pairwise A*. Exact Held–Karp up to
//!    `thp.exact_tsp_max_nodes`, the heuristic above ([`tsp::solve`]).
//! 2. **Frontier grouping and splitting (§3.4, Alg. 2, Eq. 7–9).** Frontier positions are the
//!    centroids of the map's frontier segments (at most `map.frontier_segment_max_m`, 1 m, long). Each
//!    joins its nearest unvisited anchor within `d_f`; the rest become anchors. Groups are split by
//!    Eq. 9 under the reading documented at [`split_group`]. Groups are visited in tour order, the
//!    frontiers of a group in path order (least path cost from the robot first).
//! 3. **A* and advection (§3.5, Eq. 10–11).** A* runs to the next goal; its path is sampled at `d_s`
//!    into constraint points that change the planning field within σ of the path. The robot then moves
//!    along pathlines of that field (`thp.advect_length_m` at a time), oriented toward the goal. A* is
//!    re-run only when the goal changes, the path is blocked by a newly seen obstacle, or the robot
//!    or its pathline strays more than `thp.drift_m` from the path.
//!
//! Frontiers are visited with GREEDY's rules ([`super::frontier_visit`]): stop short, look, and give
//! up a frontier still unobserved after the robot stood on it and looked. The run is complete when
//! no anchor and no reachable, observable frontier is left.
//!
//! Mechanisms the paper does not have, each a config key: `thp.advection_stall_s` (on, 5 s): when
//! advection has not brought the robot farther along its A* path for that long, the robot follows the
//! A* path itself to that goal (counted as `advection_stalls`); pathlines around a wedge or a table
//! can circle for good, and such runs ended `stuck`.
//!
//! Statistics: besides the counters of each stage, `path_m_*` split the path by why the robot was
//! driving (see `PathLedger`), and `groups_left_unfinished` / `returns_to_unfinished` count tour
//! goals that left a group with frontiers left and came back to one.
//!
//! Ablations (`[thp]`): `extension = false` keeps only the degenerate points of the first key frame
//! (Table 3); `grouping = "none" | "kmeans"` replaces anchor groups by single frontiers or k-means
//! clusters, re-solving the TSP at every goal choice (Fig. 8); `advection = false` follows the A*
//! path itself.

use super::frontier_visit::{blind_zone_viewpoint, distant_view, FrontierVisits, Visit};
use super::search::{DistanceField, Search};
use super::tsp::{self, CostMatrix};
use super::{path_length, Action, Count, FieldPlanner, Plan, PlanContext, Planner};
use crate::config::{Config, FieldConfig, Grouping, ThpConfig};
use crate::field::{StopReason, TensorField};
use crate::grid::GridSpec;
use crate::map::Map;
use crate::{Pose2, Result};
use nalgebra::Point2;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};
use std::time::Instant;

/// Shortest advected segment worth following, metres; shorter ones fall back to the A* path.
const MIN_SEGMENT_M: f64 = 0.3;
/// Clearance beyond the robot radius an escape path keeps from known obstacles (the motion guard's
/// margin), metres.
const ESCAPE_CLEAR_MARGIN_M: f64 = 0.0;
/// Escapes toward one target cell before the frontier there is given up.
const MAX_ESCAPES: u32 = 2;
/// Lloyd iterations of the k-means grouping.
const KMEANS_ITERATIONS: usize = 20;

/// Where an anchor came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AnchorSource {
    /// A tracked degenerate point of the field (its id).
    Degenerate(u64),
    /// A frontier too far from every anchor (Alg. 2), or split off a group (Eq. 9).
    Frontier,
}

#[derive(Clone, Debug)]
struct Anchor {
    pos: Point2<f64>,
    source: AnchorSource,
    visited: bool,
}

/// A frontier segment as the planner sees it in one plan.
#[derive(Clone, Debug)]
struct Frontier {
    /// Index into the plan's segment list.
    segment: usize,
    /// The segment's centroid: the frontier position `f` of §3.4.
    pos: Point2<f64>,
    /// Its least-cost observable cell: the cell the robot aims at.
    aim: usize,
    /// Path cost from the robot to `aim`.
    cost: f32,
}

impl Frontier {
    /// The visit of this frontier's segment (`segment_cells` as returned by `Thp::frontiers`).
    fn visit(&self, grid: &GridSpec, segment_cells: &[Vec<usize>], near_view: bool) -> Visit {
        Visit {
            target: segment_cells[self.segment]
                .iter()
                .map(|&i| grid.cell(i))
                .collect(),
            aim: self.aim,
            near_view,
        }
    }
}

/// A TSP node of one plan: an anchor with its group, a single frontier, or a k-means cluster.
#[derive(Clone, Debug)]
struct Node {
    /// Anchor index (anchors mode) or a plan-local number.
    key: usize,
    pos: Point2<f64>,
    /// Indices into the plan's frontier list.
    members: Vec<usize>,
}

/// The goal being driven to, with its A* path.
#[derive(Clone, Debug)]
struct Goal {
    visit: Visit,
    /// Tour node the goal belongs to (anchor index in anchors mode).
    node: usize,
    /// The A* path (cut short for viewing), world points from the robot to the goal.
    path: Vec<Point2<f64>>,
    path_cells: Vec<usize>,
    /// Whether arriving at the path's end means turning to look (false for plain look-arounds).
    look_on_arrival: bool,
    /// The action in progress ends at the path's end (not an intermediate advected segment).
    final_segment: bool,
    /// A* must be re-run before the next segment.
    stale: bool,
    /// Farthest index along `path` the robot has come, and the simulated time it got there.
    best_progress: usize,
    progress_s: f64,
    /// Advection stopped bringing the robot along (`thp.advection_stall_s`): follow `path` itself.
    direct: bool,
}

/// The THP planner. Cloneable, so that a bench can replay one planning step from a saved state.
#[derive(Clone)]
pub struct Thp {
    cfg: ThpConfig,
    field_cfg: FieldConfig,
    view_m: f64,
    near_unknown_m: f64,
    goal_tolerance_m: f64,
    radius_m: f64,
    field: Option<TensorField>,
    next_key_frame_s: f64,
    anchors: Vec<Anchor>,
    /// Degenerate-point ids already turned into anchors (or deliberately ignored).
    known_ids: BTreeSet<u64>,
    /// `P*` is not empty: anchors appeared since the last TSP solve.
    new_anchors: bool,
    /// Tour order of node keys from the last solve.
    tour: Vec<usize>,
    tour_points: Vec<Point2<f64>>,
    visits: FrontierVisits,
    goal: Option<Goal>,
    /// The action was abandoned for a reason that is not a failed attempt (new anchors).
    benign_interrupt: bool,
    tsp_ms: Option<f64>,
    /// Buffers of the planning step's cell costs and the robot's distance field, kept between steps.
    step_costs: super::StepCosts,
    flood: DistanceField,
    /// Cached cost rows: source cell → (time computed, target cell → path cost).
    cost_rows: BTreeMap<usize, (f64, BTreeMap<usize, f64>)>,
    /// Search workspaces for computing cost rows in parallel (one per worker, made on first use).
    row_searches: Vec<Search>,
    stats: ThpStats,
    ledger: PathLedger,
    /// Escapes started toward each target cell.
    escape_tries: BTreeMap<usize, u32>,
}

/// THP's run statistics (`planner_stats`, under the field names).
#[derive(Clone, Debug, Default)]
struct ThpStats {
    key_frames: Count,
    anchors_degenerate: Count,
    anchors_frontier: Count,
    anchors_visited: Count,
    groups_split: Count,
    tsp_solves: Count,
    tsp_nodes_max: Count,
    tsp_nodes_total: Count,
    cost_rows: Count,
    escapes: Count,
    escapes_given_up: Count,
    astar_new_goal: Count,
    astar_same_goal: Count,
    advected_segments: Count,
    advection_stops_at_points: Count,
    advection_fallbacks: Count,
    advection_stalls: Count,
    distant_views: Count,
    groups_left_unfinished: Count,
    returns_to_unfinished: Count,
    /// Metres driven per goal kind (`path_m_*`), indexed by [`GoalKind`].
    path_m: [Count; 5],
}

/// Why the robot is driving where it is: each goal's reason, and the metres driven for it. Written
/// to the statistics as `path_m_*`, so that a comparison with GREEDY can say where THP's extra
/// metres go (same group, next group in the tour, leaving a group with frontiers left for another,
/// coming back to such a group, or a goal outside the tour).
#[derive(Clone, Debug, Default)]
struct PathLedger {
    /// Node key (anchor) of the last tour goal (kept across goals outside the tour).
    last_node: Option<usize>,
    /// Anchors the robot left while their group still had frontiers.
    left_unfinished: BTreeSet<usize>,
    kind: GoalKind,
    last_pos: Option<Point2<f64>>,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum GoalKind {
    /// Blind-zone views, views through gaps, escapes and the initial look: no tour node.
    #[default]
    OutsideTour,
    SameGroup,
    NextGroup,
    /// A new group chosen while the previous one still had frontiers.
    LeftUnfinished,
    /// Back to a group left unfinished earlier.
    Return,
}

impl GoalKind {
    const ALL: [GoalKind; 5] = [
        GoalKind::OutsideTour,
        GoalKind::SameGroup,
        GoalKind::NextGroup,
        GoalKind::LeftUnfinished,
        GoalKind::Return,
    ];

    fn key(self) -> &'static str {
        match self {
            GoalKind::OutsideTour => "path_m_outside_tour",
            GoalKind::SameGroup => "path_m_same_group",
            GoalKind::NextGroup => "path_m_next_group",
            GoalKind::LeftUnfinished => "path_m_left_unfinished",
            GoalKind::Return => "path_m_return",
        }
    }
}

impl Thp {
    pub fn new(cfg: &Config) -> Self {
        Thp {
            cfg: cfg.thp.clone(),
            field_cfg: cfg.field.clone(),
            view_m: cfg.thp.view_distance_m,
            near_unknown_m: cfg.search.near_unknown_radius_m,
            goal_tolerance_m: cfg.motion.goal_tolerance_m,
            radius_m: cfg.robot.radius_m,
            field: None,
            next_key_frame_s: 0.0,
            anchors: Vec::new(),
            known_ids: BTreeSet::new(),
            new_anchors: false,
            tour: Vec::new(),
            tour_points: Vec::new(),
            visits: FrontierVisits::default(),
            goal: None,
            benign_interrupt: false,
            tsp_ms: None,
            step_costs: super::StepCosts::default(),
            flood: DistanceField::default(),
            cost_rows: BTreeMap::new(),
            row_searches: Vec::new(),
            stats: ThpStats::default(),
            ledger: PathLedger::default(),
            escape_tries: BTreeMap::new(),
        }
    }

    /// Classifies a new tour goal at node `node`; `open` says whether a node key still has
    /// frontiers.
    fn note_tour_goal(&mut self, node: usize, open: impl Fn(usize) -> bool) {
        let l = &mut self.ledger;
        let kind = match l.last_node {
            Some(p) if p == node => GoalKind::SameGroup,
            Some(p) if open(p) => {
                l.left_unfinished.insert(p);
                if l.left_unfinished.contains(&node) {
                    GoalKind::Return
                } else {
                    GoalKind::LeftUnfinished
                }
            }
            _ if l.left_unfinished.contains(&node) => GoalKind::Return,
            _ => GoalKind::NextGroup,
        };
        l.last_node = Some(node);
        l.kind = kind;
        match kind {
            GoalKind::LeftUnfinished => self.stats.groups_left_unfinished.add(1.0),
            GoalKind::Return => self.stats.returns_to_unfinished.add(1.0),
            _ => {}
        }
    }

    /// Adds the distance moved since the last call to the current goal's kind.
    fn note_position(&mut self, p: Point2<f64>) {
        if let Some(q) = self.ledger.last_pos.replace(p) {
            let d = (p - q).norm();
            if d > 0.0 {
                self.stats.path_m[self.ledger.kind as usize].add(d);
            }
        }
    }

    fn add_anchor(&mut self, pos: Point2<f64>, source: AnchorSource) -> usize {
        self.anchors.push(Anchor {
            pos,
            source,
            visited: false,
        });
        self.new_anchors = true;
        match source {
            AnchorSource::Degenerate(_) => self.stats.anchors_degenerate.add(1.0),
            AnchorSource::Frontier => self.stats.anchors_frontier.add(1.0),
        }
        self.anchors.len() - 1
    }

    /// Turns the field's new degenerate points into anchors (Eq. 5), and moves existing degenerate
    /// anchors with their tracked points. Points off the known traversable floor are skipped until
    /// they are on it (they may sit in unknown space, outside the walls or inside furniture).
    fn take_degenerate_points(&mut self, map: &Map, first_key_frame: bool) {
        let Some(field) = &self.field else { return };
        let grid = map.grid();
        let points: Vec<(u64, Point2<f64>)> =
            field.points().iter().map(|p| (p.id, p.pos())).collect();
        for (id, pos) in points {
            if let Some(a) = self
                .anchors
                .iter_mut()
                .find(|a| a.source == AnchorSource::Degenerate(id))
            {
                if !a.visited && on_floor(map, grid, pos) {
                    a.pos = pos;
                }
                continue;
            }
            if self.known_ids.contains(&id) || !on_floor(map, grid, pos) {
                continue;
            }
            if !self.cfg.extension && !first_key_frame {
                // Table 3 ablation: route over the first key frame's points only.
                self.known_ids.insert(id);
                continue;
            }
            self.known_ids.insert(id);
            self.add_anchor(pos, AnchorSource::Degenerate(id));
        }
    }

    /// The reachable, observable frontiers (beyond the blind zone) and, separately, the nearest one
    /// inside it, with path costs from the robot's distance field.
    fn frontiers(
        &self,
        map: &Map,
        df: &DistanceField,
        robot: Point2<f64>,
    ) -> (Vec<Frontier>, Option<Frontier>, Vec<Vec<usize>>) {
        let grid = map.grid();
        let near2 = self.near_unknown_m * self.near_unknown_m;
        let segments = map.frontiers();
        let mut out = Vec::new();
        let mut nearest_near: Option<Frontier> = None;
        let mut cells = Vec::with_capacity(segments.len());
        for (k, seg) in segments.iter().enumerate() {
            let best = seg
                .cells
                .iter()
                .map(|c| grid.index(*c))
                .filter(|&i| !self.visits.is_unobservable(i))
                .filter_map(|i| df.cost_to(i).map(|d| (d, i)))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            cells.push(seg.cells.iter().map(|c| grid.index(*c)).collect());
            let Some((cost, aim)) = best else { continue };
            let f = Frontier {
                segment: k,
                pos: seg.centroid,
                aim,
                cost,
            };
            if (grid.center(grid.cell(aim)) - robot).norm_squared() <= near2 {
                if nearest_near
                    .as_ref()
                    .is_none_or(|n| (cost, aim) < (n.cost, n.aim))
                {
                    nearest_near = Some(f);
                }
            } else {
                out.push(f);
            }
        }
        (out, nearest_near, cells)
    }

    /// Alg. 2: groups frontiers around the unvisited anchors (Eq. 7–8), makes the ungrouped ones
    /// anchors, splits groups (Eq. 9), and marks anchors with empty groups visited. Returns the nodes.
    fn group_by_anchors(&mut self, fronts: &[Frontier], robot: Point2<f64>) -> Vec<Node> {
        let mut groups: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
        for (fi, f) in fronts.iter().enumerate() {
            let nearest = self
                .anchors
                .iter()
                .enumerate()
                .filter(|(_, a)| !a.visited)
                .map(|(k, a)| ((a.pos - f.pos).norm(), k))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let k = match nearest {
                Some((d, k)) if d <= self.cfg.d_f_m => k,
                _ => self.add_anchor(f.pos, AnchorSource::Frontier),
            };
            groups.entry(k).or_default().push(fi);
        }
        let keys: Vec<usize> = groups.keys().copied().collect();
        for k in keys {
            let members = groups.get(&k).cloned().unwrap_or_default();
            let split = split_group(
                &members,
                fronts,
                robot,
                self.anchors[k].pos,
                self.cfg.d_g_m,
                self.cfg.d_p_m,
            );
            if split.is_empty() {
                continue;
            }
            self.stats.groups_split.add(1.0);
            groups.insert(
                k,
                members
                    .iter()
                    .copied()
                    .filter(|m| !split.contains(m))
                    .collect(),
            );
            for fi in split {
                let a = self.add_anchor(fronts[fi].pos, AnchorSource::Frontier);
                groups.entry(a).or_default().push(fi);
            }
        }
        for (k, a) in self.anchors.iter_mut().enumerate() {
            if !a.visited && groups.get(&k).is_none_or(|g| g.is_empty()) {
                a.visited = true;
                self.stats.anchors_visited.add(1.0);
            }
        }
        groups
            .into_iter()
            .filter(|(_, m)| !m.is_empty())
            .map(|(k, members)| Node {
                key: k,
                pos: self.anchors[k].pos,
                members,
            })
            .collect()
    }

    /// Solves the fixed-start open TSP over `nodes` (Eq. 6) from the node whose anchor is nearest the
    /// robot by path cost (Alg. 1: "start at the anchor nearest the robot"); each node is entered at
    /// its least-cost member. Sets the tour (node keys in order).
    fn solve_tour(
        &mut self,
        ctx: &mut PlanContext,
        costs: &super::StepCosts,
        df: &DistanceField,
        nodes: &[Node],
        fronts: &[Frontier],
    ) {
        let t = Instant::now();
        let access: Vec<usize> = nodes
            .iter()
            .map(|n| {
                n.members
                    .iter()
                    .map(|&m| &fronts[m])
                    .min_by(|a, b| a.cost.total_cmp(&b.cost).then(a.aim.cmp(&b.aim)))
                    .expect("nodes have members")
                    .aim
            })
            .collect();
        let grid = *ctx.map.grid();
        // The tour's start (room the paper leaves): Alg. 1 starts at the anchor nearest the robot,
        // while Alg. 2 scans a group until it is empty. Read together, a re-solve that new anchors
        // trigger in the middle of a group may keep that group as the start
        // (`thp.finish_group_first`), so the robot does not leave a half-scanned group for a nearer
        // anchor and come back to it. Off by default: on real plans it removed those returns but
        // lengthened the whole path (the nearest anchor's group is usually the cheaper detour).
        let current = self
            .goal
            .as_ref()
            .filter(|_| self.cfg.finish_group_first)
            .and_then(|g| nodes.iter().position(|n| n.key == g.node));
        let start = current.unwrap_or_else(|| {
            (0..nodes.len())
                .min_by(|&a, &b| {
                    let (fa, fb) = (
                        anchor_cost(&grid, df, &nodes[a], fronts),
                        anchor_cost(&grid, df, &nodes[b], fronts),
                    );
                    fa.total_cmp(&fb).then(a.cmp(&b))
                })
                .expect("at least one node")
        });
        let m = self.cost_matrix(ctx, costs, &access);
        let tour = tsp::solve(&m, start, self.cfg.exact_tsp_max_nodes);
        self.tour = tour.order.iter().map(|&i| nodes[i].key).collect();
        self.tour_points = tour.order.iter().map(|&i| nodes[i].pos).collect();
        self.new_anchors = false;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        self.tsp_ms = Some(self.tsp_ms.unwrap_or(0.0) + ms);
        self.stats.tsp_solves.add(1.0);
        let n = nodes.len() as f64;
        self.stats.tsp_nodes_max.raise_to(n);
        self.stats.tsp_nodes_total.add(n);
    }

    /// Path costs between the nodes' access cells (Eq. 6's dist): one Dijkstra per node
    /// ([`Search::costs_to_targets`]). A row is reused while its source cell is unchanged and younger
    /// than `thp.cost_refresh_s` (the map mostly grows, so costs change slowly); a pair missing from
    /// an old row is read from the other node's row (path costs are symmetric up to the proximity
    /// surcharge of the end cells).
    fn cost_matrix(
        &mut self,
        ctx: &mut PlanContext,
        costs: &super::StepCosts,
        access: &[usize],
    ) -> CostMatrix {
        let grid = *ctx.map.grid();
        let now = ctx.time_s;
        let refresh = self.cfg.cost_refresh_s;
        self.cost_rows
            .retain(|source, row| now - row.0 < refresh && access.contains(source));
        let mut m = CostMatrix::new(access.len());
        if access.len() < 2 {
            return m;
        }
        let mut missing: Vec<usize> = Vec::new();
        for &source in access {
            if !self.cost_rows.contains_key(&source) && !missing.contains(&source) {
                missing.push(source);
            }
        }
        // The missing rows are independent Dijkstras: spread over the thread pool, each worker with
        // its own search workspace (the result does not depend on the thread count).
        let workers = missing.len().min(rayon::current_num_threads()).max(1);
        while self.row_searches.len() < workers {
            self.row_searches.push(Search::new(&grid));
        }
        let rows: Vec<(usize, Vec<Option<f32>>)> = self.row_searches[..workers]
            .par_iter_mut()
            .enumerate()
            .flat_map_iter(|(w, search)| {
                missing
                    .iter()
                    .skip(w)
                    .step_by(workers)
                    .map(|&source| {
                        let row = search.costs_to_targets(
                            &grid,
                            |c| costs.get(c),
                            source,
                            access,
                            f32::INFINITY,
                        );
                        (source, row)
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        for (source, row_costs) in rows {
            let row = access
                .iter()
                .zip(row_costs)
                .map(|(&t, c)| (t, c.map_or(f64::INFINITY, f64::from)))
                .collect();
            self.cost_rows.insert(source, (now, row));
            self.stats.cost_rows.add(1.0);
        }
        for (i, a) in access.iter().enumerate() {
            for (j, b) in access.iter().enumerate() {
                let c = self.cost_rows[a]
                    .1
                    .get(b)
                    .or_else(|| self.cost_rows[b].1.get(a))
                    .copied()
                    .expect("the newer of two rows holds the pair");
                m.set(i, j, c);
            }
        }
        m
    }

    /// Chooses the next goal: the least-cost frontier of the first node of the tour.
    fn choose_goal(&mut self, ctx: &mut PlanContext) -> Result<Option<Action>> {
        let grid = *ctx.map.grid();
        let robot = ctx.pose.position();
        let Some(start) = super::search_source(ctx.map, &ctx.cfg.search, robot, self.radius_m)
        else {
            return Ok(Some(Action::LookAround));
        };
        // The step costs and the robot's distance field live in buffers kept between steps.
        let mut costs = std::mem::take(&mut self.step_costs);
        costs.refill(ctx.map, &ctx.cfg.search, robot);
        let mut df = std::mem::take(&mut self.flood);
        ctx.search
            .distance_field_into(&grid, |i| costs.get(i), start, f32::INFINITY, &mut df);
        let action = self.choose_goal_from(ctx, start, &costs, &df);
        self.step_costs = costs;
        self.flood = df;
        action
    }

    /// [`Thp::choose_goal`] once the step costs and the robot's distance field (from `start`) are
    /// known.
    fn choose_goal_from(
        &mut self,
        ctx: &mut PlanContext,
        start: usize,
        costs: &super::StepCosts,
        df: &DistanceField,
    ) -> Result<Option<Action>> {
        let grid = *ctx.map.grid();
        let robot = ctx.pose.position();
        let map = ctx.map;
        let (fronts, near, segment_cells) = self.frontiers(map, df, robot);
        let nodes = match self.cfg.grouping {
            Grouping::Anchors => self.group_by_anchors(&fronts, robot),
            Grouping::None => fronts
                .iter()
                .enumerate()
                .map(|(i, f)| Node {
                    key: i,
                    pos: f.pos,
                    members: vec![i],
                })
                .collect(),
            Grouping::Kmeans => {
                kmeans_nodes(&fronts, &segment_cells, grid.res, self.cfg.kmeans_cluster_m)
            }
        };
        if nodes.is_empty() {
            // No node to route over: `P*` (if any) has nothing to re-order.
            self.new_anchors = false;
            self.tour.clear();
            self.tour_points.clear();
            // Only frontiers in the blind zone are left: step back to see the floor there.
            let Some(f) = near else {
                // Frontiers are left but none is reachable: trapped in a pocket? An escape toward
                // a target that already failed `MAX_ESCAPES` times gives the frontier up there, so
                // that one unreachable target cannot keep the robot trying until the run is stuck.
                loop {
                    let open_frontiers: Vec<usize> = segment_cells
                        .iter()
                        .flatten()
                        .copied()
                        .filter(|&i| !self.visits.is_unobservable(i))
                        .collect();
                    if open_frontiers.is_empty() {
                        break;
                    }
                    let Some(path) =
                        super::escape_path(ctx, start, df, &open_frontiers, ESCAPE_CLEAR_MARGIN_M)
                    else {
                        break;
                    };
                    let target = path
                        .last()
                        .and_then(|p| grid.cell_of(*p))
                        .map_or(start, |c| grid.index(c));
                    let tries = self.escape_tries.entry(target).or_insert(0);
                    *tries += 1;
                    if *tries > MAX_ESCAPES {
                        self.stats.escapes_given_up.add(1.0);
                        self.visits.give_up_around(&grid, target, open_frontiers);
                        continue;
                    }
                    self.stats.escapes.add(1.0);
                    self.ledger.kind = GoalKind::OutsideTour;
                    self.goal = None;
                    return Ok(Some(Action::Follow {
                        path,
                        look_on_arrival: false,
                    }));
                }
                // Nothing reachable is left: look at the frontiers seen through gaps too narrow to
                // pass, each once, before calling the map done (shared with GREEDY).
                if let Some(view) = distant_view(
                    map,
                    df,
                    &segment_cells,
                    |i| self.visits.is_unobservable(i),
                    self.view_m,
                ) {
                    self.stats.distant_views.add(1.0);
                    let visit = Visit {
                        target: segment_cells[view.segment]
                            .iter()
                            .map(|&i| grid.cell(i))
                            .collect(),
                        aim: view.aim,
                        near_view: true,
                    };
                    let path = df
                        .path_to(&grid, view.viewpoint)
                        .expect("reachable by construction");
                    self.set_goal(ctx, visit, usize::MAX, &path.cells);
                    return Ok(None);
                }
                return Ok(Some(Action::Complete));
            };
            let visit = f.visit(&grid, &segment_cells, true);
            let Some(v) = blind_zone_viewpoint(map, df, grid.center(grid.cell(f.aim)), self.view_m)
            else {
                self.goal = Some(Goal {
                    visit,
                    node: usize::MAX,
                    path: Vec::new(),
                    path_cells: Vec::new(),
                    look_on_arrival: true,
                    final_segment: true,
                    stale: false,
                    best_progress: 0,
                    progress_s: ctx.time_s,
                    direct: false,
                });
                return Ok(Some(Action::LookAround));
            };
            let path = df.path_to(&grid, v).expect("reachable by construction");
            self.set_goal(ctx, visit, usize::MAX, &path.cells);
            return Ok(None);
        }
        let resolve = match self.cfg.grouping {
            Grouping::Anchors => {
                self.new_anchors || !nodes.iter().all(|n| self.tour.contains(&n.key))
            }
            Grouping::None | Grouping::Kmeans => true,
        };
        if resolve {
            self.solve_tour(ctx, costs, df, &nodes, &fronts);
        } else {
            // Follow the tour: drop visited anchors, keep the order.
            let keep: Vec<(usize, Point2<f64>)> = self
                .tour
                .iter()
                .zip(&self.tour_points)
                .filter(|(k, _)| nodes.iter().any(|n| n.key == **k))
                .map(|(k, p)| (*k, *p))
                .collect();
            self.tour = keep.iter().map(|k| k.0).collect();
            self.tour_points = keep.iter().map(|k| k.1).collect();
        }
        let first = self.tour[0];
        let node = nodes
            .iter()
            .find(|n| n.key == first)
            .expect("tour covers the nodes");
        let f = node
            .members
            .iter()
            .map(|&m| &fronts[m])
            .min_by(|a, b| a.cost.total_cmp(&b.cost).then(a.aim.cmp(&b.aim)))
            .expect("nodes have members")
            .clone();
        let visit = f.visit(&grid, &segment_cells, false);
        // Keep the current A* path if the goal did not change.
        if let Some(g) = &mut self.goal {
            if g.visit.aim == visit.aim && !g.stale {
                g.visit = visit;
                g.node = first;
                return Ok(None);
            }
        }
        // A* calls by cause, for the advection claim (§3.5): a new goal, or the same goal again.
        let same_goal = self.goal.as_ref().is_some_and(|g| g.visit.aim == visit.aim);
        if !same_goal {
            self.note_tour_goal(first, |k| nodes.iter().any(|n| n.key == k));
        }
        if same_goal {
            self.stats.astar_same_goal.add(1.0);
        } else {
            self.stats.astar_new_goal.add(1.0);
        }
        let Some(path) = ctx.search.astar(&grid, |i| costs.get(i), start, f.aim) else {
            // Reachable in the distance field, so A* finds it too; be safe all the same.
            self.visits.finished(map, &visit, false);
            return Ok(Some(Action::LookAround));
        };
        let cells = self
            .visits
            .cut_short(&grid, &path.cells, f.aim, self.view_m)
            .to_vec();
        self.set_goal(ctx, visit, first, &cells);
        Ok(None)
    }

    /// Makes `cells` (from the robot) the goal's A* path and lays it into the field (Eq. 10–11).
    fn set_goal(
        &mut self,
        ctx: &PlanContext,
        visit: Visit,
        node: usize,
        cells: &[crate::grid::Cell],
    ) {
        let grid = ctx.map.grid();
        if node == usize::MAX {
            self.ledger.kind = GoalKind::OutsideTour;
        }
        let path: Vec<Point2<f64>> = cells.iter().map(|c| grid.center(*c)).collect();
        if self.cfg.advection {
            if let Some(field) = &mut self.field {
                field.set_path(&path);
            }
        }
        self.goal = Some(Goal {
            visit,
            node,
            path_cells: cells.iter().skip(1).map(|c| grid.index(*c)).collect(),
            path,
            look_on_arrival: true,
            final_segment: false,
            stale: false,
            best_progress: 0,
            progress_s: ctx.time_s,
            direct: false,
        });
    }

    /// The next motion toward the current goal: an advected pathline of the path-shaped field, or the
    /// A* path itself (advection off, or when the pathline is too short to be worth following).
    fn next_segment(&mut self, ctx: &PlanContext) -> Action {
        let goal = self.goal.as_mut().expect("a goal is set");
        let robot = ctx.pose.position();
        if goal.path.len() < 2 {
            goal.final_segment = true;
            return Action::LookAround;
        }
        let (progress, _) = nearest_on_path(&goal.path, robot, 0);
        if progress > goal.best_progress {
            goal.best_progress = progress;
            goal.progress_s = ctx.time_s;
        } else if self.cfg.advection_stall_s > 0.0
            && !goal.direct
            && ctx.time_s - goal.progress_s >= self.cfg.advection_stall_s
        {
            goal.direct = true;
            self.stats.advection_stalls.add(1.0);
        }
        if self.cfg.advection && !goal.direct {
            if let Some(field) = &self.field {
                let aim = goal.path[(progress + 5).min(goal.path.len() - 1)];
                let heading = if (aim - robot).norm() > 1e-6 {
                    (aim.y - robot.y).atan2(aim.x - robot.x)
                } else {
                    ctx.pose.yaw
                };
                let (line, reason) =
                    field.pathline(robot, heading, self.cfg.advect_length_m, false);
                let (segment, reaches_end) = accept_pathline(
                    &line,
                    &goal.path,
                    progress,
                    self.cfg.drift_m,
                    self.goal_tolerance_m,
                    |p| {
                        let grid = ctx.map.grid();
                        grid.cell_of(p).is_some_and(|c| ctx.passable(grid.index(c)))
                    },
                );
                if path_length(&segment) >= MIN_SEGMENT_M {
                    self.stats.advected_segments.add(1.0);
                    if matches!(reason, StopReason::NearDegenerate(_)) {
                        self.stats.advection_stops_at_points.add(1.0);
                    }
                    let goal = self.goal.as_mut().expect("a goal is set");
                    goal.final_segment = reaches_end;
                    return Action::Follow {
                        path: segment,
                        look_on_arrival: reaches_end && goal.look_on_arrival,
                    };
                }
                self.stats.advection_fallbacks.add(1.0);
            }
        }
        let goal = self.goal.as_mut().expect("a goal is set");
        goal.final_segment = true;
        Action::Follow {
            path: goal.path[progress..].to_vec(),
            look_on_arrival: goal.look_on_arrival,
        }
    }

    /// Whether the goal's A* path must be re-run: blocked, or the robot strayed from it.
    fn path_invalid(&self, ctx: &PlanContext) -> bool {
        let Some(goal) = &self.goal else { return true };
        if goal.stale || goal.path.is_empty() {
            return true;
        }
        let robot = ctx.pose.position();
        let (k, d) = nearest_on_path(&goal.path, robot, 0);
        let blocked = goal.path_cells.iter().skip(k).any(|&i| !ctx.passable(i));
        blocked || d > self.cfg.drift_m
    }
}

impl FieldPlanner for Thp {
    fn update_field(&mut self, map: &Map, _pose: Pose2, time_s: f64) -> Result<()> {
        if time_s + 1e-9 < self.next_key_frame_s {
            return Ok(());
        }
        let first = self.field.is_none();
        let field = self
            .field
            .get_or_insert_with(|| TensorField::new(*map.grid(), &self.field_cfg));
        field.update(map)?;
        self.next_key_frame_s = time_s + self.cfg.field_period_s;
        self.stats.key_frames.add(1.0);
        let before = self.anchors.len();
        self.take_degenerate_points(map, first);
        if self.anchors.len() > before {
            // Alg. 1: new points break the tour loop; the next plan re-solves.
            self.new_anchors = true;
        }
        Ok(())
    }

    fn field(&self) -> Option<&TensorField> {
        self.field.as_ref()
    }
}

impl Thp {
    /// The next action (see [`Planner::plan`]).
    fn next_action(&mut self, ctx: &mut PlanContext) -> Result<Action> {
        self.note_position(ctx.pose.position());
        self.visits.ensure(ctx.map.grid());
        self.tsp_ms = None;
        let keep_goal =
            self.goal.as_ref().is_some_and(|g| {
                g.visit.is_open(ctx.map) && !g.final_segment && !g.visit.near_view
            }) && !self.new_anchors;
        if !keep_goal {
            if let Some(action) = self.choose_goal(ctx)? {
                return Ok(action);
            }
        }
        if self.path_invalid(ctx) {
            // Same goal, but the path is blocked or left behind: re-run A* to it.
            let grid = *ctx.map.grid();
            let robot = ctx.pose.position();
            let (map, search_cfg) = (ctx.map, &ctx.cfg.search);
            let goal = self.goal.clone().expect("a goal is set");
            let start = super::search_source(map, search_cfg, robot, self.radius_m);
            if start.is_some() {
                self.stats.astar_same_goal.add(1.0);
            }
            let path = start.and_then(|s| {
                ctx.search.astar(
                    &grid,
                    |i| super::step_cost(map, search_cfg, robot, i),
                    s,
                    goal.visit.aim,
                )
            });
            let Some(path) = path else {
                self.visits.finished(ctx.map, &goal.visit, false);
                self.goal = None;
                return Ok(Action::LookAround);
            };
            let cells = self
                .visits
                .cut_short(&grid, &path.cells, goal.visit.aim, self.view_m)
                .to_vec();
            self.set_goal(ctx, goal.visit, goal.node, &cells);
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
        Ok(Plan::new(
            action,
            self.tour_points.clone(),
            self.tsp_ms.take(),
        ))
    }

    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool {
        self.note_position(ctx.pose.position());
        if !matches!(action, Action::Follow { .. }) {
            return false;
        }
        let Some(goal) = &mut self.goal else {
            return false;
        };
        if !goal.visit.is_open(ctx.map) {
            // Observed on the way: done (§3.4).
            self.benign_interrupt = true;
            return true;
        }
        if self.new_anchors {
            // Alg. 1: new anchors break the loop and the TSP is re-solved.
            self.benign_interrupt = true;
            return true;
        }
        if goal.path_cells.iter().any(|&i| !ctx.passable(i)) {
            // Blocked by a newly seen obstacle: A* is re-run to the same goal (not a failed attempt;
            // a goal A* cannot reach any more is given up in `plan`).
            goal.stale = true;
            self.benign_interrupt = true;
            return true;
        }
        false
    }

    fn action_finished(&mut self, ctx: &PlanContext, reached: bool) {
        if std::mem::take(&mut self.benign_interrupt) {
            if let Some(g) = &mut self.goal {
                g.final_segment = !g.visit.is_open(ctx.map);
            }
            return;
        }
        let Some(goal) = &mut self.goal else { return };
        if reached && !goal.final_segment {
            // An advected segment ended; the goal stays.
            return;
        }
        let goal = self.goal.take().expect("checked above");
        self.visits.finished(ctx.map, &goal.visit, reached);
    }

    fn field_planner(&mut self) -> Option<&mut dyn FieldPlanner> {
        Some(self)
    }

    fn stats(&self) -> BTreeMap<String, f64> {
        let s = &self.stats;
        super::counted(
            [
                ("key_frames", s.key_frames),
                ("anchors_degenerate", s.anchors_degenerate),
                ("anchors_frontier", s.anchors_frontier),
                ("anchors_visited", s.anchors_visited),
                ("groups_split", s.groups_split),
                ("tsp_solves", s.tsp_solves),
                ("tsp_nodes_max", s.tsp_nodes_max),
                ("tsp_nodes_total", s.tsp_nodes_total),
                ("cost_rows", s.cost_rows),
                ("escapes", s.escapes),
                ("escapes_given_up", s.escapes_given_up),
                ("astar_new_goal", s.astar_new_goal),
                ("astar_same_goal", s.astar_same_goal),
                ("advected_segments", s.advected_segments),
                ("advection_stops_at_points", s.advection_stops_at_points),
                ("advection_fallbacks", s.advection_fallbacks),
                ("advection_stalls", s.advection_stalls),
                ("distant_views", s.distant_views),
                ("groups_left_unfinished", s.groups_left_unfinished),
                ("returns_to_unfinished", s.returns_to_unfinished),
            ]
            .into_iter()
            .chain(GoalKind::ALL.map(|k| (k.key(), s.path_m[k as usize]))),
        )
    }
}

/// Whether `p` lies on known traversable floor (a usable anchor position).
fn on_floor(map: &Map, grid: &GridSpec, p: Point2<f64>) -> bool {
    grid.cell_of(p)
        .is_some_and(|c| map.is_traversable(grid.index(c)))
}

/// Path cost from the robot to a node's anchor (its position): from the robot's distance field where
/// the anchor's cell is reachable, else through its nearest member (member cost plus the straight
/// distance on to the anchor), as a frontier anchor's centroid may fall off the known floor.
fn anchor_cost(grid: &GridSpec, df: &DistanceField, node: &Node, fronts: &[Frontier]) -> f32 {
    grid.cell_of(node.pos)
        .and_then(|c| df.cost_to(grid.index(c)))
        .unwrap_or_else(|| {
            node.members
                .iter()
                .map(|&m| fronts[m].cost + (fronts[m].pos - node.pos).norm() as f32)
                .fold(f32::INFINITY, f32::min)
        })
}

/// Group splitting, THP Eq. 9 — the reading used here.
///
/// The paper defines S(F_k) = {f_k | ν ≥ d_g ∨ (μ < d_p ∧ ν < d_g)} with μ the distance from the
/// robot to the group's anchor and ν a comparison of the A* length to f_k with it, but never defines
/// ν, and read literally S keeps exactly the frontiers that are far around a wall. Its stated intent
/// (Fig. 4) is to split a group that spans two rooms when the robot is at it. So:
///
/// - μ = ‖c_r − p_k‖: the robot is at the group when μ < d_p;
/// - ν = path cost(c_r, f_k) − ‖c_r − f_k‖: the detour to f_k, large exactly when a wall stands
///   between the robot and f_k (the straight distance, not μ, is the baseline, so a frontier merely
///   far across an open room is not split off);
/// - while μ < d_p, the members with ν ≥ d_g are split off and become anchors — but only when the
///   group also has members with ν < d_g (it really spans two sides). A group wholly behind a wall is
///   left whole, so the split-off group is never split again.
///
/// Returns the members (indices into `fronts`) to split off.
fn split_group(
    members: &[usize],
    fronts: &[Frontier],
    robot: Point2<f64>,
    anchor: Point2<f64>,
    d_g: f64,
    d_p: f64,
) -> Vec<usize> {
    let mu = (robot - anchor).norm();
    if mu >= d_p || members.len() < 2 {
        return Vec::new();
    }
    let detour = |m: usize| f64::from(fronts[m].cost) - (fronts[m].pos - robot).norm();
    let (far, near): (Vec<usize>, Vec<usize>) =
        members.iter().copied().partition(|&m| detour(m) >= d_g);
    if near.is_empty() {
        return Vec::new();
    }
    far
}

/// K-means grouping (the Fig. 8 baseline, clusters as in Kulich et al. 2019): one cluster per
/// `cluster_m` metres of frontier, farthest-point initialisation (deterministic), Lloyd iterations on
/// the segment centroids.
fn kmeans_nodes(
    fronts: &[Frontier],
    segment_cells: &[Vec<usize>],
    res: f64,
    cluster_m: f64,
) -> Vec<Node> {
    if fronts.is_empty() {
        return Vec::new();
    }
    let length_m: f64 = fronts
        .iter()
        .map(|f| segment_cells[f.segment].len() as f64 * res)
        .sum();
    let k = ((length_m / cluster_m).ceil() as usize).clamp(1, fronts.len());
    let mut centres = vec![fronts[0].pos];
    while centres.len() < k {
        let next = fronts
            .iter()
            .map(|f| {
                centres
                    .iter()
                    .map(|c| (c - f.pos).norm_squared())
                    .fold(f64::INFINITY, f64::min)
            })
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
            .map(|(i, _)| i)
            .expect("fronts is not empty");
        centres.push(fronts[next].pos);
    }
    let mut assign = vec![0usize; fronts.len()];
    for _ in 0..KMEANS_ITERATIONS {
        let mut changed = false;
        for (i, f) in fronts.iter().enumerate() {
            let best = (0..k)
                .min_by(|&a, &b| {
                    (centres[a] - f.pos)
                        .norm_squared()
                        .total_cmp(&(centres[b] - f.pos).norm_squared())
                        .then(a.cmp(&b))
                })
                .expect("k ≥ 1");
            changed |= assign[i] != best;
            assign[i] = best;
        }
        for (c, centre) in centres.iter_mut().enumerate() {
            let members: Vec<&Frontier> = fronts
                .iter()
                .zip(&assign)
                .filter(|(_, &a)| a == c)
                .map(|(f, _)| f)
                .collect();
            if !members.is_empty() {
                let sum = members
                    .iter()
                    .fold(nalgebra::Vector2::zeros(), |s, f| s + f.pos.coords);
                *centre = Point2::from(sum / members.len() as f64);
            }
        }
        if !changed {
            break;
        }
    }
    (0..k)
        .map(|c| Node {
            key: c,
            pos: centres[c],
            members: (0..fronts.len()).filter(|&i| assign[i] == c).collect(),
        })
        .filter(|n| !n.members.is_empty())
        .collect()
}

/// The path vertex nearest `p` at or after `from`, and its distance.
fn nearest_on_path(path: &[Point2<f64>], p: Point2<f64>, from: usize) -> (usize, f64) {
    path.iter()
        .enumerate()
        .skip(from)
        .map(|(k, q)| (k, (q - p).norm()))
        .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
        .unwrap_or((from, f64::INFINITY))
}

/// The prefix of an advected pathline the robot may follow: it stops before the first impassable
/// point, where it strays more than `drift_m` from the A* path, where it turns back along the path,
/// and once it comes within `tolerance_m` of the path's end (then `true` is returned with it).
fn accept_pathline(
    line: &[Point2<f64>],
    path: &[Point2<f64>],
    progress: usize,
    drift_m: f64,
    tolerance_m: f64,
    passable: impl Fn(Point2<f64>) -> bool,
) -> (Vec<Point2<f64>>, bool) {
    let end = *path.last().expect("path has points");
    let mut out = Vec::with_capacity(line.len());
    let mut best_progress = progress;
    for &p in line {
        if !passable(p) {
            break;
        }
        // Search a window around the progress so far, so that a path folding back on itself does
        // not make the line jump ahead.
        let window_end = (best_progress + 40).min(path.len());
        let (k, d) = nearest_on_path(&path[..window_end], p, best_progress.saturating_sub(5));
        if d > drift_m || k + 5 < best_progress {
            break;
        }
        best_progress = best_progress.max(k);
        out.push(p);
        if (p - end).norm() <= tolerance_m {
            return (out, true);
        }
    }
    (out, false)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn front(pos: (f64, f64), cost: f32) -> Frontier {
        Frontier {
            segment: 0,
            pos: Point2::new(pos.0, pos.1),
            aim: 0,
            cost,
        }
    }

    #[test]
    fn a_group_across_a_wall_is_split_when_the_robot_is_at_it() {
        let robot = Point2::new(0.0, 0.0);
        let anchor = Point2::new(1.0, 0.0);
        // f0 in the robot's room (path ≈ straight), f1 1.5 m away through the wall but 6 m by path.
        let fronts = [front((2.0, 0.0), 2.1), front((0.0, 1.5), 6.0)];
        assert_eq!(
            split_group(&[0, 1], &fronts, robot, anchor, 2.0, 3.0),
            vec![1]
        );
        // The robot far from the group (μ ≥ d_p): no split.
        let far = Point2::new(-5.0, 0.0);
        assert!(split_group(&[0, 1], &fronts, far, anchor, 2.0, 3.0).is_empty());
        // A group wholly behind the wall is not split again.
        let behind = [front((0.0, 1.5), 6.0), front((0.5, 1.5), 6.4)];
        assert!(split_group(&[0, 1], &behind, robot, anchor, 2.0, 3.0).is_empty());
        // A frontier far across an open room is not a detour.
        let open = [front((2.0, 0.0), 2.1), front((2.9, 0.0), 3.0)];
        assert!(split_group(&[0, 1], &open, robot, anchor, 2.0, 3.0).is_empty());
    }

    #[test]
    fn kmeans_separates_two_distant_clusters() {
        let mut fronts = Vec::new();
        for i in 0..4 {
            fronts.push(front((i as f64 * 0.3, 0.0), 1.0));
            fronts.push(front((20.0 + i as f64 * 0.3, 5.0), 1.0));
        }
        for (i, f) in fronts.iter_mut().enumerate() {
            f.segment = i;
        }
        // 8 segments of 10 cells at 0.1 m = 8 m of frontier, 4 m per cluster: k = 2.
        let cells = vec![vec![0usize; 10]; 8];
        let nodes = kmeans_nodes(&fronts, &cells, 0.1, 4.0);
        assert_eq!(nodes.len(), 2);
        for n in &nodes {
            let xs: Vec<f64> = n.members.iter().map(|&m| fronts[m].pos.x).collect();
            assert!(
                xs.iter().all(|&x| x < 1.0) || xs.iter().all(|&x| x > 19.0),
                "{xs:?}"
            );
            assert_eq!(n.members.len(), 4);
        }
    }

    #[test]
    fn pathline_is_cut_at_drift_obstacles_and_the_goal() {
        let path: Vec<Point2<f64>> = (0..=30).map(|i| Point2::new(i as f64 * 0.1, 0.0)).collect();
        // A line that drifts off sideways after 1 m.
        let line: Vec<Point2<f64>> = (0..=40)
            .map(|i| {
                let x = i as f64 * 0.05;
                Point2::new(x, if x > 1.0 { (x - 1.0) * 2.0 } else { 0.0 })
            })
            .collect();
        let (seg, end) = accept_pathline(&line, &path, 0, 0.5, 0.2, |_| true);
        assert!(!end);
        let last = seg.last().unwrap();
        assert!(
            last.y <= 0.5 + 1e-9 && last.x > 1.0 && last.x < 1.4,
            "{last:?}"
        );
        // An impassable point cuts the line before it.
        let (seg, _) = accept_pathline(&line, &path, 0, 0.5, 0.2, |p| p.x < 0.5);
        assert!(seg.iter().all(|p| p.x < 0.5) && !seg.is_empty());
        // A straight line along the path reaches its end.
        let straight: Vec<Point2<f64>> = (0..=70)
            .map(|i| Point2::new(i as f64 * 0.05, 0.0))
            .collect();
        let (seg, end) = accept_pathline(&straight, &path, 0, 0.5, 0.2, |_| true);
        assert!(end);
        assert!((seg.last().unwrap() - path.last().unwrap()).norm() <= 0.2);
    }
}
