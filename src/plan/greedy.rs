//! GREEDY: nearest-frontier exploration (Yamauchi 1997), the classic baseline.
//!
//! The robot drives toward the frontier segment nearest by path cost (one Dijkstra field from the
//! robot), stops `view_distance_m` short of it (a forward camera cannot see the floor right in front
//! of it), turns once in place to look into the unknown, and re-plans as soon as its target segment
//! has been seen or its path is blocked. Frontier cells within `search.near_unknown_radius_m` of the
//! robot are skipped: they border the camera's blind zone and are seen once the robot moves on. A segment that is still a frontier after
//! the robot arrived and looked, or that the robot failed to reach twice, is marked unobservable and
//! skipped from then on. The run is complete when no reachable, observable frontier is left.

use super::{Action, PlanContext, Planner};
use crate::grid::Cell;
use crate::Result;

/// Failed attempts after which a frontier segment is given up.
const MAX_ATTEMPTS: u32 = 2;

/// The nearest-frontier planner.
#[derive(Default)]
pub struct Greedy {
    /// Cells of the segment being pursued.
    target: Vec<Cell>,
    /// The path's cells, checked every step for blockage.
    path_cells: Vec<usize>,
    /// Frontier cells given up on.
    unobservable: Vec<bool>,
    /// Frontier cells already looked at from `view_distance_m`: the next approach goes all the way.
    approached: Vec<bool>,
    /// Failed attempts per target cell, keyed by the cell the robot aimed at.
    attempts: Vec<(usize, u32)>,
    aim: Option<usize>,
    /// The current target lies in the blind zone and the robot is stepping back to see it.
    near_view: bool,
}

impl Greedy {
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether frontier cell `i` was given up as unobservable (TENSOR's fallback shares the rule,
    /// and leaves such cells out of its information gain).
    pub fn is_given_up(&self, i: usize) -> bool {
        self.unobservable.get(i).copied().unwrap_or(false)
    }

    fn give_up_target(&mut self, ctx: &PlanContext) {
        let grid = ctx.map.grid();
        for c in &self.target {
            self.unobservable[grid.index(*c)] = true;
        }
    }
}

impl Planner for Greedy {
    fn name(&self) -> &'static str {
        "greedy"
    }

    fn plan(&mut self, ctx: &mut PlanContext) -> Result<Action> {
        let grid = *ctx.map.grid();
        if self.unobservable.len() != grid.cells() {
            self.unobservable = vec![false; grid.cells()];
            self.approached = vec![false; grid.cells()];
        }
        let Some(start) = grid.cell_of(ctx.pose.position()).map(|c| grid.index(c)) else {
            return Ok(Action::Complete);
        };
        let map = ctx.map;
        let (search_cfg, robot) = (&ctx.cfg.search, ctx.pose.position());
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
                if self.unobservable[i] {
                    continue;
                }
                if let Some(d) = df.cost_to(i) {
                    let near = (grid.center(*c) - robot).norm_squared() <= near2;
                    let slot = if near { &mut best_near } else { &mut best };
                    if slot.is_none_or(|(bd, bi, _)| (d, i) < (bd, bi)) {
                        *slot = Some((d, i, k));
                    }
                }
            }
        }
        self.aim = None;
        self.near_view = false;
        let look_on_arrival = ctx.cfg.greedy.look_around_on_arrival;
        let view_m = ctx.cfg.greedy.view_distance_m;
        let Some((_, goal, k)) = best else {
            // Only frontiers in the blind zone are left: step back to a viewpoint from which the
            // camera sees the floor there (the least-cost cell `view_distance_m` to twice that away).
            let Some((_, near_goal, k)) = best_near else {
                self.target.clear();
                return Ok(Action::Complete);
            };
            self.target = segments[k].cells.clone();
            self.aim = Some(near_goal);
            self.near_view = true;
            let f = grid.center(grid.cell(near_goal));
            let viewpoint = (0..grid.cells())
                .filter(|&i| map.is_traversable(i))
                .filter_map(|i| {
                    let d = (grid.center(grid.cell(i)) - f).norm();
                    (d >= view_m && d <= 2.0 * view_m)
                        .then(|| df.cost_to(i).map(|c| (c, i)))
                        .flatten()
                })
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let Some((_, v)) = viewpoint else {
                self.path_cells.clear();
                return Ok(Action::LookAround);
            };
            let path = df.path_to(&grid, v).expect("reachable by construction");
            self.path_cells = path.cells.iter().skip(1).map(|c| grid.index(*c)).collect();
            return Ok(Action::Follow {
                path: path.cells.iter().map(|c| grid.center(*c)).collect(),
                look_on_arrival,
            });
        };
        let path = df.path_to(&grid, goal).expect("reachable by construction");
        self.target = segments[k].cells.clone();
        // Stop `view_distance_m` short of the frontier (measured along the path).
        let mut keep = path.cells.len();
        let mut remaining = 0.0;
        let view_distance_m = if self.approached[goal] { 0.0 } else { view_m };
        while keep > 1 && remaining < view_distance_m {
            remaining +=
                (grid.center(path.cells[keep - 1]) - grid.center(path.cells[keep - 2])).norm();
            keep -= 1;
        }
        let cells = &path.cells[..keep];
        self.path_cells = cells.iter().skip(1).map(|c| grid.index(*c)).collect();
        self.aim = Some(goal);
        if cells.len() < 2 {
            return Ok(Action::LookAround);
        }
        Ok(Action::Follow {
            path: cells.iter().map(|c| grid.center(*c)).collect(),
            look_on_arrival,
        })
    }

    fn is_outdated(&mut self, ctx: &PlanContext, action: &Action) -> bool {
        if !matches!(action, Action::Follow { .. }) {
            return false;
        }
        let grid = ctx.map.grid();
        let seen = self
            .target
            .iter()
            .all(|c| !ctx.map.is_frontier(grid.index(*c)));
        let blocked = self.path_cells.iter().any(|&i| !ctx.passable(i));
        seen || blocked
    }

    fn action_finished(&mut self, ctx: &PlanContext, reached: bool) {
        let Some(aim) = self.aim.take() else {
            return;
        };
        let grid = ctx.map.grid();
        let still_frontier = self
            .target
            .iter()
            .any(|c| ctx.map.is_frontier(grid.index(*c)));
        if !still_frontier {
            return;
        }
        if reached {
            if self.approached[aim] || self.near_view {
                // Looked from the frontier itself and it is still one: nothing more can be seen.
                self.give_up_target(ctx);
            } else {
                for c in &self.target {
                    self.approached[grid.index(*c)] = true;
                }
            }
            return;
        }
        let entry = match self.attempts.iter_mut().find(|(c, _)| *c == aim) {
            Some(e) => e,
            None => {
                self.attempts.push((aim, 0));
                self.attempts.last_mut().expect("just pushed")
            }
        };
        entry.1 += 1;
        if entry.1 >= MAX_ATTEMPTS {
            self.give_up_target(ctx);
        }
    }
}
