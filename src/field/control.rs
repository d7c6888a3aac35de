//! Topological control (TENSOR §4.3), on a copy of the topology field's `(a, b)` grid (which is the
//! vector field `V = μ(cos 2θ, sin 2θ)` of the paper, so edits act on it directly).
//!
//! - Pair cancellation: a wedge–trisector pair whose distance over the topology graph is below
//!   `lfs(p_W) + lfs(p_T)` (Eq. 6; lfs = distance to the nearest obstacle) is removed by Laplacian
//!   smoothing of `(a, b)` on a disc around the pair, with the rim fixed, until no square in the disc
//!   has a non-zero winding (or the iteration cap is hit; the edit is then undone).
//! - Moving a point: the field is warped, `V'(p) = V(p − s(p)Δ)`, with `s = 1` near the point and a
//!   smooth fall-off to 0, `|∇s||Δ| ≤ ½`, so the warp is a diffeomorphism that carries the zero from
//!   `p₀` to `p₀ + Δ` and changes nothing else topologically. Used to move a sharp wedge (two
//!   separatrices under 90° apart) into its corner, and a trisector away from obstacles.

use super::degenerate::winding;
use super::eval::FieldGrid;
use crate::grid::Cell;
use nalgebra::{Point2, Vector2};

/// Smooths `(a, b)` on the disc of radius `r` around `center` until it holds no degenerate point.
/// Returns whether it succeeded (on failure the field is left unchanged).
pub fn cancel_in_disc(
    field: &mut FieldGrid,
    center: Point2<f64>,
    r: f64,
    max_iterations: usize,
) -> bool {
    let s = field.spec;
    let lo = s.cell_at(center.x - r, center.y - r);
    let hi = s.cell_at(center.x + r, center.y + r);
    let mut region = Vec::new();
    for y in lo.y.max(1)..=hi.y.min(s.ny as i32 - 2) {
        for x in lo.x.max(1)..=hi.x.min(s.nx as i32 - 2) {
            let c = Cell::new(x, y);
            if (s.center(c) - center).norm() <= r {
                region.push(s.index(c));
            }
        }
    }
    if region.is_empty() {
        return false;
    }
    let backup: Vec<[f64; 2]> = region.iter().map(|&i| field.ab[i]).collect();
    let regular = |f: &FieldGrid| {
        region.iter().all(|&i| {
            let sq = [i, i + 1, i + 1 + s.nx, i + s.nx];
            let sq_m = [i - 1 - s.nx, i - s.nx, i, i - 1];
            winding(&sq.map(|k| f.ab[k])) == 0 && winding(&sq_m.map(|k| f.ab[k])) == 0
        })
    };
    for it in 0..max_iterations {
        if it % 5 == 0 && regular(field) {
            return true;
        }
        let next: Vec<[f64; 2]> = region
            .iter()
            .map(|&i| {
                let n = [i + 1, i - 1, i + s.nx, i - s.nx];
                [0, 1].map(|m| n.iter().map(|&k| field.ab[k][m]).sum::<f64>() / 4.0)
            })
            .collect();
        for (&i, v) in region.iter().zip(next) {
            field.ab[i] = v;
        }
    }
    if regular(field) {
        return true;
    }
    for (&i, v) in region.iter().zip(backup) {
        field.ab[i] = v;
    }
    false
}

/// Warps the field so that a degenerate point at `from` moves to `to`.
pub fn move_point(field: &mut FieldGrid, from: Point2<f64>, to: Point2<f64>) {
    let delta: Vector2<f64> = to - from;
    let len = delta.norm();
    if len <= 0.0 {
        return;
    }
    let inner = 1.2 * len + field.spec.res;
    let width = 3.0 * len + 2.0 * field.spec.res;
    let outer = inner + width;
    let bump = |p: Point2<f64>| {
        let d = (p - from).norm();
        if d <= inner {
            1.0
        } else if d >= outer {
            0.0
        } else {
            let x = 1.0 - (d - inner) / width;
            x * x * (3.0 - 2.0 * x)
        }
    };
    let s = field.spec;
    let original = field.clone();
    let lo = s.cell_at(from.x - outer, from.y - outer);
    let hi = s.cell_at(from.x + outer, from.y + outer);
    for y in lo.y.max(0)..=hi.y.min(s.ny as i32 - 1) {
        for x in lo.x.max(0)..=hi.x.min(s.nx as i32 - 1) {
            let c = Cell::new(x, y);
            let p = s.center(c);
            let b = bump(p);
            if b > 0.0 {
                if let Some(v) = original.sample(p - delta * b) {
                    let i = s.index(c);
                    field.ab[i] = [v.a, v.b];
                    field.weight[i] = v.weight;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::degenerate::detect;

    fn field(f: impl Fn(f64, f64) -> [f64; 2]) -> FieldGrid {
        crate::field::synth::field_from_fn(2.0, f)
    }

    #[test]
    fn moving_a_wedge_moves_only_it() {
        let z = Point2::new(-0.53, 0.21);
        let mut g = field(|x, y| [x - z.x, y - z.y]);
        let to = Point2::new(0.12, -0.31);
        move_point(&mut g, z, to);
        let pts = detect(&g);
        assert_eq!(pts.len(), 1);
        assert_eq!(pts[0].winding, 1);
        assert!((pts[0].pos - to).norm() < 0.05, "{:?}", pts[0].pos);
    }

    #[test]
    fn cancelling_a_close_pair_leaves_a_regular_field() {
        // V = (x² − 0.09 + y... ): zeros at (±0.3, 0) of opposite index: V = (x² − 0.09, y) + offset.
        let mut g = field(|x, y| [x * x - 0.0961 + 0.003, y]);
        let pts = detect(&g);
        assert_eq!(pts.len(), 2);
        assert_eq!(pts.iter().map(|p| p.winding).sum::<i32>(), 0);
        assert!(cancel_in_disc(&mut g, Point2::new(0.0, 0.0), 0.8, 2000));
        assert!(detect(&g).is_empty());
    }
}
