//! The step loop: sense → map → field → plan → motion → collision check → metrics, at a fixed `dt`.

use super::metrics::{
    surface_coverage, unseen_patches, CurveSample, ExploredVolume, RunResult, StageTimes,
    Termination,
};
use super::motion::{MotionExecutor, MotionStatus};
use super::observable::{CacheOutcome, ObservableCache, ObservableSet};
use super::robot::Robot;
use crate::config::{Config, DepthRenderer, SpawnMode};
use crate::field::TensorField;
use crate::map::Map;
use crate::plan::search::Search;
use crate::plan::{Action, PlanContext, Planner, PlannerKind};
use crate::scene::{GroundTruth, Scene};
use crate::sensor::{DepthCamera, DepthFrame, MeshBvh, MeshRaster};
use crate::{Pose2, Result};
use nalgebra::Point2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use std::time::Instant;

/// What an observer sees after each step (for progress bars and logs).
pub struct StepView<'a> {
    pub step: u64,
    pub time_s: f64,
    pub budget_s: f64,
    pub pose: Pose2,
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
    pub trajectory: Vec<Pose2>,
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
        let ground_truth = crate::scene::build_ground_truth(scene, spawn, cfg)?;
        let bvh = MeshBvh::new(&scene.mesh)?;
        let (observable, observable_source) = cache.get_or_compute(scene, &ground_truth, &bvh, cfg);
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

/// Runs one exploration of `scene` with `planner` until it completes, spends its budget or gets stuck.
pub fn run(
    scene: &Scene,
    world: World,
    cfg: &Config,
    planner: PlannerKind,
    observer: &mut dyn Observer,
) -> Result<RunOutput> {
    let mut planner = planner.build(cfg)?;
    run_planner(scene, world, cfg, planner.as_mut(), observer)
}

/// [`run`] with a planner object the caller built (benches wrap a planner to record its states).
pub fn run_planner(
    scene: &Scene,
    world: World,
    cfg: &Config,
    planner: &mut dyn Planner,
    observer: &mut dyn Observer,
) -> Result<RunOutput> {
    let wall_start = Instant::now();
    let World {
        ground_truth: gt,
        bvh,
        raster,
        observable,
        ..
    } = world;
    let grid = gt.grid;
    let mut map = Map::new(grid, cfg);
    let camera = DepthCamera::new(&cfg.camera);
    let mut frame = DepthFrame::default();
    let mut robot = Robot::new(gt.spawn, &cfg.robot);
    let mut motion = MotionExecutor::new(cfg);
    let mut search = Search::new(&grid);
    let mut explored = ExploredVolume::new(&gt, &observable);
    let mut times = StageTimes::default();
    let mut curve = Vec::new();
    let mut trajectory = vec![robot.pose];

    let dt = cfg.sim.dt_s;
    // Simulated time of step k is k / steps_per_s (for dt = 0.1 this prints as 270.4, not
    // 270.40000000000003).
    let steps_per_s = 1.0 / dt;
    let total_steps = (cfg.sim.budget_s / dt).round() as u64;
    let camera_period = ((1.0 / (cfg.camera.rate_hz * dt)).round() as u64).max(1);
    let curve_period = ((cfg.sim.curve_interval_s / dt).round() as u64).max(1);
    let stuck_steps = (cfg.sim.stuck_timeout_s / dt).round() as u64;
    let collision_top = cfg.robot.height_m.min(cfg.map.band_max_m);

    let mut action = if cfg.sim.initial_look_around {
        Action::LookAround
    } else {
        Action::Follow {
            path: Vec::new(),
            look_on_arrival: false,
        }
    };
    motion.start(&action);
    let mut need_plan = !motion.is_busy();
    let mut termination = Termination::Budget;
    let mut error = None;
    let mut collisions = 0u64;
    let mut replans = 0u64;
    let mut last_gain_step = 0u64;
    let mut volume_at_last_gain = 0.0;
    let mut step = 0u64;

    curve.push(CurveSample {
        t_s: 0.0,
        path_length_m: 0.0,
        explored_volume_m3: 0.0,
        completeness: 0.0,
    });

    while step < total_steps {
        if observer.stop_requested() {
            termination = Termination::Interrupted;
            break;
        }
        let time_s = step as f64 / steps_per_s;
        // Sense.
        let t0 = Instant::now();
        let fired = step.is_multiple_of(camera_period);
        if fired {
            match cfg.camera.renderer {
                DepthRenderer::Raster => camera.render_into(&raster, robot.pose, &mut frame),
                DepthRenderer::Raycast => camera.capture_into(&bvh, robot.pose, &mut frame),
            }
        }
        let t1 = Instant::now();
        // Map.
        if fired {
            let update = map.integrate(&frame);
            explored.add(&gt, &observable, &update.newly_known);
        }
        map.clear_footprint(robot.pose.x, robot.pose.y, cfg.robot.radius_m);
        let t2 = Instant::now();
        // Field: the tensor-field planners update theirs here; GREEDY and NBV-TSP have none.
        if let Err(e) = planner.update_field(&map, robot.pose, time_s) {
            termination = Termination::Error;
            error = Some(e.to_string());
            record(&mut times, [t0, t1, t2, t2, t2, t2]);
            break;
        }
        let t3 = Instant::now();
        // Plan.
        {
            let mut ctx = PlanContext {
                map: &map,
                pose: robot.pose,
                time_s,
                cfg,
                search: &mut search,
            };
            if !need_plan && planner.is_outdated(&ctx, &action) {
                planner.action_finished(&ctx, false);
                need_plan = true;
            }
            if need_plan {
                replans += 1;
                let planned = planner.plan(&mut ctx);
                if let Some(ms) = planner.take_tsp_ms() {
                    times.record_tsp(ms);
                }
                match planned {
                    Ok(Action::Complete) => {
                        termination = Termination::Complete;
                    }
                    Ok(Action::Stuck) => {
                        termination = Termination::Stuck;
                    }
                    Ok(a) => {
                        observer.on_plan(time_s, &a, &map, &planner.tour());
                        action = a;
                        motion.start(&action);
                        need_plan = false;
                    }
                    Err(e) => {
                        termination = Termination::Error;
                        error = Some(e.to_string());
                    }
                }
            }
        }
        let t4 = Instant::now();
        if matches!(
            termination,
            Termination::Complete | Termination::Stuck | Termination::Error
        ) {
            record(&mut times, [t0, t1, t2, t3, t4, t4]);
            break;
        }
        // Motion.
        let (cmd, status) = motion.step(robot.pose, &map);
        robot.apply(cmd, dt);
        if robot.pose.x.is_nan() || robot.pose.y.is_nan() {
            return Err(crate::Error::Runtime("robot pose became NaN".into()));
        }
        if bvh.cylinder_intersects(
            robot.pose.x,
            robot.pose.y,
            cfg.robot.radius_m,
            cfg.map.band_min_m,
            collision_top,
        ) {
            collisions += 1;
        }
        match status {
            MotionStatus::Busy => {}
            MotionStatus::Done | MotionStatus::Blocked => {
                let ctx = PlanContext {
                    map: &map,
                    pose: robot.pose,
                    time_s,
                    cfg,
                    search: &mut search,
                };
                planner.action_finished(&ctx, status == MotionStatus::Done);
                need_plan = true;
            }
        }
        let t5 = Instant::now();
        record(&mut times, [t0, t1, t2, t3, t4, t5]);
        trajectory.push(robot.pose);
        step += 1;

        // Metrics and termination.
        let volume = explored.volume_m3();
        if volume - volume_at_last_gain >= cfg.sim.stuck_min_gain_m3 {
            volume_at_last_gain = volume;
            last_gain_step = step;
        }
        if step.is_multiple_of(curve_period) {
            curve.push(CurveSample {
                t_s: step as f64 / steps_per_s,
                path_length_m: robot.path_length_m,
                explored_volume_m3: volume,
                completeness: explored.completeness(),
            });
        }
        observer.on_step(&StepView {
            step,
            time_s: step as f64 / steps_per_s,
            budget_s: cfg.sim.budget_s,
            pose: robot.pose,
            completeness: explored.completeness(),
            path_length_m: robot.path_length_m,
            frame: fired.then_some(&frame),
            map: &map,
            explored_volume_m3: volume,
            collisions,
            replans,
            field: planner.field(),
            stage_ms: stage_ms([t0, t1, t2, t3, t4, t5]),
        });
        if step - last_gain_step >= stuck_steps {
            termination = Termination::Stuck;
            break;
        }
    }

    let sim_time_s = step as f64 / steps_per_s;
    if curve.last().is_none_or(|c| c.t_s < sim_time_s) {
        curve.push(CurveSample {
            t_s: sim_time_s,
            path_length_m: robot.path_length_m,
            explored_volume_m3: explored.volume_m3(),
            completeness: explored.completeness(),
        });
    }
    let wall_time_s = wall_start.elapsed().as_secs_f64();
    let result = RunResult {
        scene: scene.name.clone(),
        scene_hash: scene.content_hash.clone(),
        planner: planner.name().to_string(),
        seed: cfg.seed,
        spawn: gt.spawn,
        termination,
        error,
        completeness: explored.completeness(),
        explored_volume_m3: explored.volume_m3(),
        observable_volume_m3: observable.volume_m3(),
        reachable_area_m2: gt.reachable_area_m2(),
        explored_outside_observable_fraction: explored.outside_observable_fraction(),
        surface_coverage: surface_coverage(&observable, &map),
        unseen_observable: unseen_patches(&gt, &observable, &map),
        path_length_m: robot.path_length_m,
        sim_time_s,
        wall_time_s,
        real_time_factor: if wall_time_s > 0.0 {
            sim_time_s / wall_time_s
        } else {
            0.0
        },
        collisions,
        steps: step,
        replans,
        astar_calls: search.astar_calls,
        planner_stats: planner.stats(),
        timings_ms: times.summary(),
        version: crate::VERSION.to_string(),
        config_hash: cfg.hash(),
        curve,
    };
    observer.on_finish(&result);
    Ok(RunOutput {
        result,
        map,
        trajectory,
        ground_truth: gt,
    })
}

/// Records the five stage durations delimited by six instants.
fn record(times: &mut StageTimes, t: [Instant; 6]) {
    for (stage, ms) in stage_ms(t).into_iter().enumerate() {
        times.record(stage, ms);
    }
}

/// The five stage durations delimited by six instants, milliseconds.
fn stage_ms(t: [Instant; 6]) -> [f64; 5] {
    std::array::from_fn(|stage| (t[stage + 1] - t[stage]).as_secs_f64() * 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SpawnMode;
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
        }
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
