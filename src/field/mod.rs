//! The tensor field engine: constraints, the field (THP Eq. 11), degenerate points, topology,
//! advection, time-varying fields and topological control. It stands on plain per-cell layers
//! ([`FieldInputs`]) so that it does not depend on the map's internals.
//!
//! # Two fields over the same surface constraints
//!
//! - The **planning field** ([`TensorField::field`]): THP Eq. 11 with σ = 2.5·d_s at the map's cell
//!   size, plus the constraints of the current path (THP Eq. 10, [`TensorField::set_path`]). Advection,
//!   time-varying interpolation and the planners' queries read this one.
//! - The **topology field** ([`TensorField::topology_field`]): the surface constraints only, with
//!   σ·`topology_sigma_factor` on cells `topology_cell_factor` times wider. Degenerate points,
//!   separatrices and the graph are computed on it.
//!
//! # The axis-aligned trap, and how it is handled
//!
//! With walls at 0° and 90° only, every constraint has `b = 0`; `a` vanishes on whole curves where
//! horizontal and vertical walls balance (the 45° branches of the medial axis from each corner), and a
//! naive winding number there reports noise. The true degenerate points of such a layout sit where the
//! few non-axis constraints (corners) make `b` change sign along those curves — at medial-axis nodes:
//! room centres, doorways, junctions — but with σ = 0.5 m a corner's weight at a room centre 3 m away is
//! ~1e-16 of the nearest wall's, below rounding: the points are numerically undefined. The engine:
//!
//! 1. fits tangents by PCA over the surface cells around each sample in *exact integer arithmetic*, so
//!    straight axis-aligned walls give exactly `b = 0` and corners (an L of cells) a diagonal tangent
//!    (corner-aware: the corner sample sees both arms);
//! 2. forms `(cos 2θ, sin 2θ)` without trigonometry, so no `sin π ≈ 1.2e-16` leaks into `b`;
//! 3. finds the points on the regularised topology field (σ doubled by default), where corner
//!    contributions at room centres are ~1e-4 to 1e-7 of the walls' instead of 1e-16 or less;
//! 4. counts windings with a symbolic perturbation (zero counts as positive), so a region with `b ≡ 0`
//!    exactly (no corner within range) reports *no* point instead of noise;
//! 5. drops points closer than `min_clearance_m` to an obstacle (inside furniture, against walls:
//!    unreachable anchors), before building the graph.
//!
//! Tests (`tests` below) check on axis-aligned layouts that points are few, sit at room centres and
//! junctions, and keep their position and id when more of the scene is revealed.
//!
//! # A bounded range (not in any paper)
//!
//! Eq. 11 defines the field everywhere, and far from every wall its value is the normalised sum of
//! weights that have all decayed alike: it carries no information, yet a far cell depends on most
//! constraints, so every change of the map recomputed far tiles and the field's cost grew with the
//! grid. With a range `D` ([`TensorField::with_range`], `additions.field_range_m`), a cell farther
//! than `D` from every surface constraint takes only the limited (path) constraints, and none: no
//! field (zero tensor, no degenerate point). A change then touches only tiles within
//! `t + √((D + 2t)² + R²)` of it (`t` half a tile's diagonal, `R` the kernel's cutoff radius). The
//! edge where the field ends can hold degenerate points of its own, so `D` must lie beyond where the
//! planners look (20 m by default; `configs/default.toml` says what shorter ranges did).

pub(crate) mod advect;
pub(crate) mod clearance;
pub(crate) mod constraints;
pub(crate) mod control;
pub(crate) mod degenerate;
pub mod eval;
#[cfg(test)]
pub(crate) mod synth;
pub(crate) mod timevary;
pub(crate) mod topology;

pub use advect::{pathline, StopConditions, StopReason};
pub use constraints::{path_constraints, Constraint, SurfaceSampler};
pub use degenerate::{DegenerateKind, DegeneratePoint};
pub use eval::{FieldGrid, FieldLevel, Kernel, TensorSample};
pub use timevary::{biharmonic_window, linear_window, SpaceTimeParams, TimeVaryingField};
pub use topology::{EdgeKind, TopologyGraph};

use crate::config::FieldConfig;
use crate::error::{Error, Result};
use crate::grid::{Cell, CellRect, GridSpec, NEIGHBOURS_8};
use nalgebra::Point2;
use serde::Serialize;
use std::sync::{Arc, OnceLock};
use std::time::Instant;

/// The per-cell layers the field reads from the map (flat cell indices of `grid()`).
pub trait FieldInputs {
    fn grid(&self) -> &GridSpec;
    /// Occupied column in the height band, projected to the floor.
    fn is_surface(&self, cell: usize) -> bool;
    fn is_obstacle(&self, cell: usize) -> bool;
    fn is_unknown(&self, cell: usize) -> bool;
    /// The cells outside which every cell is unknown, no obstacle and no surface: a key frame reads
    /// the layers only inside it (the whole grid unless the inputs know better).
    fn touched(&self) -> CellRect {
        CellRect::all(self.grid())
    }
}

/// The map's layers drive the field during a run.
impl FieldInputs for crate::map::Map {
    fn grid(&self) -> &GridSpec {
        crate::map::Map::grid(self)
    }
    fn is_surface(&self, cell: usize) -> bool {
        crate::map::Map::is_surface(self, cell)
    }
    fn is_obstacle(&self, cell: usize) -> bool {
        crate::map::Map::is_obstacle(self, cell)
    }
    fn is_unknown(&self, cell: usize) -> bool {
        crate::map::Map::is_unknown(self, cell)
    }
    fn touched(&self) -> CellRect {
        crate::map::Map::touched(self)
    }
}

/// [`FieldInputs`] over plain slices (one flag per cell).
#[derive(Clone, Copy, Debug)]
pub struct MaskInputs<'a> {
    pub grid: &'a GridSpec,
    pub surface: &'a [bool],
    pub obstacle: &'a [bool],
    pub unknown: Option<&'a [bool]>,
}

impl<'a> MaskInputs<'a> {
    /// Checks that every layer has one flag per cell.
    pub fn new(
        grid: &'a GridSpec,
        surface: &'a [bool],
        obstacle: &'a [bool],
        unknown: Option<&'a [bool]>,
    ) -> Result<Self> {
        let n = grid.cells();
        for (name, len) in [
            ("surface", Some(surface.len())),
            ("obstacle", Some(obstacle.len())),
            ("unknown", unknown.map(|u| u.len())),
        ] {
            if let Some(len) = len {
                if len != n {
                    return Err(Error::Runtime(format!(
                        "field input layer `{name}` has {len} cells, the grid has {n}"
                    )));
                }
            }
        }
        Ok(MaskInputs {
            grid,
            surface,
            obstacle,
            unknown,
        })
    }
}

impl FieldInputs for MaskInputs<'_> {
    fn grid(&self) -> &GridSpec {
        self.grid
    }
    fn is_surface(&self, cell: usize) -> bool {
        self.surface[cell]
    }
    fn is_obstacle(&self, cell: usize) -> bool {
        self.obstacle[cell]
    }
    fn is_unknown(&self, cell: usize) -> bool {
        self.unknown.is_some_and(|u| u[cell])
    }
}

/// What one key-frame update did and how long it took.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct UpdateStats {
    pub samples_added: usize,
    pub samples_removed: usize,
    pub samples_refitted: usize,
    pub cells_evaluated: usize,
    pub sampling_ms: f64,
    pub field_ms: f64,
    pub topology_ms: f64,
}

/// Counts of the topological control operations applied in the last update.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ControlCounts {
    pub cancelled_pairs: usize,
    pub moved_wedges: usize,
    pub moved_trisectors: usize,
}

/// The field of one run, updated at key frames.
#[derive(Clone, Debug)]
pub struct TensorField {
    cfg: FieldConfig,
    grid: GridSpec,
    sampler: SurfaceSampler,
    main: FieldLevel,
    topo: Option<FieldLevel>,
    /// Leave the planning field's changed tiles pending until read ([`TensorField::set_lazy_planning_field`]).
    lazy_planning: bool,
    /// The planning field with its pending tiles computed, for readers holding `&self`.
    planning_snapshot: OnceLock<FieldGrid>,
    /// Per sample id: its constraint's ids in the main and topology levels.
    sample_ids: Vec<(Option<u32>, Option<u32>)>,
    path_ids: Vec<u32>,
    /// The obstacle layer of the last update, indexed for clearance queries.
    obstacle: clearance::ObstacleIndex,
    unknown: Arc<Vec<bool>>,
    tracker: degenerate::Tracker,
    topo_field: FieldGrid,
    /// Tracked degenerate points of the last key frame (the graph's nodes).
    nodes: Vec<DegeneratePoint>,
    /// The topology graph, built on first use: THP reads only the points, so separatrices and
    /// pairing are traced only for a reader of [`TensorField::graph`] (TENSOR, logs, drawing).
    graph: OnceLock<TopologyGraph>,
    /// The obstacle and unknown layers the pending graph is built with (those of its key frame).
    graph_inputs: (Arc<Vec<bool>>, Arc<Vec<bool>>),
    control: ControlCounts,
}

impl TensorField {
    pub fn new(grid: GridSpec, cfg: &FieldConfig) -> Self {
        let main = FieldLevel::new(
            grid,
            1,
            Kernel::new(cfg.sigma_m, cfg.decay, cfg.weight_cutoff),
        );
        let separate_topology = cfg.topology_sigma_factor != 1.0 || cfg.topology_cell_factor != 1;
        let topo = separate_topology.then(|| {
            FieldLevel::new(
                grid,
                cfg.topology_cell_factor,
                Kernel::new(
                    cfg.sigma_m * cfg.topology_sigma_factor,
                    cfg.decay,
                    cfg.weight_cutoff,
                ),
            )
        });
        let topo_field = topo.as_ref().unwrap_or(&main).grid.clone();
        TensorField {
            cfg: cfg.clone(),
            grid,
            sampler: SurfaceSampler::new(
                grid,
                cfg.d_s_m,
                cfg.tangent_radius_m,
                cfg.min_tangent_anisotropy,
            ),
            main,
            topo,
            lazy_planning: false,
            planning_snapshot: OnceLock::new(),
            sample_ids: Vec::new(),
            path_ids: Vec::new(),
            obstacle: clearance::ObstacleIndex::from_fn(grid, CellRect::EMPTY, |_| false),
            unknown: Arc::new(vec![false; grid.cells()]),
            tracker: degenerate::Tracker::default(),
            topo_field,
            nodes: Vec::new(),
            graph: OnceLock::from(TopologyGraph::default()),
            graph_inputs: Default::default(),
            control: ControlCounts::default(),
        }
    }

    /// The field with no value farther than `range_m` from every surface constraint (module doc, "A
    /// bounded range"); 0 or ∞ keeps Eq. 11 everywhere. Call on a new field, before its first update.
    pub fn with_range(mut self, range_m: f64) -> Self {
        if range_m > 0.0 {
            self.main.set_range(range_m);
            if let Some(topo) = &mut self.topo {
                topo.set_range(range_m);
            }
        }
        self
    }

    pub fn grid(&self) -> &GridSpec {
        &self.grid
    }

    pub fn config(&self) -> &FieldConfig {
        &self.cfg
    }

    /// The planning field's grid of `(a, b)` (pending tiles computed on first read).
    pub fn field(&self) -> &FieldGrid {
        if self.main.is_stale() {
            self.planning_snapshot
                .get_or_init(|| self.main.refreshed_grid())
        } else {
            &self.main.grid
        }
    }

    /// Lazy planning field: key frames and [`TensorField::set_path`] leave the planning field's
    /// changed tiles pending, and [`TensorField::pathline_computing`] computes only those its pathline
    /// reads. THP reads the planning field only along its pathlines, a few metres around the robot,
    /// while each key frame changes it wherever the map grew. Readers of [`TensorField::field`] still
    /// see the whole field, equal bit for bit (a tile's value depends only on the constraint set).
    /// Needs a separate topology level (topology reads the whole field); without one it has no effect.
    pub fn set_lazy_planning_field(&mut self, lazy: bool) {
        self.lazy_planning = lazy && self.topo.is_some();
        if !self.lazy_planning {
            self.main.refresh();
            self.planning_snapshot = OnceLock::new();
        }
    }

    /// The (regularised, possibly edited by topological control) field the topology was computed on.
    pub fn topology_field(&self) -> &FieldGrid {
        &self.topo_field
    }

    /// The planning field at `p` (bilinear between cell centres).
    pub fn sample(&self, p: Point2<f64>) -> Option<TensorSample> {
        self.field().sample(p)
    }

    /// Degenerate points of the last key frame, with stable ids.
    pub fn points(&self) -> &[DegeneratePoint] {
        &self.nodes
    }

    /// The topology graph of the last key frame (built now if no one asked for it yet).
    pub fn graph(&self) -> &TopologyGraph {
        self.graph.get_or_init(|| {
            let (obstacle, unknown) = &self.graph_inputs;
            self.build_graph(&self.topo_field, self.nodes.clone(), obstacle, unknown)
        })
    }

    pub fn control_counts(&self) -> ControlCounts {
        self.control
    }

    /// Every constraint of the planning field (surface and path).
    pub fn constraints(&self) -> Vec<Constraint> {
        self.main.store().all()
    }

    /// Number of surface constraints (samples with a tangent).
    pub fn surface_constraint_count(&self) -> usize {
        self.sample_ids.iter().filter(|s| s.0.is_some()).count()
    }

    /// Distance from `p` to the nearest known obstacle (exact Euclidean distance between cell centres; ∞ if none).
    pub fn clearance_at(&self, p: Point2<f64>) -> f64 {
        self.grid
            .cell_of(p)
            .map(|c| self.obstacle.clearance(self.grid.index(c)))
            .unwrap_or(0.0)
    }

    /// One key frame: samples the new surface, updates both fields incrementally, recomputes the
    /// degenerate points (tracked ids) and the topology graph.
    pub fn update(&mut self, inputs: &impl FieldInputs) -> Result<UpdateStats> {
        let mut stats = self.update_field(inputs)?;
        let t = Instant::now();
        self.compute_topology();
        stats.topology_ms = ms(t);
        Ok(stats)
    }

    /// The field part of a key frame (sampling and both fields, incrementally), without topology.
    pub fn update_field(&mut self, inputs: &impl FieldInputs) -> Result<UpdateStats> {
        if inputs.grid() != &self.grid {
            return Err(Error::Runtime(
                "field inputs use a different grid than the field".into(),
            ));
        }
        let mut stats = UpdateStats::default();
        let t0 = Instant::now();
        // Fresh layers (not written in place): a graph not built yet keeps those of its key frame.
        let touched = inputs.touched().clip(&self.grid);
        self.obstacle =
            clearance::ObstacleIndex::from_fn(self.grid, touched, |i| inputs.is_obstacle(i));
        let mut unknown = vec![true; self.grid.cells()];
        for i in touched.rows(&self.grid).flatten() {
            unknown[i] = inputs.is_unknown(i);
        }
        self.unknown = Arc::new(unknown);
        let changes = self.sampler.update(touched, |i| inputs.is_surface(i));
        stats.samples_added = changes.added.len();
        stats.samples_removed = changes.removed.len();
        stats.samples_refitted = changes.refitted.len();
        for &id in changes.removed.iter().chain(&changes.refitted) {
            if let Some((m, t)) = self.sample_ids.get_mut(id as usize).map(std::mem::take) {
                if let Some(m) = m {
                    self.main.remove(m);
                }
                if let (Some(t), Some(level)) = (t, self.topo.as_mut()) {
                    level.remove(t);
                }
            }
        }
        for &id in changes.added.iter().chain(&changes.refitted) {
            if self.sample_ids.len() <= id as usize {
                self.sample_ids.resize(id as usize + 1, (None, None));
            }
            if let Some(c) = self.sampler.constraint(id) {
                let m = self.main.insert(c);
                let t = self.topo.as_mut().map(|l| l.insert(c));
                self.sample_ids[id as usize] = (Some(m), t);
            }
        }
        stats.sampling_ms = ms(t0);
        let t1 = Instant::now();
        self.planning_snapshot = OnceLock::new();
        let main = if self.lazy_planning {
            0
        } else {
            self.main.refresh()
        };
        stats.cells_evaluated = main + self.topo.as_mut().map_or(0, |l| l.refresh());
        stats.field_ms = ms(t1);
        Ok(stats)
    }

    /// Replaces the path constraints (THP Eq. 10) of the planning field; the topology is unchanged.
    /// The path changes the field only within σ of itself (THP §3.5), so an update recomputes a
    /// narrow band around the old and the new path (or, lazy, leaves it pending).
    pub fn set_path(&mut self, path: &[Point2<f64>]) -> usize {
        self.planning_snapshot = OnceLock::new();
        for id in std::mem::take(&mut self.path_ids) {
            self.main.remove(id);
        }
        let sigma = self.cfg.sigma_m;
        for c in path_constraints(path, self.cfg.d_s_m, self.cfg.path_strength, sigma) {
            if self.grid.cell_of(c.pos).is_some() {
                self.path_ids.push(self.main.insert(c));
            }
        }
        if self.lazy_planning {
            0
        } else {
            self.main.refresh()
        }
    }

    /// Recomputes both fields from scratch (the bench's "full recompute"); returns cells evaluated.
    pub fn recompute_all(&mut self) -> usize {
        self.planning_snapshot = OnceLock::new();
        self.main.recompute_all() + self.topo.as_mut().map_or(0, |l| l.recompute_all())
    }

    /// Recomputes the planning field alone from scratch (compared with the reference in the bench).
    pub fn recompute_planning_field(&mut self) -> usize {
        self.planning_snapshot = OnceLock::new();
        self.main.recompute_all()
    }

    /// A pathline of the planning field from `start`, leaving along the direction nearest `heading`,
    /// stopping at obstacles, unknown cells (if `stop_at_unknown`) and near degenerate points.
    pub fn pathline(
        &self,
        start: Point2<f64>,
        heading: f64,
        max_len: f64,
        stop_at_unknown: bool,
    ) -> (Vec<Point2<f64>>, StopReason) {
        self.pathline_on(self.field(), start, heading, max_len, stop_at_unknown)
    }

    /// [`TensorField::pathline`] that, with the lazy planning field, computes only the pending tiles
    /// the pathline reads, and returns the same line.
    ///
    /// A pathline reads the field within `reach` of its start and points (the RK4 stages one step
    /// ahead, and the cell centres around each sample). Traced on the level as it stands, some
    /// reads may be of pending tiles; those tiles are computed and the line traced again, until a
    /// trace finds every tile it read up to date. That trace read only final values, so it is the
    /// line the whole field gives. It ends: each round computes at least one of finitely many tiles.
    pub fn pathline_computing(
        &mut self,
        start: Point2<f64>,
        heading: f64,
        max_len: f64,
        stop_at_unknown: bool,
    ) -> (Vec<Point2<f64>>, StopReason) {
        let reach = 2.0 * self.cfg.rk4_step_m + 2.0 * self.main.grid.spec.res;
        loop {
            let (line, reason) =
                self.pathline_on(&self.main.grid, start, heading, max_len, stop_at_unknown);
            let read = std::iter::once(start).chain(line.iter().copied());
            if self.main.refresh_along(read, reach) == 0 {
                // Every tile this trace read was up to date.
                return (line, reason);
            }
            self.planning_snapshot = OnceLock::new();
        }
    }

    /// A pathline of `field` under this field's stop conditions.
    fn pathline_on(
        &self,
        field: &FieldGrid,
        start: Point2<f64>,
        heading: f64,
        max_len: f64,
        stop_at_unknown: bool,
    ) -> (Vec<Point2<f64>>, StopReason) {
        let pts: Vec<Point2<f64>> = self.nodes.iter().map(|n| n.pos()).collect();
        let stop = StopConditions {
            grid: &self.grid,
            obstacle: Some(self.obstacle.mask()),
            unknown: stop_at_unknown.then_some(&self.unknown[..]),
            degenerate_points: &pts,
            degenerate_radius_m: self.cfg.arrive_radius_m,
            origin: None,
        };
        pathline(field, start, heading, max_len, self.cfg.rk4_step_m, &stop)
    }

    /// Degenerate points (tracked), separatrices and graph, with topological control if enabled.
    /// Public so that the bench can time it on its own.
    pub fn compute_topology(&mut self) {
        self.topo_field
            .clone_from(&self.topo.as_ref().unwrap_or(&self.main).grid);
        let mut nodes = self.find_points(&self.topo_field);
        self.control = ControlCounts::default();
        // Moves need no graph: apply them first, so the graph is built once in the default setting.
        if self.cfg.move_trisectors_from_obstacles || self.cfg.move_wedges_into_corners {
            let mut edited = self.topo_field.clone();
            self.move_points(&mut edited, &nodes);
            if self.control != ControlCounts::default() {
                self.topo_field = edited;
                nodes = self.find_points(&self.topo_field);
            }
        }
        let inputs = (self.obstacle.mask().clone(), self.unknown.clone());
        let mut graph = None;
        if self.cfg.cancel_pairs {
            // Cancellation needs the graph's distances: build it now.
            let built = self.build_graph(&self.topo_field, nodes.clone(), &inputs.0, &inputs.1);
            let mut edited = self.topo_field.clone();
            let cancelled = self.cancel_pairs(&mut edited, &built);
            if cancelled > 0 {
                self.control.cancelled_pairs = cancelled;
                nodes = self.find_points(&edited);
                self.topo_field = edited;
            } else {
                graph = Some(built);
            }
        }
        // Tracking keeps the order of the points, and the graph does not read their ids, so a graph
        // built from the tracked points equals one built before tracking (as it was) and relabelled.
        self.nodes = self.tracker.assign(nodes, self.cfg.track_radius_m);
        self.graph = OnceLock::new();
        if let Some(mut g) = graph {
            g.nodes = self.nodes.clone();
            let _ = self.graph.set(g);
        }
        self.graph_inputs = inputs;
    }

    /// Separatrices and the graph of `nodes` on `field` (the last key frame's layers).
    fn build_graph(
        &self,
        field: &FieldGrid,
        nodes: Vec<DegeneratePoint>,
        obstacle: &[bool],
        unknown: &[bool],
    ) -> TopologyGraph {
        let opts = topology::TraceOptions {
            step_m: self.cfg.rk4_step_m,
            max_length_m: self.cfg.separatrix_max_length_m,
            arrive_radius_m: self.cfg.arrive_radius_m,
            stop_at_unknown: self.cfg.stop_at_unknown,
        };
        topology::build(field, nodes, &self.grid, obstacle, unknown, &opts)
    }

    /// Points of `field` with their clearance, without those too close to obstacles (ids unset).
    fn find_points(&self, field: &FieldGrid) -> Vec<DegeneratePoint> {
        degenerate::detect(field)
            .into_iter()
            .filter_map(|r| {
                let kind = DegenerateKind::of_winding(r.winding)?;
                let clearance_m = self.clearance_at(r.pos);
                (clearance_m >= self.cfg.min_clearance_m && clearance_m > 0.0).then_some(
                    DegeneratePoint {
                        id: 0,
                        x: r.pos.x,
                        y: r.pos.y,
                        kind,
                        winding: r.winding,
                        clearance_m,
                    },
                )
            })
            .collect()
    }

    /// TENSOR Eq. 6 cancellations on `edited`; returns how many pairs were cancelled.
    fn cancel_pairs(&self, edited: &mut FieldGrid, graph: &TopologyGraph) -> usize {
        let nodes = &graph.nodes;
        let mut used = vec![false; nodes.len()];
        let mut pairs = Vec::new();
        for (w, nw) in nodes.iter().enumerate() {
            if nw.kind != DegenerateKind::Wedge {
                continue;
            }
            let dist = graph.distances_from(w);
            for (t, nt) in nodes.iter().enumerate() {
                if nt.kind == DegenerateKind::Trisector && dist[t] < nw.clearance_m + nt.clearance_m
                {
                    pairs.push((dist[t], w, t));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2))));
        let mut cancelled = 0;
        for (_, w, t) in pairs {
            if used[w] || used[t] {
                continue;
            }
            let (pw, pt) = (nodes[w].pos(), nodes[t].pos());
            let mid = Point2::new(0.5 * (pw.x + pt.x), 0.5 * (pw.y + pt.y));
            let r = 0.5 * (pw - pt).norm() + 2.0 * edited.spec.res;
            if control::cancel_in_disc(edited, mid, r, self.cfg.cancel_max_iterations) {
                used[w] = true;
                used[t] = true;
                cancelled += 1;
            }
        }
        cancelled
    }

    /// Moves trisectors out from obstacles and sharp wedges into their corners, on `edited`.
    fn move_points(&mut self, edited: &mut FieldGrid, nodes: &[DegeneratePoint]) {
        for n in nodes {
            let target = match n.kind {
                DegenerateKind::Trisector
                    if self.cfg.move_trisectors_from_obstacles
                        && n.clearance_m < self.cfg.trisector_clearance_m =>
                {
                    self.climb(n.pos(), |c| c >= self.cfg.trisector_clearance_m, 1.0)
                }
                DegenerateKind::Wedge
                    if self.cfg.move_wedges_into_corners
                        && sharp(&topology::separatrix_directions(edited, n.pos())) =>
                {
                    self.climb(n.pos(), |c| c < 0.5 * self.cfg.min_clearance_m, -1.0)
                }
                _ => None,
            };
            if let Some(to) = target {
                control::move_point(edited, n.pos(), to);
                if n.kind == DegenerateKind::Trisector {
                    self.control.moved_trisectors += 1;
                } else {
                    self.control.moved_wedges += 1;
                }
            }
        }
    }

    /// Walks from `p` up (`sign` = 1) or down (−1) the clearance until `done`, within `max_move_m`.
    fn climb(&self, p: Point2<f64>, done: impl Fn(f64) -> bool, sign: f64) -> Option<Point2<f64>> {
        let g = &self.grid;
        let mut c = g.cell_of(p)?;
        let steps = (self.cfg.max_move_m / g.res).floor() as usize;
        for _ in 0..steps {
            let here = self.obstacle.clearance(g.index(c));
            if done(here) {
                let q = g.center(c);
                return ((q - p).norm() > 0.0).then_some(q);
            }
            let next = NEIGHBOURS_8
                .iter()
                .filter_map(|&(dx, dy)| {
                    g.checked_index(Cell::new(c.x + dx, c.y + dy))
                        .map(|i| (self.obstacle.clearance(i), dx, dy))
                })
                .max_by(|a, b| (sign * a.0).total_cmp(&(sign * b.0)))?;
            if sign * next.0 <= sign * here {
                return None;
            }
            c = Cell::new(c.x + next.1, c.y + next.2);
        }
        None
    }
}

/// Whether two of the separatrix directions `dirs` (radians) are under 90° apart (a wedge made by a
/// sharp corner).
fn sharp(dirs: &[f64]) -> bool {
    let mut dirs: Vec<f64> = dirs
        .iter()
        .map(|d| d.rem_euclid(std::f64::consts::TAU))
        .collect();
    if dirs.len() < 2 {
        return false;
    }
    dirs.sort_by(f64::total_cmp);
    let n = dirs.len();
    (0..n).any(|k| {
        let gap = if k + 1 < n {
            dirs[k + 1] - dirs[k]
        } else {
            dirs[0] + std::f64::consts::TAU - dirs[k]
        };
        gap < std::f64::consts::FRAC_PI_2
    })
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The field of a fully observed layout (surface and obstacle layers of `grid`), in one key frame,
/// with what the update measured.
pub fn full_field(
    grid: &GridSpec,
    surface: &[bool],
    obstacle: &[bool],
    cfg: &FieldConfig,
) -> Result<(TensorField, UpdateStats)> {
    let inputs = MaskInputs::new(grid, surface, obstacle, None)?;
    let mut field = TensorField::new(*grid, cfg);
    let stats = field.update(&inputs)?;
    Ok((field, stats))
}

/// Fast field against the brute-force reference on the planning field.
#[derive(Clone, Debug, Serialize)]
pub struct ReferenceComparison {
    /// Largest difference of major-eigenvector angle where the reference's coherence ≥ 1e-4, radians.
    pub max_orientation_difference_rad: f64,
    pub reference_ms: f64,
    pub fast_full_ms: f64,
    pub speed_ratio: f64,
}

/// Runs the reference over every constraint and a full fast recompute, and compares them.
pub fn max_orientation_difference_vs_reference(field: &mut TensorField) -> ReferenceComparison {
    let cs = field.constraints();
    let t = Instant::now();
    let reference = eval::reference_grid(&cs, &field.grid, field.main.kernel());
    let reference_ms = ms(t);
    let t = Instant::now();
    field.recompute_planning_field();
    let fast_full_ms = ms(t);
    ReferenceComparison {
        max_orientation_difference_rad: eval::max_orientation_difference(
            field.field(),
            &reference,
            1e-4,
        ),
        reference_ms,
        fast_full_ms,
        speed_ratio: reference_ms / fast_full_ms.max(1e-9),
    }
}

#[cfg(test)]
mod tests;
