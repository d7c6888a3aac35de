//! Argument definitions and dispatch, one file per subcommand.

mod bench;
mod explore;
mod field;
mod replay;
mod scene;

use anyhow::Result;
use clap::{Args, Parser, Subcommand};
use std::path::{Path, PathBuf};
use tensorscout::{Config, Error, Pose2};

#[derive(Parser)]
#[command(
    name = "tensorscout",
    version,
    about = "Headless simulator and benchmark for autonomous exploration of indoor scenes",
    long_about = "Headless simulator and benchmark for autonomous exploration of indoor scenes by a ground \
robot with one forward-facing depth camera.\n\nExample:\n  tensorscout explore --scene scenes/apartment_small.obj --planner thp --json"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Explore one scene with one planner and report the metrics.
    #[command(
        after_help = "Examples:\n  tensorscout explore --scene scenes/apartment_small.obj --planner thp\n  \
tensorscout explore --scene scenes/office_large.obj --planner thp --seed 3 --json --png run.png\n  \
tensorscout explore --scene map.yaml --set robot.max_speed_mps=0.5 --spawn 1.0,2.0,1.57"
    )]
    Explore(explore::ExploreArgs),
    /// Generate, import, inspect or draw scenes.
    #[command(subcommand)]
    Scene(scene::SceneCommand),
    /// Inspect the tensor field of a scene and its topology (degenerate points, separatrices).
    #[command(
        after_help = "Examples:\n  tensorscout field --scene scenes/office_large.obj --png field.png\n  \
tensorscout field --scene scenes/small_house.obj --json --reference"
    )]
    Field(field::FieldArgs),
    /// Benchmark planners on many scenes and seeds in parallel; tables, summary and plots.
    #[command(
        after_help = "Examples:\n  tensorscout bench --scenes scenes/ --planners greedy --seeds 3 --out bench_out\n  \
tensorscout bench --scenes scenes/ --seeds 3 --out shard1 --shard 1/2\n  \
tensorscout bench merge shard1 shard2 --out bench_out"
    )]
    Bench(bench::BenchArgs),
    /// Summarise, verify or draw a run log written by `explore --log`.
    #[command(
        after_help = "Examples:\n  tensorscout replay run.mcap --json\n  tensorscout replay run.mcap --verify"
    )]
    Replay(replay::ReplayArgs),
    /// Print configuration.
    #[command(subcommand)]
    Config(ConfigCommand),
}

#[derive(Subcommand)]
enum ConfigCommand {
    /// Print the whole default config as TOML, with a comment on every key.
    #[command(after_help = "Example:\n  tensorscout config default > my.toml")]
    Default,
}

/// Config flags shared by every command that reads a config.
#[derive(Args, Clone, Default)]
pub struct ConfigArgs {
    /// TOML config file; keys not in it keep their defaults (see `tensorscout config default`).
    #[arg(long, value_name = "PATH")]
    config: Option<PathBuf>,
    /// Override one config key, e.g. `--set map.voxel_m=0.05` (repeatable, dotted keys).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// The mesh is y-up (as many modelling tools write it): rotate it to z-up on load
    /// (the same as `--set scene.y_up=true`).
    #[arg(long)]
    y_up: bool,
}

impl ConfigArgs {
    fn load(&self) -> tensorscout::Result<Config> {
        let mut cfg = Config::load(self.config.as_deref(), &self.set)?;
        cfg.scene.y_up |= self.y_up;
        Ok(cfg)
    }
}

pub fn dispatch(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Explore(args) => explore::run(args),
        Command::Scene(cmd) => scene::run(cmd),
        Command::Field(args) => field::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Replay(args) => replay::run(args),
        Command::Config(ConfigCommand::Default) => {
            print!("{}", tensorscout::config::DEFAULT_TOML);
            Ok(())
        }
    }
}

/// Where `explore` starts: `random` or a pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StartArg {
    Random,
    Pose(Pose2),
}

/// Parses `random` or `X,Y[,YAW]`.
fn parse_start(s: &str) -> std::result::Result<StartArg, String> {
    if s.trim() == "random" {
        Ok(StartArg::Random)
    } else {
        parse_spawn(s)
            .map(StartArg::Pose)
            .map_err(|e| format!("{e} (or `random`)"))
    }
}

/// Parses `X,Y[,YAW]` (metres, metres, radians).
fn parse_spawn(s: &str) -> std::result::Result<Pose2, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if !(2..=3).contains(&parts.len()) {
        return Err(format!("expected X,Y or X,Y,YAW, got `{s}`"));
    }
    let mut v = [0.0; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        *slot = p
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("`{p}` is not a finite number in `{s}`"))?;
    }
    Ok(Pose2::new(v[0], v[1], v[2]))
}

/// Refuses an output path whose folder is missing, or an existing file unless `force`; checked
/// before any work so that a long run never ends in a failed write.
fn check_output(path: &Path, force: bool) -> tensorscout::Result<()> {
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("output folder {} does not exist", parent.display()),
            ),
        ));
    }
    if path.exists() && !force {
        return Err(Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                "file exists; pass --force to overwrite it",
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spawn_parsing() {
        assert_eq!(parse_spawn("1,2").unwrap(), Pose2::new(1.0, 2.0, 0.0));
        assert_eq!(
            parse_spawn(" 1.5, -2 ,0.5").unwrap(),
            Pose2::new(1.5, -2.0, 0.5)
        );
        assert!(parse_spawn("1").is_err());
        assert!(parse_spawn("1,NaN").is_err());
        assert!(parse_spawn("1,2,3,4").is_err());
        assert_eq!(parse_start("random").unwrap(), StartArg::Random);
        assert_eq!(
            parse_start("1,2").unwrap(),
            StartArg::Pose(Pose2::new(1.0, 2.0, 0.0))
        );
        assert_eq!(
            parse_start("rand").unwrap_err(),
            "expected X,Y or X,Y,YAW, got `rand` (or `random`)"
        );
    }
}
