//! `tensorscout scene generate|import|info|render`.

use super::{
    check_distinct, check_output, emit, note, parse_spawn, progress, scene_inputs, ConfigArgs,
};
use anyhow::Result;
use clap::{Args, Subcommand};
use std::path::PathBuf;
use tensorscout::eval::{self, GroundTruth};
use tensorscout::scene::{self, generate};
use tensorscout::sim::World;
use tensorscout::{render, Pose2};

#[derive(Subcommand)]
pub enum SceneCommand {
    /// Generate a furnished indoor scene and write it as OBJ (the same seed gives the same scene).
    #[command(
        after_help = "Example:\n  tensorscout scene generate --style office --seed 4 --area 300 -o office.obj"
    )]
    Generate {
        /// Layout style: apartment, office, corridor or warehouse.
        #[arg(long, value_parser = parse_style)]
        style: generate::Style,
        /// Seed of the layout.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Floor area, m² (20–40000).
        #[arg(long, default_value_t = 100.0, allow_negative_numbers = true)]
        area: f64,
        /// Output OBJ path.
        #[arg(short, long, value_name = "PATH")]
        output: PathBuf,
        /// Overwrite the output if it exists.
        #[arg(long)]
        force: bool,
    },
    /// Import a ROS map (`.yaml` + PGM) or a HouseExpo plan (`.json`) as an extruded OBJ mesh.
    #[command(
        after_help = "Unknown cells of a ROS map are solid (the scene stays closed) unless \
`--set scene.unknown_as_free=true`. Walls are `scene.wall_height_m` (2.5 m) high.\n\nExample:\n  \
tensorscout scene import map.yaml -o house.obj"
    )]
    Import {
        /// ROS map `.yaml` or HouseExpo `.json`.
        input: PathBuf,
        /// Output OBJ path.
        #[arg(short, long, value_name = "PATH")]
        output: PathBuf,
        #[command(flatten)]
        config: ConfigArgs,
        /// Overwrite the output if it exists.
        #[arg(long)]
        force: bool,
    },
    /// Print a scene's bounds, triangle count, floor height, reachable area, observable volume and
    /// spawn.
    #[command(after_help = "Example:\n  tensorscout scene info scenes/apartment_small.obj --json")]
    Info(InfoArgs),
    /// Draw a scene's ground truth as PNG: obstacles, reachable floor, space observable from it but
    /// not reachable, never-observable space, and the spawn.
    #[command(
        after_help = "Example:\n  tensorscout scene render scenes/apartment_small.obj -o apartment.png"
    )]
    Render {
        #[command(flatten)]
        scene: SceneArgs,
        /// Output PNG path.
        #[arg(short, long, value_name = "PATH")]
        output: PathBuf,
        /// Overwrite the output if it exists.
        #[arg(long)]
        force: bool,
    },
}

/// A scene and the settings that shape its ground truth.
#[derive(Args)]
pub struct SceneArgs {
    /// Scene file: OBJ, PLY, glTF (`.gltf`/`.glb`), ROS map `.yaml` or HouseExpo `.json`.
    scene: PathBuf,
    /// Start pose `X,Y[,YAW]` (default: the scene's own, else automatic).
    #[arg(long, value_name = "X,Y[,YAW]", value_parser = parse_spawn, allow_hyphen_values = true)]
    spawn: Option<Pose2>,
    #[command(flatten)]
    config: ConfigArgs,
}

#[derive(Args)]
pub struct InfoArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

impl SceneArgs {
    /// The scene, its ground truth and what can be observed in it (through the user's cache).
    fn load(&self) -> Result<(scene::Scene, World)> {
        let cfg = self.config.load()?;
        let scene = scene::load(&self.scene, &cfg.scene)?;
        let cache = progress::user_cache(std::io::IsTerminal::is_terminal(&std::io::stderr()));
        let world = World::with_cache(&scene, &cfg, self.spawn, &cache)?;
        if let Some(w) = world.observable_source.warning() {
            note!("{w}");
        }
        warn_scene(&scene, &world.ground_truth);
        Ok((scene, world))
    }
}

pub fn run(cmd: SceneCommand) -> Result<()> {
    match cmd {
        SceneCommand::Generate {
            style,
            seed,
            area,
            output,
            force,
        } => {
            check_output(&output, force, Some("obj"))?;
            let bar = progress::bar(
                std::io::IsTerminal::is_terminal(&std::io::stderr()),
                "rooms furnished",
            );
            let generated =
                generate::generate_with_progress(style, seed, area, &mut |done, rooms| {
                    bar.set_length(rooms as u64);
                    bar.set_position(done as u64);
                });
            bar.finish_and_clear();
            let generated = generated?;
            let comments = generated.header();
            scene::write_obj(&generated.mesh, Some(generated.spawn), &comments, &output)?;
            note!(
                "wrote {} ({} triangles, {} rooms)",
                output.display(),
                generated.mesh.triangles.len(),
                generated.rooms.len()
            );
            Ok(())
        }
        SceneCommand::Import {
            input,
            output,
            config,
            force,
        } => {
            check_output(&output, force, Some("obj"))?;
            check_distinct(&[("-o", &output)], &[("the input", &input)])?;
            let cfg = config.load()?;
            let scene = scene::load(&input, &cfg.scene)?;
            check_distinct(&[("-o", &output)], &scene_inputs(&scene, &config))?;
            let gt = eval::build_ground_truth(&scene, None, &cfg)?;
            warn_scene(&scene, &gt);
            let comments = vec![format!(
                "imported from {} ({}) by tensorscout {}",
                input.display(),
                scene.source,
                tensorscout::VERSION
            )];
            scene::write_obj(&scene.mesh, Some(gt.spawn), &comments, &output)?;
            note!(
                "wrote {} ({} triangles)",
                output.display(),
                scene.mesh.triangles.len()
            );
            Ok(())
        }
        SceneCommand::Info(args) => {
            let (scene, world) = args.scene.load()?;
            let mut info = eval::info(&scene, &world.ground_truth);
            info.observable_volume_m3 = world.observable.volume_m3();
            info.observable_surface_voxels = world.observable.surface_voxels().len();
            info.observable_positions = world.observable.positions();
            if args.json {
                emit(&format!("{}\n", serde_json::to_string_pretty(&info)?))
            } else {
                emit(&info_text(&info))
            }
        }
        SceneCommand::Render {
            scene,
            output,
            force,
        } => {
            check_output(&output, force, Some("png"))?;
            check_distinct(&[("-o", &output)], &[("the scene", &scene.scene)])?;
            let (loaded, world) = scene.load()?;
            check_distinct(&[("-o", &output)], &scene_inputs(&loaded, &scene.config))?;
            render::draw_ground_truth(&world.ground_truth, Some(&world.observable))
                .save(&output)?;
            Ok(())
        }
    }
}

/// The scene's load warnings and an open-region warning, on stderr.
fn warn_scene(scene: &scene::Scene, gt: &GroundTruth) {
    for w in &scene.warnings {
        note!("warning: {w}");
    }
    if let Some(w) = scene::open_region_warning(scene, gt) {
        note!("warning: {w}");
    }
}

fn parse_style(s: &str) -> std::result::Result<generate::Style, String> {
    generate::Style::parse(s).map_err(|e| e.to_string())
}

fn info_text(i: &eval::SceneInfo) -> String {
    use std::fmt::Write as _;
    let mut o = String::new();
    let _ = writeln!(o, "scene          {} ({})", i.name, i.path);
    let _ = writeln!(o, "source         {}  hash {}", i.source, i.content_hash);
    let _ = writeln!(
        o,
        "bounds         x {:.2} .. {:.2}  y {:.2} .. {:.2}  z {:.2} .. {:.2} m",
        i.bounds_min[0],
        i.bounds_max[0],
        i.bounds_min[1],
        i.bounds_max[1],
        i.bounds_min[2],
        i.bounds_max[2]
    );
    let _ = writeln!(
        o,
        "triangles      {} ({} vertices)",
        i.triangles, i.vertices
    );
    let _ = writeln!(o, "floor height   {:.3} m (moved to z = 0)", i.floor_z);
    let _ = writeln!(o, "reachable      {:.1} m² of floor", i.reachable_area_m2);
    let _ = writeln!(
        o,
        "observable     {:.1} m³ in the height band ({} surface voxels; {} camera positions)",
        i.observable_volume_m3, i.observable_surface_voxels, i.observable_positions
    );
    let _ = writeln!(
        o,
        "spawn          ({:.2}, {:.2}, yaw {:.2}){}",
        i.spawn.x,
        i.spawn.y,
        i.spawn.yaw,
        if i.spawn_from_file {
            ""
        } else {
            " (automatic or given)"
        }
    );
    o
}
