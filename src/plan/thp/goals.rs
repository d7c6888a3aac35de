//! Choosing the next goal: the least-cost frontier of the tour's first group, a step back for a
//! frontier in the camera's blind zone, an escape from a pocket, or a look through a gap too narrow
//! to pass before the run is complete.

use super::*;

/// What choosing a goal gave.
pub(super) enum Choice {
    /// An action to take now.
    Act(Action),
    /// Drive to the goal the mode now holds.
    Drive,
}

/// The cells the robot's centre has been in. An escape toward a frontier squeezes through inflated
/// cells only beside them, back the way the robot came into its pocket. Through any physically
/// clear gap, it took THP through doors narrower than the planners' inflation into rooms no planner
/// may plan into (outside the metrics' reachable region): 12 of 99 runs on each half of the real
/// plans, 2–34 % of their explored volume outside the observable set, often into a pocket that then
/// closed (docs/experiments.md).
#[derive(Clone, Debug, Default)]
pub(super) struct Trail(Vec<bool>);

impl Trail {
    /// Marks the cell of the robot's centre `p`.
    pub(super) fn visit(&mut self, grid: &GridSpec, p: Point2<f64>) {
        if self.0.len() != grid.cells() {
            self.0 = vec![false; grid.cells()];
        }
        if let Some(c) = grid.cell_of(p) {
            self.0[grid.index(c)] = true;
        }
    }

    /// Whether cell `i` or one of its 8 neighbours is on the trail (a path sampled every step can
    /// cross a cell corner diagonally).
    pub(super) fn is_beside(&self, grid: &GridSpec, i: usize) -> bool {
        let c = grid.cell(i);
        std::iter::once((0, 0))
            .chain(crate::grid::NEIGHBOURS_8)
            .any(|(dx, dy)| {
                grid.checked_index(crate::grid::Cell::new(c.x + dx, c.y + dy))
                    .is_some_and(|j| self.0.get(j).copied().unwrap_or(false))
            })
    }
}

/// Open volume views within this of a kept one do not become tour nodes of their own: from about a
/// metre apart a view turned once shows much the same volume, metres.
const VOLUME_VIEW_NODE_SPACING_M: f64 = 1.0;

/// At most this many volume views (the largest gains after thinning) make one tour.
const VOLUME_VIEW_NODES_MAX: usize = 24;

/// The escapes from pockets (`additions.escape_tries`): where the robot has been, and how often an
/// escape was started toward each target cell.
#[derive(Clone, Debug, Default)]
pub(super) struct Escapes {
    pub(super) trail: Trail,
    tries: BTreeMap<usize, u32>,
}

/// Where THP's next goal comes from. [`Thp::choose_goal_from`] asks each in the order of
/// [`GOAL_SOURCES`]; the first that answers gives the goal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum GoalSource {
    /// A frontier in the camera's blind zone, by a step back (`additions.blind_zone_step_back`).
    BlindZone,
    /// A look from a viewpoint at the tour's frontier, when earlier looks left it open
    /// (`additions.viewpoint_looks`).
    Viewpoint,
    /// The tour's frontier: the least-cost frontier of the tour's first group (Alg. 1–2).
    Tour,
    /// An escape from a pocket when frontiers are left but none is reachable
    /// (`additions.escape_tries`).
    Escape,
    /// The end-of-run sequence ([`crate::plan::frontier::end_of_run`]), then `Complete`.
    EndOfRun,
}

/// The order in which the goal sources are asked.
pub(super) const GOAL_SOURCES: [GoalSource; 5] = [
    GoalSource::BlindZone,
    GoalSource::Viewpoint,
    GoalSource::Tour,
    GoalSource::Escape,
    GoalSource::EndOfRun,
];

/// What the goal sources of one planning step read.
struct GoalInputs<'a> {
    /// The robot's search cell, and the step costs and distance field from it.
    start: usize,
    costs: &'a plan::StepCosts,
    df: &'a DistanceField,
    /// The nearest frontier in the camera's blind zone, if any (and the step back is on).
    near: Option<Frontier>,
    /// The cells of every frontier segment.
    segment_cells: Vec<Vec<usize>>,
    /// The nodes the tour routes over.
    nodes: Vec<Node>,
    /// The tour's first node and its least-cost frontier; `None` without a node.
    tour_next: Option<(usize, Frontier)>,
}

impl Thp {
    /// The reachable, observable frontiers and, separately, the nearest other one inside the camera's
    /// blind zone around the robot, with path costs from the robot's distance field.
    ///
    /// A frontier the robot stopped short of and looked at stays among the frontiers even inside the
    /// blind zone, so its second approach (all the way, [`FrontierVisits::cut_short`]) comes next,
    /// while the robot is there. Left out, it emptied its group, its anchor counted as visited, and
    /// once the robot was away it came back as a new anchor: the robot shuttled between two such
    /// frontiers for the rest of a run (on one real plan, 110 m driven where this rule drives 36 m).
    pub(super) fn frontiers(
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
            let best = self
                .visits
                .cheapest_open(seg.cells.iter().map(|c| grid.index(*c)), df);
            cells.push(seg.cells.iter().map(|c| grid.index(*c)).collect());
            let Some((cost, aim)) = best else { continue };
            let f = Frontier {
                segment: k,
                pos: seg.centroid,
                aim,
                cost,
            };
            let near = self.rules.blind_zone_step_back
                && (grid.center(grid.cell(aim)) - robot).norm_squared() <= near2;
            if near && !self.visits.was_approached(aim) {
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

    /// Chooses the next goal: the least-cost frontier of the first node of the tour.
    pub(super) fn choose_goal(&mut self, ctx: &mut PlanContext) -> Result<Choice> {
        let grid = *ctx.map.grid();
        let robot = ctx.pose.position();
        let Some(start) = plan::search_source(ctx.map, &ctx.cfg.search, robot, self.radius_m)
        else {
            return Ok(self.way_out(ctx));
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
    /// known: plans the tour (Alg. 1–2), then asks the goal sources in the order of
    /// [`GOAL_SOURCES`] until one answers.
    pub(super) fn choose_goal_from(
        &mut self,
        ctx: &mut PlanContext,
        start: usize,
        costs: &plan::StepCosts,
        df: &DistanceField,
    ) -> Result<Choice> {
        let grid = *ctx.map.grid();
        let robot = ctx.pose.position();
        let (fronts, near, segment_cells) = self.frontiers(ctx.map, df, robot);
        let nodes = match self.cfg.grouping {
            Grouping::Anchors => self.anchors.group(&fronts, robot, (&self.cfg).into()),
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
        // Under `thp.finish_group_first` a new tour starts at the group being scanned.
        let current = (self.mode.goal())
            .filter(|_| self.cfg.finish_group_first)
            .and_then(|g| g.tour_node);
        let inputs = TourInputs {
            map: ctx.map,
            time_s: ctx.time_s,
            costs,
            df,
        };
        let new_anchors = self.anchors.has_new();
        let tour_next = (self.tour).plan(&inputs, &self.cfg, &nodes, &fronts, new_anchors, current);
        // Planned over every anchor there is (or no node was left to plan over): `P*` is empty.
        self.anchors.tour_planned();
        let at = GoalInputs {
            start,
            costs,
            df,
            near,
            segment_cells,
            nodes,
            tour_next,
        };
        for source in GOAL_SOURCES {
            let choice = match source {
                GoalSource::BlindZone => self.blind_zone_source(ctx, &at),
                GoalSource::Viewpoint => self.viewpoint_source(ctx, &at),
                GoalSource::Tour => self.tour_source(ctx, &at),
                GoalSource::Escape => self.escape_source(ctx, &at),
                GoalSource::EndOfRun => Some(self.end_of_run_source(ctx, &at)),
            };
            if let Some(choice) = choice {
                return Ok(choice);
            }
        }
        unreachable!("the end of the run always answers")
    }

    /// A frontier in the blind zone around the robot, by a step back to see the floor there: before
    /// the robot drives away to the tour's frontier (`additions.blind_zone_look_first_m`, shared
    /// with GREEDY), and whenever no tour is left.
    fn blind_zone_source(&mut self, ctx: &PlanContext, at: &GoalInputs) -> Option<Choice> {
        let near = at.near.as_ref()?;
        if let Some((_, f)) = &at.tour_next {
            if !blind_zone_first(&self.rules, f.cost) {
                return None;
            }
        }
        let visit = near.visit(ctx.map.grid(), &at.segment_cells, true);
        Some(self.blind_zone_goal(ctx, at.df, visit, None))
    }

    /// The tour's frontier, when a look from on top or from within the blind zone left it open: a
    /// look from where the camera sees the floor beside it, if anywhere does.
    fn viewpoint_source(&mut self, ctx: &PlanContext, at: &GoalInputs) -> Option<Choice> {
        let (first, f) = at.tour_next.as_ref()?;
        if !self.visits.needs_viewpoint(f.aim) {
            return None;
        }
        let grid = *ctx.map.grid();
        let mut view = f.visit(&grid, &at.segment_cells, true);
        view.target
            .retain(|c| self.visits.needs_viewpoint(grid.index(*c)));
        let seen_from = (self.visits).sighted_viewpoint(
            ctx.map,
            at.df,
            f.aim,
            self.cfg.view_distance_m,
            &ctx.cfg.camera,
        );
        let Some(v) = seen_from else {
            self.visits.no_viewpoint(&grid, &view);
            return None;
        };
        let path = at.df.path_to(&grid, v).expect("reachable by construction");
        self.set_goal(ctx, view, Some(*first), &path.cells);
        Some(Choice::Drive)
    }

    /// The tour's frontier (Alg. 1–2): the current A* path if the goal did not change, else a new
    /// one, cut short to look from `view_distance_m`.
    fn tour_source(&mut self, ctx: &mut PlanContext, at: &GoalInputs) -> Option<Choice> {
        let (first, f) = at.tour_next.as_ref()?;
        let (first, grid) = (*first, *ctx.map.grid());
        let visit = f.visit(&grid, &at.segment_cells, false);
        // Keep the current A* path if the goal did not change.
        if let Some(g) = self.mode.goal_mut() {
            if g.visit.aim == visit.aim && !g.stale {
                g.visit = visit;
                g.tour_node = Some(first);
                return Some(Choice::Drive);
            }
        }
        // A* calls by cause, for the advection claim (§3.5): a new goal, or the same goal again.
        let same_goal = self.mode.goal().is_some_and(|g| g.visit.aim == visit.aim);
        if !same_goal {
            self.note_tour_goal(first, |k| at.nodes.iter().any(|n| n.key == k));
        }
        if same_goal {
            self.stats.astar_same_goal.add(1.0);
        } else {
            self.stats.astar_new_goal.add(1.0);
        }
        let costs = at.costs;
        let Some(path) = ctx.search.astar(&grid, |i| costs.get(i), at.start, f.aim) else {
            // Reachable in the distance field, so A* finds it too; be safe all the same.
            self.visits.finished_in(ctx, &visit, false);
            return Some(Choice::Act(Action::LookAround));
        };
        let cells = self
            .visits
            .cut_short(&grid, &path.cells, f.aim, self.cfg.view_distance_m)
            .to_vec();
        self.set_goal(ctx, visit, Some(first), &cells);
        Some(Choice::Drive)
    }

    /// Frontiers are left but none is reachable: trapped in a pocket? An escape toward a target
    /// that already failed `additions.escape_tries` times gives the frontier up there, so that one
    /// unreachable target cannot keep the robot trying until the run is stuck (no escapes at all
    /// with 0). Only without a tour.
    fn escape_source(&mut self, ctx: &mut PlanContext, at: &GoalInputs) -> Option<Choice> {
        if at.tour_next.is_some() {
            return None;
        }
        let grid = *ctx.map.grid();
        let (start, df, segment_cells) = (at.start, at.df, &at.segment_cells);
        while self.rules.escape_tries > 0 {
            let open_frontiers: Vec<usize> = segment_cells
                .iter()
                .flatten()
                .copied()
                .filter(|&i| !self.visits.is_unobservable(i))
                .collect();
            if open_frontiers.is_empty() {
                break;
            }
            let trail = &self.escapes.trail;
            let Some(path) = plan::escape_path(
                ctx,
                start,
                df,
                &open_frontiers,
                self.rules.escape_clearance_m.get(),
                |i| trail.is_beside(&grid, i),
            ) else {
                break;
            };
            let target = path
                .last()
                .and_then(|p| grid.cell_of(*p))
                .map_or(start, |c| grid.index(c));
            let tries = self.escapes.tries.entry(target).or_insert(0);
            *tries += 1;
            if *tries > self.rules.escape_tries {
                self.stats.escapes_given_up.add(1.0);
                self.visits.give_up_around(&grid, target, open_frontiers);
                continue;
            }
            self.stats.escapes.add(1.0);
            self.ledger.kind = GoalKind::Escape;
            self.mode.stop();
            return Some(Choice::Act(Action::Follow {
                path,
                look_on_arrival: false,
                exact_arrival: false,
            }));
        }
        None
    }

    /// Nothing reachable is left: the end-of-run sequence (shared with GREEDY).
    fn end_of_run_source(&mut self, ctx: &mut PlanContext, at: &GoalInputs) -> Choice {
        let (map, grid, df, costs) = (ctx.map, *ctx.map.grid(), at.df, at.costs);
        let segment_cells = &at.segment_cells;
        let (rules, view_m, params) = (self.rules.clone(), self.cfg.view_distance_m, ctx.cfg);
        let camera = &params.camera;
        let ending = end_of_run(
            &rules,
            self,
            |thp| {
                let given_up = |i| thp.visits.is_unobservable(i);
                distant_view(map, df, segment_cells, given_up, view_m)
            },
            |thp| thp.next_volume_view(ctx, costs, df),
            |thp| {
                !(thp.visits)
                    .reopen_seeable(map, df, segment_cells, camera, |_| false)
                    .is_empty()
            },
        );
        match ending {
            Ending::DistantView(view) => {
                // Counted once per view: a view whose path went bad is chosen again on
                // the way to it, and each choice used to count it again.
                if self.mode.goal().is_none_or(|g| g.visit.aim != view.aim) {
                    self.stats.distant_views.add(1.0);
                }
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
                self.set_goal(ctx, visit, None, &path.cells);
                self.ledger.kind = GoalKind::DistantView;
                Choice::Drive
            }
            Ending::VolumeView(view) => {
                self.ledger.kind = GoalKind::VolumeView;
                self.mode.stop();
                let (action, _) = follow_to(&grid, df, view.cell, true, false);
                Choice::Act(action)
            }
            Ending::Reopened => Choice::Act(Action::LookAround),
            Ending::Complete => Choice::Act(Action::Complete),
        }
    }

    /// The next volume view to drive to, marked taken; `None` when views are off or none is open.
    ///
    /// With `additions.volume_view_tour` (not in the paper) the open views, thinned to one per
    /// [`VOLUME_VIEW_NODE_SPACING_M`], are ordered by a fixed-start open TSP from the robot over
    /// their path costs, as Alg. 1 orders anchors, and the first is taken; the tour is solved again
    /// at every view, since each view changes what the others would still show. Without it, the
    /// best gain per metre one view at a time, as GREEDY does ([`VolumeViews::next`]).
    fn next_volume_view(
        &mut self,
        ctx: &mut PlanContext,
        costs: &plan::StepCosts,
        df: &DistanceField,
    ) -> Option<VolumeView> {
        let grid = *ctx.map.grid();
        let mut views = self.volume_views.take()?;
        let next = if self.rules.volume_view_tour {
            let open = views.thinned(
                ctx.map,
                df,
                VOLUME_VIEW_NODE_SPACING_M,
                VOLUME_VIEW_NODES_MAX,
            );
            let first = match open.len() {
                0 => None,
                1 => Some(open[0]),
                _ => {
                    let cells: Vec<usize> = open.iter().map(|v| v.cell).collect();
                    let inputs = TourInputs {
                        map: ctx.map,
                        time_s: ctx.time_s,
                        costs,
                        df,
                    };
                    let m = self.tour.cost_matrix(&inputs, &self.cfg, &cells);
                    let from_robot = costs_from(df, &cells);
                    Some(open[open_tour_from(&m, &from_robot, self.cfg.exact_tsp_max_nodes)[0]])
                }
            };
            if let Some(v) = first {
                views.mark_taken(&grid, v.cell);
            }
            first
        } else {
            views.next(ctx.map, df)
        };
        self.volume_views = Some(views);
        next
    }

    /// For a robot trapped where no cell within two robot radii may be entered (a back-off took it
    /// into a pocket, or obstacles seen since inflated the cells around it): the escape search
    /// ([`plan::escape_path`]) to the nearest enterable cell within [`WAY_OUT_M`], counted as an
    /// escape; a look around if there is none. Only ever looking around there kept the robot turning
    /// in place until the run ended `stuck`.
    fn way_out(&mut self, ctx: &mut PlanContext) -> Choice {
        let grid = *ctx.map.grid();
        let robot = ctx.pose.position();
        let Some(here) = grid.cell_of(robot) else {
            return Choice::Act(Action::LookAround);
        };
        let (map, search_cfg) = (ctx.map, &ctx.cfg.search);
        let stay = ctx.search.distance_field(
            &grid,
            |i| plan::step_cost(map, search_cfg, robot, i),
            grid.index(here),
            f32::INFINITY,
        );
        if self.rules.escape_tries == 0 {
            return Choice::Act(Action::LookAround);
        }
        let reach = (self.rules.way_out_m.get() / grid.res).ceil() as i32;
        let targets: Vec<usize> = (-reach..=reach)
            .flat_map(|dy| (-reach..=reach).map(move |dx| (dx, dy)))
            .filter_map(|(dx, dy)| {
                grid.checked_index(crate::grid::Cell::new(here.x + dx, here.y + dy))
            })
            .filter(|&i| plan::step_cost(map, search_cfg, robot, i).is_some())
            .collect();
        let Some(path) = plan::escape_path(
            ctx,
            grid.index(here),
            &stay,
            &targets,
            self.rules.escape_clearance_m.get(),
            |_| true,
        ) else {
            return Choice::Act(Action::LookAround);
        };
        self.stats.escapes.add(1.0);
        self.ledger.kind = GoalKind::Escape;
        self.mode.stop();
        Choice::Act(Action::Follow {
            path,
            look_on_arrival: false,
            exact_arrival: false,
        })
    }

    /// Steps back from a frontier in the camera's blind zone to a cell from which the camera sees the
    /// floor there ([`blind_zone_viewpoint`]), or turns in place where there is none.
    pub(super) fn blind_zone_goal(
        &mut self,
        ctx: &PlanContext,
        df: &DistanceField,
        visit: Visit,
        tour_node: Option<usize>,
    ) -> Choice {
        let grid = *ctx.map.grid();
        self.ledger.kind = GoalKind::BlindZone;
        let Some(v) = blind_zone_viewpoint(
            ctx.map,
            df,
            visit.aim,
            self.cfg.view_distance_m,
            &ctx.cfg.camera,
        ) else {
            self.mode.drive(Goal {
                visit,
                tour_node,
                path: Vec::new(),
                path_cells: Vec::new(),
                look_on_arrival: true,
                final_segment: true,
                stale: false,
                best_progress: 0,
                progress_s: ctx.time_s,
                direct: false,
            });
            return Choice::Act(Action::LookAround);
        };
        let path = df.path_to(&grid, v).expect("reachable by construction");
        self.set_goal(ctx, visit, tour_node, &path.cells);
        Choice::Drive
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Cell;

    /// The order of the goal sources is what the module doc promises: what must precede the tour's
    /// frontier does, escapes come only once no tour is left, and the end of the run, which always
    /// answers, comes last, once.
    #[test]
    fn goal_sources_are_asked_in_their_promised_order() {
        let at = |s: GoalSource| GOAL_SOURCES.iter().position(|&x| x == s).unwrap();
        // A blind-zone frontier is looked at before the robot drives away along the tour.
        assert!(at(GoalSource::BlindZone) < at(GoalSource::Tour));
        // A frontier that needs a viewpoint look is not approached again instead.
        assert!(at(GoalSource::Viewpoint) < at(GoalSource::Tour));
        assert!(at(GoalSource::Tour) < at(GoalSource::Escape));
        assert_eq!(GOAL_SOURCES.last(), Some(&GoalSource::EndOfRun));
        for (i, s) in GOAL_SOURCES.iter().enumerate() {
            assert!(!GOAL_SOURCES[i + 1..].contains(s), "{s:?} twice");
        }
    }

    #[test]
    fn an_escape_may_squeeze_only_beside_where_the_robot_has_been() {
        let grid = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(2.0, 2.0), 1.0, 0.1);
        let mut trail = Trail::default();
        let at = |x: i32, y: i32| grid.index(Cell::new(x, y));
        // Nothing is beside an empty trail.
        assert!(!trail.is_beside(&grid, at(5, 5)));
        trail.visit(&grid, grid.center(Cell::new(5, 5)));
        for (x, y) in [(5, 5), (4, 4), (6, 5), (6, 6), (5, 4)] {
            assert!(trail.is_beside(&grid, at(x, y)), "({x}, {y})");
        }
        for (x, y) in [(7, 5), (3, 3), (5, 7), (0, 0)] {
            assert!(!trail.is_beside(&grid, at(x, y)), "({x}, {y})");
        }
        // A position off the grid marks nothing.
        trail.visit(&grid, Point2::new(-5.0, -5.0));
        assert!(!trail.is_beside(&grid, at(0, 0)));
    }
}
