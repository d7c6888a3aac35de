//! `tensorscout.Simulation`: one exploration from Python, the same step loop `explore` runs.

use crate::config;
use crate::episode::Episode;
use crate::errors::{guard, to_py, usage, IntoPy};
use crate::planner::{planner_name, state_code, Pending, PyPlanner};
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2, PyArray3};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tensorscout::log::{Recorder, RunIdentity, RunLog};
use tensorscout::map::{Map, VoxelState};
use tensorscout::plan::{Planner, PlannerKind};
use tensorscout::scene::{self, Scene};
use tensorscout::sensor::DepthFrame;
use tensorscout::sim::{NoObserver, ObservableCache, Observer, StepOutcome, Termination, World};
use tensorscout::util::on_run_pool;
use tensorscout::{Config, GridSpec, Pose2};

/// Wall time between two checks for Ctrl-C while a run goes on without the GIL.
pub const SIGNAL_CHECK: Duration = Duration::from_millis(50);

/// The built-in planners, by their command-line names.
pub const PLANNERS: [PlannerKind; 4] = [
    PlannerKind::Thp,
    PlannerKind::Tensor,
    PlannerKind::Nbv,
    PlannerKind::Greedy,
];

/// A built-in planner from its name, with the command line's list in the error.
pub fn planner_kind(py: Python<'_>, name: &str) -> PyResult<PlannerKind> {
    PLANNERS
        .into_iter()
        .find(|k| k.name() == name)
        .ok_or_else(|| {
            usage(
                py,
                format!("planner `{name}`: expected one of thp, tensor, nbv, greedy, or a Python planner object"),
            )
        })
}

/// What runs the simulation: a built-in planner or a Python object.
pub enum PlannerChoice {
    Builtin(PlannerKind),
    Python(Py<PyAny>, String),
}

impl PlannerChoice {
    pub fn from_py(obj: &Bound<'_, PyAny>) -> PyResult<PlannerChoice> {
        if let Ok(s) = obj.cast::<PyString>() {
            return Ok(PlannerChoice::Builtin(planner_kind(
                obj.py(),
                &s.extract::<String>()?,
            )?));
        }
        if !obj.hasattr("plan")? {
            return Err(usage(
                obj.py(),
                "planner: expected a built-in planner's name or an object with a plan(ctx) method",
            ));
        }
        Ok(PlannerChoice::Python(
            obj.clone().unbind(),
            planner_name(obj)?,
        ))
    }

    /// The planner object for one run.
    pub fn build(
        &self,
        py: Python<'_>,
        cfg: &Config,
        pending: &Pending,
    ) -> PyResult<Box<dyn Planner + Send>> {
        match self {
            PlannerChoice::Builtin(k) => k.build(cfg).py_err(py),
            PlannerChoice::Python(obj, name) => Ok(Box::new(PyPlanner::new(
                obj.clone_ref(py),
                name,
                pending.clone(),
            ))),
        }
    }

    /// The name results carry.
    pub fn label(&self, cfg: &Config) -> String {
        match self {
            PlannerChoice::Builtin(k) => k.label(cfg),
            PlannerChoice::Python(_, name) => name.clone(),
        }
    }
}

/// Loads a scene with its warnings shown as Python warnings.
pub fn load_scene(py: Python<'_>, path: &Path, cfg: &Config) -> PyResult<Scene> {
    let scene = py.detach(|| scene::load(path, &cfg.scene)).py_err(py)?;
    warn_all(py, &scene.warnings)?;
    Ok(scene)
}

pub fn warn_all(py: Python<'_>, lines: &[String]) -> PyResult<()> {
    if lines.is_empty() {
        return Ok(());
    }
    let warnings = py.import("warnings")?;
    for w in lines {
        warnings.call_method1("warn", (w.as_str(),))?;
    }
    Ok(())
}

/// The grid the 2D layers and the voxels share.
#[pyclass(name = "GridSpec", module = "tensorscout._native", frozen)]
#[derive(Clone, Copy)]
pub struct PyGridSpec {
    /// World x of the minimum corner of cell (0, 0), metres.
    #[pyo3(get)]
    origin_x: f64,
    /// World y of the minimum corner of cell (0, 0), metres.
    #[pyo3(get)]
    origin_y: f64,
    /// Cell and voxel edge, metres.
    #[pyo3(get)]
    resolution: f64,
    #[pyo3(get)]
    nx: usize,
    #[pyo3(get)]
    ny: usize,
    /// Voxel layers above the floor.
    #[pyo3(get)]
    nz: usize,
}

impl From<GridSpec> for PyGridSpec {
    fn from(g: GridSpec) -> Self {
        PyGridSpec {
            origin_x: g.origin_x,
            origin_y: g.origin_y,
            resolution: g.res,
            nx: g.nx,
            ny: g.ny,
            nz: g.nz,
        }
    }
}

#[pymethods]
impl PyGridSpec {
    /// `(origin_x, origin_y)`.
    #[getter]
    fn origin(&self) -> (f64, f64) {
        (self.origin_x, self.origin_y)
    }

    fn __repr__(&self) -> String {
        format!(
            "GridSpec(origin=({}, {}), resolution={}, nx={}, ny={}, nz={})",
            self.origin_x, self.origin_y, self.resolution, self.nx, self.ny, self.nz
        )
    }
}

/// The depth image of `frame`, float32 (H, W), metres along the optical axis, 0 where no reading.
pub fn depth_array<'py>(py: Python<'py>, frame: &DepthFrame) -> Bound<'py, PyArray2<f32>> {
    Array2::from_shape_vec((frame.height, frame.width), frame.depth_image())
        .expect("frame-sized")
        .into_pyarray(py)
}

/// The map's 2D layers: `state` (uint8: 0 unknown, 1 free, 2 obstacle), `known_fraction`
/// (float32: the share of each column's band voxels that are known), `frontier` and `traversable`
/// (bool), all (ny, nx).
pub fn layers_dict<'py>(py: Python<'py>, map: &Map) -> PyResult<Bound<'py, PyDict>> {
    let g = *map.grid();
    let d = PyDict::new(py);
    let state = Array2::from_shape_fn((g.ny, g.nx), |(y, x)| {
        state_code(map.cell_state(y * g.nx + x))
    });
    let mut known = Array2::<f32>::zeros((g.ny, g.nx));
    let per_layer = g.cells();
    for iz in 0..g.nz {
        for (i, k) in known.iter_mut().enumerate() {
            if map.is_voxel_known(iz * per_layer + i) {
                *k += 1.0;
            }
        }
    }
    known.mapv_inplace(|k| k / g.nz as f32);
    let frontier = Array2::from_shape_fn((g.ny, g.nx), |(y, x)| map.is_frontier(y * g.nx + x));
    let trav = Array2::from_shape_fn((g.ny, g.nx), |(y, x)| map.is_traversable(y * g.nx + x));
    d.set_item("state", state.into_pyarray(py))?;
    d.set_item("known_fraction", known.into_pyarray(py))?;
    d.set_item("frontier", frontier.into_pyarray(py))?;
    d.set_item("traversable", trav.into_pyarray(py))?;
    Ok(d)
}

/// The occupancy voxels, uint8 (nz, ny, nx): 0 unknown, 1 free, 2 occupied.
pub fn voxel_array<'py>(py: Python<'py>, map: &Map) -> Bound<'py, PyArray3<u8>> {
    let g = *map.grid();
    let v: Vec<u8> = (0..g.voxels())
        .map(|i| match map.voxel_state(i) {
            VoxelState::Unknown => 0,
            VoxelState::Free => 1,
            VoxelState::Occupied => 2,
        })
        .collect();
    Array3::from_shape_vec((g.nz, g.ny, g.nx), v)
        .expect("grid-sized")
        .into_pyarray(py)
}

/// What is left of a finished run.
struct Finished {
    result: String,
    map: Map,
    frame: DepthFrame,
    pose: Pose2,
    termination: Termination,
    time_s: f64,
    steps: u64,
}

/// One exploration of a scene by a planner, step by step.
#[pyclass(name = "Simulation", module = "tensorscout._native")]
pub struct PySimulation {
    ep: Episode,
    identity: RunIdentity,
    recorder: Option<Recorder<RunLog>>,
    finished: Option<Finished>,
    pending: Pending,
}

impl PySimulation {
    /// The run's simulation; after the run is finished, an error.
    fn live(&self) -> Option<&tensorscout::sim::Simulation<'static>> {
        (!self.ep.is_finished()).then(|| self.ep.sim())
    }

    /// Steps while `more()` and the run goes on, without the GIL; checks for Ctrl-C every
    /// [`SIGNAL_CHECK`]. Finishes the run (and its log) when it ends or is interrupted.
    fn drive(&mut self, py: Python<'_>, mut budget: u64) -> PyResult<()> {
        if self.ep.is_finished() {
            return Ok(());
        }
        loop {
            let ep = &mut self.ep;
            let rec = &mut self.recorder;
            let (outcome, left) = py.detach(move || {
                on_run_pool(move || {
                    let start = Instant::now();
                    let mut outcome = StepOutcome::Running;
                    while budget > 0 && start.elapsed() < SIGNAL_CHECK {
                        let obs: &mut dyn Observer = match rec {
                            Some(r) => r,
                            None => &mut NoObserver,
                        };
                        outcome = ep.step(obs);
                        budget -= 1;
                        if outcome != StepOutcome::Running {
                            break;
                        }
                    }
                    (outcome, budget)
                })
            });
            budget = left;
            let pending = self.pending.lock().expect("pending").take();
            let interrupt = match pending {
                Some(e) => Some(e),
                None => py.check_signals().err(),
            };
            if let Some(e) = interrupt {
                self.finish(py)?;
                return Err(e);
            }
            if outcome != StepOutcome::Running {
                return self.finish(py);
            }
            if budget == 0 {
                return Ok(());
            }
        }
    }

    /// Ends the run: its result, and the log finished (summary written).
    fn finish(&mut self, py: Python<'_>) -> PyResult<()> {
        if self.ep.is_finished() {
            return Ok(());
        }
        let frame = self.ep.sim().frame().clone();
        let out = self.ep.finish();
        let rec = self.recorder.take();
        let closed = py.detach(|| -> tensorscout::Result<()> {
            if let Some(mut r) = rec {
                r.on_finish(&out.result);
                r.sink.close()?;
            }
            Ok(())
        });
        let result = serde_json::to_string(&out.result)
            .map_err(|e| PyRuntimeError::new_err(format!("result: {e}")))?;
        self.finished = Some(Finished {
            result,
            pose: *out
                .trajectory
                .last()
                .expect("the start is in the trajectory"),
            termination: out.result.termination,
            time_s: out.result.sim_time_s,
            steps: out.result.steps,
            map: out.map,
            frame,
        });
        closed.py_err(py)
    }

    fn map(&self) -> &Map {
        match (&self.finished, self.live()) {
            (Some(f), _) => &f.map,
            (None, Some(s)) => s.map(),
            (None, None) => unreachable!("a simulation is either running or finished"),
        }
    }
}

#[pymethods]
impl PySimulation {
    /// A run of the scene at `scene` (any format the command line's `--scene` reads) by `planner`
    /// (a built-in planner's name or a Python planner object) from `spawn` (None: the scene's own;
    /// `(x, y[, yaw])`; `"random"`: drawn from the seed), under `config` (a dict of dotted keys or
    /// a TOML file path) with `seed` (default: the config's).
    #[new]
    #[pyo3(signature = (scene, planner = None, seed = None, spawn = None, config = None))]
    fn new(
        py: Python<'_>,
        scene: PathBuf,
        planner: Option<&Bound<'_, PyAny>>,
        seed: Option<u64>,
        spawn: Option<&Bound<'_, PyAny>>,
        config: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PySimulation> {
        guard(py, || {
            let mut cfg = config::load(py, config, &[], seed)?;
            let spawn = config::spawn(py, spawn, &mut cfg)?;
            let choice = match planner {
                Some(p) if !p.is_none() => PlannerChoice::from_py(p)?,
                _ => PlannerChoice::Builtin(PlannerKind::Thp),
            };
            let pending = Pending::default();
            // Fails on an unavailable planner before the scene is loaded, as `explore` does.
            let planner = choice.build(py, &cfg, &pending)?;
            let loaded = load_scene(py, &scene, &cfg)?;
            let world = py
                .detach(|| {
                    on_run_pool(|| {
                        World::with_cache(&loaded, &cfg, spawn, &ObservableCache::user())
                    })
                })
                .py_err(py)?;
            let mut w = world
                .observable_source
                .warning()
                .into_iter()
                .collect::<Vec<_>>();
            w.extend(scene::open_region_warning(&loaded, &world.ground_truth));
            warn_all(py, &w)?;
            let kind = match &choice {
                PlannerChoice::Builtin(k) => *k,
                PlannerChoice::Python(..) => PlannerKind::Thp,
            };
            let mut identity = RunIdentity::new(&scene, &loaded, kind, &cfg, spawn);
            // A Python planner is logged under its own name.
            identity.planner = choice.label(&cfg);
            let ep = Episode::new(Arc::new(loaded), Arc::new(cfg), world, planner);
            Ok(PySimulation {
                ep,
                identity,
                recorder: None,
                finished: None,
                pending,
            })
        })
    }

    /// Logs the run to the MCAP file `path`, as `explore --log` does (call before the first step;
    /// the log is finished when the run ends, also when it is interrupted).
    fn log(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        guard(py, || {
            if self.ep.is_finished() || self.ep.sim().steps() > 0 || self.recorder.is_some() {
                return Err(usage(py, "log(): call it once, before the first step"));
            }
            let cfg = self.ep.cfg();
            let log = RunLog::create(&path, &self.identity, &cfg.log).map_err(|e| to_py(py, &e))?;
            self.recorder = Some(Recorder::new(log, cfg, &self.ep.scene().mesh, None));
            Ok(())
        })
    }

    /// Runs `n` steps (fewer if the run ends); returns whether the run goes on.
    #[pyo3(signature = (n = 1))]
    fn step(&mut self, py: Python<'_>, n: u64) -> PyResult<bool> {
        guard(py, || {
            self.drive(py, n)?;
            Ok(!self.ep.is_finished())
        })
    }

    /// Runs to the end and returns the result: the object `explore --json` prints, as a dict.
    fn run<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        guard(py, || {
            self.drive(py, u64::MAX)?;
            self.result(py)
        })
    }

    /// The result once the run has ended (as `run()` returns it), else None.
    #[getter]
    fn result<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match &self.finished {
            Some(f) => py
                .import("json")?
                .call_method1("loads", (f.result.as_str(),)),
            None => Ok(py.None().into_bound(py)),
        }
    }

    /// Whether the run has ended.
    #[getter]
    fn done(&self) -> bool {
        self.ep.is_finished()
    }

    /// How the run ended (`complete`, `budget`, `stuck`, `error`, `interrupted`), None while running.
    #[getter]
    fn termination(&self) -> Option<&'static str> {
        self.finished.as_ref().map(|f| f.termination.as_str())
    }

    /// The robot's pose `(x, y, yaw)`.
    #[getter]
    fn pose(&self) -> (f64, f64, f64) {
        let p = match (&self.finished, self.live()) {
            (Some(f), _) => f.pose,
            (None, Some(s)) => s.pose(),
            _ => unreachable!(),
        };
        (p.x, p.y, p.yaw)
    }

    /// Simulated seconds so far.
    #[getter]
    fn time_s(&self) -> f64 {
        match (&self.finished, self.live()) {
            (Some(f), _) => f.time_s,
            (None, Some(s)) => s.time_s(),
            _ => unreachable!(),
        }
    }

    /// Steps run so far.
    #[getter]
    fn steps(&self) -> u64 {
        match (&self.finished, self.live()) {
            (Some(f), _) => f.steps,
            (None, Some(s)) => s.steps(),
            _ => unreachable!(),
        }
    }

    /// The grid of the map layers and voxels.
    #[getter]
    fn grid(&self) -> PyGridSpec {
        (*self.map().grid()).into()
    }

    /// The last depth frame: float32 (H, W), metres along the optical axis, 0 where no reading.
    fn depth<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        let frame = match (&self.finished, self.live()) {
            (Some(f), _) => &f.frame,
            (None, Some(s)) => s.frame(),
            _ => unreachable!(),
        };
        depth_array(py, frame)
    }

    /// The 2D map layers (see the stubs): `state`, `known_fraction`, `frontier`, `traversable`.
    fn map_layers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        layers_dict(py, self.map())
    }

    /// The occupancy voxels, uint8 (nz, ny, nx): 0 unknown, 1 free, 2 occupied.
    fn voxels<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<u8>> {
        voxel_array(py, self.map())
    }
}
