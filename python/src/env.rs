//! The cores of the Gymnasium environments (`tensorscout/Explore-v0` and its vector form): episodes
//! driven by an agent's actions, their rewards and observations, computed in Rust so that a vector
//! of them steps on the rayon pool without the GIL.

use crate::config;
use crate::episode::Episode;
use crate::errors::{guard, raise, usage, IntoPy};
use crate::simulation::{load_scene, warn_all};
use nalgebra::Point2;
use numpy::ndarray::{Array1, Array2, Array3, Array4};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use tensorscout::grid::CellState;
use tensorscout::map::Map;
use tensorscout::plan::{search_source, step_cost, Action, Plan, PlanContext, Planner};
use tensorscout::scene::Scene;
use tensorscout::sim::{Command, NoObserver, ObservableCache, StepOutcome, Termination, World};
use tensorscout::util::on_run_pool;
use tensorscout::{Config, Pose2};

/// How an agent acts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ActionType {
    /// 0 forward `forward_m`, 1 turn left `turn_deg`, 2 turn right `turn_deg` (Habitat's and
    /// PseudoSLAM's actions).
    Discrete,
    /// `(v, w)` within the robot's limits, held for `velocity_steps` steps of `dt`.
    Velocity,
    /// `(x, y)` in the world frame: the motion executor drives there along the A* path under the
    /// shared cost rule; one environment step is one goal.
    Goal,
}

impl ActionType {
    fn parse(py: Python<'_>, s: &str) -> PyResult<ActionType> {
        match s {
            "discrete" => Ok(ActionType::Discrete),
            "velocity" => Ok(ActionType::Velocity),
            "goal" => Ok(ActionType::Goal),
            _ => Err(usage(
                py,
                format!("action_type `{s}`: expected discrete, velocity or goal"),
            )),
        }
    }
}

/// One action of any type.
#[derive(Clone, Copy, Debug)]
pub enum AgentAction {
    Discrete(i64),
    Pair(f64, f64),
}

/// The environment's fixed settings.
#[derive(Clone, Debug)]
pub struct EnvParams {
    pub action_type: ActionType,
    /// Side of the square map crop, cells.
    pub crop_cells: usize,
    pub completeness_target: f64,
    pub collision_penalty: f64,
    pub forward_m: f64,
    pub turn_rad: f64,
    pub velocity_steps: u64,
}

/// The goal of the agent's current `goal` action, shared with the planner that drives to it.
#[derive(Default)]
struct GoalState {
    goal: Option<Point2<f64>>,
    /// The action towards the last goal ended (reached or blocked).
    finished: bool,
    /// Whether the last goal had a path.
    reachable: bool,
}

/// The planner of `goal` actions: the A* path from the robot to the agent's goal under the shared
/// cost rule, followed by the motion executor. A goal without a path ends the step at once.
struct GoalPlanner(Arc<Mutex<GoalState>>);

impl Planner for GoalPlanner {
    fn name(&self) -> &'static str {
        "agent"
    }

    fn plan(&mut self, ctx: &mut PlanContext) -> tensorscout::Result<Plan> {
        let mut st = self.0.lock().expect("goal");
        let goal = st.goal.take();
        let map = ctx.map;
        let grid = *map.grid();
        let (cfg, robot) = (&ctx.cfg.search, ctx.pose.position());
        let path = goal.and_then(|g| {
            let source = search_source(map, cfg, robot, ctx.cfg.robot.radius_m)?;
            let target = grid.index(grid.cell_of(g)?);
            let cost = |i: usize| step_cost(map, cfg, robot, i);
            ctx.search.astar(&grid, cost, source, target)
        });
        st.reachable = path.is_some();
        let path = path
            .map(|p| p.cells.iter().map(|c| grid.center(*c)).collect())
            .unwrap_or_default();
        Ok(Action::Follow {
            path,
            look_on_arrival: false,
            exact_arrival: false,
        }
        .into())
    }

    fn is_outdated(&mut self, _ctx: &PlanContext, _action: &Action) -> bool {
        false
    }

    fn action_finished(&mut self, _ctx: &PlanContext, _reached: bool) {
        self.0.lock().expect("goal").finished = true;
    }
}

/// What the agent observes: the depth image (H·W), the pose and the map crop (S·S·4).
pub struct Obs {
    depth: Vec<f32>,
    pose: [f32; 3],
    map: Vec<u8>,
}

/// The benchmark's metrics after a step.
#[derive(Clone, Debug, Default)]
pub struct Info {
    completeness: f64,
    explored_volume_m3: f64,
    collisions: u64,
    path_length_m: f64,
    time_s: f64,
    steps: u64,
    termination: Option<Termination>,
    goal_reachable: Option<bool>,
}

impl Info {
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("completeness", self.completeness)?;
        d.set_item("explored_volume_m3", self.explored_volume_m3)?;
        d.set_item("collisions", self.collisions)?;
        d.set_item("path_length_m", self.path_length_m)?;
        d.set_item("time_s", self.time_s)?;
        d.set_item("steps", self.steps)?;
        d.set_item("termination", self.termination.map(Termination::as_str))?;
        if let Some(r) = self.goal_reachable {
            d.set_item("goal_reachable", r)?;
        }
        Ok(d)
    }
}

/// A step's outcome.
pub struct StepOut {
    obs: Obs,
    reward: f64,
    terminated: bool,
    truncated: bool,
    info: Info,
}

/// One environment: its scene and config, and the episode in progress.
pub struct EnvCore {
    scene: Arc<Scene>,
    cfg: Config,
    spawn: Option<Pose2>,
    params: EnvParams,
    ep: Option<Episode>,
    goal: Arc<Mutex<GoalState>>,
    next_seed: u64,
    volume: f64,
    collisions: u64,
    ended: bool,
    depth_hw: (usize, usize),
}

impl EnvCore {
    /// Starts an episode with `seed` (default: the seed after the last episode's) and observes.
    fn reset(&mut self, seed: Option<u64>) -> tensorscout::Result<(Obs, Info)> {
        let seed = seed.unwrap_or(self.next_seed);
        self.next_seed = seed.wrapping_add(1);
        let mut cfg = self.cfg.clone();
        cfg.seed = seed;
        let world = World::with_cache(&self.scene, &cfg, self.spawn, &ObservableCache::user())?;
        self.goal = Arc::new(Mutex::new(GoalState::default()));
        let planner = Box::new(GoalPlanner(self.goal.clone()));
        self.ep = None;
        let mut ep = Episode::new(self.scene.clone(), Arc::new(cfg), world, planner);
        // The first step stands still, so that the first observation holds the first frame.
        ep.sim_mut()
            .step_commanded(Command::default(), &mut NoObserver);
        self.ep = Some(ep);
        self.volume = 0.0;
        self.collisions = 0;
        self.ended = false;
        let info = self.info(None);
        self.volume = info.explored_volume_m3;
        self.collisions = info.collisions;
        Ok((self.observe(), info))
    }

    fn ep(&mut self) -> &mut Episode {
        self.ep.as_mut().expect("reset before step")
    }

    fn info(&self, goal_reachable: Option<bool>) -> Info {
        let sim = self.ep.as_ref().expect("episode").sim();
        Info {
            completeness: sim.completeness(),
            explored_volume_m3: sim.explored_volume_m3(),
            collisions: sim.collisions(),
            path_length_m: sim.path_length_m(),
            time_s: sim.time_s(),
            steps: sim.steps(),
            termination: sim.ended(),
            goal_reachable,
        }
    }

    /// One step per command, until the commands or the episode end.
    fn command(&mut self, cmds: &[Command]) {
        let sim = self.ep().sim_mut();
        for &cmd in cmds {
            if sim.step_commanded(cmd, &mut NoObserver) != StepOutcome::Running {
                return;
            }
        }
    }

    /// The simulated seconds `action` is expected to take: the order in which a vector hands its
    /// environments to threads, longest first, so that no thread is left with a long one at the end.
    /// A hint only: results never depend on it.
    fn expected_s(&self, action: Option<AgentAction>) -> f64 {
        let (Some(ep), Some(action)) = (&self.ep, action) else {
            return 0.0;
        };
        let (c, p) = (ep.cfg(), &self.params);
        let (vmax, wmax) = (c.robot.max_speed_mps, c.robot.max_turn_rate_rps);
        match (p.action_type, action) {
            (ActionType::Discrete, AgentAction::Discrete(0)) => p.forward_m / vmax,
            (ActionType::Discrete, _) => p.turn_rad / wmax,
            (ActionType::Velocity, _) => p.velocity_steps as f64 * c.sim.dt_s,
            (ActionType::Goal, AgentAction::Pair(x, y)) if !self.ended => {
                let pose = ep.sim().pose();
                (x - pose.x).hypot(y - pose.y) / vmax
            }
            _ => 0.0,
        }
    }

    /// Runs one agent action.
    fn step(&mut self, action: AgentAction) -> tensorscout::Result<StepOut> {
        if self.ep.is_none() || self.ended {
            return Err(tensorscout::Error::usage(
                "step() after the episode ended (or before reset()); call reset() first",
            ));
        }
        let p = self.params.clone();
        let (dt, vmax, wmax) = {
            let c = self.ep().cfg();
            (c.sim.dt_s, c.robot.max_speed_mps, c.robot.max_turn_rate_rps)
        };
        let mut goal_reachable = None;
        match (p.action_type, action) {
            (ActionType::Discrete, AgentAction::Discrete(a)) => {
                let (total, rate, v_sign, w_sign) = match a {
                    0 => (p.forward_m, vmax, 1.0, 0.0),
                    1 => (p.turn_rad, wmax, 0.0, 1.0),
                    2 => (p.turn_rad, wmax, 0.0, -1.0),
                    _ => {
                        return Err(tensorscout::Error::usage(format!(
                            "discrete action {a}: expected 0 (forward), 1 (left) or 2 (right)"
                        )))
                    }
                };
                // Whole steps at full rate, the last one at the rate that makes the total exact.
                let mut cmds = Vec::new();
                let mut left = total;
                while left > 1e-12 {
                    let r = rate.min(left / dt);
                    cmds.push(Command {
                        v: v_sign * r,
                        w: w_sign * r,
                    });
                    left -= r * dt;
                }
                self.command(&cmds);
            }
            (ActionType::Velocity, AgentAction::Pair(v, w)) => {
                if !(v.is_finite() && w.is_finite()) {
                    return Err(tensorscout::Error::usage(
                        "velocity action: v and w must be finite",
                    ));
                }
                self.command(&vec![Command { v, w }; p.velocity_steps as usize]);
            }
            (ActionType::Goal, AgentAction::Pair(x, y)) => {
                if !(x.is_finite() && y.is_finite()) {
                    return Err(tensorscout::Error::usage(
                        "goal action: x and y must be finite",
                    ));
                }
                {
                    let mut st = self.goal.lock().expect("goal");
                    st.goal = Some(Point2::new(x, y));
                    st.finished = false;
                }
                loop {
                    if self.ep().step(&mut NoObserver) != StepOutcome::Running
                        || self.goal.lock().expect("goal").finished
                    {
                        break;
                    }
                }
                goal_reachable = Some(self.goal.lock().expect("goal").reachable);
            }
            (t, a) => {
                return Err(tensorscout::Error::usage(format!(
                    "action {a:?} does not fit action_type {t:?}"
                )))
            }
        }
        let info = self.info(goal_reachable);
        if info.termination == Some(Termination::Error) {
            let msg = self
                .ep
                .as_ref()
                .and_then(|e| e.sim().error().map(|e| e.to_string()))
                .unwrap_or_default();
            self.ended = true;
            return Err(tensorscout::Error::Runtime(msg));
        }
        let reward = (info.explored_volume_m3 - self.volume)
            - p.collision_penalty * (info.collisions - self.collisions) as f64;
        self.volume = info.explored_volume_m3;
        self.collisions = info.collisions;
        let terminated = info.completeness >= p.completeness_target;
        let truncated = !terminated && info.termination.is_some();
        self.ended = terminated || truncated;
        Ok(StepOut {
            obs: self.observe(),
            reward,
            terminated,
            truncated,
            info,
        })
    }

    /// The observation now.
    fn observe(&self) -> Obs {
        let sim = self.ep.as_ref().expect("episode").sim();
        let frame = sim.frame();
        let (h, w) = self.depth_hw;
        let mut depth = frame.depth_image();
        // Before the first frame (never after reset) the image is empty.
        depth.resize(h * w, 0.0);
        let pose = sim.pose();
        Obs {
            depth,
            pose: [pose.x as f32, pose.y as f32, pose.yaw as f32],
            map: crop(sim.map(), pose, self.params.crop_cells),
        }
    }
}

/// The robot-centred, axis-aligned crop of `s × s` cells of the map: per cell the channels free,
/// obstacle, unknown and frontier (0 or 1); row 0 is the lowest y, column 0 the lowest x. Cells off
/// the map are unknown.
fn crop(map: &Map, pose: Pose2, s: usize) -> Vec<u8> {
    let g = *map.grid();
    let c0 = g.cell_at(pose.x, pose.y);
    let half = (s / 2) as i32;
    let mut out = vec![0u8; s * s * 4];
    for r in 0..s {
        for c in 0..s {
            let cell = tensorscout::Cell::new(c0.x - half + c as i32, c0.y - half + r as i32);
            let o = (r * s + c) * 4;
            match g.checked_index(cell) {
                Some(i) => {
                    match map.cell_state(i) {
                        CellState::Free => out[o] = 1,
                        CellState::Obstacle => out[o + 1] = 1,
                        CellState::Unknown => out[o + 2] = 1,
                    }
                    out[o + 3] = u8::from(map.is_frontier(i));
                }
                None => out[o + 2] = 1,
            }
        }
    }
    out
}

/// The observation as the dict Gymnasium expects.
fn obs_dict<'py>(
    py: Python<'py>,
    o: Obs,
    hw: (usize, usize),
    s: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item(
        "depth",
        Array3::from_shape_vec((hw.0, hw.1, 1), o.depth)
            .expect("frame-sized")
            .into_pyarray(py),
    )?;
    d.set_item("pose", Array1::from_vec(o.pose.to_vec()).into_pyarray(py))?;
    d.set_item(
        "map",
        Array3::from_shape_vec((s, s, 4), o.map)
            .expect("crop-sized")
            .into_pyarray(py),
    )?;
    Ok(d)
}

/// Builds an environment core (scene loaded once, config resolved once).
#[allow(clippy::too_many_arguments)]
fn build_core(
    py: Python<'_>,
    scene: &Path,
    action_type: &str,
    config: Option<&Bound<'_, PyAny>>,
    spawn: Option<&Bound<'_, PyAny>>,
    crop_m: f64,
    completeness_target: f64,
    collision_penalty: f64,
    seed: Option<u64>,
) -> PyResult<EnvCore> {
    let action_type = ActionType::parse(py, action_type)?;
    // The environment's own defaults, which the user's keys replace: no turn in place before the
    // agent's first action, and no `stuck` ending before the budget (the agent decides).
    let defaults = ["sim.initial_look_around=false".to_string()];
    let mut cfg = config::load(py, config, &defaults, seed)?;
    let user_stuck = config
        .and_then(|c| {
            c.cast::<PyDict>()
                .ok()
                .map(|d| d.contains("sim.stuck_timeout_s"))
        })
        .transpose()?
        .unwrap_or(false);
    if !user_stuck {
        cfg.sim.stuck_timeout_s = cfg.sim.budget_s;
    }
    let spawn = config::spawn(py, spawn, &mut cfg)?;
    if !(crop_m.is_finite() && crop_m > 0.0) {
        return Err(usage(
            py,
            format!("map_size_m {crop_m}: expected a positive number"),
        ));
    }
    if !(completeness_target.is_finite() && (0.0..=1.0).contains(&completeness_target)) {
        return Err(usage(
            py,
            format!("completeness_target {completeness_target}: expected 0 to 1"),
        ));
    }
    if !(collision_penalty.is_finite() && collision_penalty >= 0.0) {
        return Err(usage(
            py,
            format!("collision_penalty {collision_penalty}: expected a non-negative number"),
        ));
    }
    let loaded = load_scene(py, scene, &cfg)?;
    let camera = tensorscout::sensor::DepthCamera::new(&cfg.camera);
    let (w, h) = camera.image_size();
    let params = EnvParams {
        action_type,
        crop_cells: ((crop_m / cfg.map.voxel_m).round() as usize).max(1),
        completeness_target,
        collision_penalty,
        forward_m: 0.25,
        turn_rad: 10f64.to_radians(),
        velocity_steps: 1,
    };
    // The first world, built now so that a scene without room for the robot fails here, and so
    // that the observable set is cached before the first reset.
    let world = py
        .detach(|| {
            on_run_pool(|| World::with_cache(&loaded, &cfg, spawn, &ObservableCache::user()))
        })
        .py_err(py)?;
    warn_all(
        py,
        &world
            .observable_source
            .warning()
            .into_iter()
            .collect::<Vec<_>>(),
    )?;
    let next_seed = cfg.seed;
    Ok(EnvCore {
        scene: Arc::new(loaded),
        cfg,
        spawn,
        params,
        ep: None,
        goal: Arc::default(),
        next_seed,
        volume: 0.0,
        collisions: 0,
        ended: false,
        depth_hw: (h, w),
    })
}

fn parse_action(py: Python<'_>, t: ActionType, a: &Bound<'_, PyAny>) -> PyResult<AgentAction> {
    match t {
        ActionType::Discrete => a
            .extract::<i64>()
            .map(AgentAction::Discrete)
            .map_err(|_| usage(py, "discrete action: expected an integer 0, 1 or 2")),
        _ => {
            let v: Vec<f64> = a
                .extract()
                .map_err(|_| usage(py, "action: expected two numbers"))?;
            match v[..] {
                [p, q] => Ok(AgentAction::Pair(p, q)),
                _ => Err(usage(
                    py,
                    format!("action: expected two numbers, got {}", v.len()),
                )),
            }
        }
    }
}

/// The settings every environment core reports to its Python wrapper.
fn describe<'py>(py: Python<'py>, core: &EnvCore) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let c = &core.cfg;
    let g = tensorscout::eval::build_ground_truth(&core.scene, core.spawn, c)
        .map(|gt| gt.grid)
        .py_err(py)?;
    d.set_item("depth_shape", (core.depth_hw.0, core.depth_hw.1))?;
    d.set_item("max_range_m", c.camera.max_range_m.get())?;
    d.set_item("crop_cells", core.params.crop_cells)?;
    d.set_item("max_speed_mps", c.robot.max_speed_mps)?;
    d.set_item("max_turn_rate_rps", c.robot.max_turn_rate_rps)?;
    d.set_item(
        "bounds",
        (
            g.origin_x,
            g.origin_y,
            g.origin_x + g.nx as f64 * g.res,
            g.origin_y + g.ny as f64 * g.res,
        ),
    )?;
    d.set_item("dt_s", c.sim.dt_s)?;
    d.set_item("budget_s", c.sim.budget_s.get())?;
    Ok(d)
}

/// One environment (the core of `tensorscout.ExploreEnv`).
#[pyclass(name = "EnvCore", module = "tensorscout._native")]
pub struct PyEnvCore {
    core: EnvCore,
}

#[pymethods]
impl PyEnvCore {
    #[new]
    #[pyo3(signature = (scene, action_type = "discrete", config = None, spawn = None, map_size_m = 8.0, completeness_target = 0.95, collision_penalty = 0.1, seed = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        scene: PathBuf,
        action_type: &str,
        config: Option<&Bound<'_, PyAny>>,
        spawn: Option<&Bound<'_, PyAny>>,
        map_size_m: f64,
        completeness_target: f64,
        collision_penalty: f64,
        seed: Option<u64>,
    ) -> PyResult<PyEnvCore> {
        guard(py, || {
            Ok(PyEnvCore {
                core: build_core(
                    py,
                    &scene,
                    action_type,
                    config,
                    spawn,
                    map_size_m,
                    completeness_target,
                    collision_penalty,
                    seed,
                )?,
            })
        })
    }

    /// The spaces' sizes and bounds.
    fn describe<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        guard(py, || describe(py, &self.core))
    }

    #[pyo3(signature = (seed = None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seed: Option<u64>,
    ) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
        guard(py, || {
            let core = &mut self.core;
            let (obs, info) = py.detach(|| on_run_pool(|| core.reset(seed))).py_err(py)?;
            let (hw, s) = (self.core.depth_hw, self.core.params.crop_cells);
            Ok((obs_dict(py, obs, hw, s)?, info.to_dict(py)?))
        })
    }

    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        action: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyDict>, f64, bool, bool, Bound<'py, PyDict>)> {
        guard(py, || {
            let a = parse_action(py, self.core.params.action_type, action)?;
            let core = &mut self.core;
            let out = py.detach(|| on_run_pool(|| core.step(a))).py_err(py)?;
            let (hw, s) = (self.core.depth_hw, self.core.params.crop_cells);
            Ok((
                obs_dict(py, out.obs, hw, s)?,
                out.reward,
                out.terminated,
                out.truncated,
                out.info.to_dict(py)?,
            ))
        })
    }
}

/// N environments stepped in parallel, without the GIL (the core of
/// `tensorscout.ExploreVectorEnv`). Each environment's episode depends only on its own seeds and
/// actions, never on the number of threads.
#[pyclass(name = "VecEnvCore", module = "tensorscout._native")]
pub struct PyVecEnvCore {
    cores: Vec<EnvCore>,
    workers: EnvWorkers,
}

/// The threads that step a vector's environments: one single-thread rayon pool each. Every thread
/// takes the next environment from a shared counter, so a long step on one thread does not hold
/// the others back, and an environment's own parallel loops (rendering, integration, planning)
/// run inline on its thread. On one pool of N threads those loops were split between the threads
/// as well, which cost about 4 % more CPU time than one thread and kept two threads at 1.74× one.
struct EnvWorkers {
    pools: Vec<rayon::ThreadPool>,
}

/// Runs `work` once on the thread of each pool and returns when all have finished; the calling
/// thread only waits. (Each pool's thread is kept, so nothing is started per call.)
fn on_each(pools: &[rayon::ThreadPool], work: &(dyn Fn() + Sync)) {
    match pools {
        [] => {}
        [only] => only.install(work),
        [first, rest @ ..] => first.in_place_scope(|s| {
            s.spawn(|_| work());
            on_each(rest, work);
        }),
    }
}

impl EnvWorkers {
    fn new(threads: usize) -> Result<Self, rayon::ThreadPoolBuildError> {
        let pools = (0..threads)
            .map(|_| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(1)
                    .stack_size(8 << 20)
                    .build()
            })
            .collect::<Result<_, _>>()?;
        Ok(EnvWorkers { pools })
    }

    /// `f(i, &mut items[i])` for every item, in parallel, handed to the threads in `order` (every
    /// index once); the results in the items' order. A panic in `f` reaches the caller (after every
    /// thread has stopped).
    fn map<T: Send, R: Send>(
        &self,
        items: &mut [T],
        order: &[usize],
        f: impl Fn(usize, &mut T) -> R + Sync,
    ) -> Vec<R> {
        let n = items.len();
        debug_assert_eq!(order.len(), n);
        let slots: Vec<Mutex<&mut T>> = items.iter_mut().map(Mutex::new).collect();
        let results: Vec<Mutex<Option<R>>> = (0..n).map(|_| Mutex::new(None)).collect();
        let next = AtomicUsize::new(0);
        let work = || {
            while let Some(&i) = order.get(next.fetch_add(1, Ordering::Relaxed)) {
                let mut item = slots[i].lock().unwrap_or_else(|e| e.into_inner());
                let r = f(i, &mut item);
                *results[i].lock().unwrap_or_else(|e| e.into_inner()) = Some(r);
            }
        };
        on_each(&self.pools[..self.pools.len().min(n)], &work);
        results
            .into_iter()
            .map(|r| {
                r.into_inner()
                    .unwrap_or_else(|e| e.into_inner())
                    .expect("every item stepped")
            })
            .collect()
    }
}

/// Stacks the observations of all environments.
fn stack<'py>(
    py: Python<'py>,
    obs: Vec<Obs>,
    hw: (usize, usize),
    s: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let n = obs.len();
    let mut depth = Vec::with_capacity(n * hw.0 * hw.1);
    let mut pose = Vec::with_capacity(n * 3);
    let mut map = Vec::with_capacity(n * s * s * 4);
    for o in obs {
        depth.extend_from_slice(&o.depth);
        pose.extend_from_slice(&o.pose);
        map.extend_from_slice(&o.map);
    }
    let d = PyDict::new(py);
    d.set_item(
        "depth",
        Array4::from_shape_vec((n, hw.0, hw.1, 1), depth)
            .expect("sized")
            .into_pyarray(py),
    )?;
    d.set_item(
        "pose",
        Array2::from_shape_vec((n, 3), pose)
            .expect("sized")
            .into_pyarray(py),
    )?;
    d.set_item(
        "map",
        Array4::from_shape_vec((n, s, s, 4), map)
            .expect("sized")
            .into_pyarray(py),
    )?;
    Ok(d)
}

#[pymethods]
impl PyVecEnvCore {
    #[new]
    #[pyo3(signature = (scene, num_envs, action_type = "discrete", config = None, spawn = None, map_size_m = 8.0, completeness_target = 0.95, collision_penalty = 0.1, seed = None, num_threads = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        scene: PathBuf,
        num_envs: usize,
        action_type: &str,
        config: Option<&Bound<'_, PyAny>>,
        spawn: Option<&Bound<'_, PyAny>>,
        map_size_m: f64,
        completeness_target: f64,
        collision_penalty: f64,
        seed: Option<u64>,
        num_threads: Option<usize>,
    ) -> PyResult<PyVecEnvCore> {
        guard(py, || {
            if num_envs == 0 {
                return Err(usage(py, "num_envs: expected at least 1"));
            }
            if num_threads == Some(0) {
                return Err(usage(py, "num_threads: expected at least 1"));
            }
            let first = build_core(
                py,
                &scene,
                action_type,
                config,
                spawn,
                map_size_m,
                completeness_target,
                collision_penalty,
                seed,
            )?;
            // Environment i starts from seed + i, so that the environments differ by default.
            let cores = (0..num_envs as u64)
                .map(|i| EnvCore {
                    scene: first.scene.clone(),
                    cfg: first.cfg.clone(),
                    spawn: first.spawn,
                    params: first.params.clone(),
                    ep: None,
                    goal: Arc::default(),
                    next_seed: first.next_seed.wrapping_add(i),
                    volume: 0.0,
                    collisions: 0,
                    ended: false,
                    depth_hw: first.depth_hw,
                })
                .collect();
            let threads = num_threads
                .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
            let workers = EnvWorkers::new(threads)
                .map_err(|e| raise(py, "RunError", format!("cannot start the threads: {e}")))?;
            Ok(PyVecEnvCore { cores, workers })
        })
    }

    #[getter]
    fn num_envs(&self) -> usize {
        self.cores.len()
    }

    fn describe<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        guard(py, || describe(py, &self.cores[0]))
    }

    /// Resets every environment whose entry in `mask` is true (all when None) with its seed from
    /// `seeds` (None: the seed after its last episode's); returns the stacked observations of all
    /// and the infos of the reset ones (None for the others).
    #[pyo3(signature = (seeds = None, mask = None))]
    #[allow(clippy::type_complexity)]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seeds: Option<Vec<Option<u64>>>,
        mask: Option<Vec<bool>>,
    ) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyList>)> {
        guard(py, || {
            let n = self.cores.len();
            let seeds = seeds.unwrap_or_else(|| vec![None; n]);
            let mask = mask.unwrap_or_else(|| vec![true; n]);
            if seeds.len() != n || mask.len() != n {
                return Err(usage(
                    py,
                    format!("reset: expected {n} seeds and mask entries"),
                ));
            }
            let (cores, workers) = (&mut self.cores, &self.workers);
            let out: Vec<tensorscout::Result<(Obs, Option<Info>)>> = py.detach(|| {
                workers.map(cores, &(0..n).collect::<Vec<_>>(), |i, c| {
                    if mask[i] {
                        c.reset(seeds[i]).map(|(o, info)| (o, Some(info)))
                    } else {
                        Ok((c.observe(), None))
                    }
                })
            });
            let mut obs = Vec::with_capacity(n);
            let infos = PyList::empty(py);
            for r in out {
                let (o, i) = r.py_err(py)?;
                obs.push(o);
                match i {
                    Some(i) => infos.append(i.to_dict(py)?)?,
                    None => infos.append(py.None())?,
                }
            }
            let (hw, s) = (self.cores[0].depth_hw, self.cores[0].params.crop_cells);
            Ok((stack(py, obs, hw, s)?, infos))
        })
    }

    /// Steps every environment whose entry in `mask` is true (all when None) with its action (a
    /// sequence of N actions; the others' are ignored); returns the stacked observations of all,
    /// rewards, terminated and truncated flags (0 and false for the others), and the infos (None
    /// for the others).
    #[pyo3(signature = (actions, mask = None))]
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: &Bound<'py, PyAny>,
        mask: Option<Vec<bool>>,
    ) -> PyResult<(
        Bound<'py, PyDict>,
        Vec<f64>,
        Vec<bool>,
        Vec<bool>,
        Bound<'py, PyList>,
    )> {
        guard(py, || {
            let n = self.cores.len();
            let items: Vec<Bound<'py, PyAny>> = actions.try_iter()?.collect::<PyResult<_>>()?;
            let mask = mask.unwrap_or_else(|| vec![true; n]);
            if items.len() != n || mask.len() != n {
                return Err(usage(
                    py,
                    format!(
                        "step: expected {n} actions and mask entries, got {} and {}",
                        items.len(),
                        mask.len()
                    ),
                ));
            }
            let t = self.cores[0].params.action_type;
            let acts: Vec<Option<AgentAction>> = items
                .iter()
                .zip(&mask)
                .map(|(a, &m)| m.then(|| parse_action(py, t, a)).transpose())
                .collect::<PyResult<_>>()?;
            let mut order: Vec<usize> = (0..n).collect();
            let expected: Vec<f64> = self
                .cores
                .iter()
                .zip(&acts)
                .map(|(c, a)| c.expected_s(*a))
                .collect();
            order.sort_by(|&a, &b| expected[b].total_cmp(&expected[a]));
            let (cores, workers) = (&mut self.cores, &self.workers);
            let out: Vec<tensorscout::Result<Result<StepOut, Obs>>> = py.detach(|| {
                workers.map(cores, &order, |i, c| match acts[i] {
                    Some(a) => c.step(a).map(Ok),
                    None => Ok(Err(c.observe())),
                })
            });
            let (mut obs, mut rew, mut term, mut trunc) = (vec![], vec![], vec![], vec![]);
            let infos = PyList::empty(py);
            for r in out {
                match r.py_err(py)? {
                    Ok(s) => {
                        obs.push(s.obs);
                        rew.push(s.reward);
                        term.push(s.terminated);
                        trunc.push(s.truncated);
                        infos.append(s.info.to_dict(py)?)?;
                    }
                    Err(o) => {
                        obs.push(o);
                        rew.push(0.0);
                        term.push(false);
                        trunc.push(false);
                        infos.append(py.None())?;
                    }
                }
            }
            let (hw, s) = (self.cores[0].depth_hw, self.cores[0].params.crop_cells);
            Ok((stack(py, obs, hw, s)?, rew, term, trunc, infos))
        })
    }
}
