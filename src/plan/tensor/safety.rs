//! TENSOR's safety moves (§6): moving away from a wall along its normal, and stepping clear when the
//! motion guard pins the robot.

use super::*;

impl Tensor {
    /// Moves away along the normal of a wall the body is closer than `wall_clearance_m` to, when
    /// the known free space allows a real gain of clearance.
    pub(super) fn wall_escape(&mut self, ctx: &PlanContext) -> Option<Action> {
        let robot = ctx.pose.position();
        let want = ctx.cfg.robot.radius_m + self.cfg.wall_clearance_m;
        if ctx.time_s - self.last_escape_s < self.field_cfg.keyframe_period_s {
            return None;
        }
        let o = ctx.map.nearest_obstacle_point(robot, want)?;
        let d = (robot - o).norm();
        if d < 1e-6 {
            return None;
        }
        let best = walk(ctx, robot, (robot - o) / d, want - d);
        let gained = ctx
            .map
            .nearest_obstacle_point(best, want)
            .map_or(want, |q| (q - best).norm())
            - d;
        if gained < 0.1 {
            return None;
        }
        self.last_escape_s = ctx.time_s;
        self.stats.wall_escapes += 1;
        self.current = Current::Escape;
        Some(Action::Follow {
            path: vec![robot, best],
            look_on_arrival: false,
            exact_arrival: false,
        })
    }

    /// A step straight away from the nearest hazard (known obstacle or never-seen cell, as the
    /// executor's guard sees them), when the guard pins the robot and a look did not help.
    pub(super) fn step_clear(&mut self, ctx: &PlanContext) -> Option<Action> {
        let robot = ctx.pose.position();
        let h = ctx.map.nearest_hazard(robot, 1.0)?;
        let d = (robot - h).norm();
        if d < 1e-6 {
            return None;
        }
        let to = walk(ctx, robot, (robot - h) / d, 0.4);
        if (to - robot).norm() < 0.1 {
            return None;
        }
        self.stats.unblocks += 1;
        self.current = Current::Escape;
        Some(Action::Follow {
            path: vec![robot, to],
            look_on_arrival: false,
            exact_arrival: false,
        })
    }
}

/// The farthest point up to `max_m` from `from` along `dir` reached through traversable cells.
pub(super) fn walk(
    ctx: &PlanContext,
    from: Point2<f64>,
    dir: Vector2<f64>,
    max_m: f64,
) -> Point2<f64> {
    let grid = ctx.map.grid();
    let step = 0.5 * grid.res;
    let mut best = from;
    let mut s = step;
    while s <= max_m + 1e-9 {
        let q = from + dir * s;
        let ok = grid
            .cell_of(q)
            .is_some_and(|c| ctx.map.is_traversable(grid.index(c)));
        if !ok {
            break;
        }
        best = q;
        s += step;
    }
    best
}
