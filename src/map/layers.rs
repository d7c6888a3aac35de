//! 2D layers derived from the voxels, kept up to date incrementally: column state, obstacle inflation,
//! traversability, surface cells and frontier cells.

use super::occupancy::{inflation_test_radius2, ObstacleBox, Occupancy, VoxelState};
use super::MapParams;
use crate::grid::{Cell, CellRect, GridSpec, NEIGHBOURS_8};
use nalgebra::Point2;
use std::collections::VecDeque;
use std::f64::consts::SQRT_2;
use std::ops::Range;

pub use crate::grid::CellState;

/// A connected piece of frontier, short enough to be one goal.
#[derive(Clone, Debug, PartialEq)]
pub struct FrontierSegment {
    /// Member cells, ascending by flat index.
    pub cells: Vec<Cell>,
    /// Mean of the member cell centres.
    pub centroid: Point2<f64>,
    /// The member cell nearest the centroid (lowest index on ties): a reachable goal.
    pub anchor: Cell,
}

/// The voxel layers that can block the robot: `[band_min_m, robot.height_m]`.
pub fn robot_band(grid: &GridSpec, params: &MapParams) -> Range<usize> {
    grid.layers_in(params.map.band_min_m, params.robot_height_m)
}

/// Offsets of the cells whose centres lie within `radius` of a cell's centre.
fn disc_offsets(grid: &GridSpec, radius: f64) -> Vec<(i32, i32)> {
    let reach = (radius / grid.res).ceil() as i32;
    let mut offsets = Vec::new();
    for dy in -reach..=reach {
        for dx in -reach..=reach {
            if ((dx * dx + dy * dy) as f64).sqrt() * grid.res <= radius {
                offsets.push((dx, dy));
            }
        }
    }
    offsets
}

/// The 2D layers.
#[derive(Clone, Debug)]
pub struct Layers {
    grid: GridSpec,
    /// Voxel layers that can block the robot: `[band_min_m, robot.height_m]`.
    robot_band: Range<usize>,
    /// Voxel layers whose occupied voxels are surfaces: `[band_min_m, band_max_m]`.
    surface_band: Range<usize>,
    /// Known voxels a column's robot band needs to count as free.
    min_known: usize,
    /// The robot band's layers below the camera.
    below_eye: Range<usize>,
    /// Squared inflation test radius: the robot radius plus the margin, less the slack by which an
    /// obstacle box reaches beyond its hits. A cell is then inflated when its centre lies within the
    /// inflation radius of a ray hit (exactly so for walls along the grid axes), the same rule the
    /// ground truth's reachable region applies to the true surfaces. Measured to the grown box
    /// itself, a door that the reachable region passes with a centimetre to spare was closed.
    inflation_radius2: f64,
    /// Squared proximity radius (inflation radius + `map.proximity_band_m`).
    proximity_radius2: f64,
    /// Offsets of the cells that a box inside a cell can have within the proximity radius.
    reach_offsets: Vec<(i32, i32)>,
    segment_max_m: f64,
    segment_min_cells: usize,
    state: Vec<CellState>,
    /// Cells the robot has stood on: free in 2D unless an obstacle is seen there.
    footprint: Vec<bool>,
    /// Cells with a known voxel in the robot band, an obstacle, or the robot's footprint: cells the
    /// robot has any evidence about. A never-seen cell may hide a wall.
    seen: Vec<bool>,
    /// Unknown cells known only above the camera: looked over, never across at eye level. Rays
    /// pass above a cabinet taller than the camera and clear the voxels over it, while its faces
    /// that no look met head-on stay unknown; such a cell counts as an obstacle filling the cell.
    hidden: Vec<bool>,
    surface: Vec<bool>,
    /// Per Obstacle cell, the obstacle box its inflation and proximity counts were made with (so
    /// that they can be taken back exactly); `None` for other cells.
    applied_box: Vec<Option<ObstacleBox>>,
    /// Number of obstacle boxes within the inflation radius of each cell's centre.
    inflation: Vec<u32>,
    /// How many of those are boxes of hidden cells: a frontier may lie in their inflation (the robot
    /// cannot stand there, but the unknown beside it is worth a look from where it can).
    hidden_inflation: Vec<u32>,
    /// Whether the box a cell counts with is a hidden cell's.
    applied_hidden: Vec<bool>,
    /// Number of obstacle boxes within the proximity radius of each cell's centre.
    proximity: Vec<u32>,
    traversable: Vec<bool>,
    frontier: Vec<bool>,
    /// Holds every column the map has recomputed, every footprint cell and every cell
    /// [`Self::settle`] has looked at: outside it a cell is as in an all-unknown map (no state,
    /// surface, seen or hidden flag, traversability or frontier), so the searches, the frontier scan
    /// and the field's key frames need not look there.
    touched: CellRect,
}

impl Layers {
    /// All-unknown layers over `grid`.
    pub fn new(grid: GridSpec, params: &MapParams) -> Layers {
        let m = &params.map;
        let robot_band = robot_band(&grid, params);
        let surface_band = grid.layers_in(m.band_min_m, m.band_max_m);
        let min_known =
            ((m.column_known_fraction * robot_band.len() as f64).ceil() as usize).max(1);
        let below_eye = robot_band.start..grid.layers_in(0.0, params.eye_height_m).end;
        let radius = params.robot_radius_m + m.inflation_margin_m;
        let proximity_radius = radius + m.proximity_band_m;
        // A box lies within half a cell diagonal of its cell's centre.
        let reach_offsets = disc_offsets(&grid, proximity_radius + 0.5 * SQRT_2 * grid.res);
        let n = grid.cells();
        Layers {
            grid,
            robot_band,
            surface_band,
            min_known,
            below_eye,
            inflation_radius2: inflation_test_radius2(radius),
            proximity_radius2: proximity_radius * proximity_radius,
            reach_offsets,
            segment_max_m: m.frontier_segment_max_m,
            segment_min_cells: m.frontier_min_cells,
            state: vec![CellState::Unknown; n],
            footprint: vec![false; n],
            seen: vec![false; n],
            hidden: vec![false; n],
            surface: vec![false; n],
            applied_box: vec![None; n],
            inflation: vec![0; n],
            hidden_inflation: vec![0; n],
            applied_hidden: vec![false; n],
            proximity: vec![0; n],
            traversable: vec![false; n],
            frontier: vec![false; n],
            touched: CellRect::EMPTY,
        }
    }

    pub fn states(&self) -> &[CellState] {
        &self.state
    }
    pub fn traversable(&self) -> &[bool] {
        &self.traversable
    }
    pub fn surface(&self) -> &[bool] {
        &self.surface
    }
    /// Where the obstacle of Obstacle cell `idx` is, the whole cell for a hidden cell (`None` for
    /// other cells).
    pub fn obstacle_box(&self, idx: usize) -> Option<ObstacleBox> {
        self.applied_box[idx]
    }
    /// Whether cell `idx` lies within the inflation radius of a known obstacle.
    pub fn is_inflated(&self, idx: usize) -> bool {
        self.inflation[idx] > 0
    }
    /// Whether cell `idx` lies within the proximity radius of a known obstacle (searches prefer
    /// cells that are not, so that paths keep off walls where there is room).
    pub fn is_near_obstacle(&self, idx: usize) -> bool {
        self.proximity[idx] > 0
    }
    pub fn frontier(&self) -> &[bool] {
        &self.frontier
    }

    /// The inflation and proximity counters, for tests comparing incremental and recomputed layers.
    #[cfg(test)]
    pub(super) fn counters(&self) -> (&[u32], &[u32], &[u32]) {
        (&self.inflation, &self.hidden_inflation, &self.proximity)
    }

    /// Whether cell `idx` is known only above the camera (see the field's doc).
    pub fn is_hidden(&self, idx: usize) -> bool {
        self.hidden[idx]
    }

    /// Whether the robot has any evidence about cell `idx` (see the field's doc).
    pub fn is_seen(&self, idx: usize) -> bool {
        self.seen[idx]
    }

    /// The state, surface flag, seen flag and hidden flag of one column, from its voxels and the
    /// footprint flag.
    fn column(&self, occ: &Occupancy, idx: usize) -> (CellState, bool, bool, bool) {
        let cell = self.grid.cell(idx);
        let mut known = 0;
        let mut lowest_known = false;
        let mut known_below_eye = false;
        let mut blocked = false;
        for iz in self.robot_band.clone() {
            let s = occ.state(self.grid.voxel_index(cell, iz));
            if s != VoxelState::Unknown {
                known += 1;
                lowest_known |= iz == self.robot_band.start;
                known_below_eye |= self.below_eye.contains(&iz);
            }
            blocked |= s == VoxelState::Occupied;
        }
        // Sticky obstacles: the scene is static and the sensor exact, so every hit lies on a real
        // surface. A voxel a wall only partly fills is later crossed by grazing rays that miss the
        // wall and drive its log-odds below zero; the column must still block the robot.
        blocked |= !occ.obstacle_box(idx).is_empty();
        let surface = self
            .surface_band
            .clone()
            .any(|iz| occ.state(self.grid.voxel_index(cell, iz)) == VoxelState::Occupied);
        let state = if blocked {
            CellState::Obstacle
        } else if (known >= self.min_known && lowest_known) || self.footprint[idx] {
            CellState::Free
        } else {
            CellState::Unknown
        };
        let hidden = state == CellState::Unknown && known > 0 && !known_below_eye;
        (
            state,
            surface,
            known > 0 || blocked || self.footprint[idx],
            hidden,
        )
    }

    /// The box Obstacle cell `idx` should count with: its hits', or the whole cell if it has none
    /// (which cannot happen while hits are what makes voxels occupied, but costs nothing to cover).
    fn box_for(&self, occ: &Occupancy, idx: usize) -> Option<ObstacleBox> {
        (self.state[idx] == CellState::Obstacle || self.hidden[idx]).then(|| {
            let b = occ.obstacle_box(idx);
            if b.is_empty() {
                ObstacleBox::cell(&self.grid, self.grid.cell(idx))
            } else {
                b
            }
        })
    }

    /// Recomputes the given columns (flat cell indices, whose voxel states changed), moves the
    /// inflation of the columns whose obstacle box grew, and updates everything that depends on them.
    pub fn update_columns(&mut self, occ: &Occupancy, columns: &[u32], grown_boxes: &[u32]) {
        let mut changed = Vec::new();
        // A column whose box grew may have become an obstacle with no voxel changing state.
        for &c in columns.iter().chain(grown_boxes) {
            let c = c as usize;
            let (state, surface, seen, hidden) = self.column(occ, c);
            self.surface[c] = surface;
            self.seen[c] = seen;
            self.hidden[c] = hidden;
            self.set_state(c, state, &mut changed);
            self.touched.add(self.grid.cell(c));
        }
        for &c in columns.iter().chain(grown_boxes) {
            let c = c as usize;
            self.apply_box(c, self.box_for(occ, c), &mut changed);
        }
        self.settle(changed);
    }

    /// The robot stands at `(x, y)`: cells whose centre lies within `radius` and that are not Obstacle
    /// become Free (a 2D fact only; no voxel becomes known).
    pub fn clear_footprint(&mut self, x: f64, y: f64, radius: f64) {
        let mut changed = Vec::new();
        let lo = self.grid.cell_at(x - radius, y - radius);
        let hi = self.grid.cell_at(x + radius, y + radius);
        for cy in lo.y..=hi.y {
            for cx in lo.x..=hi.x {
                let Some(idx) = self.grid.checked_index(Cell::new(cx, cy)) else {
                    continue;
                };
                let p = self.grid.center(Cell::new(cx, cy));
                if (p - Point2::new(x, y)).norm() <= radius {
                    self.touched.add(Cell::new(cx, cy));
                    self.footprint[idx] = true;
                    self.seen[idx] = true;
                    if self.state[idx] == CellState::Unknown {
                        self.set_state(idx, CellState::Free, &mut changed);
                    }
                    if self.hidden[idx] {
                        self.hidden[idx] = false;
                        self.apply_box(idx, None, &mut changed);
                    }
                }
            }
        }
        self.settle(changed);
    }

    /// Sets a cell's state (the caller keeps its obstacle box in step with [`Self::apply_box`]).
    /// Cells whose traversability may have changed are pushed onto `changed`.
    fn set_state(&mut self, idx: usize, new: CellState, changed: &mut Vec<usize>) {
        if self.state[idx] != new {
            self.state[idx] = new;
            changed.push(idx);
        }
    }

    /// Whether `b`, the box cell `idx` counts with, is a hidden cell's: a box of a cell that is not an
    /// obstacle can only be.
    fn is_hidden_box(&self, idx: usize, b: Option<ObstacleBox>) -> bool {
        b.is_some() && self.state[idx] != CellState::Obstacle
    }

    /// Makes `new` the obstacle box that cell `idx` counts with in the inflation and proximity
    /// counters: takes back the old box's counts, if any, and adds the new one's.
    fn apply_box(&mut self, idx: usize, new: Option<ObstacleBox>, changed: &mut Vec<usize>) {
        let (old, old_hidden) = (self.applied_box[idx], self.applied_hidden[idx]);
        let new_hidden = self.is_hidden_box(idx, new);
        if (old, old_hidden) == (new, new_hidden) {
            return;
        }
        if let Some(b) = old {
            self.count_box(idx, &b, false, old_hidden, changed);
        }
        if let Some(b) = new {
            self.count_box(idx, &b, true, new_hidden, changed);
        }
        self.applied_box[idx] = new;
        self.applied_hidden[idx] = new_hidden;
    }

    /// Adds (or removes) box `b` of cell `idx` to the counters of the cells whose centres lie within
    /// the inflation and proximity radii of it (`hidden`: a hidden cell's box). Cells whose inflation
    /// by any box or by known obstacles flips are pushed onto `changed`.
    fn count_box(
        &mut self,
        idx: usize,
        b: &ObstacleBox,
        add: bool,
        hidden: bool,
        changed: &mut Vec<usize>,
    ) {
        let cell = self.grid.cell(idx);
        for &(dx, dy) in &self.reach_offsets {
            let nc = Cell::new(cell.x + dx, cell.y + dy);
            let Some(n) = self.grid.checked_index(nc) else {
                continue;
            };
            let d2 = b.distance_squared(self.grid.center(nc));
            if d2 > self.proximity_radius2 {
                continue;
            }
            if add {
                self.proximity[n] += 1;
            } else {
                self.proximity[n] -= 1;
            }
            if d2 > self.inflation_radius2 {
                continue;
            }
            let before = (self.inflation[n] > 0, self.obstacle_inflated(n));
            if add {
                self.inflation[n] += 1;
                self.hidden_inflation[n] += u32::from(hidden);
            } else {
                self.inflation[n] -= 1;
                self.hidden_inflation[n] -= u32::from(hidden);
            }
            if before != (self.inflation[n] > 0, self.obstacle_inflated(n)) {
                changed.push(n);
            }
        }
    }

    /// Whether cell `idx` lies within the inflation radius of a known obstacle (not only of hidden
    /// cells).
    fn obstacle_inflated(&self, idx: usize) -> bool {
        self.inflation[idx] > self.hidden_inflation[idx]
    }

    fn is_traversable_now(&self, idx: usize) -> bool {
        self.state[idx] == CellState::Free && self.inflation[idx] == 0
    }

    /// A Free cell beside an Unknown one, outside the inflation of known obstacles. In the inflation
    /// of hidden cells only, the robot cannot stand there but could look at it, so it stays a
    /// frontier: the searches do not reach it, and a run that ends without looking at it reports it
    /// among the frontiers left. Hidden cells' inflation hiding the frontier ended runs `complete`
    /// with a room behind a tall partition never entered and nothing reported.
    fn is_frontier_now(&self, idx: usize) -> bool {
        if self.state[idx] != CellState::Free || self.obstacle_inflated(idx) {
            return false;
        }
        let c = self.grid.cell(idx);
        NEIGHBOURS_8[..4].iter().any(|&(dx, dy)| {
            self.grid
                .checked_index(Cell::new(c.x + dx, c.y + dy))
                .is_some_and(|n| self.state[n] == CellState::Unknown)
        })
    }

    /// Recomputes traversability of the `changed` cells, then the frontier flag of them and their
    /// 4-neighbours (a frontier depends on its own traversability and its neighbours' states).
    fn settle(&mut self, mut changed: Vec<usize>) {
        changed.sort_unstable();
        changed.dedup();
        let mut frontier_dirty = Vec::with_capacity(changed.len() * 5);
        for &idx in &changed {
            self.traversable[idx] = self.is_traversable_now(idx);
            frontier_dirty.push(idx);
            let c = self.grid.cell(idx);
            for &(dx, dy) in &NEIGHBOURS_8[..4] {
                if let Some(n) = self.grid.checked_index(Cell::new(c.x + dx, c.y + dy)) {
                    frontier_dirty.push(n);
                }
            }
        }
        for idx in frontier_dirty {
            self.frontier[idx] = self.is_frontier_now(idx);
            self.touched.add(self.grid.cell(idx));
        }
    }

    /// Numbers of obstacle boxes within the inflation radius of cell `idx`'s centre, of those the
    /// hidden cells' boxes, and of boxes within the proximity radius.
    fn boxes_within(&self, idx: usize) -> (u32, u32, u32) {
        let c = self.grid.cell(idx);
        let centre = self.grid.center(c);
        let (mut inflation, mut hidden, mut proximity) = (0, 0, 0);
        for &(dx, dy) in &self.reach_offsets {
            let Some(o) = self.grid.checked_index(Cell::new(c.x + dx, c.y + dy)) else {
                continue;
            };
            if let Some(b) = self.applied_box[o] {
                let d2 = b.distance_squared(centre);
                let inflates = d2 <= self.inflation_radius2;
                inflation += inflates as u32;
                hidden += (inflates && self.applied_hidden[o]) as u32;
                proximity += (d2 <= self.proximity_radius2) as u32;
            }
        }
        (inflation, hidden, proximity)
    }

    /// Recomputes every layer from the voxels and footprint flags, without the incremental machinery.
    pub fn recompute_all(&mut self, occ: &Occupancy) {
        let n = self.grid.cells();
        for idx in 0..n {
            let (state, surface, seen, hidden) = self.column(occ, idx);
            self.state[idx] = state;
            self.surface[idx] = surface;
            self.seen[idx] = seen;
            self.hidden[idx] = hidden;
        }
        // Each cell gathers the obstacle boxes near it (not the boxes scattering counts, as the
        // incremental path does), so that this is an independent check of it.
        for idx in 0..n {
            self.applied_box[idx] = self.box_for(occ, idx);
            self.applied_hidden[idx] = self.is_hidden_box(idx, self.applied_box[idx]);
        }
        for idx in 0..n {
            let (inflation, hidden, proximity) = self.boxes_within(idx);
            self.inflation[idx] = inflation;
            self.hidden_inflation[idx] = hidden;
            self.proximity[idx] = proximity;
        }
        for idx in 0..n {
            self.traversable[idx] = self.is_traversable_now(idx);
        }
        for idx in 0..n {
            self.frontier[idx] = self.is_frontier_now(idx);
        }
        self.touched = CellRect::all(&self.grid);
    }

    /// The cells outside which the map is as it was before any frame (see `touched`).
    pub fn touched(&self) -> CellRect {
        self.touched
    }

    /// Frontier cells clustered into 8-connected components, each split into pieces whose member cell
    /// centres are at most `frontier_segment_max_m` apart, dropping pieces with fewer than
    /// `frontier_min_cells` cells. Ordered by lowest cell index.
    pub fn frontiers(&self) -> Vec<FrontierSegment> {
        let g = &self.grid;
        let n = g.cells();
        // 0 = not yet collected; ASSIGNED = placed in a piece (or dropped with it); otherwise the
        // component the cell waits in.
        const ASSIGNED: u32 = u32::MAX;
        let mut pending = vec![0u32; n];
        let mut component_id = 0u32;
        let mut segments = Vec::new();
        let mut queue = VecDeque::new();
        let max_cells2 = (self.segment_max_m / g.res).powi(2) * (1.0 + 1e-9);
        // Every frontier cell lies in `touched`; its rows come in ascending index order.
        for start in self.touched.rows(g).flatten() {
            if !self.frontier[start] || pending[start] != 0 {
                continue;
            }
            // Collect the component.
            component_id += 1;
            let mut component = vec![start];
            pending[start] = component_id;
            queue.push_back(start);
            while let Some(i) = queue.pop_front() {
                let c = g.cell(i);
                for &(dx, dy) in &NEIGHBOURS_8 {
                    if let Some(j) = g.checked_index(Cell::new(c.x + dx, c.y + dy)) {
                        if self.frontier[j] && pending[j] == 0 {
                            pending[j] = component_id;
                            component.push(j);
                            queue.push_back(j);
                        }
                    }
                }
            }
            component.sort_unstable();
            // Split it greedily: grow from the lowest pending cell, through pending cells, taking a
            // cell only if it stays within the length limit of every member so far.
            for &seed in &component {
                if pending[seed] != component_id {
                    continue;
                }
                pending[seed] = ASSIGNED;
                let mut piece = vec![seed];
                queue.push_back(seed);
                while let Some(i) = queue.pop_front() {
                    let c = g.cell(i);
                    for &(dx, dy) in &NEIGHBOURS_8 {
                        let nc = Cell::new(c.x + dx, c.y + dy);
                        let Some(j) = g.checked_index(nc) else {
                            continue;
                        };
                        if pending[j] != component_id {
                            continue;
                        }
                        let fits = piece.iter().all(|&m| {
                            let mc = g.cell(m);
                            let (ex, ey) = ((mc.x - nc.x) as f64, (mc.y - nc.y) as f64);
                            ex * ex + ey * ey <= max_cells2
                        });
                        if fits {
                            pending[j] = ASSIGNED;
                            piece.push(j);
                            queue.push_back(j);
                        }
                    }
                }
                if piece.len() >= self.segment_min_cells {
                    piece.sort_unstable();
                    segments.push(self.segment(&piece));
                }
            }
        }
        segments.sort_by_key(|s: &FrontierSegment| g.index(s.cells[0]));
        segments
    }

    fn segment(&self, piece: &[usize]) -> FrontierSegment {
        let g = &self.grid;
        let cells: Vec<Cell> = piece.iter().map(|&i| g.cell(i)).collect();
        let sum = cells
            .iter()
            .fold(nalgebra::Vector2::zeros(), |s, &c| s + g.center(c).coords);
        let centroid = Point2::from(sum / cells.len() as f64);
        let mut anchor = cells[0];
        let mut best = f64::INFINITY;
        for &c in &cells {
            let d = (g.center(c) - centroid).norm_squared();
            if d < best {
                best = d;
                anchor = c;
            }
        }
        FrontierSegment {
            cells,
            centroid,
            anchor,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Config;

    fn layers(nx: usize, ny: usize) -> Layers {
        let grid = GridSpec {
            origin_x: 0.0,
            origin_y: 0.0,
            res: 0.1,
            nx,
            ny,
            nz: 18,
        };
        // Fixed here so that the known answers below do not move with the defaults.
        let mut cfg = Config::default();
        cfg.robot.radius_m = 0.25;
        cfg.map.inflation_margin_m = 0.04;
        cfg.map.proximity_band_m = 0.3;
        cfg.map.frontier_min_cells = 3;
        Layers::new(grid, &MapParams::from(&cfg))
    }

    /// Sets cell `(x, y)`'s state; an Obstacle gets `b` as its box, else the point at the cell centre.
    fn set_with_box(l: &mut Layers, x: i32, y: i32, s: CellState, b: Option<ObstacleBox>) {
        let mut changed = Vec::new();
        let c = Cell::new(x, y);
        let idx = l.grid.index(c);
        l.set_state(idx, s, &mut changed);
        let centre = l.grid.center(c);
        let point = ObstacleBox {
            min: [centre.x as f32, centre.y as f32],
            max: [centre.x as f32, centre.y as f32],
        };
        let b = (s == CellState::Obstacle).then(|| b.unwrap_or(point));
        l.apply_box(idx, b, &mut changed);
        l.settle(changed);
    }

    fn set(l: &mut Layers, x: i32, y: i32, s: CellState) {
        set_with_box(l, x, y, s, None);
    }

    fn all_free(nx: usize, ny: usize) -> Layers {
        let mut l = layers(nx, ny);
        for idx in 0..l.grid.cells() {
            let c = l.grid.cell(idx);
            set(&mut l, c.x, c.y, CellState::Free);
        }
        assert!(l.traversable.iter().all(|&t| t));
        l
    }

    #[test]
    fn inflation_blocks_cells_within_robot_radius_plus_margin() {
        let mut l = all_free(21, 21);
        set(&mut l, 10, 10, CellState::Obstacle);
        // An obstacle at the centre of cell (10, 10), radius 0.25 + 0.04 = 0.29 m, tested against the
        // box less its 0.01 m slack, so 0.28 m: (2, 1) (0.224) and 2 cells straight (0.2) are blocked;
        // (2, 2) diagonal (0.283), 3 cells straight (0.3) and (3, 1) (0.316) are free.
        let t = |dx: i32, dy: i32| l.traversable[l.grid.index(Cell::new(10 + dx, 10 + dy))];
        assert!(!t(0, 0) && !t(2, 0) && !t(0, -2) && !t(-2, 1));
        assert!(t(2, 2) && t(3, 0) && t(0, -3) && t(3, 1) && t(-2, 3));
        // Proximity reaches 0.29 + 0.3 = 0.59 m: (5, 2) (0.539) is near; (6, 0) (0.6) and (4, 5) (0.640)
        // are not.
        let near = |dx: i32, dy: i32| l.is_near_obstacle(l.grid.index(Cell::new(10 + dx, 10 + dy)));
        assert!(near(5, 2) && near(0, 0) && !near(6, 0) && !near(4, 5));
        // Removing the obstacle frees everything again.
        set(&mut l, 10, 10, CellState::Free);
        assert!(l.traversable.iter().all(|&t| t));
        assert!(l.inflation.iter().all(|&n| n == 0));
        assert!(l.proximity.iter().all(|&n| n == 0));
    }

    #[test]
    fn inflation_measures_to_the_obstacle_box_and_follows_it_when_it_grows() {
        let mut l = all_free(21, 21);
        // A wall face at x = 1.0, the left edge of cell (10, 10) (x 1.0–1.1): the box is the thin
        // strip x 1.0–1.01. Cell centres at x = 0.75 (0.25 m from it) are blocked, x = 0.65 (0.35 m)
        // free, where the cell centre rule (0.4 m and 0.3 m from x = 1.05) would have passed 0.75.
        let wall = |x0: f32, x1: f32| ObstacleBox {
            min: [x0, 1.0],
            max: [x1, 1.1],
        };
        set_with_box(&mut l, 10, 10, CellState::Obstacle, Some(wall(1.0, 1.01)));
        let t = |l: &Layers, x: i32, y: i32| l.traversable[l.grid.index(Cell::new(x, y))];
        assert!(!t(&l, 7, 10) && t(&l, 6, 10));
        // Right side: x = 1.35 is 0.34 m from x = 1.01, free; x = 1.25 (0.24 m) blocked.
        assert!(t(&l, 13, 10) && !t(&l, 12, 10));
        // The box grows to x 1.0–1.1: the right side's inflation follows.
        let mut changed = Vec::new();
        let idx = l.grid.index(Cell::new(10, 10));
        l.apply_box(idx, Some(wall(1.0, 1.1)), &mut changed);
        l.settle(changed);
        assert!(!t(&l, 13, 10) && t(&l, 14, 10) && !t(&l, 7, 10) && t(&l, 6, 10));
        // Taking the obstacle away takes back exactly what the latest box added.
        set(&mut l, 10, 10, CellState::Free);
        assert!(l.traversable.iter().all(|&t| t));
        assert!(l.inflation.iter().chain(&l.proximity).all(|&n| n == 0));
        // The counts equal a direct check of every cell against every box.
        let boxes = [(3, 4, wall(0.3, 0.38)), (15, 15, wall(1.5, 1.6))];
        for &(x, y, b) in &boxes {
            let b = ObstacleBox {
                min: [b.min[0], y as f32 * 0.1 + 0.03],
                max: [b.max[0], y as f32 * 0.1 + 0.05],
            };
            assert_eq!(
                l.grid.cell_at(b.min[0] as f64, b.min[1] as f64),
                Cell::new(x, y)
            );
            set_with_box(&mut l, x, y, CellState::Obstacle, Some(b));
        }
        for idx in 0..l.grid.cells() {
            let p = l.grid.center(l.grid.cell(idx));
            let (mut inflation, mut proximity) = (0, 0);
            for o in 0..l.grid.cells() {
                if let Some(b) = l.obstacle_box(o) {
                    let d = b.distance_squared(p).sqrt();
                    inflation += (d <= 0.28) as u32;
                    proximity += (d <= 0.59) as u32;
                }
            }
            assert_eq!((l.inflation[idx], l.proximity[idx]), (inflation, proximity));
        }
    }

    #[test]
    fn frontier_cells_border_unknown() {
        let mut l = layers(10, 10);
        for x in 0..5 {
            for y in 0..10 {
                set(&mut l, x, y, CellState::Free);
            }
        }
        for idx in 0..l.grid.cells() {
            let c = l.grid.cell(idx);
            assert_eq!(l.frontier[idx], c.x == 4, "{c:?}");
        }
        let segs = l.frontiers();
        // A 10-cell line (0.9 m between end centres) fits one 1 m piece.
        assert_eq!(segs.len(), 1);
        assert_eq!(segs[0].cells.len(), 10);
        // The centroid lies on the boundary between (4, 4) and (4, 5); rounding picks one.
        assert!([Cell::new(4, 4), Cell::new(4, 5)].contains(&segs[0].anchor));
        assert!((segs[0].centroid - Point2::new(0.45, 0.5)).norm() < 1e-9);
    }

    #[test]
    fn clear_footprint_frees_unknown_but_not_obstacles() {
        let mut l = layers(20, 20);
        set(&mut l, 10, 10, CellState::Obstacle);
        l.clear_footprint(1.0, 1.0, 0.25);
        fn s_at(l: &Layers, x: i32, y: i32) -> CellState {
            l.state[l.grid.index(Cell::new(x, y))]
        }
        assert_eq!(s_at(&l, 10, 10), CellState::Obstacle);
        assert_eq!(s_at(&l, 9, 9), CellState::Free);
        // Cell (11, 11) has its centre 0.212 m away; cell (12, 10) 0.255 m away.
        assert_eq!(s_at(&l, 11, 11), CellState::Free);
        assert_eq!(s_at(&l, 12, 10), CellState::Unknown);
        // Footprint cells are traversable only outside the obstacle's inflation.
        assert!(!l.traversable[l.grid.index(Cell::new(11, 11))]);
        l.clear_footprint(0.45, 0.45, 0.1);
        assert!(l.traversable[l.grid.index(Cell::new(4, 4))]);
        l.clear_footprint(1.05, 1.2, 0.1);
        assert_eq!(s_at(&l, 10, 12), CellState::Free);
        assert!(!l.traversable[l.grid.index(Cell::new(10, 12))]);
    }

    #[test]
    fn long_frontiers_split_into_pieces_within_the_length_limit() {
        let mut l = layers(60, 30);
        // Free rectangle x < 40, y 5..25 with an L-shaped frontier along x = 39 and y = 24.
        for x in 0..40 {
            for y in 5..25 {
                set(&mut l, x, y, CellState::Free);
            }
        }
        let segs = l.frontiers();
        let total: usize = segs.iter().map(|s| s.cells.len()).sum();
        let frontier_cells = l.frontier.iter().filter(|&&f| f).count();
        assert!(segs.len() >= 6, "{}", segs.len());
        assert!(total <= frontier_cells);
        for s in &segs {
            assert!(s.cells.len() >= 3);
            assert!(s.cells.contains(&s.anchor));
            for a in &s.cells {
                for b in &s.cells {
                    let d = (l.grid.center(*a) - l.grid.center(*b)).norm();
                    assert!(d <= 1.0 + 1e-9, "piece longer than 1 m: {d}");
                }
            }
        }
        // Ordered by lowest cell and reproducible.
        let firsts: Vec<usize> = segs.iter().map(|s| l.grid.index(s.cells[0])).collect();
        assert!(firsts.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(segs, l.frontiers());
    }
}
