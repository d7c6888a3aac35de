//! The motion executor shared by every planner: pure-pursuit path following with turning in place,
//! full-turn look-arounds, and a guard that never drives the disc toward a known obstacle.

use super::robot::Command;
use crate::config::{Config, MotionConfig, RobotConfig};
use crate::map::Map;
use crate::plan::{Action, EXACT_ARRIVAL_M};
use crate::util::wrap_angle;
use crate::Pose2;
use nalgebra::{Point2, Vector2};
use std::f64::consts::{PI, TAU};

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
        /// Drive on past the goal tolerance where it is safe (see [`Action::Follow`]); the steps
        /// spent within the goal tolerance so far.
        exact_arrival: bool,
        steps_near_goal: u32,
        /// Tracking the path itself rather than pure pursuit, after the guard tripped near a corner;
        /// until the clearance is back.
        tight: bool,
    },
    Looking {
        turned_rad: f64,
    },
    /// Backing off from a hazard the robot got too close to: turn to the heading in which the
    /// clearance grows most ([`escape_heading`]) and creep forward until the clearance is back,
    /// then report `Blocked`.
    Escaping {
        steps_left: u32,
        /// The way the robot came (its heading when the back-off began, reversed): of equally good
        /// headings the nearest to it. Fixed for the back-off, or a robot that turned to go one
        /// way along a gap would find the other way "back" and turn again.
        back: f64,
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
    /// `additions.exact_arrival`: whether an action's `exact_arrival` is honoured (not in any
    /// paper); off, every path ends within the goal tolerance.
    exact_arrival: bool,
}

/// Most steps spent driving from the goal tolerance to the exact end of an `exact_arrival` path
/// (3 s at the default step): pure pursuit can circle a point it reaches at an angle.
const EXACT_APPROACH_STEPS: u32 = 30;
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
/// Look-ahead when tracking the path tightly past a corner: just over one diagonal cell step, metres.
const TIGHT_LOOKAHEAD_M: f64 = 0.15;
/// Tight tracking ends once the clearance exceeds the inflation radius by this, metres (hysteresis,
/// so that pure pursuit does not cut the same corner again at once).
const TIGHT_EXIT_MARGIN_M: f64 = 0.05;

/// What the motion executor reads of the config: its own section, the robot's body and speeds, the
/// step, and the map's inflation margin (the clearance paths keep, which the guard must allow).
#[derive(Clone, Debug, PartialEq)]
pub struct MotionParams {
    pub motion: MotionConfig,
    pub robot: RobotConfig,
    /// `sim.dt_s`.
    pub dt_s: f64,
    /// `map.inflation_margin_m`.
    pub inflation_margin_m: f64,
    /// `additions.exact_arrival`.
    pub exact_arrival: bool,
}

impl From<&Config> for MotionParams {
    fn from(cfg: &Config) -> MotionParams {
        MotionParams {
            motion: cfg.motion.clone(),
            robot: cfg.robot.clone(),
            dt_s: cfg.sim.dt_s,
            inflation_margin_m: cfg.map.inflation_margin_m,
            exact_arrival: cfg.additions.exact_arrival,
        }
    }
}

impl MotionExecutor {
    pub fn new(p: &MotionParams) -> Self {
        let (robot, motion) = (&p.robot, &p.motion);
        MotionExecutor {
            phase: Phase::Idle,
            dt: p.dt_s,
            radius: robot.radius_m,
            max_speed: robot.max_speed_mps,
            max_turn: robot.max_turn_rate_rps,
            turn_in_place: motion.turn_in_place_rad.get(),
            lookahead: motion.lookahead_m.get(),
            goal_tolerance: motion.goal_tolerance_m,
            slow_clearance: motion.slow_clearance_m.get(),
            free_clearance: robot.radius_m + p.inflation_margin_m,
            guard_clearance: robot.radius_m + GUARD_MARGIN_M.min(p.inflation_margin_m),
            exact_arrival: p.exact_arrival,
        }
    }

    /// Starts executing `action` (replacing any action in progress).
    pub fn start(&mut self, action: &Action) {
        self.phase = match action {
            Action::Follow {
                path,
                look_on_arrival,
                exact_arrival,
            } if !path.is_empty() => Phase::Following {
                path: path.clone(),
                progress: 0,
                look_on_arrival: *look_on_arrival,
                exact_arrival: *exact_arrival && self.exact_arrival,
                steps_near_goal: 0,
                tight: false,
            },
            Action::Follow { .. } | Action::Complete | Action::Stuck => Phase::Idle,
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
            Phase::Following { .. } => self.follow(pose, map),
            Phase::Escaping { steps_left, back } => {
                let here = pose.position();
                let clearance = obstacle_clearance(map, here, self.slow_clearance);
                *steps_left = steps_left.saturating_sub(1);
                let done = clearance >= self.free_clearance || *steps_left == 0;
                // With the guard's clearance to spare, a heading that keeps it will do: along a gap
                // the clearance stays the same but for the sub-millimetre steps between the
                // obstacle boxes of neighbouring cells, and requiring it never to shrink left no
                // heading at all.
                let least = clearance.min(self.guard_clearance);
                let away = (!done)
                    .then(|| escape_heading(map, here, least, self.slow_clearance, *back))
                    .flatten();
                let Some(heading) = away else {
                    self.phase = Phase::Idle;
                    return (Command::default(), MotionStatus::Blocked);
                };
                let err = wrap_angle(heading - pose.yaw);
                let w = (HEADING_GAIN * err).clamp(-self.max_turn, self.max_turn);
                if err.abs() > self.turn_in_place {
                    return (Command { v: 0.0, w }, MotionStatus::Busy);
                }
                let v = ESCAPE_SPEED_FRACTION * self.max_speed;
                let next = super::robot::integrate(pose, v, w, self.dt);
                // The same rule as tight tracking: a move that keeps the guard clearance is safe.
                // Requiring the clearance never to shrink at all froze a robot standing between
                // two hazards with clearance to spare: along the gap it stays equal, and each step
                // of the turn's arc lost a fraction of a millimetre.
                let next_clearance = obstacle_clearance(map, next.position(), self.slow_clearance);
                if next_clearance < clearance - CLEARANCE_TOLERANCE_M
                    && next_clearance < self.guard_clearance - CLEARANCE_TOLERANCE_M
                {
                    // The arc of turning while moving loses clearance: finish the turn in place,
                    // onto the heading itself, so that the next step goes straight along it. A
                    // proportional turn only approaches the heading, and a robot standing at the
                    // guard's clearance in a gap lost a fraction
                    // of a millimetre on every step, was refused every step, and never moved again.
                    let w = (err / self.dt).clamp(-self.max_turn, self.max_turn);
                    return (Command { v: 0.0, w }, MotionStatus::Busy);
                }
                (Command { v, w }, MotionStatus::Busy)
            }
        }
    }
}

/// Headings tried when backing off.
const ESCAPE_HEADINGS: usize = 16;
/// How far ahead a heading is probed when backing off, metres.
const ESCAPE_PROBE_M: f64 = 0.05;

/// Clearances within this of the best count as equally good when backing off, metres.
const ESCAPE_TIE_M: f64 = 1e-3;
/// Clearances that differ by less than this count as equal when backing off, metres (a micrometre):
/// the rounding of the obstacle boxes' f32 corners and of a move along a gap's edge, which would
/// otherwise read as a step closer to the hazard.
const CLEARANCE_TOLERANCE_M: f64 = 1e-6;

/// The heading in which the clearance grows most over a short step from `here`, among those in
/// which it stays at least `least`; of equally good ones, the nearest to `back` (the way the robot
/// came). `None` if every heading brings the disc closer to a hazard than that.
///
/// Straight away from the nearest hazard is not enough: between two hazards (a gap the guard finds a
/// little too narrow) it leads toward the other one, and the robot stayed wedged there until the
/// run ended `stuck`.
fn escape_heading(map: &Map, here: Point2<f64>, least: f64, max_m: f64, back: f64) -> Option<f64> {
    let probes: Vec<(f64, f64)> = (0..ESCAPE_HEADINGS)
        .map(|k| {
            let heading = wrap_angle(k as f64 * TAU / ESCAPE_HEADINGS as f64);
            let probe = here + ESCAPE_PROBE_M * Vector2::new(heading.cos(), heading.sin());
            (obstacle_clearance(map, probe, max_m), heading)
        })
        .filter(|&(c, _)| c >= least - CLEARANCE_TOLERANCE_M)
        .collect();
    let best = probes.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    probes
        .into_iter()
        .filter(|&(c, _)| c >= best - ESCAPE_TIE_M)
        .min_by(|a, b| {
            let off = |h: f64| wrap_angle(h - back).abs();
            off(a.1).total_cmp(&off(b.1)).then(a.1.total_cmp(&b.1))
        })
        .map(|(_, heading)| heading)
}

impl MotionExecutor {
    /// One step of path following: pure pursuit with speed reduced near obstacles, and a guard that
    /// refuses to bring the disc closer to a hazard than `guard_clearance`. When the guard trips
    /// (pure pursuit cuts the corner at a door jamb), the robot tracks the path itself until its
    /// clearance is back; if even that is unsafe, it backs off and reports `Blocked`.
    fn follow(&mut self, pose: Pose2, map: &Map) -> (Command, MotionStatus) {
        let limits = self.limits();
        let Phase::Following {
            path,
            progress,
            look_on_arrival,
            exact_arrival,
            steps_near_goal,
            tight,
        } = &mut self.phase
        else {
            unreachable!("follow is called in the following phase");
        };
        let here = pose.position();
        let goal = *path.last().expect("non-empty path");
        let to_goal = (goal - here).norm();
        let arrived = to_goal <= self.goal_tolerance && {
            *steps_near_goal += 1;
            // Driving on to the exact end: only while the disc stays over seen floor, both where it
            // stands and at the end (a low object in an Unknown cell is invisible to the guard),
            // and for a few seconds at most.
            !*exact_arrival
                || to_goal <= EXACT_ARRIVAL_M
                || *steps_near_goal > EXACT_APPROACH_STEPS
                || !map.disc_over_seen_floor(here, self.radius)
                || !map.disc_over_seen_floor(goal, self.radius)
        };
        if arrived {
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
        let clearance = obstacle_clearance(map, here, self.slow_clearance);
        if *tight && clearance >= self.free_clearance + TIGHT_EXIT_MARGIN_M {
            *tight = false;
        }
        if *tight {
            return match track_tightly(&limits, pose, map, &path[*progress..], clearance) {
                Some(cmd) => (cmd, MotionStatus::Busy),
                None => self.back_off(pose, map),
            };
        }
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
        let slow = if self.slow_clearance > self.radius {
            ((clearance - self.radius) / (self.slow_clearance - self.radius))
                .clamp(MIN_SPEED_FRACTION, 1.0)
        } else {
            1.0
        };
        let v = self.max_speed * err.cos().max(0.0) * slow * (to_goal / 0.5).min(1.0);
        let next = super::robot::integrate(pose, v, w, self.dt);
        let next_clearance = obstacle_clearance(map, next.position(), self.slow_clearance);
        if next_clearance < self.guard_clearance && next_clearance < clearance {
            if to_goal <= self.goal_tolerance {
                // Already arrived by the goal tolerance: the exact end is not worth a detour.
                *exact_arrival = false;
                return self.follow(pose, map);
            }
            // Moving on would bring the disc closer to a hazard than is safe: track tightly.
            *tight = true;
            return self.follow(pose, map);
        }
        (Command { v, w }, MotionStatus::Busy)
    }

    /// Starts backing off from the nearest hazard (see [`Phase::Escaping`]).
    fn back_off(&mut self, pose: Pose2, map: &Map) -> (Command, MotionStatus) {
        self.phase = Phase::Escaping {
            steps_left: ESCAPE_STEPS,
            back: pose.yaw + PI,
        };
        self.step(pose, map)
    }

    fn limits(&self) -> Limits {
        Limits {
            dt: self.dt,
            max_speed: self.max_speed,
            max_turn: self.max_turn,
            slow_clearance: self.slow_clearance,
            guard_clearance: self.guard_clearance,
        }
    }
}

/// The executor's limits that tight tracking needs.
struct Limits {
    dt: f64,
    max_speed: f64,
    max_turn: f64,
    slow_clearance: f64,
    guard_clearance: f64,
}

/// A slow command along `path` (from the robot's progress on) itself, aimed at the point
/// `TIGHT_LOOKAHEAD_M` ahead: turn in place toward it, then creep. A move is accepted if it keeps the
/// guard clearance or does not come closer to the nearest hazard. `None` when no move is safe.
fn track_tightly(
    limits: &Limits,
    pose: Pose2,
    map: &Map,
    path: &[Point2<f64>],
    clearance: f64,
) -> Option<Command> {
    let here = pose.position();
    let goal = *path.last()?;
    let target = path
        .iter()
        .find(|p| (*p - here).norm() >= TIGHT_LOOKAHEAD_M)
        .copied()
        .unwrap_or(goal);
    let d = target - here;
    let err = wrap_angle(d.y.atan2(d.x) - pose.yaw);
    let w = (HEADING_GAIN * err).clamp(-limits.max_turn, limits.max_turn);
    if err.abs() > ALIGNED_RAD {
        return Some(Command { v: 0.0, w });
    }
    let v = (MIN_SPEED_FRACTION * limits.max_speed).min(d.norm() / limits.dt);
    let next = super::robot::integrate(pose, v, w, limits.dt);
    let next_clearance = obstacle_clearance(map, next.position(), limits.slow_clearance);
    let safe = next_clearance >= limits.guard_clearance || next_clearance >= clearance;
    safe.then_some(Command { v, w })
}

/// Distance from `p` to the nearest hazard, searched within `max_m` (returns `max_m` when none is
/// nearer).
pub fn obstacle_clearance(map: &Map, p: Point2<f64>, max_m: f64) -> f64 {
    map.nearest_hazard(p, max_m)
        .map_or(max_m, |o| (o - p).norm())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridSpec;
    use crate::map::testing::seen_from;
    use crate::plan::search::Search;
    use crate::scene::TriMesh;
    use crate::sensor::raycast::testing::push_box;
    use crate::sensor::MeshBvh;
    use std::f64::consts::PI;

    /// Places the robot looked around from in [`room_and_corridor`]: two in the room, four along
    /// the corridor.
    const ROOM_AND_CORRIDOR_SPOTS: [(f64, f64); 6] = [
        (1.1, 1.0),
        (3.0, 1.0),
        (1.1, 2.4),
        (2.5, 2.4),
        (4.0, 2.4),
        (5.5, 2.4),
    ];

    /// A room (y < 1.9) and a 0.8 m corridor along its top (y 2.0–2.8), joined by a 0.8 m door
    /// (x 0.7–1.5) in the wall between them; the map is built from looks around in both.
    fn room_and_corridor(cfg: &Config) -> (Map, MeshBvh) {
        room_and_corridor_seen_from(cfg, &ROOM_AND_CORRIDOR_SPOTS)
    }

    /// [`room_and_corridor`] with the map built from looks around at `spots` only.
    fn room_and_corridor_seen_from(cfg: &Config, spots: &[(f64, f64)]) -> (Map, MeshBvh) {
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [0.0, 0.0, 0.0], [6.0, 2.9, 2.5]);
        push_box(&mut mesh, [0.0, 1.9, 0.0], [0.7, 2.0, 2.5]);
        push_box(&mut mesh, [1.5, 1.9, 0.0], [6.0, 2.0, 2.5]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let grid = GridSpec::covering(
            Point2::new(-0.5, -0.5),
            Point2::new(6.5, 3.5),
            cfg.map.band_max_m,
            cfg.map.voxel_m,
        );
        let looks = spots
            .iter()
            .flat_map(|&(x, y)| (0..16).map(move |k| Pose2::new(x, y, k as f64 * PI / 8.0)));
        let mut map = seen_from(grid, cfg, &bvh, looks);
        for &(x, y) in spots {
            map.clear_footprint(x, y, cfg.robot.radius_m);
        }
        (map, bvh)
    }

    /// Steps `exec` from `pose` until its action ends or `max_steps` pass, asserting at every step
    /// that the robot's cylinder does not touch the mesh; the last pose and status.
    fn drive(
        cfg: &Config,
        exec: &mut MotionExecutor,
        map: &Map,
        bvh: &MeshBvh,
        mut pose: Pose2,
        max_steps: usize,
    ) -> (Pose2, MotionStatus) {
        let top = cfg.robot.height_m.min(cfg.map.band_max_m);
        let mut status = MotionStatus::Busy;
        for _ in 0..max_steps {
            let (cmd, s) = exec.step(pose, map);
            pose = super::super::robot::integrate(pose, cmd.v, cmd.w, cfg.sim.dt_s);
            let (x, y, r) = (pose.x, pose.y, cfg.robot.radius_m);
            let hit = bvh.cylinder_intersects(x, y, r, cfg.map.band_min_m, top);
            assert!(!hit, "collision at {pose:?}");
            status = s;
            if s != MotionStatus::Busy {
                break;
            }
        }
        (pose, status)
    }

    #[test]
    fn a_path_around_a_door_jamb_is_followed_without_touching_it() {
        let cfg = Config::default();
        let (map, bvh) = room_and_corridor(&cfg);
        let grid = *map.grid();
        // Up through the door and right along the corridor: the path turns sharply around the
        // door's right jamb, where pure pursuit cuts the corner.
        let (start, goal) = (Point2::new(1.1, 1.0), Point2::new(4.0, 2.4));
        let cell = |p: Point2<f64>| grid.index(grid.cell_of(p).unwrap());
        let mut search = Search::new(&grid);
        let path = search
            .astar(
                &grid,
                |i| crate::plan::step_cost(&map, &cfg.search, start, i),
                cell(start),
                cell(goal),
            )
            .expect("the door is wide enough to plan through");
        let path: Vec<Point2<f64>> = path.cells.iter().map(|c| grid.center(*c)).collect();
        let mut exec = MotionExecutor::new(&MotionParams::from(&cfg));
        exec.start(&Action::Follow {
            path,
            look_on_arrival: false,
            exact_arrival: false,
        });
        let pose = Pose2::new(start.x, start.y, PI / 2.0);
        let (pose, status) = drive(&cfg, &mut exec, &map, &bvh, pose, 2000);
        assert_eq!(status, MotionStatus::Done, "stopped at {pose:?}");
        assert!((pose.position() - goal).norm() <= cfg.motion.goal_tolerance_m + 1e-9);
    }

    /// Two 0.4 m wide boxes, one from y = 0 to `lower_top`, one from `upper_bottom` to y = 1 (x 0.8–1.2,
    /// 1 m tall), mapped from looks around on all four sides.
    /// Follows the A* path from `start` to `goal` in `map` with or without `exact_arrival`; the
    /// robot's distance from `goal` when the action ends `Done`.
    fn arrival_distance(
        cfg: &Config,
        map: &Map,
        bvh: &MeshBvh,
        start: Point2<f64>,
        goal: Point2<f64>,
        exact_arrival: bool,
    ) -> f64 {
        let grid = *map.grid();
        let cell = |p: Point2<f64>| grid.index(grid.cell_of(p).unwrap());
        let path = Search::new(&grid)
            .astar(
                &grid,
                |i| crate::plan::step_cost(map, &cfg.search, start, i),
                cell(start),
                cell(goal),
            )
            .expect("reachable");
        let path: Vec<Point2<f64>> = path.cells.iter().map(|c| grid.center(*c)).collect();
        let goal = *path.last().unwrap();
        let mut exec = MotionExecutor::new(&MotionParams::from(cfg));
        exec.start(&Action::Follow {
            path,
            look_on_arrival: false,
            exact_arrival,
        });
        let d = goal - start;
        let pose = Pose2::new(start.x, start.y, d.y.atan2(d.x));
        let (pose, status) = drive(cfg, &mut exec, map, bvh, pose, 2000);
        assert_eq!(status, MotionStatus::Done, "stopped at {pose:?}");
        (pose.position() - goal).norm()
    }

    #[test]
    fn an_exact_arrival_drives_on_to_the_end_only_over_seen_floor() {
        let cfg = Config::default();
        let (map, bvh) = room_and_corridor(&cfg);
        let (tolerance, r) = (cfg.motion.goal_tolerance_m, cfg.robot.radius_m);
        let start = Point2::new(3.0, 1.0);
        // Between two spots the robot looked around from: seen floor all the way.
        let seen_goal = Point2::new(1.1, 1.0);
        assert!(map.disc_over_seen_floor(seen_goal, r));
        let plain = arrival_distance(&cfg, &map, &bvh, start, seen_goal, false);
        assert!(plain > EXACT_ARRIVAL_M && plain <= tolerance, "{plain}");
        let exact = arrival_distance(&cfg, &map, &bvh, start, seen_goal, true);
        assert!(exact <= EXACT_ARRIVAL_M, "{exact}");
        // Looks from the start only leave its blind zone unseen: at a traversable cell with an Unknown cell
        // under the disc, the goal tolerance stands.
        let (map, bvh) = room_and_corridor_seen_from(&cfg, &ROOM_AND_CORRIDOR_SPOTS[1..2]);
        let grid = *map.grid();
        let beside_unknown = (0..grid.cells())
            .filter(|&i| map.is_traversable(i))
            .map(|i| grid.center(grid.cell(i)))
            .filter(|&p| p.y < 1.9 && !map.disc_over_seen_floor(p, r))
            .min_by(|a, b| (a - start).norm().total_cmp(&(b - start).norm()))
            .expect("looks from the start leave unseen floor beside traversable cells");
        let stopped = arrival_distance(&cfg, &map, &bvh, start, beside_unknown, true);
        assert!(
            stopped > EXACT_ARRIVAL_M && stopped <= tolerance,
            "{stopped}"
        );
    }

    fn gap_between_boxes(cfg: &Config, lower_top: f32, upper_bottom: f32) -> (Map, MeshBvh) {
        let mut mesh = TriMesh::default();
        push_box(&mut mesh, [0.8, 0.0, 0.0], [1.2, lower_top, 1.0]);
        push_box(&mut mesh, [0.8, upper_bottom, 0.0], [1.2, 1.0, 1.0]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let grid = GridSpec::covering(
            Point2::new(-1.0, -1.5),
            Point2::new(3.0, 2.5),
            cfg.map.band_max_m,
            cfg.map.voxel_m,
        );
        let looks = [(-0.5, 0.5), (2.5, 0.5), (1.0, -1.2), (1.0, 2.2)]
            .into_iter()
            .flat_map(|(x, y)| (0..16).map(move |k| Pose2::new(x, y, k as f64 * PI / 8.0)));
        (seen_from(grid, cfg, &bvh, looks), bvh)
    }

    /// Two walls 0.55 m apart, seen from all sides, with the robot between them facing along the gap:
    /// straight away from the nearer wall leads toward the other, so the robot backs off along the
    /// gap, the way it came.
    #[test]
    fn backing_off_between_two_hazards_follows_the_gap() {
        let cfg = Config::default();
        let (map, _) = gap_between_boxes(&cfg, 0.225, 0.775);
        let here = Point2::new(1.0, 0.5);
        let max_m = cfg.motion.slow_clearance_m.get();
        let clearance = obstacle_clearance(&map, here, max_m);
        assert!(clearance < cfg.robot.radius_m + 0.05, "{clearance}");
        let nearest = map
            .nearest_hazard(here, max_m)
            .expect("a wall within reach");
        let away = (here - nearest).normalize();
        assert!(obstacle_clearance(&map, here + ESCAPE_PROBE_M * away, max_m) <= clearance);
        let back = PI;
        let heading =
            escape_heading(&map, here, clearance, max_m, back).expect("the gap leads out");
        assert!(wrap_angle(heading - back).abs() < 1e-9, "heading {heading}");
        // Facing the other way, it backs off the other way.
        let heading = escape_heading(&map, here, clearance, max_m, 0.0).expect("the gap leads out");
        assert!(wrap_angle(heading).abs() < 1e-9, "heading {heading}");
        // Just past the end of the gap, out of it, whichever way the robot faces.
        let near_end = Point2::new(1.25, 0.5);
        let c = obstacle_clearance(&map, near_end, max_m);
        let heading = escape_heading(&map, near_end, c, max_m, back).expect("out of the gap");
        let step = Vector2::new(heading.cos(), heading.sin()) * ESCAPE_PROBE_M;
        assert!(obstacle_clearance(&map, near_end + step, max_m) > c + ESCAPE_TIE_M);
        // Where every heading loses clearance there is none.
        assert_eq!(escape_heading(&map, here, f64::INFINITY, max_m, back), None);
    }

    /// A robot standing across a gap between two boxes 0.58 m apart, with more than the guard's
    /// clearance but less than the inflation radius, and sent toward the nearer box: it backs off
    /// along the gap and out of it rather than freezing where it stands.
    #[test]
    fn backing_off_with_clearance_to_spare_leaves_the_gap() {
        let cfg = Config::default();
        let (map, bvh) = gap_between_boxes(&cfg, 0.21, 0.79);
        let params = MotionParams::from(&cfg);
        let mut exec = MotionExecutor::new(&params);
        let max_m = cfg.motion.slow_clearance_m.get();
        let pose = Pose2::new(1.0, 0.495, -PI / 2.0);
        let start = obstacle_clearance(&map, pose.position(), max_m);
        assert!(
            start > exec.guard_clearance && start < exec.free_clearance,
            "{start}"
        );
        assert_backs_out_of_the_gap(&cfg, &mut exec, &map, &bvh, pose);
    }

    /// Sends the robot at `pose` straight toward the gap's lower box: the guard refuses, and the
    /// back-off must carry it out of the gap (clearance back to the inflation radius) before it
    /// reports `Blocked`.
    fn assert_backs_out_of_the_gap(
        cfg: &Config,
        exec: &mut MotionExecutor,
        map: &Map,
        bvh: &MeshBvh,
        pose: Pose2,
    ) {
        exec.start(&Action::Follow {
            path: vec![pose.position(), Point2::new(pose.x, 0.1)],
            look_on_arrival: false,
            exact_arrival: false,
        });
        let (pose, status) = drive(cfg, exec, map, bvh, pose, 200);
        assert_eq!(status, MotionStatus::Blocked);
        let end = obstacle_clearance(map, pose.position(), cfg.motion.slow_clearance_m.get());
        assert!(
            end >= exec.free_clearance,
            "still in the gap at {pose:?}: {end}"
        );
    }

    /// A robot standing in a gap at exactly the guard's clearance from the lower box, sent toward
    /// it: every move of the back-off's turning arc would come a fraction of a millimetre closer,
    /// so it must finish the turn in place and then leave along the gap (it used to stay put until
    /// the back-off gave up, and the run ended `stuck`).
    #[test]
    fn backing_off_at_exactly_the_guard_clearance_leaves_the_gap() {
        let cfg = Config::default();
        let (map, bvh) = gap_between_boxes(&cfg, 0.21, 0.77);
        let params = MotionParams::from(&cfg);
        let mut exec = MotionExecutor::new(&params);
        let max_m = cfg.motion.slow_clearance_m.get();
        let probe = Point2::new(1.0, 0.48);
        let lower = map.nearest_hazard(probe, max_m).expect("the lower box");
        assert!(lower.y < probe.y, "{lower:?}");
        let pose = Pose2::new(lower.x, lower.y + exec.guard_clearance, -PI / 2.0);
        let start = obstacle_clearance(&map, pose.position(), max_m);
        assert!((start - exec.guard_clearance).abs() < 1e-6, "{start}");
        assert_backs_out_of_the_gap(&cfg, &mut exec, &map, &bvh, pose);
    }
}
