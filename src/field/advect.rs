//! Particle advection along the major eigenvector field (TENSOR §4.2), also used to trace separatrices.
//!
//! The line field has no sign, so every evaluation is flipped to agree (angle under 90°) with the
//! current direction of travel; the first direction is the given heading. Integration is RK4 with a
//! fixed step `h` (metres of arc length).

use super::eval::FieldGrid;
use crate::grid::GridSpec;
use nalgebra::{Point2, Vector2};
use serde::Serialize;

/// Why a pathline ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    MaxLength,
    Obstacle,
    Unknown,
    /// Came within the stop radius of degenerate point number `.0` of the given list.
    NearDegenerate(usize),
    Border,
    /// The field vanished exactly: no direction to follow.
    Degenerate,
}

/// What stops a pathline, besides its length. Masks are per cell of `grid`.
#[derive(Clone, Copy, Debug)]
pub struct StopConditions<'a> {
    pub grid: &'a GridSpec,
    pub obstacle: Option<&'a [bool]>,
    pub unknown: Option<&'a [bool]>,
    pub degenerate_points: &'a [Point2<f64>],
    pub degenerate_radius_m: f64,
    /// Point index to ignore until the line has left its stop radius (the separatrix's own origin).
    pub origin: Option<usize>,
}

impl<'a> StopConditions<'a> {
    /// Only the grid border stops the line.
    pub fn border_only(grid: &'a GridSpec) -> Self {
        StopConditions {
            grid,
            obstacle: None,
            unknown: None,
            degenerate_points: &[],
            degenerate_radius_m: 0.0,
            origin: None,
        }
    }

    fn check(&self, p: Point2<f64>, travelled: f64) -> Option<StopReason> {
        let Some(c) = self.grid.cell_of(p) else {
            return Some(StopReason::Border);
        };
        let i = self.grid.index(c);
        if self.obstacle.is_some_and(|m| m[i]) {
            return Some(StopReason::Obstacle);
        }
        if self.unknown.is_some_and(|m| m[i]) {
            return Some(StopReason::Unknown);
        }
        let r2 = self.degenerate_radius_m * self.degenerate_radius_m;
        for (k, q) in self.degenerate_points.iter().enumerate() {
            if Some(k) == self.origin && travelled < 2.0 * self.degenerate_radius_m {
                continue;
            }
            if (p - q).norm_squared() < r2 {
                return Some(StopReason::NearDegenerate(k));
            }
        }
        None
    }
}

/// Traces a line through a (possibly time-varying) line field. `field(p, s)` gives `(a, b)` at `p`
/// after `s` metres of travel, or `None` outside the field's domain.
pub fn trace(
    field: impl Fn(Point2<f64>, f64) -> Option<[f64; 2]>,
    start: Point2<f64>,
    heading: f64,
    max_len: f64,
    h: f64,
    stop: &StopConditions,
) -> (Vec<Point2<f64>>, StopReason) {
    let mut line = vec![start];
    if let Some(r) = stop.check(start, 0.0) {
        return (line, r);
    }
    let mut dir = Vector2::new(heading.cos(), heading.sin());
    let mut p = start;
    let mut s = 0.0;
    let unit = |p: Point2<f64>, s: f64, along: Vector2<f64>| -> Option<Vector2<f64>> {
        let [a, b] = field(p, s)?;
        let mu = a.hypot(b);
        if !(mu > 0.0 && mu.is_finite()) {
            return None;
        }
        // Half-angle of (a, b)/μ without trigonometry.
        let c2 = a / mu;
        let e = Vector2::new(
            ((1.0 + c2) / 2.0).max(0.0).sqrt(),
            ((1.0 - c2) / 2.0).max(0.0).sqrt().copysign(b),
        );
        Some(if e.dot(&along) < 0.0 { -e } else { e })
    };
    while s < max_len - 1e-12 {
        let step = h.min(max_len - s);
        let Some(k1) = unit(p, s, dir) else {
            let r = if field(p, s).is_none() {
                StopReason::Border
            } else {
                StopReason::Degenerate
            };
            return (line, r);
        };
        let k2 = unit(p + k1 * (step / 2.0), s + step / 2.0, k1);
        let k3 = k2.and_then(|k2| unit(p + k2 * (step / 2.0), s + step / 2.0, k1));
        let k4 = k3.and_then(|k3| unit(p + k3 * step, s + step, k1));
        let (Some(k2), Some(k3), Some(k4)) = (k2, k3, k4) else {
            return (line, StopReason::Border);
        };
        let v = (k1 + k2 * 2.0 + k3 * 2.0 + k4) / 6.0;
        if v.norm() < 1e-12 {
            return (line, StopReason::Degenerate);
        }
        let v = v.normalize();
        p += v * step;
        s += step;
        dir = v;
        line.push(p);
        if let Some(r) = stop.check(p, s) {
            return (line, r);
        }
    }
    (line, StopReason::MaxLength)
}

/// A pathline through a static field from `start`, leaving along the field direction nearest to
/// `heading`.
pub fn pathline(
    field: &FieldGrid,
    start: Point2<f64>,
    heading: f64,
    max_len: f64,
    h: f64,
    stop: &StopConditions,
) -> (Vec<Point2<f64>>, StopReason) {
    trace(
        |p, _| field.sample(p).map(|s| [s.a, s.b]),
        start,
        heading,
        max_len,
        h,
        stop,
    )
}

/// Mean absolute change of heading between consecutive steps of a polyline, radians per step.
#[cfg(test)]
pub fn mean_turn(line: &[Point2<f64>]) -> f64 {
    let headings: Vec<f64> = line
        .windows(2)
        .map(|w| (w[1].y - w[0].y).atan2(w[1].x - w[0].x))
        .collect();
    if headings.len() < 2 {
        return 0.0;
    }
    headings
        .windows(2)
        .map(|w| crate::util::wrap_angle(w[1] - w[0]).abs())
        .sum::<f64>()
        / (headings.len() - 1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uniform(theta: f64) -> (GridSpec, FieldGrid) {
        let spec = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(5.0, 5.0), 1.0, 0.1);
        let mut g = FieldGrid::zeros(spec);
        for i in 0..spec.cells() {
            g.ab[i] = [(2.0 * theta).cos(), (2.0 * theta).sin()];
            g.weight[i] = 1.0;
        }
        (spec, g)
    }

    #[test]
    fn follows_the_field_in_the_heading_sense() {
        let (spec, g) = uniform(0.3);
        let stop = StopConditions::border_only(&spec);
        // Heading almost backwards along the field: the line goes the opposite way, straight.
        let (line, r) = pathline(&g, Point2::new(2.5, 2.5), 0.3 + 3.0, 1.0, 0.05, &stop);
        assert_eq!(r, StopReason::MaxLength);
        let d = line.last().unwrap() - line[0];
        assert!((d.norm() - 1.0).abs() < 1e-9);
        assert!((d.y.atan2(d.x) - (0.3 - std::f64::consts::PI)).abs() < 1e-9);
        assert!(mean_turn(&line) < 1e-9);
    }

    #[test]
    fn stops_at_obstacles_and_degenerate_points() {
        let (spec, g) = uniform(0.0);
        let mut obstacle = vec![false; spec.cells()];
        for y in 0..spec.ny {
            obstacle[spec.index(crate::grid::Cell::new(40, y as i32))] = true;
        }
        let mut stop = StopConditions::border_only(&spec);
        stop.obstacle = Some(&obstacle);
        let (line, r) = pathline(&g, Point2::new(1.0, 2.5), 0.0, 10.0, 0.05, &stop);
        assert_eq!(r, StopReason::Obstacle);
        assert!((line.last().unwrap().x - 4.0).abs() < 0.06);
        let pts = [Point2::new(3.0, 2.5)];
        stop.degenerate_points = &pts;
        stop.degenerate_radius_m = 0.3;
        let (line, r) = pathline(&g, Point2::new(1.0, 2.5), 0.0, 10.0, 0.05, &stop);
        assert_eq!(r, StopReason::NearDegenerate(0));
        assert!((line.last().unwrap() - pts[0]).norm() < 0.3);
        let (_, r) = pathline(
            &g,
            Point2::new(1.0, 2.5),
            std::f64::consts::PI,
            10.0,
            0.05,
            &stop,
        );
        assert_eq!(r, StopReason::Border);
    }
}
