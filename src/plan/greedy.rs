//! GREEDY: nearest-frontier exploration (Yamauchi 1997), the classic baseline.
//!
//! The robot drives to the frontier segment nearest by path distance (one Dijkstra distance field
//! from the robot), turns once in place on arrival to look into the unknown, and re-plans as soon as
//! its target segment has been seen or its path is blocked. A segment that is still a frontier after
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
    /// Failed attempts per target cell, keyed by the cell the robot aimed at.
    attempts: Vec<(usize, u32)>,
    aim: Option<usize>,
}

impl Greedy {
    pub fn new() -> Self {
        Self::default()
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
        }
        let Some(start) = grid.cell_of(ctx.pose.position()).map(|c| grid.index(c)) else {
            return Ok(Action::Complete);
        };
        let map = ctx.map;
        let unknown_is_free = ctx.cfg.search.unknown_is_free;
        let df = ctx.search.distance_field(
            &grid,
            |i| super::passable(map, unknown_is_free, i),
            start,
            f32::INFINITY,
        );
        // Nearest observable frontier cell over all segments; ties go to the lower cell index.
        let mut best: Option<(f32, usize, usize)> = None;
        let segments = map.frontiers();
        for (k, seg) in segments.iter().enumerate() {
            for c in &seg.cells {
                let i = grid.index(*c);
                if self.unobservable[i] {
                    continue;
                }
                if let Some(d) = df.distance(i) {
                    if best.is_none_or(|(bd, bi, _)| (d, i) < (bd, bi)) {
                        best = Some((d, i, k));
                    }
                }
            }
        }
        let Some((_, goal, k)) = best else {
            self.target.clear();
            return Ok(Action::Complete);
        };
        let path = df.path_to(&grid, goal).expect("reachable by construction");
        self.target = segments[k].cells.clone();
        self.path_cells = path.cells.iter().skip(1).map(|c| grid.index(*c)).collect();
        self.aim = Some(goal);
        Ok(Action::Follow {
            path: path.cells.iter().map(|c| grid.center(*c)).collect(),
            look_on_arrival: ctx.cfg.greedy.look_around_on_arrival,
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
            // Arrived and looked, yet the segment is still a frontier: nothing more can be seen here.
            self.give_up_target(ctx);
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
