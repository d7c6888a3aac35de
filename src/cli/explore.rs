//! `tensorscout explore`: one run, its metrics, and optionally a picture.

use super::live::{self, Pacer, Rate};
use super::{
    check_distinct, check_output, emit, note, parse_start, scene_inputs, signals, ConfigArgs,
    ProfileArg, StartArg,
};
use anyhow::Result;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use nalgebra::Point2;
use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::PathBuf;
use tensorscout::log::{Recorder, RunIdentity, RunLog, Sinks};
use tensorscout::map::Map;
use tensorscout::plan::Action;
use tensorscout::plan::PlannerKind;
use tensorscout::sim::{self, Observer, RunResult, StepView, World};
use tensorscout::{render, scene, Pose2};

#[derive(Args)]
pub struct ExploreArgs {
    /// Scene to explore: OBJ, PLY or glTF (`.gltf`/`.glb`) mesh, ROS map `.yaml`, or HouseExpo `.json`.
    #[arg(long, value_name = "PATH")]
    scene: PathBuf,
    /// Exploration planner.
    #[arg(long, value_enum, default_value_t = PlannerKind::Thp)]
    planner: PlannerKind,
    #[command(flatten)]
    config: ConfigArgs,
    #[command(flatten)]
    profile: ProfileArg,
    /// Seed of the run's random stream (overrides the config's `seed`; 0 to 2^63 - 1).
    #[arg(long, value_parser = clap::value_parser!(u64).range(..=i64::MAX as u64))]
    seed: Option<u64>,
    /// Start pose `X,Y[,YAW]` in metres and radians, or `random`: a pose drawn from the seed over
    /// the reachable region, the same for every planner (default: the scene's own, else automatic).
    #[arg(long, value_name = "X,Y[,YAW]|random", value_parser = parse_start, allow_hyphen_values = true)]
    spawn: Option<StartArg>,
    /// Draw the final map, the path, the start and the end into this PNG.
    #[arg(long, value_name = "PATH")]
    png: Option<PathBuf>,
    /// Log the run to this MCAP file (opens in Foxglove; see `tensorscout replay`).
    #[arg(long, value_name = "PATH.mcap")]
    log: Option<PathBuf>,
    /// Serve the run live over the Foxglove WebSocket protocol (the log's topics and schemas) at
    /// HOST:PORT, 127.0.0.1:8765 when none is given; open it in Foxglove or Lichtblick with
    /// *Open connection → Foxglove WebSocket*. A slow client loses messages, never slows the run.
    #[arg(long, value_name = "HOST:PORT", num_args = 0..=1, default_missing_value = live::DEFAULT_ADDR)]
    live: Option<String>,
    /// With --live: simulated seconds per wall second (1 = real time, the default; 0.25 slows it
    /// down), or `max` for as fast as it goes.
    #[arg(long, value_name = "R|max", value_parser = live::parse_rate, requires = "live")]
    rate: Option<Rate>,
    /// Write the final 2D map into this existing folder as a ROS map_server pair, `map.yaml` and a
    /// trinary `map.pgm` (free 254, obstacle 0, unknown 205) at the map's resolution and origin.
    #[arg(long, value_name = "DIR")]
    map_out: Option<PathBuf>,
    /// Write the robot's trajectory to this file in TUM format (`t x y z qx qy qz qw` a line): the
    /// pose as the robot estimated it, which is the true one unless [noise.pose] or
    /// [noise.motion] is on.
    #[arg(long, value_name = "FILE")]
    trajectory: Option<PathBuf>,
    /// Write the true trajectory to this file in TUM format, to compare with --trajectory's
    /// estimate (`evo_ape tum TRUE EST`).
    #[arg(long, value_name = "FILE")]
    trajectory_true: Option<PathBuf>,
    /// Print exactly one JSON object with every metric on stdout.
    #[arg(long)]
    json: bool,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// Overwrite output files that already exist.
    #[arg(long)]
    force: bool,
}

/// Forwards to every observer (the log and live view, the progress bar, the pacer); a SIGINT or
/// SIGTERM asks the run to stop.
struct All<'a>(Vec<&'a mut dyn Observer>);

impl Observer for All<'_> {
    fn on_step(&mut self, view: &StepView) {
        self.0.iter_mut().for_each(|o| o.on_step(view));
    }
    fn on_plan(&mut self, time_s: f64, action: &Action, map: &Map, tour: &[Point2<f64>]) {
        self.0
            .iter_mut()
            .for_each(|o| o.on_plan(time_s, action, map, tour));
    }
    fn on_finish(&mut self, result: &RunResult) {
        self.0.iter_mut().for_each(|o| o.on_finish(result));
    }
    fn stop_requested(&self) -> bool {
        signals::stop_requested() || self.0.iter().any(|o| o.stop_requested())
    }
}

/// Shows simulated time and completeness on stderr.
struct Progress {
    bar: ProgressBar,
}

impl Observer for Progress {
    fn on_step(&mut self, view: &StepView) {
        if view.step.is_multiple_of(50) {
            self.bar.set_position(view.time_s as u64);
            self.bar.set_message(format!(
                "completeness {:.3}  path {:.1} m",
                view.completeness, view.path_length_m
            ));
        }
    }
}

fn write_file(path: &std::path::Path, bytes: &[u8]) -> tensorscout::Result<()> {
    std::fs::write(path, bytes).map_err(|e| tensorscout::Error::io(path, e))
}

pub fn run(args: ExploreArgs) -> Result<()> {
    let mut cfg = args.config.load_with(&args.profile)?;
    if let Some(seed) = args.seed {
        cfg.seed = seed;
    }
    if let Some(png) = &args.png {
        check_output(png, args.force, Some("png"))?;
    }
    if let Some(log) = &args.log {
        check_output(log, args.force, None)?;
    }
    if let Some(dir) = &args.map_out {
        if !dir.is_dir() {
            return Err(tensorscout::Error::io(
                dir,
                std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "--map-out folder does not exist",
                ),
            )
            .into());
        }
        check_output(&dir.join(scene::rosmap::MAP_YAML), args.force, Some("yaml"))?;
        check_output(&dir.join(scene::rosmap::MAP_PGM), args.force, Some("pgm"))?;
    }
    for file in [&args.trajectory, &args.trajectory_true]
        .into_iter()
        .flatten()
    {
        check_output(file, args.force, None)?;
    }
    let map_files = args.map_out.as_ref().map(|d| {
        (
            d.join(scene::rosmap::MAP_YAML),
            d.join(scene::rosmap::MAP_PGM),
        )
    });
    let mut outputs: Vec<(&str, &std::path::Path)> = [
        ("--png", &args.png),
        ("--log", &args.log),
        ("--trajectory", &args.trajectory),
        ("--trajectory-true", &args.trajectory_true),
    ]
    .into_iter()
    .filter_map(|(flag, p)| p.as_deref().map(|p| (flag, p)))
    .collect();
    if let Some((yaml, pgm)) = &map_files {
        outputs.push(("--map-out", yaml));
        outputs.push(("--map-out", pgm));
    }
    let config_file = args.config.config.as_deref();
    let inputs: Vec<(&str, &std::path::Path)> = std::iter::once(("--scene", args.scene.as_path()))
        .chain(config_file.map(|p| ("--config", p)))
        .collect();
    check_distinct(&outputs, &inputs)?;
    let spawn: Option<Pose2> = match args.spawn {
        Some(StartArg::Random) => {
            cfg.sim.spawn = tensorscout::config::SpawnMode::Random;
            None
        }
        Some(StartArg::Pose(p)) => Some(p),
        None => None,
    };
    // Fail on an unavailable planner before the scene is loaded.
    args.planner.build(&cfg)?;
    // A port in use fails here, before any work.
    let live_server = args.live.as_deref().map(live::serve).transpose()?;
    let scene = scene::load(&args.scene, &cfg.scene)?;
    check_distinct(&outputs, &scene_inputs(&scene, &args.config))?;
    for w in &scene.warnings {
        note!("warning: {w}");
    }
    // Where the progress bar shows; there, too, the line that the observable set is being computed,
    // which can take minutes at full camera resolution.
    let interactive = !args.quiet && std::io::stderr().is_terminal();
    let cache = super::progress::user_cache(interactive);
    let world = World::with_cache(&scene, &cfg, spawn, &cache)?;
    if let Some(w) = &world.spawn_warning {
        note!("{w}");
    }
    if let Some(w) = world.observable_source.warning() {
        note!("{w}");
    }
    if let Some(w) = scene::open_region_warning(&scene, &world.ground_truth) {
        note!("warning: {w}");
    }

    // From here a SIGINT or SIGTERM stops the run cleanly: its result is printed and its log
    // finished, then the process exits 130 or 143.
    let _cooperative = signals::Cooperative::begin();
    let log = match &args.log {
        Some(path) => {
            let identity = RunIdentity::new(&args.scene, &scene, args.planner, &cfg, spawn);
            Some(RunLog::create(path, &identity, &cfg.log)?)
        }
        None => None,
    };
    // One recorder builds every message once, for the file and the live view.
    let mut recorder = (log.is_some() || live_server.is_some()).then(|| {
        let sinks = Sinks {
            log,
            live: live_server,
        };
        Recorder::new(sinks, &cfg, &scene.mesh, None)
    });
    let mut pacer = args
        .live
        .is_some()
        .then(|| Pacer::new(args.rate.unwrap_or(Rate::Times(1.0))));
    let mut progress = interactive.then(|| {
        let bar = ProgressBar::new(cfg.sim.budget_s.get() as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] sim {pos}/{len} s {bar:30} {msg}",
            )
            .expect("valid template"),
        );
        Progress { bar }
    });
    let mut observers: Vec<&mut dyn Observer> = Vec::new();
    if let Some(r) = recorder.as_mut() {
        observers.push(r);
    }
    if let Some(p) = progress.as_mut() {
        observers.push(p);
    }
    if let Some(p) = pacer.as_mut() {
        observers.push(p);
    }
    let output = sim::run(&scene, world, &cfg, args.planner, &mut All(observers));
    if let Some(p) = &progress {
        p.bar.finish_and_clear();
    }
    // The log is finished (summary section written) whatever the run's outcome; the live view
    // gets what is queued for it, then says what it delivered.
    if let Some(r) = recorder {
        if let Some(server) = r.sink.live {
            live::report(&server.close());
        }
        if let Some(l) = r.sink.log {
            l.close()?;
        }
    }
    let output = output?;
    let r = &output.result;
    // The result is printed before the picture is drawn, so that a failed write loses nothing.
    let mut text = String::new();
    if args.json {
        writeln!(text, "{}", serde_json::to_string(r)?)?;
    } else {
        writeln!(
            text,
            "scene          {} ({})",
            r.scene,
            args.scene.display()
        )?;
        writeln!(text, "planner        {}  seed {}", r.planner, r.seed)?;
        writeln!(
            text,
            "start          ({:.2}, {:.2}, yaw {:.2})",
            r.spawn.x, r.spawn.y, r.spawn.yaw
        )?;
        writeln!(text, "termination    {}", r.termination.as_str())?;
        writeln!(
            text,
            "completeness   {:.3}  of the observable {:.2} m³ (reachable floor {:.1} m²)",
            r.completeness, r.observable_volume_m3, r.reachable_area_m2
        )?;
        writeln!(
            text,
            "explored       {:.2} m³ ({:.2} % outside the observable set)",
            r.explored_volume_m3,
            100.0 * r.explored_outside_observable_fraction
        )?;
        writeln!(text, "surface        {:.3}", r.surface_coverage)?;
        for p in &r.unseen_observable {
            writeln!(
                text,
                "  unseen {:.2} m³ around ({:.1}, {:.1}), {:.1}–{:.1} m high{}",
                p.volume_m3,
                p.x,
                p.y,
                p.z_min_m,
                p.z_max_m,
                if p.over_reachable_floor {
                    ""
                } else {
                    ", not over reachable floor"
                }
            )?;
        }
        if let Some(left) = r.frontiers_left.filter(|&n| n > 0) {
            writeln!(
                text,
                "frontiers left {left} cells reachable, bordering unseen observable space"
            )?;
            for g in &r.frontier_groups_left {
                writeln!(
                    text,
                    "  frontier {} cells around ({:.1}, {:.1})",
                    g.cells, g.x, g.y
                )?;
            }
        }
        writeln!(text, "path length    {:.1} m", r.path_length_m)?;
        writeln!(
            text,
            "time           {:.1} s simulated, {:.2} s wall, {:.0}× real time",
            r.sim_time_s, r.wall_time_s, r.real_time_factor
        )?;
        writeln!(text, "collisions     {}", r.collisions)?;
        if let (Some(p), Some(rc), Some(f)) = (r.map_precision, r.map_recall, r.free_but_occupied) {
            writeln!(
                text,
                "map quality    precision {p:.3}  recall {rc:.3}  known free but occupied {:.2} %",
                100.0 * f
            )?;
        }
        if let (Some(rmse), Some(max)) = (r.ate_rmse_m, r.ate_max_m) {
            writeln!(text, "pose error     ATE {rmse:.3} m RMSE, {max:.3} m max")?;
        }
        for (stage, s) in &r.timings_ms {
            writeln!(
                text,
                "  {stage:<7} mean {:.3} ms  p50 {:.3}  p95 {:.3}  max {:.3}",
                s.mean, s.p50, s.p95, s.max
            )?;
        }
    }
    emit(&text)?;
    if let Some(png) = &args.png {
        render::draw_run(&output.map, &output.ground_truth, &output.trajectory).save(png)?;
    }
    if let Some(dir) = &args.map_out {
        use tensorscout::scene::rosmap;
        let (yaml, pgm) = rosmap::ros_map_files(output.map.grid(), output.map.cell_states());
        write_file(&dir.join(rosmap::MAP_PGM), pgm.as_slice())?;
        write_file(&dir.join(rosmap::MAP_YAML), yaml.as_bytes())?;
    }
    let tum = [
        (&args.trajectory, &output.estimated_trajectory),
        (&args.trajectory_true, &output.trajectory),
    ];
    for (file, poses) in tum {
        if let Some(file) = file {
            let text = tensorscout::log::tum::tum_text(poses, cfg.sim.dt_s);
            write_file(file, text.as_bytes())?;
        }
    }
    if let Some(e) = &r.error {
        return Err(tensorscout::Error::Runtime(e.clone()).into());
    }
    Ok(())
}
