//! Planners written in Python, run by the step loop through the `Planner` trait.
//!
//! A Python planner is any object with `plan(ctx) -> action`; optionally `action_finished(reached)`,
//! `is_outdated(ctx) -> bool` and `stats() -> dict[str, float]`. `ctx` is a [`PyPlanContext`], valid
//! only during the call. The action is one of the classes of `tensorscout.planner` (`Follow`,
//! `LookAround`, `Complete`, `Stuck`), recognised by their `kind` attribute.

use crate::errors::usage;
use nalgebra::Point2;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::exceptions::{PyException, PyRuntimeError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex, OnceLock};
use tensorscout::grid::CellState;
use tensorscout::map::Map;
use tensorscout::plan::search::Search;
use tensorscout::plan::{search_source, step_cost, Action, Plan, PlanContext, PlanParams, Planner};
use tensorscout::Pose2;

/// A name as `&'static str` (the `Planner` trait's): one leaked copy per distinct name, so a long
/// batch of runs of the same planner leaks nothing more.
pub fn intern(name: &str) -> &'static str {
    static NAMES: OnceLock<Mutex<HashMap<String, &'static str>>> = OnceLock::new();
    let mut names = NAMES.get_or_init(Default::default).lock().expect("names");
    if let Some(n) = names.get(name) {
        return n;
    }
    let leaked: &'static str = Box::leak(name.to_string().into_boxed_str());
    names.insert(name.to_string(), leaked);
    leaked
}

/// The label a Python planner's runs carry: its `name` attribute, else its class name.
pub fn planner_name(obj: &Bound<'_, PyAny>) -> PyResult<String> {
    if let Ok(n) = obj.getattr("name") {
        if let Ok(s) = n.extract::<String>() {
            return Ok(s);
        }
    }
    let class = if obj.is_instance_of::<pyo3::types::PyType>() {
        obj.clone()
    } else {
        obj.getattr("__class__")?
    };
    class.getattr("__name__")?.extract()
}

/// A Python exception that is not an `Exception` (KeyboardInterrupt, SystemExit) raised inside a
/// planner: it does not end the run as an error but is raised again by whoever drives the run.
pub type Pending = Arc<Mutex<Option<PyErr>>>;

/// A planner object written in Python.
pub struct PyPlanner {
    obj: Py<PyAny>,
    name: &'static str,
    pending: Pending,
    /// An exception `is_outdated` raised: the trait's answer there is a bool, so the error ends the
    /// run at the next `plan` call, which the outdated answer brings at once.
    raised_in_is_outdated: Option<tensorscout::Error>,
}

impl PyPlanner {
    pub fn new(obj: Py<PyAny>, name: &str, pending: Pending) -> PyPlanner {
        PyPlanner {
            obj,
            name: intern(name),
            pending,
            raised_in_is_outdated: None,
        }
    }

    /// A Python error as the run's error, with its traceback; a KeyboardInterrupt or SystemExit is
    /// kept for the driver to raise.
    fn failure(&self, py: Python<'_>, e: PyErr, what: &str) -> tensorscout::Error {
        if !e.is_instance_of::<PyException>(py) {
            let msg = e.to_string();
            *self.pending.lock().expect("pending") = Some(e);
            return tensorscout::Error::Runtime(format!("interrupted: {msg}"));
        }
        let tb = format_traceback(py, &e);
        tensorscout::Error::Runtime(format!(
            "python planner {} raised in {what}: {}\n{tb}",
            self.name,
            e.value(py)
        ))
    }

    /// Calls `method(ctx, *args)` with a context over `ctx` that is invalidated after the call.
    #[allow(clippy::too_many_arguments)]
    fn call_with_ctx<T>(
        &self,
        map: &Map,
        params: &PlanParams,
        pose: Pose2,
        time_s: f64,
        search: Option<&mut Search>,
        method: &str,
        extract: impl FnOnce(&Bound<'_, PyAny>) -> PyResult<T>,
    ) -> PyResult<T> {
        Python::attach(|py| {
            let pctx = Bound::new(py, PyPlanContext::over(map, params, pose, time_s, search))?;
            let out = self.obj.bind(py).call_method1(method, (pctx.clone(),));
            pctx.borrow_mut().alive = false;
            extract(&out?)
        })
    }
}

fn format_traceback(py: Python<'_>, e: &PyErr) -> String {
    let formatted = py.import("traceback").and_then(|tb| {
        tb.call_method1(
            "format_exception",
            (e.get_type(py), e.value(py), e.traceback(py)),
        )
    });
    match formatted.and_then(|lines| lines.extract::<Vec<String>>()) {
        Ok(lines) => lines.concat().trim_end().to_string(),
        Err(_) => e.to_string(),
    }
}

/// A Python action object as an [`Action`].
pub fn action_from_py(obj: &Bound<'_, PyAny>) -> PyResult<Action> {
    let py = obj.py();
    let kind: String = obj
        .getattr("kind")
        .and_then(|k| k.extract())
        .map_err(|_| {
            usage(
                py,
                "plan() must return a tensorscout action: Follow(path), LookAround(), Complete() or Stuck()",
            )
        })?;
    match kind.as_str() {
        "follow" => {
            let path: Vec<(f64, f64)> = obj.getattr("path")?.extract().map_err(|_| {
                usage(
                    py,
                    "Follow.path: expected a sequence of (x, y) world points",
                )
            })?;
            if path.iter().any(|(x, y)| !(x.is_finite() && y.is_finite())) {
                return Err(usage(py, "Follow.path: every point must be finite"));
            }
            Ok(Action::Follow {
                path: path.into_iter().map(|(x, y)| Point2::new(x, y)).collect(),
                look_on_arrival: obj.getattr("look_on_arrival")?.extract()?,
                exact_arrival: obj.getattr("exact_arrival")?.extract()?,
            })
        }
        "look_around" => Ok(Action::LookAround),
        "complete" => Ok(Action::Complete),
        "stuck" => Ok(Action::Stuck),
        other => Err(usage(py, format!("unknown action kind `{other}`"))),
    }
}

impl Planner for PyPlanner {
    fn name(&self) -> &'static str {
        self.name
    }

    fn plan(&mut self, ctx: &mut PlanContext) -> tensorscout::Result<Plan> {
        if let Some(e) = self.raised_in_is_outdated.take() {
            return Err(e);
        }
        let search: &mut Search = ctx.search;
        let r = self.call_with_ctx(
            ctx.map,
            ctx.cfg,
            ctx.pose,
            ctx.time_s,
            Some(search),
            "plan",
            action_from_py,
        );
        r.map(Plan::from)
            .map_err(|e| Python::attach(|py| self.failure(py, e, "plan")))
    }

    fn is_outdated(&mut self, ctx: &PlanContext, _action: &Action) -> bool {
        let has = Python::attach(|py| self.obj.bind(py).hasattr("is_outdated").unwrap_or(false));
        if !has {
            return false;
        }
        let answer = self.call_with_ctx(
            ctx.map,
            ctx.cfg,
            ctx.pose,
            ctx.time_s,
            None,
            "is_outdated",
            |r| r.extract::<bool>(),
        );
        answer.unwrap_or_else(|e| {
            let error = Python::attach(|py| self.failure(py, e, "is_outdated"));
            self.raised_in_is_outdated = Some(error);
            true
        })
    }

    fn action_finished(&mut self, _ctx: &PlanContext, reached: bool) {
        Python::attach(|py| {
            let obj = self.obj.bind(py);
            if obj.hasattr("action_finished").unwrap_or(false) {
                if let Err(e) = obj.call_method1("action_finished", (reached,)) {
                    // Not an error path of the trait: shown, and a KeyboardInterrupt kept.
                    if !e.is_instance_of::<PyException>(py) {
                        *self.pending.lock().expect("pending") = Some(e);
                    } else {
                        e.print(py);
                    }
                }
            }
        })
    }

    fn stats(&self) -> BTreeMap<String, f64> {
        Python::attach(|py| {
            let obj = self.obj.bind(py);
            if !obj.hasattr("stats").unwrap_or(false) {
                return BTreeMap::new();
            }
            obj.call_method0("stats")
                .and_then(|d| d.extract::<BTreeMap<String, f64>>())
                .unwrap_or_default()
        })
    }
}

/// What a Python planner sees during `plan(ctx)`: the map arrays, the pose, the frontier cells and
/// groups, and A* and Dijkstra under the cost rule every built-in planner uses. Valid only during
/// the call that received it.
#[pyclass(name = "PlanContext", module = "tensorscout._native")]
pub struct PyPlanContext {
    map: *const Map,
    params: *const PlanParams,
    search: *mut Search,
    pose: Pose2,
    time_s: f64,
    alive: bool,
}

// SAFETY: the pointers are followed only while `alive`, that is during the `plan()` call that lent
// them (`call_with_ctx`), while the step loop that owns the data waits for the call and changes
// nothing; the map and params are only read, and the search workspace is reached only through
// `&mut self`, which Python's borrow of the object makes exclusive. Which thread makes the call (a
// worker of the run pool) or later drops the object does not matter.
unsafe impl Send for PyPlanContext {}
unsafe impl Sync for PyPlanContext {}

impl PyPlanContext {
    fn over(
        map: &Map,
        params: &PlanParams,
        pose: Pose2,
        time_s: f64,
        search: Option<&mut Search>,
    ) -> PyPlanContext {
        PyPlanContext {
            map,
            params,
            search: search.map_or(std::ptr::null_mut(), |s| s as *mut Search),
            pose,
            time_s,
            alive: true,
        }
    }

    /// The map; the lifetime is not tied to `self` so that a search can borrow the workspace
    /// beside it (both are lent by the step loop for the call, see `call_with_ctx`).
    fn map<'m>(&self) -> PyResult<&'m Map> {
        if !self.alive {
            return Err(PyRuntimeError::new_err(
                "this PlanContext was used after the plan() call it was given to",
            ));
        }
        // SAFETY: alive means we are inside the call that lent `map` (see `call_with_ctx`).
        Ok(unsafe { &*self.map })
    }

    fn params<'m>(&self) -> &'m PlanParams {
        // SAFETY: read only after `map()` checked that the context is alive.
        unsafe { &*self.params }
    }

    /// The search workspace, during `plan` only.
    fn search(&mut self) -> PyResult<&mut Search> {
        self.map()?;
        if self.search.is_null() {
            return Err(PyRuntimeError::new_err(
                "searches are available in plan() only",
            ));
        }
        // SAFETY: alive, and the workspace is lent exclusively for the call.
        Ok(unsafe { &mut *self.search })
    }

    fn cell_index(&self, x: f64, y: f64) -> PyResult<Option<usize>> {
        let grid = *self.map()?.grid();
        Ok(grid.cell_of(Point2::new(x, y)).map(|c| grid.index(c)))
    }

    fn source(&self) -> PyResult<Option<usize>> {
        let map = self.map()?;
        let p = self.params();
        Ok(search_source(
            map,
            &p.search,
            self.pose.position(),
            p.robot.radius_m,
        ))
    }
}

/// A grid-shaped array (ny rows, nx columns) of `f(cell)`.
fn grid_array<'py, T: numpy::Element + Copy>(
    py: Python<'py>,
    map: &Map,
    f: impl Fn(usize) -> T,
) -> Bound<'py, PyArray2<T>> {
    let g = map.grid();
    Array2::from_shape_fn((g.ny, g.nx), |(y, x)| f(y * g.nx + x)).into_pyarray(py)
}

/// 0 unknown, 1 free, 2 obstacle (the map's cell states).
pub fn state_code(s: CellState) -> u8 {
    match s {
        CellState::Unknown => 0,
        CellState::Free => 1,
        CellState::Obstacle => 2,
    }
}

#[pymethods]
impl PyPlanContext {
    /// The robot's pose `(x, y, yaw)`, metres and radians.
    #[getter]
    fn pose(&self) -> (f64, f64, f64) {
        (self.pose.x, self.pose.y, self.pose.yaw)
    }

    /// Simulated seconds so far.
    #[getter]
    fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The grid's geometry.
    #[getter]
    fn grid(&self) -> PyResult<crate::simulation::PyGridSpec> {
        Ok((*self.map()?.grid()).into())
    }

    /// Cell states, uint8 (ny, nx): 0 unknown, 1 free, 2 obstacle.
    fn cell_states<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u8>>> {
        let map = self.map()?;
        Ok(grid_array(py, map, |i| state_code(map.cell_state(i))))
    }

    /// Traversable cells (free and clear of the inflated obstacles), bool (ny, nx).
    fn traversable<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<bool>>> {
        let map = self.map()?;
        Ok(grid_array(py, map, |i| map.is_traversable(i)))
    }

    /// Frontier cells, bool (ny, nx).
    fn frontier<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<bool>>> {
        let map = self.map()?;
        Ok(grid_array(py, map, |i| map.is_frontier(i)))
    }

    /// Frontier groups: a list of dicts with `cells` (list of (ix, iy)), `centroid` (x, y) and
    /// `anchor` (ix, iy), the group's cell nearest its centroid.
    fn frontier_groups<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let map = self.map()?;
        let out = PyList::empty(py);
        for seg in map.frontiers() {
            let d = PyDict::new(py);
            let cells: Vec<(i32, i32)> = seg.cells.iter().map(|c| (c.x, c.y)).collect();
            d.set_item("cells", cells)?;
            d.set_item("centroid", (seg.centroid.x, seg.centroid.y))?;
            d.set_item("anchor", (seg.anchor.x, seg.anchor.y))?;
            out.append(d)?;
        }
        Ok(out)
    }

    /// The cell `(ix, iy)` holding world point `(x, y)`, or None off the grid.
    fn cell_of(&self, x: f64, y: f64) -> PyResult<Option<(i32, i32)>> {
        let grid = *self.map()?.grid();
        Ok(grid.cell_of(Point2::new(x, y)).map(|c| (c.x, c.y)))
    }

    /// World centre `(x, y)` of cell `(ix, iy)`.
    fn cell_center(&self, ix: i32, iy: i32) -> PyResult<(f64, f64)> {
        let grid = *self.map()?.grid();
        let p = grid.center(tensorscout::Cell::new(ix, iy));
        Ok((p.x, p.y))
    }

    /// The cost of entering cell `(ix, iy)` now under the shared cost rule, None if it may not be
    /// entered.
    fn step_cost(&self, ix: i32, iy: i32) -> PyResult<Option<f32>> {
        let map = self.map()?;
        let grid = *map.grid();
        let c = tensorscout::Cell::new(ix, iy);
        Ok(grid
            .checked_index(c)
            .and_then(|i| step_cost(map, &self.params().search, self.pose.position(), i)))
    }

    /// Least path costs from the robot to every cell under the shared cost rule (Dijkstra),
    /// float32 (ny, nx), `inf` where unreachable.
    fn distance_field<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let source = self.source()?;
        let map = self.map()?;
        let grid = *map.grid();
        let (cfg, robot) = (&self.params().search, self.pose.position());
        let costs = match source {
            Some(s) => {
                let cost = |i: usize| step_cost(map, cfg, robot, i);
                self.search()?
                    .distance_field(&grid, cost, s, f32::INFINITY)
                    .cost
            }
            None => vec![f32::INFINITY; grid.cells()],
        };
        Ok(Array2::from_shape_vec((grid.ny, grid.nx), costs)
            .expect("grid-sized")
            .into_pyarray(py))
    }

    /// The least-cost path (A*) from the robot to world point `(x, y)` under the shared cost rule,
    /// as world points (cell centres, the robot's cell first), or None if unreachable.
    fn astar(&mut self, x: f64, y: f64) -> PyResult<Option<Vec<(f64, f64)>>> {
        let (Some(source), Some(goal)) = (self.source()?, self.cell_index(x, y)?) else {
            return Ok(None);
        };
        let map = self.map()?;
        let grid = *map.grid();
        let (cfg, robot) = (&self.params().search, self.pose.position());
        let cost = |i: usize| step_cost(map, cfg, robot, i);
        let path = self.search()?.astar(&grid, cost, source, goal);
        Ok(path.map(|p| {
            p.cells
                .iter()
                .map(|c| {
                    let q = grid.center(*c);
                    (q.x, q.y)
                })
                .collect()
        }))
    }
}
