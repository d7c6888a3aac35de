//! The robot: a unicycle with bounded speed and turn rate, carrying a fixed forward camera.

use crate::config::RobotConfig;
use crate::Pose2;

/// A velocity command: forward speed (m/s) and turn rate (rad/s).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Command {
    pub v: f64,
    pub w: f64,
}

/// The robot's state.
#[derive(Clone, Debug)]
pub struct Robot {
    pub pose: Pose2,
    /// Distance driven so far, metres.
    pub path_length_m: f64,
    max_speed: f64,
    max_turn: f64,
}

impl Robot {
    pub fn new(pose: Pose2, cfg: &RobotConfig) -> Self {
        Robot {
            pose,
            path_length_m: 0.0,
            max_speed: cfg.max_speed_mps,
            max_turn: cfg.max_turn_rate_rps,
        }
    }

    /// Clamps `cmd` to the robot's limits (no reversing) and integrates it exactly over `dt` (an arc
    /// of constant curvature), returning the clamped command.
    pub fn apply(&mut self, cmd: Command, dt: f64) -> Command {
        let v = cmd.v.clamp(0.0, self.max_speed);
        let w = cmd.w.clamp(-self.max_turn, self.max_turn);
        self.pose = integrate(self.pose, v, w, dt);
        self.path_length_m += v * dt;
        Command { v, w }
    }
}

/// Pose after driving `v`, `w` for `dt` from `p` along the exact unicycle arc.
pub fn integrate(p: Pose2, v: f64, w: f64, dt: f64) -> Pose2 {
    let yaw1 = p.yaw + w * dt;
    let (x, y) = if w.abs() < 1e-9 {
        (p.x + v * dt * p.yaw.cos(), p.y + v * dt * p.yaw.sin())
    } else {
        let r = v / w;
        (
            p.x + r * (yaw1.sin() - p.yaw.sin()),
            p.y - r * (yaw1.cos() - p.yaw.cos()),
        )
    };
    Pose2::new(x, y, crate::util::wrap_angle(yaw1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn robot() -> Robot {
        Robot::new(Pose2::new(0.0, 0.0, 0.0), &crate::Config::default().robot)
    }

    #[test]
    fn straight_line() {
        let mut r = robot();
        for _ in 0..10 {
            r.apply(Command { v: 0.5, w: 0.0 }, 0.1);
        }
        assert!((r.pose.x - 0.5).abs() < 1e-12 && r.pose.y.abs() < 1e-12);
        assert!((r.path_length_m - 0.5).abs() < 1e-12);
    }

    #[test]
    fn limits_are_enforced() {
        let mut r = robot();
        let c = r.apply(Command { v: 5.0, w: -9.0 }, 0.1);
        assert_eq!(c, Command { v: 1.0, w: -1.0 });
        let c = r.apply(Command { v: -1.0, w: 0.0 }, 0.1);
        assert_eq!(c.v, 0.0);
    }

    #[test]
    fn full_circle_returns_home() {
        // v = 1, w = 1: a circle of radius 1 with period 2π.
        let mut p = Pose2::new(0.0, 0.0, 0.0);
        let n = 1000;
        for _ in 0..n {
            p = integrate(p, 1.0, 1.0, 2.0 * PI / n as f64);
        }
        assert!(p.x.abs() < 1e-9 && p.y.abs() < 1e-9, "{p:?}");
        // Quarter circle ends at (1, 1) facing +y.
        let q = integrate(Pose2::new(0.0, 0.0, 0.0), 1.0, 1.0, PI / 2.0);
        assert!((q.x - 1.0).abs() < 1e-12 && (q.y - 1.0).abs() < 1e-12);
        assert!((q.yaw - PI / 2.0).abs() < 1e-12);
    }
}
