//! The step loop: sense → map → field → plan → motion → collision check → metrics, at a fixed `dt`.

use super::clock::{Stage, StageClock};
use super::motion::{MotionExecutor, MotionParams, MotionStatus};
use super::odometry::{ate, Odometry};
use super::result::{CurveSample, RunResult, Termination};
use super::robot::{Command, Robot};
use crate::config::{Config, DepthRenderer, SpawnMode};
use crate::eval::map_quality;
use crate::eval::{
    frontiers_left, surface_coverage, unseen_patches, CacheOutcome, ExploredVolume, GroundTruth,
    ObservableCache, ObservableParams, ObservableSet,
};
use crate::field::TensorField;
use crate::map::Map;
use crate::plan::search::Search;
use crate::plan::{Action, Plan, PlanContext, PlanParams, Planner, PlannerKind};
use crate::scene::Scene;
use crate::sensor::{DepthCamera, DepthFrame, DepthNoise, MeshBvh, MeshRaster};
use crate::{Pose2, Result};
use nalgebra::Point2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use std::time::Instant;

/// What an observer sees after each step (for progress bars and logs).
pub struct StepView<'a> {
    pub step: u64,
    /// Simulated time at the end of the step: the time of `pose` and of the metrics.
    pub time_s: f64,
    pub budget_s: f64,
    /// The robot's pose at `time_s`, after this step's motion, as the robot knows it (its estimate
    /// with `[noise.pose]`; the map is built in this frame).
    pub pose: Pose2,
    /// The true pose at `time_s` (`pose` unless pose or motion noise is on).
    pub true_pose: Pose2,
    /// Simulated time at the start of the step, when `frame` was rendered and `map` and `field`
    /// were last updated: what a log stamps them with.
    pub sensed_time_s: f64,
    /// The estimated pose at `sensed_time_s`: the one `frame` is placed at (and integrated at).
    pub sensed_pose: Pose2,
    /// The true pose at `sensed_time_s`, the one `frame` was rendered from.
    pub sensed_true_pose: Pose2,
    pub completeness: f64,
    pub path_length_m: f64,
    pub frame: Option<&'a DepthFrame>,
    pub map: &'a Map,
    pub explored_volume_m3: f64,
    pub collisions: u64,
    pub replans: u64,
    /// The planner's own tensor field (THP, TENSOR; with THP's path constraints), if it has one.
    pub field: Option<&'a TensorField>,
    /// Wall time of this step's stages (see `metrics::STAGES`), milliseconds: not deterministic.
    pub stage_ms: [f64; 5],
}

/// Receives every step of a run; all methods default to doing nothing.
pub trait Observer {
    fn on_step(&mut self, _view: &StepView) {}
    /// Called when the planner chose a new action (after `on_step` of the same step, if any), with
    /// the planner's tour (TSP order of its goals; empty for planners without one).
    fn on_plan(&mut self, _time_s: f64, _action: &Action, _map: &Map, _tour: &[Point2<f64>]) {}
    /// Called once with the result, after the loop ended.
    fn on_finish(&mut self, _result: &RunResult) {}
    /// Checked every step: `true` ends the run with `Termination::Interrupted`.
    fn stop_requested(&self) -> bool {
        false
    }
}

/// An observer that ignores everything.
pub struct NoObserver;
impl Observer for NoObserver {}

/// Everything a run leaves behind: the result, the final map, the trajectory and the ground truth.
pub struct RunOutput {
    pub result: RunResult,
    pub map: Map,
    /// The true poses: the start, then one per step.
    pub trajectory: Vec<Pose2>,
    /// The robot's estimates of them (`trajectory` unless pose or motion noise is on).
    pub estimated_trajectory: Vec<Pose2>,
    pub ground_truth: GroundTruth,
}

/// The world a run happens in: the scene's ground truth, its ray-casting structure (collisions, and
/// depth with `camera.renderer = "raycast"`), its rasteriser (depth by default) and what the camera
/// could observe in it, built once.
pub struct World {
    pub ground_truth: GroundTruth,
    pub bvh: MeshBvh,
    pub raster: MeshRaster,
    pub observable: Arc<ObservableSet>,
    /// Where the observable set came from (cache hit, computed, repaired).
    pub observable_source: CacheOutcome,
    /// A file spawn line a random start could not use (see `eval::build_ground_truth_for_start`).
    pub spawn_warning: Option<String>,
}

/// Stream of the run's ChaCha generator that draws a random start: separate from every planner's
/// draws, so a seed gives the same start whichever planner runs.
const SPAWN_STREAM: u64 = 0x0073_7061_776e;

impl World {
    /// Voxelises the scene, builds its BVH and computes the observable set without a disk cache;
    /// `spawn` overrides the scene's own spawn (see [`World::with_cache`]).
    pub fn new(scene: &Scene, cfg: &Config, spawn: Option<Pose2>) -> Result<World> {
        Self::with_cache(scene, cfg, spawn, &ObservableCache::none())
    }

    /// [`World::new`] with the observable set read from (or written to) `cache`. With
    /// `sim.spawn = "random"` the start is drawn from the run's seed, uniformly over the cells of the
    /// reachable region of the scene's own spawn that keep `sim.random_spawn_margin_m` beyond the
    /// inflation radius, with a uniform heading.
    pub fn with_cache(
        scene: &Scene,
        cfg: &Config,
        spawn: Option<Pose2>,
        cache: &ObservableCache,
    ) -> Result<World> {
        if cfg.sim.spawn == SpawnMode::Random && spawn.is_some() {
            return Err(crate::Error::usage(
                "an explicit start pose and `sim.spawn = \"random\"` exclude each other",
            ));
        }
        let (ground_truth, spawn_warning) =
            crate::eval::build_ground_truth_for_start(scene, spawn, cfg)?;
        let bvh = MeshBvh::new(&scene.mesh)?;
        let (observable, observable_source) = cache.get_or_compute(
            scene,
            &ground_truth,
            &bvh,
            &cfg.camera,
            &ObservableParams::from_config(&cfg.metrics),
        );
        let ground_truth = match cfg.sim.spawn {
            SpawnMode::Scene => ground_truth,
            SpawnMode::Random => {
                let pose = random_spawn(&ground_truth, cfg, &scene.name)?;
                ground_truth.with_spawn(pose)?
            }
        };
        let raster = MeshRaster::new(&scene.mesh)?;
        Ok(World {
            ground_truth,
            bvh,
            raster,
            observable: Arc::new(observable),
            observable_source,
            spawn_warning,
        })
    }
}

/// A start drawn from the run's seed (see [`World::with_cache`]).
fn random_spawn(gt: &GroundTruth, cfg: &Config, scene: &str) -> Result<Pose2> {
    let margin = cfg.sim.random_spawn_margin_m;
    let cells = gt.spawn_candidates(margin);
    if cells.is_empty() {
        return Err(crate::Error::usage(format!(
            "{scene}: no reachable cell keeps {:.2} m from every obstacle for a random start (inflation radius {:.2} m + sim.random_spawn_margin_m {:.2} m)",
            gt.inflation_m() + margin,
            gt.inflation_m(),
            margin
        )));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    rng.set_stream(SPAWN_STREAM);
    let cell = cells[rng.random_range(0..cells.len())];
    let yaw = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let p = gt.grid.center(gt.grid.cell(cell));
    Ok(Pose2::new(p.x, p.y, yaw))
}

/// Runs one exploration of `scene` with `planner` until it completes, spends its budget or gets stuck:
/// [`Simulation::new`], [`Simulation::step`] until the run ends, [`Simulation::finish`].
///
/// A failure during the run (the planner's, or a pose that became NaN) ends it with
/// [`Termination::Error`] and the message in [`RunResult::error`]; `Err` means the run could not
/// start (the planner could not be built).
pub fn run(
    scene: &Scene,
    world: World,
    cfg: &Config,
    planner: PlannerKind,
    observer: &mut dyn Observer,
) -> Result<RunOutput> {
    Ok(Simulation::new(scene, world, cfg, planner)?.run_to_end(observer))
}

/// What a step of the simulation left: the run goes on, or it ended (and how).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepOutcome {
    Running,
    Ended(Termination),
}

/// One exploration, step by step: sense → map → field → plan → motion → collision check →
/// metrics, at a fixed `dt`.
///
/// ```no_run
/// use tensorscout::plan::PlannerKind;
/// use tensorscout::sim::{NoObserver, Simulation, StepOutcome, World};
/// use tensorscout::Config;
/// # fn main() -> tensorscout::Result<()> {
/// let cfg = Config::default();
/// let scene = tensorscout::scene::load("scenes/apartment_small.obj".as_ref(), &cfg.scene)?;
/// let world = World::new(&scene, &cfg, None)?;
/// let mut sim = Simulation::new(&scene, world, &cfg, PlannerKind::Greedy)?;
/// while sim.step(&mut NoObserver) == StepOutcome::Running {}
/// let out = sim.finish();
/// println!("{} after {} steps", out.result.termination.as_str(), out.result.steps);
/// # Ok(()) }
/// ```
pub struct Simulation<'a> {
    scene: &'a Scene,
    cfg: &'a Config,
    planner: Box<dyn Planner + 'a>,
    /// What the planner reads of the config ([`PlanContext::cfg`]).
    plan_params: PlanParams,
    gt: GroundTruth,
    bvh: MeshBvh,
    raster: MeshRaster,
    observable: Arc<ObservableSet>,
    map: Map,
    camera: DepthCamera,
    frame: DepthFrame,
    /// `[noise.depth]`, when on.
    depth_noise: Option<DepthNoise>,
    /// The true pose is `robot.pose`.
    robot: Robot,
    /// `[noise.pose]` and `[noise.motion]`, when either is on: the robot's estimate of its pose.
    odometry: Option<Odometry>,
    /// The estimates, one per pose of `trajectory`, when `odometry` is on.
    estimates: Vec<Pose2>,
    motion: MotionExecutor,
    search: Search,
    explored: ExploredVolume,
    clock: StageClock,
    curve: Vec<CurveSample>,
    trajectory: Vec<Pose2>,
    action: Action,
    need_plan: bool,
    collisions: u64,
    replans: u64,
    last_gain_step: u64,
    volume_at_last_gain: f64,
    step: u64,
    /// How the run ended, once it has.
    ended: Option<Termination>,
    /// The failure that ended the run with [`Termination::Error`].
    error: Option<crate::Error>,
    wall_start: Instant,
    // Fixed by the config.
    dt: f64,
    steps_per_s: f64,
    total_steps: u64,
    camera_period: u64,
    curve_period: u64,
    stuck_steps: u64,
    collision_top: f64,
}

impl<'a> Simulation<'a> {
    /// A run of `scene` in `world` with a fresh planner of `kind`; fails only if the planner cannot
    /// be built from `cfg`.
    pub fn new(
        scene: &'a Scene,
        world: World,
        cfg: &'a Config,
        kind: PlannerKind,
    ) -> Result<Simulation<'a>> {
        Ok(Self::with_planner(scene, world, cfg, kind.build(cfg)?))
    }

    /// A run with a planner object the caller built (benches wrap a planner to record its states;
    /// a `&mut P` is a planner too, so the caller can keep it).
    pub fn with_planner(
        scene: &'a Scene,
        world: World,
        cfg: &'a Config,
        planner: Box<dyn Planner + 'a>,
    ) -> Simulation<'a> {
        let wall_start = Instant::now();
        let World {
            ground_truth: gt,
            bvh,
            raster,
            observable,
            ..
        } = world;
        let grid = gt.grid;
        let dt = cfg.sim.dt_s;
        let robot = Robot::new(gt.spawn, &cfg.robot);
        let mut motion = MotionExecutor::new(&MotionParams::from(cfg));
        let action = if cfg.sim.initial_look_around {
            Action::LookAround
        } else {
            Action::Follow {
                path: Vec::new(),
                look_on_arrival: false,
                exact_arrival: false,
            }
        };
        motion.start(&action);
        Simulation {
            scene,
            cfg,
            planner,
            plan_params: PlanParams::from(cfg),
            map: Map::new(grid, cfg),
            camera: DepthCamera::new(&cfg.camera),
            frame: DepthFrame::default(),
            depth_noise: DepthNoise::new(cfg),
            odometry: Odometry::new(cfg, robot.pose),
            estimates: if cfg.noise.pose_is_noisy() {
                vec![robot.pose]
            } else {
                Vec::new()
            },
            trajectory: vec![robot.pose],
            robot,
            need_plan: !motion.is_busy(),
            motion,
            search: Search::new(&grid),
            explored: ExploredVolume::new(&gt, &observable),
            clock: StageClock::default(),
            curve: vec![CurveSample {
                t_s: 0.0,
                path_length_m: 0.0,
                explored_volume_m3: 0.0,
                completeness: 0.0,
            }],
            action,
            collisions: 0,
            replans: 0,
            last_gain_step: 0,
            volume_at_last_gain: 0.0,
            step: 0,
            ended: None,
            error: None,
            wall_start,
            dt,
            // Simulated time of step k is k / steps_per_s (for dt = 0.1 this prints as 270.4, not
            // 270.40000000000003).
            steps_per_s: 1.0 / dt,
            total_steps: (cfg.sim.budget_s.get() / dt).round() as u64,
            camera_period: ((1.0 / (cfg.camera.rate_hz.get() * dt)).round() as u64).max(1),
            curve_period: ((cfg.sim.curve_interval_s / dt).round() as u64).max(1),
            stuck_steps: (cfg.sim.stuck_timeout_s.get() / dt).round() as u64,
            collision_top: cfg.robot.height_m.min(cfg.map.band_max_m),
            gt,
            bvh,
            raster,
            observable,
        }
    }

    /// Steps until the run ends, then [`Simulation::finish`]es it and tells `observer`.
    pub fn run_to_end(mut self, observer: &mut dyn Observer) -> RunOutput {
        while self.step(observer) == StepOutcome::Running {}
        let out = self.finish();
        observer.on_finish(&out.result);
        out
    }

    /// Steps run so far.
    pub fn steps(&self) -> u64 {
        self.step
    }

    /// Simulated seconds so far.
    pub fn time_s(&self) -> f64 {
        self.step as f64 / self.steps_per_s
    }

    /// The robot's pose now, as it knows it: its estimate with `[noise.pose]`, else the truth.
    pub fn pose(&self) -> Pose2 {
        self.odometry
            .as_ref()
            .map_or(self.robot.pose, Odometry::estimate)
    }

    /// The robot's true pose now.
    pub fn true_pose(&self) -> Pose2 {
        self.robot.pose
    }

    /// The map built so far.
    pub fn map(&self) -> &Map {
        &self.map
    }

    /// The last depth frame the camera took (empty before the first step).
    pub fn frame(&self) -> &DepthFrame {
        &self.frame
    }

    /// The scene's ground truth (reachable region, spawn) the run is measured against.
    pub fn ground_truth(&self) -> &GroundTruth {
        &self.gt
    }

    /// Explored band volume so far, m³ (the result's `explored_volume_m3`).
    pub fn explored_volume_m3(&self) -> f64 {
        self.explored.volume_m3()
    }

    /// Completeness so far: the explored share of the observable volume.
    pub fn completeness(&self) -> f64 {
        self.explored.completeness()
    }

    /// Distance driven so far, metres.
    pub fn path_length_m(&self) -> f64 {
        self.robot.path_length_m
    }

    /// Collisions so far.
    pub fn collisions(&self) -> u64 {
        self.collisions
    }

    /// What the planner reads of the config, for searches under the shared cost rule from outside
    /// the planner (the Python bindings' planning context).
    pub fn plan_params(&self) -> &PlanParams {
        &self.plan_params
    }

    /// How the run ended, if it has.
    pub fn ended(&self) -> Option<Termination> {
        self.ended
    }

    /// The failure that ended the run, if one did.
    pub fn error(&self) -> Option<&crate::Error> {
        self.error.as_ref()
    }

    /// Ends the run now; every later [`Simulation::step`] reports the same ending.
    fn end(&mut self, termination: Termination) -> StepOutcome {
        self.ended = Some(termination);
        StepOutcome::Ended(termination)
    }

    /// Ends the run with [`Termination::Error`] and keeps the error for the result.
    fn fail(&mut self, e: crate::Error) -> StepOutcome {
        self.error = Some(e);
        self.end(Termination::Error)
    }

    /// Runs one step of `dt`. Once the run has ended this does nothing and reports the ending
    /// again. The budget ends the run at the step that spends it; `observer` may stop it before a
    /// step ([`Observer::stop_requested`]).
    pub fn step(&mut self, observer: &mut dyn Observer) -> StepOutcome {
        self.advance(None, observer)
    }

    /// One step of `dt` driven by `command` from outside (an agent in a learning environment)
    /// instead of the planner and the motion executor: sense, map and metrics as in
    /// [`Simulation::step`], no field or plan stage, and the command (clamped to the robot's limits)
    /// in place of the executor's. A move that would make the robot's body touch the scene is not
    /// made (the robot stays where it was) and counts as a collision.
    pub fn step_commanded(&mut self, command: Command, observer: &mut dyn Observer) -> StepOutcome {
        self.advance(Some(command), observer)
    }

    /// [`Simulation::step`], or with `command` [`Simulation::step_commanded`].
    fn advance(&mut self, command: Option<Command>, observer: &mut dyn Observer) -> StepOutcome {
        if let Some(t) = self.ended {
            return StepOutcome::Ended(t);
        }
        if self.step >= self.total_steps {
            return self.end(Termination::Budget);
        }
        if observer.stop_requested() {
            return self.end(Termination::Interrupted);
        }
        let cfg = self.cfg;
        let time_s = self.time_s();
        let sensed = (self.pose(), self.robot.pose);
        // What the robot believes: the map, the field, the planner and the motion guard use it.
        let belief = sensed.0;
        self.clock.begin();
        // Sense: the camera sees the scene from the true pose; the frame is placed at the estimate.
        let fired = self.step.is_multiple_of(self.camera_period);
        if fired {
            match cfg.camera.renderer {
                DepthRenderer::Raster => {
                    self.camera
                        .render_into(&self.raster, self.robot.pose, &mut self.frame)
                }
                DepthRenderer::Raycast => {
                    self.camera
                        .capture_into(&self.bvh, self.robot.pose, &mut self.frame)
                }
            }
            if let Some(noise) = &mut self.depth_noise {
                noise.apply(&mut self.frame, self.step);
            }
            if self.odometry.is_some() {
                self.camera.repose(belief, &mut self.frame);
            }
        }
        self.clock.lap(Stage::Sense);
        // Map.
        if fired {
            let update = self.map.integrate(&self.frame);
            self.explored
                .add(&self.gt, &self.observable, &update.newly_known);
        }
        self.map
            .clear_footprint(belief.x, belief.y, cfg.robot.radius_m);
        self.clock.lap(Stage::Map);
        if let Some(cmd) = command {
            return self.commanded_motion(cmd, time_s, sensed, fired, observer);
        }
        // Field: the tensor-field planners update theirs here; GREEDY and NBV-TSP have none.
        if let Some(fp) = self.planner.field_planner() {
            if let Err(e) = fp.update_field(&self.map, belief, time_s) {
                self.clock.end();
                return self.fail(e);
            }
        }
        self.clock.lap(Stage::Field);
        // Plan.
        let planned = self.plan_stage(time_s, observer);
        self.clock.lap(Stage::Plan);
        match planned {
            Ok(None) => {}
            Ok(Some(ending)) => {
                self.clock.end();
                return self.end(ending);
            }
            Err(e) => {
                self.clock.end();
                return self.fail(e);
            }
        }
        // Motion.
        let (cmd, status) = self.motion.step(belief, &self.map);
        if let Err(failed) = self.apply_command(cmd) {
            return failed;
        }
        let pose = self.pose();
        match status {
            MotionStatus::Busy => {}
            MotionStatus::Done | MotionStatus::Blocked => {
                let ctx = PlanContext {
                    map: &self.map,
                    pose,
                    time_s,
                    cfg: &self.plan_params,
                    search: &mut self.search,
                };
                self.planner
                    .action_finished(&ctx, status == MotionStatus::Done);
                self.need_plan = true;
            }
        }
        self.clock.lap(Stage::Motion);
        self.clock.end();
        self.end_step(time_s, sensed, fired, observer)
    }

    /// The motion stage of [`Simulation::step_commanded`]: the field and plan stages count zero.
    fn commanded_motion(
        &mut self,
        cmd: Command,
        time_s: f64,
        sensed: (Pose2, Pose2),
        fired: bool,
        observer: &mut dyn Observer,
    ) -> StepOutcome {
        self.clock.lap(Stage::Field);
        self.clock.lap(Stage::Plan);
        let before = (self.robot.clone(), self.odometry.clone());
        match self.apply_command(cmd) {
            Err(failed) => return failed,
            // The move into the scene is not made.
            Ok(true) => (self.robot, self.odometry) = before,
            Ok(false) => {}
        }
        self.clock.lap(Stage::Motion);
        self.clock.end();
        self.end_step(time_s, sensed, fired, observer)
    }

    /// Moves the robot by `cmd` for one `dt` (with `[noise.motion]`, by what it really executes;
    /// the estimate follows) and counts a collision if its body then touches the scene (answering
    /// whether it does); `Err` with the step's outcome when the pose became NaN, which fails the
    /// run.
    fn apply_command(&mut self, cmd: Command) -> std::result::Result<bool, StepOutcome> {
        let from = self.robot.pose;
        let applied = self.robot.apply(cmd, self.dt);
        if let Some(odometry) = &mut self.odometry {
            let executed = odometry.execute(self.step, from, self.robot.pose);
            // The distance driven is the executed one.
            let driven = (executed.x - from.x).hypot(executed.y - from.y);
            self.robot.path_length_m += driven - applied.v * self.dt;
            self.robot.pose = executed;
            odometry.observe(self.step, from, executed);
        }
        if self.robot.pose.x.is_nan() || self.robot.pose.y.is_nan() {
            self.clock.end();
            return Err(self.fail(crate::Error::Runtime("robot pose became NaN".into())));
        }
        let (pose, cfg) = (self.robot.pose, self.cfg);
        let hit = self.bvh.cylinder_intersects(
            pose.x,
            pose.y,
            cfg.robot.radius_m,
            cfg.map.band_min_m,
            self.collision_top,
        );
        if hit {
            self.collisions += 1;
        }
        Ok(hit)
    }

    /// The end of every step: the trajectory, the metrics, the observer and the run's end.
    /// `sensed` is the (estimated, true) pose at the step's start.
    fn end_step(
        &mut self,
        time_s: f64,
        sensed: (Pose2, Pose2),
        fired: bool,
        observer: &mut dyn Observer,
    ) -> StepOutcome {
        let cfg = self.cfg;
        let (pose, true_pose) = (self.pose(), self.robot.pose);
        self.trajectory.push(true_pose);
        if self.odometry.is_some() {
            self.estimates.push(pose);
        }
        self.step += 1;

        // Metrics and termination.
        let volume = self.explored.volume_m3();
        if volume - self.volume_at_last_gain >= cfg.sim.stuck_min_gain_m3.get() {
            self.volume_at_last_gain = volume;
            self.last_gain_step = self.step;
        }
        if self.step.is_multiple_of(self.curve_period) {
            self.curve.push(CurveSample {
                t_s: self.time_s(),
                path_length_m: self.robot.path_length_m,
                explored_volume_m3: volume,
                completeness: self.explored.completeness(),
            });
        }
        observer.on_step(&StepView {
            step: self.step,
            time_s: self.time_s(),
            budget_s: cfg.sim.budget_s.get(),
            pose,
            true_pose,
            sensed_time_s: time_s,
            sensed_pose: sensed.0,
            sensed_true_pose: sensed.1,
            completeness: self.explored.completeness(),
            path_length_m: self.robot.path_length_m,
            frame: fired.then_some(&self.frame),
            map: &self.map,
            explored_volume_m3: volume,
            collisions: self.collisions,
            replans: self.replans,
            field: self.planner.field_planner().and_then(|fp| fp.field()),
            stage_ms: self.clock.step_ms(),
        });
        if self.step - self.last_gain_step >= self.stuck_steps {
            return self.end(Termination::Stuck);
        }
        if self.step >= self.total_steps {
            return self.end(Termination::Budget);
        }
        StepOutcome::Running
    }

    /// The plan stage: abandons an outdated action and asks for a new one when needed. The run's
    /// ending when the planner answered that nothing is left to explore (`complete`) or that its
    /// method cannot go on (`stuck`).
    fn plan_stage(
        &mut self,
        time_s: f64,
        observer: &mut dyn Observer,
    ) -> Result<Option<Termination>> {
        let pose = self.pose();
        let mut ctx = PlanContext {
            map: &self.map,
            pose,
            time_s,
            cfg: &self.plan_params,
            search: &mut self.search,
        };
        if !self.need_plan && self.planner.is_outdated(&ctx, &self.action) {
            self.planner.action_finished(&ctx, false);
            self.need_plan = true;
        }
        if !self.need_plan {
            return Ok(None);
        }
        self.replans += 1;
        let Plan { action, report } = self.planner.plan(&mut ctx)?;
        if let Some(ms) = report.tsp_ms {
            self.clock.record_tsp(ms);
        }
        match action {
            Action::Complete => Ok(Some(Termination::Complete)),
            Action::Stuck => Ok(Some(Termination::Stuck)),
            a => {
                observer.on_plan(time_s, &a, &self.map, &report.tour);
                self.action = a;
                self.motion.start(&self.action);
                self.need_plan = false;
                Ok(None)
            }
        }
    }

    /// The run's result, final map, trajectory and ground truth. A run not yet ended counts as
    /// interrupted at the steps run so far.
    pub fn finish(mut self) -> RunOutput {
        let termination = self.ended.unwrap_or(Termination::Interrupted);
        let sim_time_s = self.time_s();
        let explored = &self.explored;
        if self.curve.last().is_none_or(|c| c.t_s < sim_time_s) {
            self.curve.push(CurveSample {
                t_s: sim_time_s,
                path_length_m: self.robot.path_length_m,
                explored_volume_m3: explored.volume_m3(),
                completeness: explored.completeness(),
            });
        }
        let wall_time_s = self.wall_start.elapsed().as_secs_f64();
        let (gt, map, cfg) = (&self.gt, &self.map, self.cfg);
        let left = frontiers_left(gt, &self.observable, map);
        let quality = cfg
            .noise
            .any()
            .then(|| map_quality(gt, &self.observable, map));
        let pose_error = self
            .odometry
            .is_some()
            .then(|| ate(&self.estimates, &self.trajectory));
        let result = RunResult {
            scene: self.scene.name.clone(),
            scene_hash: self.scene.content_hash.clone(),
            planner: self.planner.name().to_string(),
            profile: cfg.profile.name().to_string(),
            seed: cfg.seed,
            spawn: gt.spawn,
            termination,
            error: self.error.as_ref().map(|e| e.to_string()),
            completeness: explored.completeness(),
            explored_volume_m3: explored.volume_m3(),
            observable_volume_m3: self.observable.volume_m3(),
            reachable_area_m2: gt.reachable_area_m2(),
            explored_outside_observable_fraction: explored.outside_observable_fraction(),
            surface_coverage: surface_coverage(&self.observable, map),
            unseen_observable: unseen_patches(gt, &self.observable, map),
            frontiers_left: Some(left.cells),
            frontier_groups_left: left.groups,
            path_length_m: self.robot.path_length_m,
            sim_time_s,
            wall_time_s,
            real_time_factor: if wall_time_s > 0.0 {
                sim_time_s / wall_time_s
            } else {
                0.0
            },
            collisions: self.collisions,
            steps: self.step,
            replans: self.replans,
            astar_calls: self.search.astar_calls,
            planner_stats: self.planner.stats(),
            timings_ms: self.clock.times().summary(),
            version: crate::VERSION.to_string(),
            config_hash: cfg.hash(),
            curve: self.curve,
            map_precision: quality.map(|q| q.precision),
            map_recall: quality.map(|q| q.recall),
            free_but_occupied: quality.map(|q| q.free_but_occupied),
            ate_rmse_m: pose_error.map(|e| e.0),
            ate_max_m: pose_error.map(|e| e.1),
        };
        let estimated_trajectory = if self.odometry.is_some() {
            self.estimates
        } else {
            self.trajectory.clone()
        };
        RunOutput {
            result,
            map: self.map,
            trajectory: self.trajectory,
            estimated_trajectory,
            ground_truth: self.gt,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{NonNegative, Positive, SpawnMode};
    use crate::sensor::raycast::testing::furnished_room;

    fn scene(mesh: crate::scene::TriMesh) -> Scene {
        Scene {
            name: "room".into(),
            path: "room.obj".into(),
            mesh,
            spawn: None,
            content_hash: "room".into(),
            floor_z: 0.0,
            source: "obj".into(),
            warnings: Vec::new(),
            inputs: Vec::new(),
        }
    }

    /// A planner that looks around `looks` times, then answers `last` (complete, or an error).
    struct Scripted {
        looks: usize,
        plans: usize,
        fail: bool,
    }

    impl Planner for Scripted {
        fn name(&self) -> &'static str {
            "scripted"
        }
        fn plan(&mut self, _ctx: &mut PlanContext) -> Result<Plan> {
            self.plans += 1;
            if self.plans <= self.looks {
                Ok(Action::LookAround.into())
            } else if self.fail {
                Err(crate::Error::Runtime("scripted failure".into()))
            } else {
                Ok(Action::Complete.into())
            }
        }
        fn is_outdated(&mut self, _ctx: &PlanContext, _action: &Action) -> bool {
            false
        }
        fn action_finished(&mut self, _ctx: &PlanContext, _reached: bool) {}
    }

    fn scripted(looks: usize, fail: bool) -> Scripted {
        Scripted {
            looks,
            plans: 0,
            fail,
        }
    }

    /// The 4 m furnished test room, built once.
    fn small_room() -> &'static Scene {
        static ROOM: std::sync::OnceLock<Scene> = std::sync::OnceLock::new();
        ROOM.get_or_init(|| scene(furnished_room(4.0)))
    }

    /// A simulation of the small room with `planner` under `cfg`.
    fn room_sim<'a>(cfg: &'a Config, planner: &'a mut dyn Planner) -> Simulation<'a> {
        let world = World::new(small_room(), cfg, None).unwrap();
        Simulation::with_planner(small_room(), world, cfg, Box::new(planner))
    }

    /// Steps `sim` until it ends; returns the outcome of every step.
    fn drive(sim: &mut Simulation, observer: &mut dyn Observer) -> Vec<StepOutcome> {
        let mut outcomes = Vec::new();
        loop {
            let o = sim.step(observer);
            outcomes.push(o);
            if o != StepOutcome::Running {
                return outcomes;
            }
            assert!(outcomes.len() < 100_000, "the run never ends");
        }
    }

    /// The budget ends the run at exactly the step it allows (budget / dt), not one later; a step
    /// after the end changes nothing and reports the same ending.
    #[test]
    fn the_budget_ends_the_run_at_its_step() {
        let mut cfg = Config::default();
        cfg.sim.budget_s = Positive::new(3.0).unwrap();
        cfg.sim.stuck_timeout_s = Positive::new(1000.0).unwrap();
        let mut planner = scripted(usize::MAX, false);
        let mut sim = room_sim(&cfg, &mut planner);
        let outcomes = drive(&mut sim, &mut NoObserver);
        assert_eq!(outcomes.len(), 30);
        assert_eq!(outcomes[29], StepOutcome::Ended(Termination::Budget));
        assert_eq!(sim.steps(), 30);
        assert_eq!(sim.step(&mut NoObserver), outcomes[29]);
        assert_eq!(sim.steps(), 30);
        let out = sim.finish();
        assert_eq!(out.result.termination, Termination::Budget);
        assert_eq!((out.result.steps, out.result.sim_time_s), (30, 3.0));
        assert_eq!(out.trajectory.len(), 31);
        assert_eq!(out.result.error, None);
    }

    /// A planner that answers "complete" ends the run `complete` in the step it says so, before any
    /// motion of that step.
    #[test]
    fn a_planner_that_is_done_completes_the_run() {
        let cfg = Config::default();
        let mut planner = scripted(2, false);
        let mut sim = room_sim(&cfg, &mut planner);
        let outcomes = drive(&mut sim, &mut NoObserver);
        assert_eq!(
            outcomes.last(),
            Some(&StepOutcome::Ended(Termination::Complete))
        );
        let steps = sim.steps();
        assert_eq!(steps as usize, outcomes.len() - 1);
        let out = sim.finish();
        assert_eq!(planner.plans, 3);
        assert_eq!(out.result.termination, Termination::Complete);
        assert_eq!(out.result.replans, 3);
        assert_eq!(out.trajectory.len() as u64, steps + 1);
        assert!(out.result.completeness > 0.0);
    }

    /// A planner's error ends the run `error` with its message in the result: the one way every
    /// failure during a run leaves.
    #[test]
    fn a_planner_error_ends_the_run_with_its_message() {
        let cfg = Config::default();
        let mut planner = scripted(1, true);
        let mut sim = room_sim(&cfg, &mut planner);
        let outcomes = drive(&mut sim, &mut NoObserver);
        assert_eq!(
            outcomes.last(),
            Some(&StepOutcome::Ended(Termination::Error))
        );
        assert_eq!(sim.error().map(|e| e.exit_code()), Some(1));
        let out = sim.finish();
        assert_eq!(out.result.termination, Termination::Error);
        assert_eq!(out.result.error.as_deref(), Some("scripted failure"));
    }

    /// No gain for `sim.stuck_timeout_s` ends the run `stuck` at exactly that step.
    #[test]
    fn no_progress_ends_the_run_stuck_at_the_timeout() {
        let mut cfg = Config::default();
        cfg.sim.stuck_timeout_s = Positive::new(2.0).unwrap();
        cfg.sim.stuck_min_gain_m3 = NonNegative::new(1e9).unwrap();
        let mut planner = scripted(usize::MAX, false);
        let mut sim = room_sim(&cfg, &mut planner);
        let outcomes = drive(&mut sim, &mut NoObserver);
        assert_eq!(outcomes.len(), 20);
        assert_eq!(outcomes[19], StepOutcome::Ended(Termination::Stuck));
    }

    /// An observer's stop request ends the run before the next step; the result covers the steps
    /// run so far.
    #[test]
    fn a_stop_request_interrupts_before_the_next_step() {
        struct StopAt(u64, u64);
        impl Observer for StopAt {
            fn on_step(&mut self, view: &StepView) {
                self.1 = view.step;
            }
            fn stop_requested(&self) -> bool {
                self.1 >= self.0
            }
        }
        let cfg = Config::default();
        let world = World::new(small_room(), &cfg, None).unwrap();
        let mut sim = Simulation::new(small_room(), world, &cfg, PlannerKind::Greedy).unwrap();
        let mut stop = StopAt(7, 0);
        let outcomes = drive(&mut sim, &mut stop);
        assert_eq!(outcomes.len(), 8);
        assert_eq!(outcomes[7], StepOutcome::Ended(Termination::Interrupted));
        let out = sim.finish();
        assert_eq!((out.result.steps, out.result.sim_time_s), (7, 0.7));
    }

    /// A whole NBV-TSP exploration of the smallest shipped scene (about 3 s in release): it completes with
    /// nearly everything seen and no collision, and a second run gives the identical result.
    #[test]
    #[ignore = "heavy tier: cargo test -- --ignored"]
    fn explores_apartment_small_completely_and_deterministically() {
        let cfg = Config::default();
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/apartment_small.obj");
        let scene = crate::scene::load(&path, &cfg.scene).unwrap();
        let explore = || {
            let world = World::new(&scene, &cfg, None).unwrap();
            run(&scene, world, &cfg, PlannerKind::Nbv, &mut NoObserver)
                .unwrap()
                .result
        };
        let a = explore();
        assert_eq!(a.termination, Termination::Complete);
        assert_eq!(a.collisions, 0);
        assert!(a.completeness >= 0.95, "{}", a.completeness);
        assert!(a.planner_stats["tsp_solves"] >= 1.0);
        let b = explore();
        assert_eq!(
            (a.steps, a.path_length_m, a.completeness, &a.planner_stats),
            (b.steps, b.path_length_m, b.completeness, &b.planner_stats)
        );
    }

    #[test]
    fn random_starts_follow_the_seed_only() {
        let s = scene(furnished_room(6.0));
        let mut cfg = Config::default();
        cfg.sim.spawn = SpawnMode::Random;
        let start = |seed: u64| {
            let mut c = cfg.clone();
            c.seed = seed;
            World::new(&s, &c, None).unwrap().ground_truth.spawn
        };
        let (a, b, c) = (start(1), start(2), start(3));
        assert!(a != b && b != c && a != c, "{a:?} {b:?} {c:?}");
        // The same seed gives the same start again (and so for every planner).
        assert_eq!(start(2), b);
        // Each start is reachable, keeps the inflation radius plus the margin, and faces anywhere.
        let gt = World::new(&s, &cfg, None).unwrap().ground_truth;
        for p in [a, b, c] {
            let cell = gt.grid.index(gt.grid.cell_of(p.position()).unwrap());
            assert!(gt.reachable(cell));
            assert!(gt
                .spawn_candidates(cfg.sim.random_spawn_margin_m)
                .contains(&cell));
            assert!((-std::f64::consts::PI..std::f64::consts::PI).contains(&p.yaw));
        }
        // An explicit pose and a random start exclude each other.
        let e = World::new(&s, &cfg, Some(Pose2::new(3.0, 3.0, 0.0)))
            .err()
            .unwrap();
        assert_eq!(e.exit_code(), 2);
    }

    #[test]
    fn random_start_without_room_is_a_clear_error() {
        // A 0.8 m square box: the robot fits at its centre (radius 0.29 < 0.4) but no cell keeps the
        // extra 0.1 m margin a random start asks for.
        let mut mesh = crate::scene::TriMesh::default();
        crate::sensor::raycast::testing::push_box(&mut mesh, [0.0, 0.0, 0.0], [0.8, 0.8, 2.5]);
        let s = scene(mesh);
        let mut cfg = Config::default();
        cfg.sim.spawn = SpawnMode::Random;
        let e = World::new(&s, &cfg, Some(Pose2::new(0.4, 0.4, 0.0)).filter(|_| false))
            .err()
            .unwrap();
        assert_eq!(
            e.to_string(),
            "room: no reachable cell keeps 0.39 m from every obstacle for a random start (inflation radius 0.29 m + sim.random_spawn_margin_m 0.10 m)"
        );
        assert_eq!(e.exit_code(), 2);
    }
}
