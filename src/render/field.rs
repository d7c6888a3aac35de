//! Pictures of the field: line glyphs coloured by coherence, separatrices and edges, degenerate points.

use crate::field::{DegenerateKind, TensorField};
use image::{Rgb, RgbImage};
use nalgebra::Point2;

pub use super::palette::{
    fade, GLYPH, OTHER_DEGENERATE as OTHER, SEPARATRIX, TOPOLOGY_EDGE as PAIRING, TRISECTOR, WEDGE,
};

/// Draws over `img`, which must be `nx·scale × ny·scale` pixels of the field's grid with +y up
/// (row 0 at the grid's top): a glyph every `glyph_every` cells where `known(cell index)` holds
/// (the palette's glyph colour where the field is coherent, fading to white where it is nearly
/// isotropic), separatrices, shortest-path pairings, wedges and trisectors in their palette colours.
pub fn draw_field(
    img: &mut RgbImage,
    field: &TensorField,
    scale: u32,
    glyph_every: usize,
    known: &dyn Fn(usize) -> bool,
) {
    let g = *field.grid();
    let scale = scale.max(1);
    if img.width() != g.nx as u32 * scale || img.height() != g.ny as u32 * scale {
        return;
    }
    let to_px = |p: Point2<f64>| -> (f64, f64) {
        let fx = (p.x - g.origin_x) / g.res * scale as f64;
        let fy = (g.ny as f64) * scale as f64 - (p.y - g.origin_y) / g.res * scale as f64;
        (fx, fy)
    };
    let step = glyph_every.max(1);
    let half = 0.4 * step as f64 * g.res;
    for y in (step / 2..g.ny).step_by(step) {
        for x in (step / 2..g.nx).step_by(step) {
            let c = crate::grid::Cell::new(x as i32, y as i32);
            let s = field.field().at_index(g.index(c));
            if s.weight <= 0.0 || !known(g.index(c)) {
                continue;
            }
            let shade = fade(GLYPH, 0.8 * (1.0 - s.coherence().clamp(0.0, 1.0)));
            let e = s.major() * half;
            let p = g.center(c);
            line(img, to_px(p - e), to_px(p + e), shade);
        }
    }
    let graph = field.graph();
    for sep in &graph.separatrices {
        polyline(img, &sep.polyline, &to_px, SEPARATRIX);
    }
    for e in &graph.edges {
        if e.kind == crate::field::EdgeKind::ShortestPath {
            polyline(img, &e.polyline, &to_px, PAIRING);
        }
    }
    for n in &graph.nodes {
        let colour = match n.kind {
            DegenerateKind::Wedge => WEDGE,
            DegenerateKind::Trisector => TRISECTOR,
            DegenerateKind::Other => OTHER,
        };
        let (cx, cy) = to_px(n.pos());
        let r = (2 * scale) as i64 + 1;
        for dy in -r..=r {
            for dx in -r..=r {
                if dx * dx + dy * dy <= r * r {
                    put(img, cx as i64 + dx, cy as i64 + dy, colour);
                }
            }
        }
    }
}

fn polyline(
    img: &mut RgbImage,
    pts: &[[f64; 2]],
    to_px: &dyn Fn(Point2<f64>) -> (f64, f64),
    c: Rgb<u8>,
) {
    for w in pts.windows(2) {
        line(
            img,
            to_px(Point2::new(w[0][0], w[0][1])),
            to_px(Point2::new(w[1][0], w[1][1])),
            c,
        );
    }
}

fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, c);
    }
}

fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), c: Rgb<u8>) {
    let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
    for k in 0..=n {
        let t = k as f64 / n as f64;
        put(
            img,
            (a.0 + (b.0 - a.0) * t).floor() as i64,
            (a.1 + (b.1 - a.1) * t).floor() as i64,
            c,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::field::synth;

    /// The office layout's field, drawn: its degenerate points and its separatrices or pairings show
    /// in their palette colours.
    #[test]
    fn drawing_the_office_field_shows_points_and_lines() {
        let l = synth::office(0.1);
        let (f, _) =
            crate::field::full_field(&l.grid, &l.surface, &l.surface, &Config::default().field)
                .unwrap();
        let mut img = RgbImage::new(l.grid.nx as u32 * 2, l.grid.ny as u32 * 2);
        draw_field(&mut img, &f, 2, 4, &|_| true);
        assert!(img.pixels().any(|p| *p == WEDGE || *p == TRISECTOR));
        assert!(img.pixels().any(|p| *p == SEPARATRIX || *p == PAIRING));
    }
}
