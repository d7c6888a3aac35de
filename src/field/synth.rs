//! Synthetic layouts for the field's tests (the shipped scenes live elsewhere): walls and
//! boxes as axis-aligned rectangles rasterised into a surface mask (cell centres inside a rectangle).

use crate::field::eval::FieldGrid;
use crate::grid::GridSpec;
use nalgebra::{Point2, Rotation2};

/// A rasterised layout: the grid and the cells covered by geometry (surface = obstacle here).
#[derive(Clone, Debug)]
pub struct Layout {
    pub grid: GridSpec,
    pub surface: Vec<bool>,
}

/// A rectangle `[x0, y0, x1, y1]`, possibly rotated by `angle` about `pivot`.
#[derive(Clone, Copy, Debug)]
pub struct Rect {
    pub min: Point2<f64>,
    pub max: Point2<f64>,
}

/// An axis-aligned wall from `(x0, y0)` to `(x1, y1)` (one of them equal) of thickness `t`.
pub fn wall(x0: f64, y0: f64, x1: f64, y1: f64, t: f64) -> Rect {
    let h = t / 2.0;
    Rect {
        min: Point2::new(x0.min(x1) - h, y0.min(y1) - h),
        max: Point2::new(x0.max(x1) + h, y0.max(y1) + h),
    }
}

/// Rasterises rectangles, rotated by `angle` about `pivot` (0 for none), onto a grid covering
/// `[lo, hi]` at `res`.
pub fn rasterise(
    rects: &[Rect],
    lo: Point2<f64>,
    hi: Point2<f64>,
    res: f64,
    angle: f64,
    pivot: Point2<f64>,
) -> Layout {
    let grid = GridSpec::covering(lo, hi, 2.0, res);
    let inv = Rotation2::new(-angle);
    let surface = (0..grid.cells())
        .map(|i| {
            let p = grid.center(grid.cell(i));
            let q = pivot + inv * (p - pivot);
            rects
                .iter()
                .any(|r| q.x >= r.min.x && q.x < r.max.x && q.y >= r.min.y && q.y < r.max.y)
        })
        .collect();
    Layout { grid, surface }
}

/// A closed rectangular room with walls through `[x0, x1] × [y0, y1]`.
pub fn room(x0: f64, y0: f64, x1: f64, y1: f64, t: f64) -> Vec<Rect> {
    vec![
        wall(x0, y0, x1, y0, t),
        wall(x0, y1, x1, y1, t),
        wall(x0, y0, x0, y1, t),
        wall(x1, y0, x1, y1, t),
    ]
}

/// A ~20 × 20 m office: a + junction of 2 m corridors, eight rooms with 1 m doorways, a T junction
/// where a side corridor meets the main one, and furniture boxes.
pub fn office_rects() -> Vec<Rect> {
    let t = 0.2;
    let mut r = room(0.0, 0.0, 20.0, 20.0, t);
    // Corridor walls (y = 9 and 11, x = 9 and 11) with doorways into each room.
    for &y in &[9.0, 11.0] {
        r.push(wall(0.0, y, 1.0, y, t));
        r.push(wall(2.0, y, 5.5, y, t));
        r.push(wall(6.5, y, 9.0, y, t));
        r.push(wall(11.0, y, 13.0, y, t));
        r.push(wall(14.0, y, 16.5, y, t));
        r.push(wall(17.5, y, 20.0, y, t));
    }
    for &x in &[9.0, 11.0] {
        r.push(wall(x, 0.0, x, 9.0, t));
        r.push(wall(x, 11.0, x, 20.0, t));
    }
    // Rooms: each quadrant split in two.
    r.push(wall(4.5, 0.0, 4.5, 9.0, t));
    r.push(wall(4.5, 11.0, 4.5, 20.0, t));
    r.push(wall(15.0, 11.0, 15.0, 20.0, t));
    // Lower-right quadrant: a side corridor (T junction with the main one) between two rooms.
    r.push(wall(14.0, 0.0, 14.0, 9.0, t));
    r.push(wall(16.0, 0.0, 16.0, 9.0, t));
    // Furniture.
    for (x, y, w, h) in [
        (2.0, 3.0, 1.2, 0.6),
        (6.5, 5.0, 0.8, 0.8),
        (12.0, 15.0, 1.0, 1.6),
        (17.5, 4.0, 0.8, 1.2),
    ] {
        r.push(Rect {
            min: Point2::new(x, y),
            max: Point2::new(x + w, y + h),
        });
    }
    r
}

/// The office rasterised at `res`.
pub fn office(res: f64) -> Layout {
    rasterise(
        &office_rects(),
        Point2::new(-0.5, -0.5),
        Point2::new(20.5, 20.5),
        res,
        0.0,
        Point2::origin(),
    )
}

/// The part of `surface` within `radius` of any of `centres` (a crude "what has been seen").
pub fn reveal(layout: &Layout, centres: &[Point2<f64>], radius: f64) -> Vec<bool> {
    let g = &layout.grid;
    (0..g.cells())
        .map(|i| {
            layout.surface[i] && {
                let p = g.center(g.cell(i));
                centres.iter().any(|c| (p - c).norm() <= radius)
            }
        })
        .collect()
}

/// A field over `[-half, half]²` at 0.1 m whose (a, b) at each cell centre is `f(x, y)`, with unit
/// weights: locally linear fields with known degenerate points.
pub fn field_from_fn(half: f64, f: impl Fn(f64, f64) -> [f64; 2]) -> FieldGrid {
    let spec = GridSpec::covering(Point2::new(-half, -half), Point2::new(half, half), 1.0, 0.1);
    let mut g = FieldGrid::zeros(spec);
    for i in 0..spec.cells() {
        let p = spec.center(spec.cell(i));
        g.ab[i] = f(p.x, p.y);
        g.weight[i] = 1.0;
    }
    g
}
