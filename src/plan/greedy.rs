//! GREEDY: nearest-frontier exploration (Yamauchi, "A frontier-based approach for autonomous
//! exploration", CIRA 1997), the classic baseline.
//!
//! Yamauchi's method, as this code reads it for a forward depth camera (the `published` profile):
//! the robot drives toward the frontier segment nearest by path cost (one Dijkstra field from the
//! robot), stops `greedy.view_distance_m` short of it along the path (a forward camera sees nothing
//! of the floor right in front of it, so the look is taken from a step back; at the default mount
//! it sees the floor from 1.45 m), turns once in place to look (Yamauchi's sensor sweep on
//! arrival), and re-plans as soon as its target segment
//! has been seen or its path is blocked by a newly seen obstacle (not counted as a failure). A
//! frontier still open after that look is dropped, as is one the robot fails to reach
//! (`additions.approach_attempts` = 1: the cells within `additions.unreached_give_up_m` of its aim).
//! The run is complete when no reachable frontier is left.
//!
//! The default profile adds the rules of `[additions]` (none in Yamauchi's method; see
//! [`super::frontier`]): a second approach and a look from on top
//! (`look_from_on_top`), looks from viewpoints chosen to see the floor beside a frontier
//! (`viewpoint_looks`), a step back to see a frontier in the camera's blind zone before driving
//! away (`blind_zone_step_back`, [`super::frontier::blind_zone_first`]), and the end-of-run
//! sequence ([`super::frontier::end_of_run`]): a look at each frontier seen through a gap too
//! narrow to pass (`distant_views`), views of the unknown volume no frontier shows
//! (`volume_views`, [`super::frontier::VolumeViews`]) and the reopening of given-up frontiers
//! the camera would still see (`reopen_max`).
//!
//! Statistics: `path_m_frontier`, `path_m_blind_zone`, `path_m_distant_view` and
//! `path_m_volume_view` split the path by the goal the robot was driving to (a look from a viewpoint
//! chosen for a frontier counts under `frontier`), to compare with THP's split of the same names.

use super::frontier::VolumeViews;
use super::frontier::{
    blind_zone_first, blind_zone_viewpoint, distant_view, end_of_run, follow_to, Ending,
    FrontierVisits, Visit, VisitRules,
};
use super::{Action, Count, Odometer, Plan, PlanContext, Planner};
use crate::config::GreedyConfig;
use crate::Result;
use std::collections::BTreeMap;

/// The nearest-frontier planner.
pub struct Greedy {
    cfg: GreedyConfig,
    visits: FrontierVisits,
    /// The frontier being pursued, if any.
    visit: Option<Visit>,
    /// The path's cells, checked every step for blockage.
    path_cells: Vec<usize>,
    /// The current action was cut short by a newly seen obstacle on its path: the frontier is planned
    /// for again, and this does not count as a failed attempt at it (as in THP). Counting it gave up
    /// frontiers behind doors whose first path crossed blind-zone cells that turned out inflated.
    rerouted: bool,
    /// Looks through gaps too narrow to pass (`planner_stats.distant_views`).
    distant_views: Count,
    /// Views of the unknown volume before `Complete` (`additions.volume_views`), if on.
    volume_views: Option<VolumeViews>,
    /// The goal being driven to, and the metres driven per kind of goal (`path_m_*`).
    goal_kind: GoalKind,
    odometer: Odometer,
    path_m: [Count; 4],
}

/// Why GREEDY is driving where it is (`path_m_*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum GoalKind {
    /// The nearest frontier, or a viewpoint chosen to see it.
    Frontier,
    /// A step back to see a frontier in the camera's blind zone.
    BlindZone,
    /// A look through a gap too narrow to pass.
    DistantView,
    /// A view of unknown volume no frontier shows.
    VolumeView,
}

impl GoalKind {
    const KEYS: [&'static str; 4] = [
        "path_m_frontier",
        "path_m_blind_zone",
        "path_m_distant_view",
        "path_m_volume_view",
    ];
}

impl Greedy {
    /// GREEDY with its section of the config, the rules by which it gives frontiers up, and the
    /// volume views it takes before `Complete` (`None`: it completes when no frontier is left, as
    /// Yamauchi's method).
    pub fn new(cfg: &GreedyConfig, rules: VisitRules, volume_views: Option<VolumeViews>) -> Self {
        Greedy {
            cfg: cfg.clone(),
            visits: FrontierVisits::new(rules),
            visit: None,
            path_cells: Vec::new(),
            rerouted: false,
            distant_views: Count::default(),
            volume_views,
            goal_kind: GoalKind::Frontier,
            odometer: Odometer::default(),
            path_m: [Count::default(); 4],
        }
    }

    /// Whether frontier cell `i` was given up as unobservable (TENSOR's fallback shares the rule,
    /// and leaves such cells out of its information gain).
    pub fn is_given_up(&self, i: usize) -> bool {
        self.visits.is_unobservable(i)
    }
}

impl Greedy {
    /// Adds the distance moved since the last call to the current goal's kind.
    fn note_position(&mut self, ctx: &PlanContext) {
        let d = self.odometer.advance(ctx.pose.position());
        if d > 0.0 {
            self.path_m[self.goal_kind as usize].add(d);
        }
    }

    /// The next action: toward the nearest frontier, or `Complete` (see [`Planner::plan`]; TENSOR's
    /// fallback asks it too).
    pub fn next_action(&mut self, ctx: &mut PlanContext) -> Result<Action> {
        let grid = *ctx.map.grid();
        self.visits.ensure(&grid);
        self.visit = None;
        self.path_cells.clear();
        let Some(start) = grid.cell_of(ctx.pose.position()).map(|c| grid.index(c)) else {
            return Ok(Action::Complete);
        };
        let (map, params) = (ctx.map, ctx.cfg);
        let (search_cfg, robot) = (&params.search, ctx.pose.position());
        let step_back = params.additions.blind_zone_step_back;
        let near2 = search_cfg.near_unknown_radius_m.powi(2);
        let df = ctx.search.distance_field(
            &grid,
            |i| super::step_cost(map, search_cfg, robot, i),
            start,
            f32::INFINITY,
        );
        // Nearest observable frontier cell over all segments, beyond the blind zone if there is one;
        // ties go to the lower cell index.
        let mut best: Option<(f32, usize, usize)> = None;
        let mut best_near: Option<(f32, usize, usize)> = None;
        let segments = map.frontiers();
        for (k, seg) in segments.iter().enumerate() {
            for c in &seg.cells {
                let i = grid.index(*c);
                if self.visits.is_unobservable(i) {
                    continue;
                }
                if let Some(d) = df.cost_to(i) {
                    // A frontier approached once (stopped short of, looked at) competes as any
                    // other even inside the blind zone: its second approach comes while the robot
                    // is there (the rule THP shares).
                    let near = step_back
                        && (grid.center(*c) - robot).norm_squared() <= near2
                        && !self.visits.was_approached(i);
                    let slot = if near { &mut best_near } else { &mut best };
                    if slot.is_none_or(|(bd, bi, _)| (d, i) < (bd, bi)) {
                        *slot = Some((d, i, k));
                    }
                }
            }
        }
        let look_on_arrival = self.cfg.look_around_on_arrival;
        let view_m = self.cfg.view_distance_m.get();
        // A frontier in the blind zone comes first, unless the nearest one beyond it is within
        // `additions.blind_zone_look_first_m` (the robot would not drive away from it).
        let best =
            best.filter(|b| best_near.is_none() || !blind_zone_first(&params.additions, b.0));
        let Some((_, goal, k)) = best else {
            // A frontier in the blind zone is next: step back to a viewpoint from which the
            // camera sees the floor there.
            let Some((_, near_goal, k)) = best_near else {
                // Nothing reachable is left: the end-of-run sequence.
                let cells: Vec<Vec<usize>> = segments
                    .iter()
                    .map(|s| s.cells.iter().map(|c| grid.index(*c)).collect())
                    .collect();
                let ending = end_of_run(
                    &params.additions,
                    self,
                    |g| distant_view(map, &df, &cells, |i| g.visits.is_unobservable(i), view_m),
                    |g| g.volume_views.as_mut().and_then(|v| v.next(map, &df)),
                    |g| {
                        let camera = &params.camera;
                        !(g.visits)
                            .reopen_seeable(map, &df, &cells, camera, |_| false)
                            .is_empty()
                    },
                );
                return Ok(match ending {
                    Ending::DistantView(view) => {
                        self.distant_views.add(1.0);
                        self.goal_kind = GoalKind::DistantView;
                        self.visit = Some(Visit {
                            target: segments[view.segment].cells.clone(),
                            aim: view.aim,
                            near_view: true,
                        });
                        let action;
                        (action, self.path_cells) =
                            follow_to(&grid, &df, view.viewpoint, true, true);
                        action
                    }
                    Ending::VolumeView(view) => {
                        self.goal_kind = GoalKind::VolumeView;
                        let action;
                        (action, self.path_cells) = follow_to(&grid, &df, view.cell, true, false);
                        action
                    }
                    Ending::Reopened => Action::LookAround,
                    Ending::Complete => Action::Complete,
                });
            };
            self.visit = Some(Visit {
                target: segments[k].cells.clone(),
                aim: near_goal,
                near_view: true,
            });
            self.goal_kind = GoalKind::BlindZone;
            let Some(v) = blind_zone_viewpoint(map, &df, near_goal, view_m, &ctx.cfg.camera) else {
                return Ok(Action::LookAround);
            };
            let action;
            (action, self.path_cells) = follow_to(&grid, &df, v, look_on_arrival, true);
            return Ok(action);
        };
        self.goal_kind = GoalKind::Frontier;
        if self.visits.needs_viewpoint(goal) {
            // A look from on top or from within the blind zone left it: next from where the camera
            // sees the floor beside it, if any.
            let visit = Visit {
                target: segments[k]
                    .cells
                    .iter()
                    .copied()
                    .filter(|c| self.visits.needs_viewpoint(grid.index(*c)))
                    .collect(),
                aim: goal,
                near_view: true,
            };
            match self
                .visits
                .sighted_viewpoint(map, &df, goal, view_m, &ctx.cfg.camera)
            {
                Some(v) => {
                    self.visit = Some(visit);
                    let action;
                    (action, self.path_cells) = follow_to(&grid, &df, v, look_on_arrival, true);
                    return Ok(action);
                }
                None => self.visits.no_viewpoint(&grid, &visit),
            }
        }
        let path = df.path_to(&grid, goal).expect("reachable by construction");
        let cells = self.visits.cut_short(&grid, &path.cells, goal, view_m);
        self.path_cells = cells.iter().skip(1).map(|c| grid.index(*c)).collect();
        self.visit = Some(Visit {
            target: segments[k].cells.clone(),
            aim: goal,
            near_view: false,
        });
        if cells.len() < 2 {
            return Ok(Action::LookAround);
        }
        Ok(Action::Follow {
            path: cells.iter().map(|c| grid.center(*c)).collect(),
            look_on_arrival,
            exact_arrival: false,
        })
    }
}

impl Planner for Greedy {
    fn name(&self) -> &'static str {
        "greedy"
    }

    fn plan(&mut self, ctx: &mut PlanContext) -> Result<Plan> {
        self.note_position(ctx);
        self.next_action(ctx).map(Plan::from)
    }

    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool {
        self.note_position(ctx);
        if !matches!(action, Action::Follow { .. }) {
            return false;
        }
        let seen = self.visit.as_ref().is_some_and(|v| !v.is_open(ctx.map));
        let blocked = self.path_cells.iter().any(|&i| !ctx.passable(i));
        self.rerouted = blocked && !seen;
        seen || blocked
    }

    fn stats(&self) -> BTreeMap<String, f64> {
        super::counted(
            [
                ("distant_views", self.distant_views),
                ("volume_views", VolumeViews::taken(&self.volume_views)),
            ]
            .into_iter()
            .chain(self.visits.stats())
            .chain(GoalKind::KEYS.into_iter().zip(self.path_m)),
        )
    }

    fn action_finished(&mut self, ctx: &PlanContext, reached: bool) {
        if std::mem::take(&mut self.rerouted) {
            self.visit = None;
            return;
        }
        if let Some(visit) = self.visit.take() {
            self.visits.finished_in(ctx, &visit, reached);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Config, NonNegative};
    use crate::map::testing::{furnished_room_setup, seen_from};
    use crate::plan::search::Search;
    use crate::plan::PlanParams;
    use crate::Pose2;

    /// How far from the robot GREEDY's first frontier is, after one look east from (1, 4) in the
    /// furnished room: the floor behind and beside the robot is still unknown (in the blind zone),
    /// while frontiers beyond it lie farther east.
    fn first_aim_from_robot_m(look_first_m: f64) -> f64 {
        let mut cfg = Config::default();
        cfg.additions.blind_zone_look_first_m = NonNegative::new(look_first_m).unwrap();
        let (grid, bvh) = furnished_room_setup(&cfg);
        let pose = Pose2::new(1.0, 4.0, 0.0);
        let map = seen_from(grid, &cfg, &bvh, [pose]);
        let params = PlanParams::from(&cfg);
        let mut search = Search::new(&grid);
        let mut greedy = Greedy::new(&cfg.greedy, (&cfg.additions).into(), None);
        let mut ctx = PlanContext {
            map: &map,
            pose,
            time_s: 0.0,
            cfg: &params,
            search: &mut search,
        };
        greedy.next_action(&mut ctx).unwrap();
        let aim = greedy.visit.as_ref().expect("a frontier to visit").aim;
        (grid.center(grid.cell(aim)) - pose.position()).norm()
    }

    #[test]
    fn a_frontier_in_the_blind_zone_is_looked_at_before_a_farther_one() {
        let blind_zone_m = Config::default().search.near_unknown_radius_m;
        assert!(first_aim_from_robot_m(0.0) <= blind_zone_m);
        // With a threshold beyond every goal's cost, the blind zone waits until nothing else is left.
        assert!(first_aim_from_robot_m(1e3) > blind_zone_m);
    }
}
