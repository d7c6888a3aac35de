//! PNG pictures of maps, ground truth and paths.
//!
//! A [`Canvas`] maps a [`GridSpec`] onto an image: each cell is `scale × scale` pixels and image row 0
//! is the grid's top (largest y), so pictures read like a floor plan with x right and y up.

use crate::grid::GridSpec;
use crate::map::{CellState, Map};
use crate::scene::GroundTruth;
use crate::{Error, Pose2, Result};
use image::{Rgb, RgbImage};
use nalgebra::Point2;
use std::path::Path;

pub mod palette;

pub use palette::{
    FREE, FRONTIER, INFLATED, OCCUPIED, PATH, REGION, ROBOT, START, TRUTH_WALL, UNKNOWN,
};

/// Largest picture side, pixels; the cell scale is chosen to stay under it.
const MAX_SIDE_PX: usize = 1600;

/// An image over a grid.
pub struct Canvas {
    pub image: RgbImage,
    pub grid: GridSpec,
    /// Pixels per cell edge.
    pub scale: u32,
}

impl Canvas {
    /// A canvas for `grid`, filled with `background`, at the largest scale (1–8 px per cell) that keeps
    /// the picture under 1,600 px a side.
    pub fn new(grid: GridSpec, background: Rgb<u8>) -> Self {
        let scale = (MAX_SIDE_PX / grid.nx.max(grid.ny)).clamp(1, 8) as u32;
        let image =
            RgbImage::from_pixel(grid.nx as u32 * scale, grid.ny as u32 * scale, background);
        Canvas { image, grid, scale }
    }

    /// Pixel coordinates (column, row; fractional) of a world point.
    pub fn to_px(&self, p: Point2<f64>) -> (f64, f64) {
        let s = self.scale as f64 / self.grid.res;
        let col = (p.x - self.grid.origin_x) * s;
        let row = self.image.height() as f64 - (p.y - self.grid.origin_y) * s;
        (col, row)
    }

    /// Paints every cell for which `color` returns a colour.
    pub fn paint_cells(&mut self, color: impl Fn(usize) -> Option<Rgb<u8>>) {
        for idx in 0..self.grid.cells() {
            if let Some(c) = color(idx) {
                self.fill_cell(idx, c);
            }
        }
    }

    fn fill_cell(&mut self, idx: usize, c: Rgb<u8>) {
        let cell = self.grid.cell(idx);
        let x0 = cell.x as u32 * self.scale;
        let y0 = (self.grid.ny as u32 - 1 - cell.y as u32) * self.scale;
        for y in y0..y0 + self.scale {
            for x in x0..x0 + self.scale {
                self.image.put_pixel(x, y, c);
            }
        }
    }

    /// Sets one pixel if it lies inside the image.
    pub fn plot(&mut self, col: i64, row: i64, c: Rgb<u8>) {
        if col >= 0
            && row >= 0
            && (col as u32) < self.image.width()
            && (row as u32) < self.image.height()
        {
            self.image.put_pixel(col as u32, row as u32, c);
        }
    }

    /// A filled disc of `radius_px` pixels around a world point.
    pub fn disc(&mut self, p: Point2<f64>, radius_px: f64, c: Rgb<u8>) {
        let (cx, cy) = self.to_px(p);
        let r = radius_px.ceil() as i64;
        for dy in -r..=r {
            for dx in -r..=r {
                if (dx * dx + dy * dy) as f64 <= radius_px * radius_px {
                    self.plot(cx as i64 + dx, cy as i64 + dy, c);
                }
            }
        }
    }

    /// A line between world points, `width_px` wide.
    pub fn line(&mut self, a: Point2<f64>, b: Point2<f64>, width_px: f64, c: Rgb<u8>) {
        let (ax, ay) = self.to_px(a);
        let (bx, by) = self.to_px(b);
        let n = ((bx - ax).abs().max((by - ay).abs()).ceil() as usize).max(1);
        let half = (width_px / 2.0).max(0.5);
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let (x, y) = (ax + (bx - ax) * t, ay + (by - ay) * t);
            let r = half.floor() as i64;
            for dy in -r..=r {
                for dx in -r..=r {
                    self.plot(x as i64 + dx, y as i64 + dy, c);
                }
            }
        }
    }

    /// A polyline through world points.
    pub fn polyline(&mut self, points: &[Point2<f64>], width_px: f64, c: Rgb<u8>) {
        for w in points.windows(2) {
            self.line(w[0], w[1], width_px, c);
        }
    }

    /// Writes the picture as PNG.
    pub fn save(&self, path: &Path) -> Result<()> {
        self.image.save(path).map_err(|e| match e {
            image::ImageError::IoError(io) => Error::io(path, io),
            other => Error::Runtime(format!("{}: {other}", path.display())),
        })
    }
}

/// The ground truth: explorable region tinted, obstacle columns dark, the spawn marked.
pub fn draw_ground_truth(gt: &GroundTruth) -> Canvas {
    let mut canvas = Canvas::new(gt.grid, FREE);
    canvas.paint_cells(|i| {
        if gt.obstacle_column(i) {
            Some(OCCUPIED)
        } else if gt.in_region(i) {
            Some(REGION)
        } else {
            None
        }
    });
    let spawn = gt.spawn.position();
    let r = 0.25 / gt.grid.res * canvas.scale as f64;
    canvas.disc(spawn, r.max(3.0), START);
    canvas
}

/// A run's map: free (shaded where too close to an obstacle for the robot), occupied and unknown
/// cells, ground-truth walls faint where the map has not seen them, frontier cells, the driven path, the start and the end.
pub fn draw_run(map: &Map, gt: &GroundTruth, trajectory: &[Pose2]) -> Canvas {
    let mut canvas = Canvas::new(*map.grid(), UNKNOWN);
    canvas.paint_cells(|i| match map.cell_state(i) {
        CellState::Obstacle => Some(OCCUPIED),
        CellState::Free if map.is_frontier(i) => Some(FRONTIER),
        CellState::Free if !map.is_traversable(i) => Some(INFLATED),
        CellState::Free => Some(FREE),
        CellState::Unknown if gt.obstacle_column(i) => Some(TRUTH_WALL),
        CellState::Unknown => None,
    });
    let points: Vec<Point2<f64>> = trajectory.iter().map(|p| p.position()).collect();
    canvas.polyline(&points, 2.0, PATH);
    let r = (0.25 / map.grid().res * canvas.scale as f64).max(3.0);
    if let (Some(first), Some(last)) = (points.first(), points.last()) {
        canvas.disc(*first, r, START);
        canvas.disc(*last, r, palette::ROBOT);
    }
    canvas
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn world_to_pixel_has_y_up() {
        let g = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(10.0, 5.0), 1.0, 0.1);
        let c = Canvas::new(g, FREE);
        assert_eq!(c.scale, 8);
        assert_eq!((c.image.width(), c.image.height()), (800, 400));
        let (x, y) = c.to_px(Point2::new(0.0, 0.0));
        assert_eq!((x, y), (0.0, 400.0));
        let (x, y) = c.to_px(Point2::new(10.0, 5.0));
        assert!((x - 800.0).abs() < 1e-9 && y.abs() < 1e-9);
    }

    #[test]
    fn painted_cell_lands_where_its_centre_maps() {
        let g = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(2.0, 1.0), 1.0, 0.1);
        let mut c = Canvas::new(g, FREE);
        let cell = crate::Cell::new(3, 7);
        let idx = g.index(cell);
        c.paint_cells(|i| (i == idx).then_some(OCCUPIED));
        let (px, py) = c.to_px(g.center(cell));
        assert_eq!(*c.image.get_pixel(px as u32, py as u32), OCCUPIED);
        assert_eq!(*c.image.get_pixel(0, 0), FREE);
    }
}
