//! The robot's trajectory in the TUM RGB-D format that `evo` and most SLAM tools read: one pose a
//! line, `t x y z qx qy qz qw` (seconds, metres, unit quaternion), after a `#` header line.

use crate::Pose2;
use std::fmt::Write;

/// The TUM text of `trajectory`, whose `k`-th pose is at simulated time `k · dt_s` (the poses a run
/// records: the start, then one per step). The robot is on the floor (z = 0) and turns about +z.
pub fn tum_text(trajectory: &[Pose2], dt_s: f64) -> String {
    let mut out = String::from("# timestamp tx ty tz qx qy qz qw\n");
    let steps_per_s = 1.0 / dt_s;
    for (k, p) in trajectory.iter().enumerate() {
        // The same time expression as the step loop, so that times read 270.4, not 270.40000000000003.
        let t = k as f64 / steps_per_s;
        let (s, c) = (p.yaw / 2.0).sin_cos();
        let _ = writeln!(out, "{t} {} {} 0 0 0 {s} {c}", p.x, p.y);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_have_eight_numbers_and_unit_quaternions() {
        let poses = [
            Pose2::new(0.0, 0.0, 0.0),
            Pose2::new(1.5, -2.0, std::f64::consts::FRAC_PI_2),
        ];
        let text = tum_text(&poses, 0.1);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "# timestamp tx ty tz qx qy qz qw");
        assert_eq!(lines[1], "0 0 0 0 0 0 0 1");
        let v: Vec<f64> = lines[2].split(' ').map(|x| x.parse().unwrap()).collect();
        assert_eq!(v.len(), 8);
        assert_eq!(v[0], 0.1);
        assert_eq!((v[1], v[2], v[3]), (1.5, -2.0, 0.0));
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((v[6] - h).abs() < 1e-12 && (v[7] - h).abs() < 1e-12);
    }
}
