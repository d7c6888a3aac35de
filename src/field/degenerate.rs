//! Degenerate points: detection by winding number, sub-cell placement, classification, tracking.
//!
//! The winding number of `(a, b)` around each square of four neighbouring grid samples is counted in
//! quadrants with a *symbolic perturbation*: a zero `a` or `b` counts as positive. Where `b ≡ 0`
//! exactly (axis-aligned constraints only, see `mod.rs`), the field never leaves the upper half-plane
//! as seen by this rule, so a degenerate curve yields winding 0 instead of noise; isolated zeros
//! that `b` really crosses are counted exactly once, because each edge's contribution is shared,
//! with opposite signs, by the two squares on either side.

use super::eval::FieldGrid;
use crate::grid::Cell;
use nalgebra::Point2;
use serde::Serialize;

/// Type of a degenerate point, from the winding number of `(a, b)` (twice the tensor index).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DegenerateKind {
    /// Winding +1 (tensor index +½).
    Wedge,
    /// Winding −1 (tensor index −½).
    Trisector,
    /// Any other non-zero winding (a higher-order point; reported, not used by planners).
    Other,
}

impl DegenerateKind {
    pub fn of_winding(w: i32) -> Option<Self> {
        match w {
            0 => None,
            1 => Some(DegenerateKind::Wedge),
            -1 => Some(DegenerateKind::Trisector),
            _ => Some(DegenerateKind::Other),
        }
    }
}

/// A degenerate point with a stable id (kept across key frames by [`Tracker`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DegeneratePoint {
    pub id: u64,
    pub x: f64,
    pub y: f64,
    pub kind: DegenerateKind,
    /// Winding number of `(a, b)` around the point (+1 wedge, −1 trisector).
    pub winding: i32,
    /// Distance to the nearest obstacle cell, metres (∞ if none is known).
    pub clearance_m: f64,
}

impl DegeneratePoint {
    pub fn pos(&self) -> Point2<f64> {
        Point2::new(self.x, self.y)
    }
}

/// A point found on one field, before tracking.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawPoint {
    pub pos: Point2<f64>,
    pub winding: i32,
}

fn quadrant(v: [f64; 2]) -> i32 {
    match (v[0] >= 0.0, v[1] >= 0.0) {
        (true, true) => 0,
        (false, true) => 1,
        (false, false) => 2,
        (true, false) => 3,
    }
}

/// Winding number of the closed polygon of values `v` (counter-clockwise), symbolic-perturbation rule.
pub fn winding(v: &[[f64; 2]]) -> i32 {
    let mut quarter = 0;
    for k in 0..v.len() {
        let (p, q) = (v[k], v[(k + 1) % v.len()]);
        quarter += match (quadrant(q) - quadrant(p)).rem_euclid(4) {
            0 => 0,
            1 => 1,
            3 => -1,
            _ => {
                if p[0] * q[1] - p[1] * q[0] >= 0.0 {
                    2
                } else {
                    -2
                }
            }
        };
    }
    quarter / 4
}

/// Every square of four neighbouring samples with non-zero winding, with the point placed inside it
/// (Newton on the bilinear interpolant; the square's centre if that fails to converge).
pub fn detect(field: &FieldGrid) -> Vec<RawPoint> {
    let s = &field.spec;
    let mut out = Vec::new();
    if s.nx < 2 || s.ny < 2 {
        return out;
    }
    for y in 0..s.ny - 1 {
        for x in 0..s.nx - 1 {
            let i00 = s.index(Cell::new(x as i32, y as i32));
            let idx = [i00, i00 + 1, i00 + 1 + s.nx, i00 + s.nx];
            if idx.iter().any(|&i| field.weight[i] <= 0.0) {
                continue;
            }
            let v = idx.map(|i| field.ab[i]);
            // Four corners in one quadrant wind zero times: most squares, and no need to walk them.
            let q = quadrant(v[0]);
            if v[1..].iter().all(|&c| quadrant(c) == q) {
                continue;
            }
            let w = winding(&v);
            if w != 0 {
                let (u, t) = locate(v);
                let o = s.center(Cell::new(x as i32, y as i32));
                out.push(RawPoint {
                    pos: Point2::new(o.x + u * s.res, o.y + t * s.res),
                    winding: w,
                });
            }
        }
    }
    out
}

/// The zero of the bilinear interpolant of `v` (corners 00, 10, 11, 01) in the unit square.
fn locate(v: [[f64; 2]; 4]) -> (f64, f64) {
    let f = |u: f64, t: f64, k: usize| {
        v[0][k] * (1.0 - u) * (1.0 - t)
            + v[1][k] * u * (1.0 - t)
            + v[2][k] * u * t
            + v[3][k] * (1.0 - u) * t
    };
    let (mut u, mut t) = (0.5, 0.5);
    for _ in 0..30 {
        let (fa, fb) = (f(u, t, 0), f(u, t, 1));
        let du = |k: usize| (v[1][k] - v[0][k]) * (1.0 - t) + (v[2][k] - v[3][k]) * t;
        let dt = |k: usize| (v[3][k] - v[0][k]) * (1.0 - u) + (v[2][k] - v[1][k]) * u;
        let (a11, a12, a21, a22) = (du(0), dt(0), du(1), dt(1));
        let det = a11 * a22 - a12 * a21;
        if det == 0.0 || !det.is_finite() {
            return (0.5, 0.5);
        }
        let su = (fa * a22 - fb * a12) / det;
        let st = (a11 * fb - a21 * fa) / det;
        u = (u - su).clamp(0.0, 1.0);
        t = (t - st).clamp(0.0, 1.0);
        if su.abs() + st.abs() < 1e-12 {
            break;
        }
    }
    (u, t)
}

/// Keeps ids stable across key frames: a new point within `radius` of a point of the same kind from
/// the previous key frame takes its id (closest pairs first); others get fresh ids.
#[derive(Clone, Debug, Default)]
pub struct Tracker {
    next_id: u64,
    last: Vec<DegeneratePoint>,
}

impl Tracker {
    pub fn assign(
        &mut self,
        mut points: Vec<DegeneratePoint>,
        radius: f64,
    ) -> Vec<DegeneratePoint> {
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (i, p) in points.iter().enumerate() {
            for (j, q) in self.last.iter().enumerate() {
                let d = (p.pos() - q.pos()).norm();
                if p.kind == q.kind && d <= radius {
                    pairs.push((d, j, i));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut new_taken = vec![false; points.len()];
        let mut old_taken = vec![false; self.last.len()];
        for (_, j, i) in pairs {
            if !new_taken[i] && !old_taken[j] {
                new_taken[i] = true;
                old_taken[j] = true;
                points[i].id = self.last[j].id;
            }
        }
        for (i, p) in points.iter_mut().enumerate() {
            if !new_taken[i] {
                p.id = self.next_id;
                self.next_id += 1;
            }
        }
        self.last = points.clone();
        points
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridSpec;

    #[test]
    fn winding_of_known_fields() {
        // (a, b) = (x, y) sampled around the origin: +1; (x, -y): -1.
        let sq = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
        assert_eq!(winding(&sq), 1);
        let conj: Vec<[f64; 2]> = sq.iter().map(|v| [v[0], -v[1]]).collect();
        assert_eq!(winding(&conj), -1);
        // z² around the origin: +2.
        let z2: Vec<[f64; 2]> = (0..8)
            .map(|k| {
                let (y, x) = (k as f64 * std::f64::consts::FRAC_PI_4).sin_cos();
                [x * x - y * y, 2.0 * x * y]
            })
            .collect();
        assert_eq!(winding(&z2), 2);
        // b ≡ 0 with a changing sign: a degenerate curve, no point.
        assert_eq!(
            winding(&[[1.0, 0.0], [-1.0, 0.0], [-1.0, 0.0], [1.0, 0.0]]),
            0
        );
        assert_eq!(
            winding(&[[1.0, -0.0], [-2.0, 0.0], [-1.0, -0.0], [3.0, 0.0]]),
            0
        );
    }

    #[test]
    fn detect_places_the_zero_inside_the_cell() {
        let spec = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(1.0, 1.0), 1.0, 0.1);
        let mut g = FieldGrid::zeros(spec);
        let z = Point2::new(0.437, 0.612);
        for i in 0..spec.cells() {
            let p = spec.center(spec.cell(i));
            g.ab[i] = [p.x - z.x, -(p.y - z.y)];
            g.weight[i] = 1.0;
        }
        let pts = detect(&g);
        assert_eq!(pts.len(), 1);
        assert_eq!(pts[0].winding, -1);
        assert!((pts[0].pos - z).norm() < 1e-9);
    }

    #[test]
    fn tracker_keeps_ids_within_radius() {
        let p = |x: f64, kind| DegeneratePoint {
            id: 0,
            x,
            y: 0.0,
            kind,
            winding: 1,
            clearance_m: 1.0,
        };
        let mut t = Tracker::default();
        let a = t.assign(
            vec![p(0.0, DegenerateKind::Wedge), p(5.0, DegenerateKind::Wedge)],
            0.5,
        );
        assert_eq!((a[0].id, a[1].id), (0, 1));
        let b = t.assign(
            vec![
                p(9.0, DegenerateKind::Wedge),
                p(5.3, DegenerateKind::Wedge),
                p(0.1, DegenerateKind::Trisector),
            ],
            0.5,
        );
        assert_eq!((b[0].id, b[1].id, b[2].id), (2, 1, 3));
    }
}
