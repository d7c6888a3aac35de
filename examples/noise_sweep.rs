//! Summarises a noise sweep: bench folders of the same scenes, seeds and planners, one per noise
//! level, into a Markdown table (per level and planner: completeness, path length, collisions,
//! stuck runs, map precision and recall, ATE) and one PNG of completeness and collisions against
//! the noise level.
//!
//! ```text
//! cargo run --release --example noise_sweep -- OUT.png off=DIR kinect=DIR realsense=DIR …
//! ```
//!
//! Means with the half-width of a normal 95 % interval (1.96 σ/√n) over the runs that finished
//! without an error; failed rows are counted apart.

use plotters::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use tensorscout::bench::SERIES_COLOURS;
use tensorscout::sim::RunResult;

/// Mean and 95 % half-width of `v` (0 for fewer than two values).
fn mean_ci(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    if v.is_empty() {
        return (f64::NAN, 0.0);
    }
    let mean = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (mean, 0.0);
    }
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, 1.96 * (var / n).sqrt())
}

/// The results of one bench folder, and how many of its rows failed.
fn read(dir: &Path) -> (Vec<RunResult>, usize) {
    let path = dir.join("results.jsonl");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut ok = Vec::new();
    let mut failed = 0;
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let row: serde_json::Value = serde_json::from_str(line).expect("a JSON row");
        match row
            .get("result")
            .cloned()
            .map(serde_json::from_value::<RunResult>)
        {
            Some(Ok(r)) if r.termination != tensorscout::sim::Termination::Error => ok.push(r),
            _ => failed += 1,
        }
    }
    (ok, failed)
}

struct Cell {
    runs: usize,
    completeness: (f64, f64),
    path: (f64, f64),
    collisions: (f64, f64),
    collided_runs: usize,
    stuck: usize,
    precision: (f64, f64),
    recall: (f64, f64),
    free_occupied: (f64, f64),
    ate: (f64, f64),
}

fn cell(runs: &[&RunResult]) -> Cell {
    let col = |f: &dyn Fn(&RunResult) -> Option<f64>| -> (f64, f64) {
        let v: Vec<f64> = runs.iter().filter_map(|r| f(r)).collect();
        mean_ci(&v)
    };
    Cell {
        runs: runs.len(),
        completeness: col(&|r| Some(r.completeness)),
        path: col(&|r| Some(r.path_length_m)),
        collisions: col(&|r| Some(r.collisions as f64)),
        collided_runs: runs.iter().filter(|r| r.collisions > 0).count(),
        stuck: runs
            .iter()
            .filter(|r| r.termination == tensorscout::sim::Termination::Stuck)
            .count(),
        precision: col(&|r| r.map_precision),
        recall: col(&|r| r.map_recall),
        free_occupied: col(&|r| r.free_but_occupied),
        ate: col(&|r| r.ate_rmse_m),
    }
}

fn fmt(v: (f64, f64), digits: usize) -> String {
    if v.0.is_nan() {
        "–".into()
    } else {
        format!("{:.*} ± {:.*}", digits, v.0, digits, v.1)
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: noise_sweep OUT.png LABEL=BENCH_DIR ...");
        std::process::exit(2);
    }
    let out = PathBuf::from(&args[0]);
    let mut levels: Vec<(String, Vec<RunResult>, usize)> = Vec::new();
    for a in &args[1..] {
        let (label, dir) = a.split_once('=').unwrap_or_else(|| {
            eprintln!("expected LABEL=BENCH_DIR, got {a}");
            std::process::exit(2);
        });
        let (runs, failed) = read(Path::new(dir));
        levels.push((label.to_string(), runs, failed));
    }
    let planners: Vec<String> = {
        let mut p: Vec<String> = levels
            .iter()
            .flat_map(|(_, r, _)| r.iter().map(|r| r.planner.clone()))
            .collect();
        p.sort();
        p.dedup();
        p
    };
    println!("| noise | planner | runs | completeness | path L (m) | collisions / run | runs with collisions | stuck | map precision | map recall | known free but occupied | ATE RMSE (m) |");
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut cells: BTreeMap<(usize, String), Cell> = BTreeMap::new();
    for (k, (label, runs, failed)) in levels.iter().enumerate() {
        for p in &planners {
            let rs: Vec<&RunResult> = runs.iter().filter(|r| &r.planner == p).collect();
            if rs.is_empty() {
                continue;
            }
            let c = cell(&rs);
            println!(
                "| {label} | {p} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                c.runs,
                fmt(c.completeness, 3),
                fmt(c.path, 1),
                fmt(c.collisions, 2),
                c.collided_runs,
                c.stuck,
                fmt(c.precision, 3),
                fmt(c.recall, 3),
                fmt((c.free_occupied.0 * 100.0, c.free_occupied.1 * 100.0), 2)
                    .replace(" ±", " % ±")
                    + if c.free_occupied.0.is_nan() { "" } else { " %" },
                fmt(c.ate, 3),
            );
            cells.insert((k, p.clone()), c);
        }
        if *failed > 0 {
            println!("| {label} | (failed rows) | {failed} | | | | | | | | | |");
        }
    }
    draw(
        &out,
        &levels.iter().map(|l| l.0.clone()).collect::<Vec<_>>(),
        &planners,
        &cells,
    )
    .unwrap_or_else(|e| {
        eprintln!("{}: {e}", out.display());
        std::process::exit(1);
    });
}

/// Two panels: completeness and collisions per run against the noise level, a line per planner
/// with 95 % bars.
fn draw(
    out: &Path,
    levels: &[String],
    planners: &[String],
    cells: &BTreeMap<(usize, String), Cell>,
) -> Result<(), Box<dyn std::error::Error>> {
    tensorscout::render::register_font();
    let (w, h) = (1400u32, 560u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let panels = root.split_evenly((1, 2));
        type Pick = fn(&Cell) -> (f64, f64);
        let metrics: [(&str, Pick); 2] = [
            ("completeness", |c| c.completeness),
            ("collisions per run", |c| c.collisions),
        ];
        let n = levels.len();
        for (panel, (name, pick)) in panels.iter().zip(metrics) {
            let hi = cells
                .values()
                .map(|c| pick(c).0 + pick(c).1)
                .fold(0.0f64, f64::max);
            let (y0, y1) = if name == "completeness" {
                let lo = cells
                    .values()
                    .map(|c| pick(c).0 - pick(c).1)
                    .fold(1.0f64, f64::min);
                ((lo - 0.05).max(0.0), 1.0)
            } else {
                (0.0, (hi * 1.15).max(1.0))
            };
            let mut chart = ChartBuilder::on(panel)
                .caption(format!("{name} against noise"), ("sans-serif", 26))
                .margin(16)
                .x_label_area_size(50)
                .y_label_area_size(70)
                .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), y0..y1)?;
            chart
                .configure_mesh()
                .x_labels(n)
                .x_label_formatter(&|x| {
                    let k = x.round();
                    if (x - k).abs() < 1e-6 && k >= 0.0 && (k as usize) < n {
                        levels[k as usize].clone()
                    } else {
                        String::new()
                    }
                })
                .x_desc("noise level")
                .y_desc(name)
                .label_style(("sans-serif", 18))
                .axis_desc_style(("sans-serif", 20))
                .draw()?;
            for (i, p) in planners.iter().enumerate() {
                let colour = SERIES_COLOURS[i % SERIES_COLOURS.len()];
                // Planners side by side at each level, so that their bars do not hide each other.
                let dx = (i as f64 - (planners.len() as f64 - 1.0) / 2.0) * 0.06;
                let pts: Vec<(f64, (f64, f64))> = (0..n)
                    .filter_map(|k| cells.get(&(k, p.clone())).map(|c| (k as f64 + dx, pick(c))))
                    .collect();
                chart
                    .draw_series(LineSeries::new(
                        pts.iter().map(|(x, v)| (*x, v.0)),
                        colour.stroke_width(3),
                    ))?
                    .label(p.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(3))
                    });
                chart.draw_series(pts.iter().map(|(x, v)| {
                    PathElement::new(
                        vec![(*x, v.0 - v.1), (*x, v.0 + v.1)],
                        colour.stroke_width(2),
                    )
                }))?;
                chart.draw_series(
                    pts.iter()
                        .map(|(x, v)| Circle::new((*x, v.0), 5, colour.filled())),
                )?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::MiddleLeft)
                .label_font(("sans-serif", 18))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()?;
        }
        root.present()?;
    }
    image::RgbImage::from_raw(w, h, buf)
        .ok_or("bad image buffer")?
        .save(out)?;
    Ok(())
}
