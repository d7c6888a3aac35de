//! `tensorscout scene generate|import|info|render`.

use super::{check_output, parse_spawn, ConfigArgs};
use anyhow::Result;
use clap::{Args, Subcommand};
use std::path::PathBuf;
use tensorscout::scene::{self, generate, GroundTruth};
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
        /// Floor area, m² (20–2000).
        #[arg(long, default_value_t = 100.0)]
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
    /// Print a scene's bounds, triangle count, floor height, explorable area and spawn.
    #[command(after_help = "Example:\n  tensorscout scene info scenes/apartment_small.obj --json")]
    Info(InfoArgs),
    /// Draw a scene's ground truth (obstacles, explorable region, spawn) as PNG.
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
    #[arg(long, value_name = "X,Y[,YAW]", value_parser = parse_spawn)]
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
    fn load(&self) -> Result<(scene::Scene, GroundTruth)> {
        let cfg = self.config.load()?;
        let scene = scene::load(&self.scene, &cfg.scene)?;
        let gt = GroundTruth::build(&scene.mesh, self.spawn.or(scene.spawn), &cfg)?;
        Ok((scene, gt))
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
            check_output(&output, force)?;
            let generated = generate::generate(style, seed, area)?;
            let comments = generated.header();
            scene::write_obj(&generated.mesh, Some(generated.spawn), &comments, &output)?;
            eprintln!(
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
            check_output(&output, force)?;
            let cfg = config.load()?;
            let scene = scene::load(&input, &cfg.scene)?;
            let gt = GroundTruth::build(&scene.mesh, scene.spawn, &cfg)?;
            let comments = vec![format!(
                "imported from {} ({}) by tensorscout {}",
                input.display(),
                scene.source,
                tensorscout::VERSION
            )];
            scene::write_obj(&scene.mesh, Some(gt.spawn), &comments, &output)?;
            eprintln!(
                "wrote {} ({} triangles)",
                output.display(),
                scene.mesh.triangles.len()
            );
            Ok(())
        }
        SceneCommand::Info(args) => {
            let (scene, gt) = args.scene.load()?;
            let info = scene::info(&scene, &gt);
            if args.json {
                println!("{}", serde_json::to_string_pretty(&info)?);
            } else {
                print_info(&info);
            }
            Ok(())
        }
        SceneCommand::Render {
            scene,
            output,
            force,
        } => {
            check_output(&output, force)?;
            let (_, gt) = scene.load()?;
            render::draw_ground_truth(&gt).save(&output)?;
            Ok(())
        }
    }
}

fn parse_style(s: &str) -> std::result::Result<generate::Style, String> {
    generate::Style::parse(s).map_err(|e| e.to_string())
}

fn print_info(i: &scene::ground_truth::SceneInfo) {
    println!("scene          {} ({})", i.name, i.path);
    println!("source         {}  hash {}", i.source, i.content_hash);
    println!(
        "bounds         x {:.2} .. {:.2}  y {:.2} .. {:.2}  z {:.2} .. {:.2} m",
        i.bounds_min[0],
        i.bounds_max[0],
        i.bounds_min[1],
        i.bounds_max[1],
        i.bounds_min[2],
        i.bounds_max[2]
    );
    println!("triangles      {} ({} vertices)", i.triangles, i.vertices);
    println!("floor height   {:.3} m (moved to z = 0)", i.floor_z);
    println!(
        "explorable     {:.1} m² ({} cells), {:.1} m³ in the height band",
        i.explorable_area_m2, i.region_cells, i.explorable_volume_m3
    );
    println!("surface voxels {}", i.surface_voxels);
    println!(
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
}
