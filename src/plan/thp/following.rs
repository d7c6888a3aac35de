//! Driving to a goal (THP §3.5, Eq. 10–11): the A* path laid into the field, advected pathlines
//! accepted while they keep to it, and the watchdog that falls back to the path itself.

use super::*;

/// Shortest advected segment worth following, metres; shorter ones fall back to the A* path.
pub(super) const MIN_SEGMENT_M: f64 = 0.3;

/// The goal being driven to, with its A* path.
#[derive(Clone, Debug)]
pub(super) struct Goal {
    pub(super) visit: Visit,
    /// Tour node the goal belongs to (anchor index in anchors mode); `None` for a goal outside the
    /// tour (a step back for the blind zone, a look through a gap).
    pub(super) tour_node: Option<usize>,
    /// The A* path (cut short for viewing), world points from the robot to the goal.
    pub(super) path: Vec<Point2<f64>>,
    pub(super) path_cells: Vec<usize>,
    /// Whether arriving at the path's end means turning to look (false for plain look-arounds).
    pub(super) look_on_arrival: bool,
    /// The action in progress ends at the path's end (not an intermediate advected segment).
    pub(super) final_segment: bool,
    /// A* must be re-run before the next segment.
    pub(super) stale: bool,
    /// Farthest index along `path` the robot has come, and the simulated time it got there.
    pub(super) best_progress: usize,
    pub(super) progress_s: f64,
    /// Advection stopped bringing the robot along (`additions.advection_stall_s`): follow `path` itself.
    pub(super) direct: bool,
}

/// The path vertex nearest `p` at or after `from`, and its distance.
pub(super) fn nearest_on_path(path: &[Point2<f64>], p: Point2<f64>, from: usize) -> (usize, f64) {
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
pub(super) fn accept_pathline(
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

impl Thp {
    /// Makes `cells` (from the robot) the goal's A* path and lays it into the field (Eq. 10–11).
    pub(super) fn set_goal(
        &mut self,
        ctx: &PlanContext,
        visit: Visit,
        tour_node: Option<usize>,
        cells: &[crate::grid::Cell],
    ) {
        let grid = ctx.map.grid();
        let path: Vec<Point2<f64>> = cells.iter().map(|c| grid.center(*c)).collect();
        if self.cfg.advection {
            if let Some(field) = &mut self.key_frames.field {
                field.set_path(&path);
            }
        }
        self.mode.drive(Goal {
            visit,
            tour_node,
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
    pub(super) fn next_segment(&mut self, ctx: &PlanContext) -> Action {
        let Some(mut goal) = self.mode.stop() else {
            return Action::LookAround;
        };
        let action = self.next_segment_of(ctx, &mut goal);
        self.mode.drive(goal);
        action
    }

    /// [`Thp::next_segment`] for `goal`.
    fn next_segment_of(&mut self, ctx: &PlanContext, goal: &mut Goal) -> Action {
        let robot = ctx.pose.position();
        if goal.path.len() < 2 {
            goal.final_segment = true;
            return Action::LookAround;
        }
        let (progress, _) = nearest_on_path(&goal.path, robot, 0);
        if progress > goal.best_progress {
            goal.best_progress = progress;
            goal.progress_s = ctx.time_s;
        } else if self.rules.advection_stall_s.get() > 0.0
            && !goal.direct
            && ctx.time_s - goal.progress_s >= self.rules.advection_stall_s.get()
        {
            goal.direct = true;
            self.stats.advection_stalls.add(1.0);
        }
        if self.cfg.advection && !goal.direct {
            let aim = goal.path[(progress + 5).min(goal.path.len() - 1)];
            let heading = if (aim - robot).norm() > 1e-6 {
                (aim.y - robot.y).atan2(aim.x - robot.x)
            } else {
                ctx.pose.yaw
            };
            let traced = self.key_frames.field.as_mut().map(|field| {
                field.pathline_computing(robot, heading, self.cfg.advect_length_m, false)
            });
            if let Some((line, reason)) = traced {
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
                    goal.final_segment = reaches_end;
                    let exact_arrival = reaches_end && goal.visit.near_view;
                    let mut path = segment;
                    if exact_arrival {
                        // The pathline ends within the goal tolerance of the viewpoint; an exact
                        // arrival is at the viewpoint itself (0.2 m off it the aimed voxel was out
                        // of view, and the frontier was given up unseen).
                        path.push(*goal.path.last().expect("path has points"));
                    }
                    return Action::Follow {
                        path,
                        look_on_arrival: reaches_end && goal.look_on_arrival,
                        exact_arrival,
                    };
                }
                self.stats.advection_fallbacks.add(1.0);
            }
        }
        goal.final_segment = true;
        Action::Follow {
            path: goal.path[progress..].to_vec(),
            look_on_arrival: goal.look_on_arrival,
            exact_arrival: goal.visit.near_view,
        }
    }

    /// Whether the goal's A* path must be re-run: blocked, or the robot strayed from it.
    pub(super) fn path_invalid(&self, ctx: &PlanContext, goal: &Goal) -> bool {
        if goal.stale || goal.path.is_empty() {
            return true;
        }
        let robot = ctx.pose.position();
        let (k, d) = nearest_on_path(&goal.path, robot, 0);
        let blocked = goal.path_cells.iter().skip(k).any(|&i| !ctx.passable(i));
        blocked || d > self.cfg.drift_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::grid::Cell;
    use crate::map::testing::{furnished_room_setup, seen_from};
    use crate::plan::search::Search;

    /// An advected segment that comes within the goal tolerance of a viewpoint chosen for a look
    /// (`near_view`, arrived at exactly) ends at the viewpoint itself; any other goal's segment
    /// ends where the pathline does, within the tolerance.
    #[test]
    fn a_look_from_a_viewpoint_ends_at_the_viewpoint_not_within_its_tolerance() {
        let cfg = Config::default();
        let (grid, bvh) = furnished_room_setup(&cfg);
        let around = (0..16).map(|i| Pose2::new(4.0, 4.0, i as f64 * std::f64::consts::TAU / 16.0));
        let map = seen_from(grid, &cfg, &bvh, around.chain([Pose2::new(1.0, 1.0, 0.8)]));
        let params = PlanParams::from(&cfg);
        let mut search = Search::new(&grid);
        // A straight run of 16 cells the robot may enter (1.5 m, inside one advected segment).
        let ctx_probe = PlanContext {
            map: &map,
            pose: Pose2::new(4.0, 4.0, 0.0),
            time_s: 0.0,
            cfg: &params,
            search: &mut search,
        };
        let cells: Vec<Cell> = (0..grid.ny as i32)
            .flat_map(|y| (0..grid.nx as i32 - 16).map(move |x| (x, y)))
            .map(|(x, y)| (x..x + 16).map(|x| Cell::new(x, y)).collect::<Vec<_>>())
            .find(|run| run.iter().all(|c| ctx_probe.passable(grid.index(*c))))
            .expect("a clear run of floor");
        let (start, end) = (grid.center(cells[0]), grid.center(cells[15]));
        let ctx = PlanContext {
            pose: Pose2::new(start.x, start.y, 0.0),
            ..ctx_probe
        };
        for near_view in [true, false] {
            let mut thp = Thp::new(&super::super::ThpParams::from(&cfg));
            thp.key_frames.field = Some(TensorField::new(grid, &cfg.field));
            let visit = Visit {
                target: vec![cells[15]],
                aim: grid.index(cells[15]),
                near_view,
            };
            thp.set_goal(&ctx, visit, None, &cells);
            let Action::Follow {
                path,
                exact_arrival,
                ..
            } = thp.next_segment(&ctx)
            else {
                panic!("a segment to follow");
            };
            assert_eq!(thp.stats.advected_segments.get(), Some(1.0), "advected");
            let last = *path.last().unwrap();
            assert_eq!(exact_arrival, near_view);
            if near_view {
                assert_eq!(last, end);
            } else {
                assert!(
                    (last - end).norm() <= thp.goal_tolerance_m,
                    "{last} far from {end}"
                );
            }
        }
    }

    /// A goal outside the tour (a step back to look at a blind-zone frontier) is kept at a segment
    /// end and through new anchors until it is reached or seen; re-chosen there, two such goals
    /// with viewpoints beside each other sent the robot back and forth without a look until the
    /// run was stuck. A tour goal is re-chosen when new anchors arrive (Alg. 1).
    #[test]
    fn a_step_back_for_the_blind_zone_is_kept_until_it_is_done() {
        let cfg = Config::default();
        let (grid, bvh) = furnished_room_setup(&cfg);
        // One look to the east leaves most of the room unknown, so frontiers are left.
        let map = seen_from(grid, &cfg, &bvh, [Pose2::new(4.0, 4.0, 0.0)]);
        let params = PlanParams::from(&cfg);
        let mut search = Search::new(&grid);
        let ctx = PlanContext {
            map: &map,
            pose: Pose2::new(4.0, 4.0, 0.0),
            time_s: 0.0,
            cfg: &params,
            search: &mut search,
        };
        let robot = grid.cell_of(ctx.pose.position()).unwrap();
        // A short run of cells the robot may enter, from where it stands.
        let cells: Vec<Cell> = (0..6).map(|k| Cell::new(robot.x + k, robot.y)).collect();
        assert!(
            cells.iter().all(|c| ctx.passable(grid.index(*c))),
            "clear run"
        );
        // The frontier cell farthest from the robot: never the next goal chosen afresh.
        let far = map
            .frontiers()
            .iter()
            .flat_map(|s| s.cells.clone())
            .max_by(|a, b| {
                let d = |c: &Cell| (grid.center(*c) - ctx.pose.position()).norm();
                d(a).total_cmp(&d(b)).then(a.cmp(b))
            })
            .expect("frontiers are left");
        let mut ctx = ctx;
        for tour_node in [None, Some(0)] {
            let mut thp = Thp::new(&super::super::ThpParams::from(&cfg));
            let visit = Visit {
                target: vec![far],
                aim: grid.index(far),
                near_view: true,
            };
            thp.set_goal(&ctx, visit, tour_node, &cells);
            // A new degenerate point: `P*` is not empty.
            (thp.anchors).take_points(&[(1, ctx.pose.position())], |_| true, true);
            assert!(thp.anchors.has_new());
            let _ = thp.next_action(&mut ctx).unwrap();
            let kept = thp
                .mode
                .goal()
                .is_some_and(|g| g.visit.aim == grid.index(far));
            assert_eq!(kept, tour_node.is_none(), "tour node {tour_node:?}");
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
