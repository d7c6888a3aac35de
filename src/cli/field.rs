//! `tensorscout field`: the tensor field of a scene and its topology, as if fully observed.

use super::{check_distinct, check_output, emit, note, scene_inputs, ConfigArgs};
use anyhow::Result;
use clap::{Args, ValueEnum};
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;
use tensorscout::field::{self, ControlCounts, DegenerateKind, TensorField, UpdateStats};
use tensorscout::render::draw_field;
use tensorscout::scene;
use tensorscout::{render, Pose2};

/// What the field is built from.
#[derive(Clone, Copy, ValueEnum)]
pub enum Known {
    /// The whole ground truth, as if the scene had been fully observed.
    Full,
}

#[derive(Args)]
pub struct FieldArgs {
    /// Scene file: OBJ, PLY, glTF (`.gltf`/`.glb`), ROS map `.yaml` or HouseExpo `.json`.
    #[arg(long, value_name = "PATH")]
    scene: PathBuf,
    /// What is known of the scene.
    #[arg(long, value_enum, default_value = "full")]
    known: Known,
    /// Start pose `X,Y[,YAW]`; it picks the explorable region (default: the scene's own).
    #[arg(long, value_name = "X,Y[,YAW]", value_parser = super::parse_spawn, allow_hyphen_values = true)]
    spawn: Option<Pose2>,
    #[command(flatten)]
    config: ConfigArgs,
    /// Draw the field (glyphs coloured by anisotropy), wedges, trisectors and separatrices.
    #[arg(long, value_name = "PATH")]
    png: Option<PathBuf>,
    /// Print the counts, timings and degenerate points as one JSON object.
    #[arg(long)]
    json: bool,
    /// Also run the brute-force f64 evaluator and compare orientations and speed.
    #[arg(long)]
    reference: bool,
    /// Overwrite the PNG if it exists.
    #[arg(long)]
    force: bool,
}

pub fn run(args: FieldArgs) -> Result<()> {
    let cfg = args.config.load()?;
    if let Some(png) = &args.png {
        check_output(png, args.force, Some("png"))?;
        check_distinct(&[("--png", png)], &[("--scene", &args.scene)])?;
    }
    let scene = scene::load(&args.scene, &cfg.scene)?;
    if let Some(png) = &args.png {
        check_distinct(&[("--png", png)], &scene_inputs(&scene, &args.config))?;
    }
    for w in &scene.warnings {
        note!("warning: {w}");
    }
    let gt = tensorscout::eval::build_ground_truth(&scene, args.spawn, &cfg)?;
    let Known::Full = args.known;
    let surface = gt.surface_columns();
    let t = Instant::now();
    let (mut tensor_field, stats) =
        field::full_field(&gt.grid, &surface, gt.obstacle_columns(), &cfg.field)?;
    let report = FieldReport::of(&tensor_field, &stats, t.elapsed().as_secs_f64() * 1e3);
    let comparison = args
        .reference
        .then(|| field::max_orientation_difference_vs_reference(&mut tensor_field));
    if let Some(png) = &args.png {
        let mut canvas = render::draw_ground_truth(&gt, None);
        let scale = canvas.scale;
        // Glyphs only over the explorable region (known free space of the ground truth).
        draw_field(&mut canvas.image, &tensor_field, scale, 4, &|i| {
            gt.in_region(i) && !gt.obstacle_column(i)
        });
        use tensorscout::render::field as d;
        let graph = tensor_field.graph();
        canvas.note(d::GLYPH);
        for n in &graph.nodes {
            canvas.note(match n.kind {
                DegenerateKind::Wedge => d::WEDGE,
                DegenerateKind::Trisector => d::TRISECTOR,
                DegenerateKind::Other => d::OTHER,
            });
        }
        if !graph.separatrices.is_empty() {
            canvas.note(d::SEPARATRIX);
        }
        if graph
            .edges
            .iter()
            .any(|e| e.kind == field::EdgeKind::ShortestPath)
        {
            canvas.note(d::PAIRING);
        }
        canvas.save(png)?;
    }
    if args.json {
        let mut value = serde_json::to_value(&report)?;
        value["scene"] = scene.name.clone().into();
        if let Some(c) = &comparison {
            value["reference"] = serde_json::to_value(c)?;
        }
        emit(&format!("{}\n", serde_json::to_string(&value)?))?;
    } else {
        use std::fmt::Write as _;
        let mut o = String::new();
        let _ = writeln!(o, "scene          {}", scene.name);
        let _ = writeln!(o, "constraints    {}", report.constraints);
        let _ = writeln!(
            o,
            "degenerate     {} wedges, {} trisectors, {} other",
            report.wedges, report.trisectors, report.other_points
        );
        let _ = writeln!(
            o,
            "topology       {} separatrices, {} graph edges",
            report.separatrices, report.graph_edges
        );
        let t = &report.timings_ms;
        let _ = writeln!(
            o,
            "timings        sampling {:.1} ms, field {:.1} ms, topology {:.1} ms, total {:.1} ms",
            t.sampling, t.field, t.topology, t.total
        );
        if let Some(c) = &comparison {
            let _ = writeln!(
            o,

                "reference      max orientation difference {:.2e} rad; reference {:.1} ms vs fast {:.1} ms ({:.0}×)",
                c.max_orientation_difference_rad, c.reference_ms, c.fast_full_ms, c.speed_ratio
            );
        }
        emit(&o)?;
    }
    Ok(())
}

/// One degenerate point in a report.
#[derive(Clone, Debug, Serialize)]
pub struct PointReport {
    pub id: u64,
    pub x: f64,
    pub y: f64,
    #[serde(rename = "type")]
    pub kind: DegenerateKind,
}

/// Timings of the field's one update, milliseconds.
#[derive(Clone, Debug, Serialize)]
pub struct ReportTimings {
    pub sampling: f64,
    pub field: f64,
    pub topology: f64,
    pub total: f64,
}

/// What `tensorscout field --json` prints.
#[derive(Clone, Debug, Serialize)]
pub struct FieldReport {
    pub constraints: usize,
    pub wedges: usize,
    pub trisectors: usize,
    pub other_points: usize,
    pub graph_edges: usize,
    pub separatrices: usize,
    pub control: ControlCounts,
    pub timings_ms: ReportTimings,
    pub points: Vec<PointReport>,
}

impl FieldReport {
    /// The report of a field after its last update.
    pub fn of(field: &TensorField, stats: &UpdateStats, total_ms: f64) -> Self {
        let graph = field.graph();
        let (wedges, trisectors) = graph.counts();
        FieldReport {
            constraints: field.surface_constraint_count(),
            wedges,
            trisectors,
            other_points: graph.nodes.len() - wedges - trisectors,
            graph_edges: graph.edges.len(),
            separatrices: graph.separatrices.len(),
            control: field.control_counts(),
            timings_ms: ReportTimings {
                sampling: stats.sampling_ms,
                field: stats.field_ms,
                topology: stats.topology_ms,
                total: total_ms,
            },
            points: graph
                .nodes
                .iter()
                .map(|n| PointReport {
                    id: n.id,
                    x: n.x,
                    y: n.y,
                    kind: n.kind,
                })
                .collect(),
        }
    }
}
