//! `plots/`: per scene, ε against path length (THP Fig. 6) and completeness against simulated time,
//! every planner on one plot: its mean curve over seeds, with a band from the lowest to the highest
//! seed, one colour and legend entry per planner; on the ε plots, the scene's observable volume as
//! a ceiling line (no planner can pass it). A run that ended keeps its final value to the plot's
//! right edge, so runs of different lengths average over the same abscissae.
//!
//! Drawn by plotters into an RGB buffer (saved as PNG with `image`), text with the embedded DejaVu
//! Sans (assets/fonts), so the output does not depend on the machine's fonts; and the same plot as
//! SVG beside each PNG (plotters' SVG backend), sized so that its text stays legible at a paper's
//! column width.
//! Not drawn yet: TSP time per planning step (THP Fig. 8): runs do not record TSP timings so far.

use super::store::{BenchRow, RunStatus};
use super::summary::{run_labeller, scene_name};
use crate::sim::CurveSample;
use crate::{Error, Result};
use plotters::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

/// The PNG's size, pixels.
const SIZE: (u32, u32) = (900, 600);
/// The SVG's size, user units (px): smaller than the PNG so that, scaled to a paper's column width
/// (about 252 pt, 3.5 in), its smallest text is still above 8 pt.
const SVG_SIZE: (u32, u32) = (480, 340);
/// Series colours of every plot (Okabe–Ito, readable by colour-blind readers): planners by name
/// order here, and the examples' plots.
pub const SERIES_COLOURS: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
];

/// Text sizes of one plot, pixels: title, axis descriptions, tick labels, legend.
#[derive(Clone, Copy)]
struct Fonts {
    title: u32,
    axis: u32,
    ticks: u32,
    legend: u32,
}

const PNG_FONTS: Fonts = Fonts {
    title: 28,
    axis: 24,
    ticks: 20,
    legend: 20,
};
/// Plotters writes an SVG `font-size` of the requested size ÷ 1.24, so 20 → 16.1 units → 8.5 pt at
/// 252 pt column width. No title: a paper's figure has a caption instead (and the scene's name
/// would not fit at this size).
const SVG_FONTS: Fonts = Fonts {
    title: 0,
    axis: 22,
    ticks: 20,
    legend: 20,
};

/// One planner's curve over seeds, on a common abscissa: the mean and the lowest and highest seed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Band {
    pub mean: Vec<(f64, f64)>,
    pub lo: Vec<(f64, f64)>,
    pub hi: Vec<(f64, f64)>,
}

/// Samples on the common abscissa of a plot.
const BAND_SAMPLES: usize = 200;

impl Band {
    /// The band of `runs` (each a curve with non-decreasing x) over `[0, x_max]`.
    pub fn of(runs: &[Vec<(f64, f64)>], x_max: f64) -> Band {
        let mut b = Band::default();
        if runs.is_empty() {
            return b;
        }
        for k in 0..=BAND_SAMPLES {
            let x = x_max * k as f64 / BAND_SAMPLES as f64;
            let ys: Vec<f64> = runs.iter().map(|r| value_at(r, x)).collect();
            let mean = ys.iter().sum::<f64>() / ys.len() as f64;
            b.mean.push((x, mean));
            b.lo.push((x, ys.iter().copied().fold(f64::INFINITY, f64::min)));
            b.hi.push((x, ys.iter().copied().fold(f64::NEG_INFINITY, f64::max)));
        }
        b
    }
}

/// A curve's value at `x`: linear between its samples, its first value before them and its last
/// after them (a run that ended keeps what it reached).
fn value_at(curve: &[(f64, f64)], x: f64) -> f64 {
    match curve.iter().position(|p| p.0 >= x) {
        None => curve.last().map_or(0.0, |p| p.1),
        Some(0) => curve[0].1,
        Some(i) => {
            let (a, b) = (curve[i - 1], curve[i]);
            if b.0 > a.0 {
                a.1 + (x - a.0) / (b.0 - a.0) * (b.1 - a.1)
            } else {
                b.1
            }
        }
    }
}

/// The curves of one plot, per planner (name order).
type Series = BTreeMap<String, Band>;

/// A horizontal reference line and its legend label.
type Ceiling<'a> = Option<(f64, &'a str)>;

/// Draws one plot on any plotters backend (the PNG's bitmap, the SVG).
fn draw_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    s: &Series,
    ceiling: Ceiling,
    f: Fonts,
) -> std::result::Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let pts = s.values().flat_map(|b| b.hi.iter());
    let x_max = pts.clone().map(|p| p.0).fold(0.0, f64::max).max(1e-6) * 1.02;
    let y_max = pts
        .map(|p| p.1)
        .chain(ceiling.map(|c| c.0))
        .fold(0.0, f64::max)
        .max(1e-6)
        * 1.05;
    let mut builder = ChartBuilder::on(root);
    if f.title > 0 {
        builder.caption(title, ("sans-serif", f.title));
    }
    let mut chart = builder
        .margin(12)
        .x_label_area_size(f.axis * 2 + f.ticks)
        .y_label_area_size(f.axis * 2 + f.ticks * 2)
        .build_cartesian_2d(0.0..x_max, 0.0..y_max)
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_labels(6)
        .y_labels(6)
        .axis_desc_style(("sans-serif", f.axis))
        .label_style(("sans-serif", f.ticks))
        .draw()
        .map_err(|x| e(&x))?;
    for (i, (planner, band)) in s.iter().enumerate() {
        let colour = SERIES_COLOURS[i % SERIES_COLOURS.len()];
        // The band: the highest seed's curve out and the lowest one's back.
        let outline: Vec<(f64, f64)> = band
            .hi
            .iter()
            .copied()
            .chain(band.lo.iter().rev().copied())
            .collect();
        chart
            .draw_series(std::iter::once(Polygon::new(
                outline,
                colour.mix(0.2).filled(),
            )))
            .map_err(|x| e(&x))?;
        chart
            .draw_series(LineSeries::new(
                band.mean.iter().copied(),
                colour.stroke_width(2),
            ))
            .map_err(|x| e(&x))?
            .label(planner.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(3))
            });
    }
    if let Some((y, label)) = ceiling {
        chart
            .draw_series(LineSeries::new(
                [(0.0, y), (x_max, y)],
                BLACK.mix(0.6).stroke_width(1),
            ))
            .map_err(|x| e(&x))?
            .label(label)
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], BLACK.mix(0.6)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .label_font(("sans-serif", f.legend))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))
}

/// One plot: title, axis labels, series, an optional ceiling line. Writes `path` (PNG) and the same
/// plot as SVG beside it (`path` with the extension `svg`, without the title; text as SVG text in
/// the reader's sans-serif font).
pub fn line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    s: &Series,
    ceiling: Ceiling,
) -> Result<()> {
    crate::render::register_font();
    let (w, h) = SIZE;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    let draw_err = |e: &dyn std::fmt::Display| Error::Runtime(format!("{}: {e}", path.display()));
    {
        let root = BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area();
        draw_plot(&root, title, x_label, y_label, s, ceiling, PNG_FONTS)
            .map_err(|e| draw_err(&e))?;
    }
    let img = image::RgbImage::from_raw(w, h, buf)
        .ok_or_else(|| Error::Runtime(format!("{}: bad image buffer", path.display())))?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| draw_err(&e))?;
    super::store::write_atomic(path, &png)?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SVG_SIZE).into_drawing_area();
        draw_plot(&root, title, x_label, y_label, s, ceiling, SVG_FONTS)
            .map_err(|e| draw_err(&e))?;
    }
    super::store::write_atomic(&path.with_extension("svg"), svg.as_bytes())
}

/// A file-name-safe version of a scene name.
fn file_stem(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Writes both plots for every scene with at least one successful run.
pub fn write_plots(dir: &Path, rows: &[BenchRow]) -> Result<()> {
    let label = run_labeller(rows);
    let mut by_scene: BTreeMap<String, BTreeMap<String, Vec<&[CurveSample]>>> = BTreeMap::new();
    // The observable volume of each scene (the same for every start in its reachable region; the
    // largest is shown if configs differ).
    let mut ceiling: BTreeMap<String, f64> = BTreeMap::new();
    for r in rows.iter().filter(|r| r.status == RunStatus::Ok) {
        if let Some(res) = &r.result {
            let scene = scene_name(&r.key.scene_path);
            let c = ceiling.entry(scene.clone()).or_insert(0.0);
            *c = c.max(res.observable_volume_m3);
            by_scene
                .entry(scene)
                .or_default()
                .entry(label(r))
                .or_default()
                .push(&res.curve);
        }
    }
    if by_scene.is_empty() {
        return Ok(());
    }
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    for (scene, planners) in &by_scene {
        let series = |f: fn(&CurveSample) -> (f64, f64)| -> Series {
            let lines: BTreeMap<&String, Vec<Vec<(f64, f64)>>> = planners
                .iter()
                .map(|(p, curves)| {
                    (
                        p,
                        curves.iter().map(|c| c.iter().map(f).collect()).collect(),
                    )
                })
                .collect();
            let x_max = lines
                .values()
                .flatten()
                .flatten()
                .map(|p| p.0)
                .fold(0.0, f64::max);
            lines
                .into_iter()
                .map(|(p, runs)| (p.clone(), Band::of(&runs, x_max)))
                .collect()
        };
        let observable = ceiling
            .get(scene)
            .copied()
            .filter(|&v| v > 0.0)
            .map(|v| (v, "observable volume"));
        let stem = file_stem(scene);
        line_plot(
            &dir.join(format!("{stem}_volume_vs_path.png")),
            &format!("{scene}: explored volume ε against path length"),
            "path length L (m)",
            "explored volume ε (m³)",
            &series(|c| (c.path_length_m, c.explored_volume_m3)),
            observable,
        )?;
        line_plot(
            &dir.join(format!("{stem}_completeness_vs_time.png")),
            &format!("{scene}: completeness against simulated time"),
            "simulated time (s)",
            "completeness",
            &series(|c| (c.t_s, c.completeness)),
            None,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_font_parses() {
        assert!(ab_glyph_parses(crate::render::FONT));
    }

    fn ab_glyph_parses(bytes: &'static [u8]) -> bool {
        plotters::style::register_font("test-font", FontStyle::Normal, bytes).is_ok()
    }

    #[test]
    fn band_known_answer() {
        // Two runs: one reaches 2 at x = 1, the other ends at x = 0.5 with 1.5 and keeps it.
        let b = Band::of(
            &[vec![(0.0, 0.0), (1.0, 2.0)], vec![(0.0, 0.0), (0.5, 1.5)]],
            1.0,
        );
        assert_eq!(b.mean.len(), BAND_SAMPLES + 1);
        let at = |v: &[(f64, f64)], x: f64| v.iter().find(|p| (p.0 - x).abs() < 1e-9).unwrap().1;
        assert!((at(&b.mean, 0.5) - (1.0 + 1.5) / 2.0).abs() < 1e-12);
        assert!((at(&b.lo, 0.5) - 1.0).abs() < 1e-12 && (at(&b.hi, 0.5) - 1.5).abs() < 1e-12);
        assert!((at(&b.mean, 1.0) - (2.0 + 1.5) / 2.0).abs() < 1e-12);
        assert!((at(&b.lo, 1.0) - 1.5).abs() < 1e-12 && (at(&b.hi, 1.0) - 2.0).abs() < 1e-12);
        assert_eq!(Band::of(&[], 1.0), Band::default());
    }

    #[test]
    fn plot_is_a_png_with_ink() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        let mut s = Series::new();
        s.insert(
            "greedy".into(),
            Band::of(
                &[vec![(0.0, 0.0), (1.0, 2.0)], vec![(0.0, 0.0), (0.5, 1.5)]],
                1.0,
            ),
        );
        line_plot(&p, "t", "x", "y", &s, Some((2.5, "observable volume"))).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), SIZE);
        // The greedy line's colour appears somewhere.
        assert!(img.pixels().any(|px| px.0 == [0, 114, 178]));
        // The SVG beside it: the same labels and line colour, and no text below 8 pt once the
        // plot is scaled to a 252 pt (3.5 in) paper column.
        let svg = std::fs::read_to_string(dir.path().join("a.svg")).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("greedy"), "{svg}");
        assert!(svg.contains("#0072B2"), "line colour");
        let sizes: Vec<f64> = svg
            .split("font-size=\"")
            .skip(1)
            .map(|r| r.split('"').next().unwrap().parse().unwrap())
            .collect();
        assert!(!sizes.is_empty());
        let pt = |units: f64| units * 252.0 / f64::from(SVG_SIZE.0);
        assert!(sizes.iter().all(|&u| pt(u) >= 8.0), "{sizes:?}");
    }
}
