//! PNG pictures of maps, ground truth and paths.
//!
//! A [`Canvas`] maps a [`GridSpec`] onto an image: each cell is `scale × scale` pixels and image row 0
//! is the grid's top (largest y), so pictures read like a floor plan with x right and y up. Colours
//! come from [`palette`]; the canvas remembers which palette entries it drew, and [`Canvas::save`]
//! writes the picture with a panel on its right: a scale bar and a legend of exactly those entries.

use crate::eval::GroundTruth;
use crate::grid::GridSpec;
use crate::map::{CellState, Map};
use crate::sim::ObservableSet;
use crate::{Error, Pose2, Result};
use image::{Rgb, RgbImage};
use nalgebra::Point2;
use std::path::Path;

pub mod field;
pub mod palette;

pub use field::draw_field;
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
    /// Palette entries drawn so far (for the legend).
    used: Vec<Rgb<u8>>,
}

/// The embedded font of every picture's text (DejaVu Sans, assets/fonts), so that no system fonts
/// are needed.
pub const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Registers [`FONT`] with plotters as "sans-serif" (once per process).
pub fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The font is compiled in and known to parse; a unit test draws text with it.
        let _ =
            plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, FONT);
    });
}

/// Width of the legend panel, pixels.
const PANEL_PX: u32 = 300;
const LEGEND_ROW_PX: u32 = 24;
const TEXT_PX: f64 = 17.0;

impl Canvas {
    /// A canvas for `grid`, filled with `background`, at the largest scale (1–8 px per cell) that keeps
    /// the picture under 1,600 px a side.
    pub fn new(grid: GridSpec, background: Rgb<u8>) -> Self {
        let scale = (MAX_SIDE_PX / grid.nx.max(grid.ny)).clamp(1, 8) as u32;
        let image =
            RgbImage::from_pixel(grid.nx as u32 * scale, grid.ny as u32 * scale, background);
        Canvas {
            image,
            grid,
            scale,
            used: vec![background],
        }
    }

    /// Records that palette colour `c` appears in the picture (done by every drawing call; use it
    /// for colours drawn faded or by hand).
    pub fn note(&mut self, c: Rgb<u8>) {
        if !self.used.contains(&c) && palette::LEGEND.iter().any(|e| e.1 == c) {
            self.used.push(c);
        }
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
        let mut last = None;
        for idx in 0..self.grid.cells() {
            if let Some(c) = color(idx) {
                self.fill_cell(idx, c);
                if last != Some(c) {
                    self.note(c);
                    last = Some(c);
                }
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
        self.note(c);
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
        self.note(c);
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

    /// The picture with its panel: a scale bar, then a legend of every palette entry drawn (in
    /// palette order).
    pub fn with_legend(&self) -> RgbImage {
        let (w, h) = self.image.dimensions();
        let mut entries: Vec<_> = palette::LEGEND
            .iter()
            .filter(|e| self.used.contains(&e.1))
            .collect();
        entries.dedup_by_key(|e| e.1);
        let needed = 110 + LEGEND_ROW_PX * entries.len() as u32;
        let (tw, th) = (w + PANEL_PX, h.max(needed));
        let mut out = RgbImage::from_pixel(tw, th, Rgb([255, 255, 255]));
        image::imageops::replace(&mut out, &self.image, 0, 0);
        let fill = |img: &mut RgbImage, x0: u32, y0: u32, x1: u32, y1: u32, c: Rgb<u8>| {
            for y in y0..y1.min(th) {
                for x in x0..x1.min(tw) {
                    img.put_pixel(x, y, c);
                }
            }
        };
        let black = Rgb([0, 0, 0]);
        let x0 = w + 16;
        // Scale bar: the longest of 1-2-5 × 10^k metres that fits in 200 px.
        let px_per_m = self.scale as f64 / self.grid.res;
        let mut len_m = 0.1;
        for k in -1..4 {
            for m in [1.0, 2.0, 5.0] {
                let l = m * 10f64.powi(k);
                if l * px_per_m <= 200.0 {
                    len_m = l;
                }
            }
        }
        let bar_px = (len_m * px_per_m).round().max(1.0) as u32;
        fill(&mut out, x0, 40, x0 + bar_px, 46, black);
        fill(&mut out, x0, 34, x0 + 2, 52, black);
        fill(&mut out, x0 + bar_px - 2, 34, x0 + bar_px, 52, black);
        let mut texts = vec![
            (format!("{len_m} m"), (x0 + bar_px + 10, 34)),
            (format!("cell {} m", self.grid.res), (x0, 60)),
        ];
        texts.insert(0, ("scale".to_string(), (x0, 8)));
        for (k, (label, c, swatch)) in entries.iter().enumerate() {
            let y = 100 + k as u32 * LEGEND_ROW_PX;
            let mid = y + LEGEND_ROW_PX / 2;
            match swatch {
                palette::Swatch::Cell => {
                    fill(
                        &mut out,
                        x0 - 1,
                        mid - 9,
                        x0 + 21,
                        mid + 9,
                        Rgb([90, 90, 90]),
                    );
                    fill(&mut out, x0, mid - 8, x0 + 20, mid + 8, *c);
                }
                palette::Swatch::Line => fill(&mut out, x0, mid - 2, x0 + 20, mid + 2, *c),
                palette::Swatch::Dot => {
                    for dy in -7i32..=7 {
                        for dx in -7i32..=7 {
                            if dx * dx + dy * dy <= 49 {
                                let (x, y) =
                                    ((x0 as i32 + 10 + dx) as u32, (mid as i32 + dy) as u32);
                                out.put_pixel(x, y, *c);
                            }
                        }
                    }
                }
            }
            texts.push((label.to_string(), (x0 + 30, y + 3)));
        }
        draw_texts(&mut out, &texts);
        out
    }

    /// Writes the picture, with its scale bar and legend, as PNG.
    pub fn save(&self, path: &Path) -> Result<()> {
        self.with_legend().save(path).map_err(|e| match e {
            image::ImageError::IoError(io) => Error::io(path, io),
            other => Error::Runtime(format!("{}: {other}", path.display())),
        })
    }
}

/// Draws black text (top-left anchored) with the embedded font.
fn draw_texts(img: &mut RgbImage, texts: &[(String, (u32, u32))]) {
    use plotters::prelude::*;
    register_font();
    let (w, h) = img.dimensions();
    let root = BitMapBackend::with_buffer(img, (w, h)).into_drawing_area();
    let style = ("sans-serif", TEXT_PX).into_font().color(&BLACK);
    for (t, (x, y)) in texts {
        // Drawing text into an in-memory buffer cannot fail but for a missing glyph; then the
        // label is left out rather than the picture.
        let _ = root.draw_text(t, &style, (*x as i32, *y as i32));
    }
    let _ = root.present();
}

/// The ground truth: obstacle columns dark, the reachable floor tinted, the spawn marked. With
/// the observable set, the space observable from the reachable floor but not reachable, and the
/// space never observable, get colours of their own; without it, the rest stays white.
pub fn draw_ground_truth(gt: &GroundTruth, observable: Option<&ObservableSet>) -> Canvas {
    let background = if observable.is_some() {
        palette::NEVER_OBSERVABLE
    } else {
        FREE
    };
    let mut canvas = Canvas::new(gt.grid, background);
    canvas.paint_cells(|i| {
        if gt.obstacle_column(i) {
            Some(OCCUPIED)
        } else if gt.reachable(i) {
            Some(palette::REACHABLE_FLOOR)
        } else if observable.is_some_and(|o| o.column_observable(gt, i)) {
            Some(palette::OBSERVABLE_UNREACHABLE)
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
