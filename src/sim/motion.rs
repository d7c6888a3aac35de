//! The motion executor shared by every planner: pure-pursuit path following with turning in place,
//! full-turn look-arounds, and a guard that never drives the disc toward a known obstacle.

use super::robot::Command;
use crate::config::Config;
use crate::grid::Cell;
use crate::map::Map;
use crate::plan::Action;
use crate::util::wrap_angle;
use crate::Pose2;
use nalgebra::Point2;
use std::f64::consts::TAU;

/// How the current action is going.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionStatus {
    /// Still executing.
    Busy,
    /// Finished: the path's end was reached (and the look-around done, if asked).
    Done,
    /// A known obstacle blocks the way; the planner must re-plan.
    Blocked,
}

enum Phase {
    Idle,
    Following {
        path: Vec<Point2<f64>>,
        /// Index of the path point the robot has progressed to.
        progress: usize,
        look_on_arrival: bool,
    },
    Looking {
        turned_rad: f64,
    },
    /// Backing off from a known obstacle the robot got too close to: turn away from the nearest
    /// obstacle cell and creep forward until the clearance is back, then report `Blocked`.
    Escaping {
        steps_left: u32,
    },
}

/// Turns an [`Action`] into velocity commands, step by step.
pub struct MotionExecutor {
    phase: Phase,
    dt: f64,
    radius: f64,
    max_speed: f64,
    max_turn: f64,
    turn_in_place: f64,
    lookahead: f64,
    goal_tolerance: f64,
    slow_clearance: f64,
    /// Clearance (to obstacle surfaces) at which the robot's own spot is out of every obstacle's
    /// inflation again: the inflation radius.
    free_clearance: f64,
    /// Clearance under which the guard refuses to move closer to an obstacle.
    guard_clearance: f64,
}

/// Gain of the proportional heading controller, 1/s.
const HEADING_GAIN: f64 = 2.0;
/// Heading error under which the robot counts as facing its look-ahead point, radians.
const ALIGNED_RAD: f64 = 0.1;
/// Most steps spent backing off from an obstacle before giving the planner the problem.
const ESCAPE_STEPS: u32 = 40;
/// Speed while backing off, as a fraction of the maximum.
const ESCAPE_SPEED_FRACTION: f64 = 0.2;
/// The guard stops the robot from driving closer to a known obstacle surface than the robot radius
/// plus this, metres. Clearances are measured to the obstacle boxes (the hits, give or take 1 cm,
/// never farther than a seen surface), so this only covers surface between hits and path following
/// between cell centres, which comes a little closer to obstacles than the centres themselves (the
/// inflation radius); capped at `map.inflation_margin_m`, or paths through doors would get refused.
const GUARD_MARGIN_M: f64 = 0.02;
/// Speed never drops below this fraction near obstacles, so narrow doors are still passed.
const MIN_SPEED_FRACTION: f64 = 0.3;

impl MotionExecutor {
    pub fn new(cfg: &Config) -> Self {
        MotionExecutor {
            phase: Phase::Idle,
            dt: cfg.sim.dt_s,
            radius: cfg.robot.radius_m,
            max_speed: cfg.robot.max_speed_mps,
            max_turn: cfg.robot.max_turn_rate_rps,
            turn_in_place: cfg.motion.turn_in_place_rad,
            lookahead: cfg.motion.lookahead_m,
            goal_tolerance: cfg.motion.goal_tolerance_m,
            slow_clearance: cfg.motion.slow_clearance_m,
            free_clearance: cfg.robot.radius_m + cfg.map.inflation_margin_m,
            guard_clearance: cfg.robot.radius_m + GUARD_MARGIN_M.min(cfg.map.inflation_margin_m),
        }
    }

    /// Starts executing `action` (replacing any action in progress).
    pub fn start(&mut self, action: &Action) {
        self.phase = match action {
            Action::Follow {
                path,
                look_on_arrival,
            } if !path.is_empty() => Phase::Following {
                path: path.clone(),
                progress: 0,
                look_on_arrival: *look_on_arrival,
            },
            Action::Follow { .. } | Action::Complete => Phase::Idle,
            Action::LookAround => Phase::Looking { turned_rad: 0.0 },
        };
    }

    /// Whether an action is in progress.
    pub fn is_busy(&self) -> bool {
        !matches!(self.phase, Phase::Idle)
    }

    /// The command for this step and the status of the action.
    pub fn step(&mut self, pose: Pose2, map: &Map) -> (Command, MotionStatus) {
        match &mut self.phase {
            Phase::Idle => (Command::default(), MotionStatus::Done),
            Phase::Looking { turned_rad } => {
                let w = self.max_turn.min((TAU - *turned_rad) / self.dt);
                *turned_rad += w * self.dt;
                if *turned_rad >= TAU - 1e-9 {
                    self.phase = Phase::Idle;
                    (Command { v: 0.0, w }, MotionStatus::Done)
                } else {
                    (Command { v: 0.0, w }, MotionStatus::Busy)
                }
            }
            Phase::Following {
                path,
                progress,
                look_on_arrival,
            } => {
                let here = pose.position();
                let goal = *path.last().expect("non-empty path");
                if (goal - here).norm() <= self.goal_tolerance {
                    self.phase = if *look_on_arrival {
                        Phase::Looking { turned_rad: 0.0 }
                    } else {
                        Phase::Idle
                    };
                    let status = if self.is_busy() {
                        MotionStatus::Busy
                    } else {
                        MotionStatus::Done
                    };
                    return (Command::default(), status);
                }
                // Advance progress to the nearest point within a short window ahead.
                let window = (*progress + 20).min(path.len());
                let nearest = (*progress..window)
                    .min_by(|&a, &b| {
                        (path[a] - here)
                            .norm_squared()
                            .total_cmp(&(path[b] - here).norm_squared())
                    })
                    .unwrap_or(*progress);
                *progress = nearest;
                let target = path[*progress..]
                    .iter()
                    .find(|p| (*p - here).norm() >= self.lookahead)
                    .copied()
                    .unwrap_or(goal);
                let d = target - here;
                let err = wrap_angle(d.y.atan2(d.x) - pose.yaw);
                let w = (HEADING_GAIN * err).clamp(-self.max_turn, self.max_turn);
                if err.abs() > self.turn_in_place {
                    return (Command { v: 0.0, w }, MotionStatus::Busy);
                }
                let clearance = obstacle_clearance(map, here, self.slow_clearance);
                let slow = if self.slow_clearance > self.radius {
                    ((clearance - self.radius) / (self.slow_clearance - self.radius))
                        .clamp(MIN_SPEED_FRACTION, 1.0)
                } else {
                    1.0
                };
                let to_goal = (goal - here).norm();
                let v = self.max_speed * err.cos().max(0.0) * slow * (to_goal / 0.5).min(1.0);
                let next = super::robot::integrate(pose, v, w, self.dt);
                let next_clearance = obstacle_clearance(map, next.position(), self.slow_clearance);
                if next_clearance < self.guard_clearance && next_clearance < clearance {
                    // Moving on would bring the disc closer to a known obstacle than is safe. Turn in
                    // place toward the path first; if already aligned, back off and re-plan.
                    if err.abs() > ALIGNED_RAD {
                        return (Command { v: 0.0, w }, MotionStatus::Busy);
                    }
                    self.phase = Phase::Escaping {
                        steps_left: ESCAPE_STEPS,
                    };
                    return self.step(pose, map);
                }
                (Command { v, w }, MotionStatus::Busy)
            }
            Phase::Escaping { steps_left } => {
                let here = pose.position();
                let clearance = obstacle_clearance(map, here, self.slow_clearance);
                let away = nearest_obstacle(map, here, self.slow_clearance).map(|o| here - o);
                *steps_left = steps_left.saturating_sub(1);
                let done = clearance >= self.free_clearance || *steps_left == 0;
                let Some(away) = away.filter(|_| !done) else {
                    self.phase = Phase::Idle;
                    return (Command::default(), MotionStatus::Blocked);
                };
                let err = wrap_angle(away.y.atan2(away.x) - pose.yaw);
                let w = (HEADING_GAIN * err).clamp(-self.max_turn, self.max_turn);
                if err.abs() > self.turn_in_place {
                    return (Command { v: 0.0, w }, MotionStatus::Busy);
                }
                let v = ESCAPE_SPEED_FRACTION * self.max_speed;
                let next = super::robot::integrate(pose, v, w, self.dt);
                if obstacle_clearance(map, next.position(), self.slow_clearance) < clearance {
                    return (Command { v: 0.0, w }, MotionStatus::Busy);
                }
                (Command { v, w }, MotionStatus::Busy)
            }
        }
    }
}

/// Distance from `p` to the nearest hazard, searched within `max_m` (returns `max_m` when none is
/// nearer).
pub fn obstacle_clearance(map: &Map, p: Point2<f64>, max_m: f64) -> f64 {
    nearest_obstacle(map, p, max_m).map_or(max_m, |o| (o - p).norm())
}

/// The hazard point nearest to `p` within `max_m`: a known obstacle surface point (see
/// [`Map::nearest_obstacle_point`]: measured to the obstacle boxes, which hold the ray hits), or the
/// nearest point of a never-seen cell grown by half a cell. The camera faces forward and sees nothing
/// nearer than its minimum range, so a wall beside the robot may be unknown, and the cell holding
/// its face may count as seen through the free part of its voxels; the guard keeps the disc that far
/// from cells the robot has no evidence about, as it keeps it off known obstacles.
pub fn nearest_obstacle(map: &Map, p: Point2<f64>, max_m: f64) -> Option<Point2<f64>> {
    let mut best = map.nearest_obstacle_point(p, max_m);
    let mut best_d2 = best.map_or(max_m * max_m, |o| (o - p).norm_squared());
    let grid = map.grid();
    let half = 1.0 * grid.res;
    let c = grid.cell_at(p.x, p.y);
    let r = (max_m / grid.res).ceil() as i32 + 1;
    for dy in -r..=r {
        for dx in -r..=r {
            let n = Cell::new(c.x + dx, c.y + dy);
            let Some(i) = grid.checked_index(n) else {
                continue;
            };
            if map.is_seen(i) {
                continue;
            }
            let centre = grid.center(n);
            let q = Point2::new(
                p.x.clamp(centre.x - half, centre.x + half),
                p.y.clamp(centre.y - half, centre.y + half),
            );
            let d2 = (q - p).norm_squared();
            if d2 < best_d2 {
                best_d2 = d2;
                best = Some(q);
            }
        }
    }
    best
}
