//! Grid search on the 2D traversable layer: A* (8-connected, octile heuristic) and a one-to-many
//! Dijkstra distance field.
//!
//! Searches take a cost function: `None` for a cell that cannot be entered, `Some(m)` with `m ≥ 1`
//! for the cost per metre of entering it (1 for plain shortest paths; more near obstacles). The octile
//! heuristic stays admissible because no multiplier is below 1.
//!
//! Both work on flat arrays owned by a reusable [`Search`] workspace: a generation stamp marks which
//! entries are valid for the current query, so no per-query clearing and no per-node allocation.
//! Diagonal moves are allowed only when both orthogonal neighbours are passable, so paths never cut
//! the corner of a blocked cell.

use crate::grid::{Cell, GridSpec};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

const SQRT2: f32 = std::f32::consts::SQRT_2;

/// A heap entry: priority (f for A*, g for Dijkstra) and cell, packed into one `u64` as
/// `priority bits << 32 | cell` and ordered as a min-heap. Priorities are finite and non-negative,
/// whose IEEE bits order as the values do, so one integer comparison orders by priority and then by
/// cell index: the expansion order is fully deterministic, and cheap to keep.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Entry(u64);

impl Entry {
    fn new(priority: f32, cell: usize) -> Self {
        debug_assert!(priority >= 0.0 && priority.is_finite());
        Entry((u64::from(priority.to_bits()) << 32) | cell as u64)
    }

    fn priority(self) -> f32 {
        f32::from_bits((self.0 >> 32) as u32)
    }

    fn cell(self) -> usize {
        (self.0 & u64::from(u32::MAX)) as usize
    }
}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.cmp(&self.0)
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// The search state of one cell, 8 bytes so that the neighbour checks of a search stay in cache.
/// Generations are even: `stamp` equals the query's generation once the cell is reached (and `g`
/// is valid), and the generation + 1 once it is settled.
#[derive(Clone, Copy)]
struct NodeState {
    stamp: u32,
    g: f32,
}

/// A found path: the cells from start to goal, and its length in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct GridPath {
    pub cells: Vec<Cell>,
    pub length_m: f64,
}

/// A reusable search workspace for one grid size.
#[derive(Clone)]
pub struct Search {
    cells: usize,
    generation: u32,
    /// Per-cell search state.
    state: Vec<NodeState>,
    /// Per-cell parent on the best path found (valid where the state is reached); apart from the
    /// state because only improvements write it.
    parent: Vec<u32>,
    heap: BinaryHeap<Entry>,
    /// Number of A* queries answered, for reports.
    pub astar_calls: u64,
}

/// Least costs from one source to every cell, with parents for path extraction.
#[derive(Clone, Debug, Default)]
pub struct DistanceField {
    pub source: usize,
    /// Least path cost from the source (metres weighted by the cost multipliers);
    /// `f32::INFINITY` where unreachable.
    pub cost: Vec<f32>,
    parent: Vec<u32>,
    /// The cells the last search wrote, so that the next one resets only those: a search settles
    /// the known floor, not the grid.
    written: Vec<u32>,
}

impl DistanceField {
    /// Least cost to `cell`, or `None` if unreachable.
    pub fn cost_to(&self, cell: usize) -> Option<f32> {
        let d = self.cost[cell];
        d.is_finite().then_some(d)
    }

    /// The least-cost path from the source to `target` (inclusive), or `None` if unreachable.
    pub fn path_to(&self, grid: &GridSpec, target: usize) -> Option<GridPath> {
        self.cost_to(target)?;
        let mut cells = vec![grid.cell(target)];
        let mut at = target;
        while at != self.source {
            at = self.parent[at] as usize;
            cells.push(grid.cell(at));
        }
        cells.reverse();
        Some(GridPath::new(grid, cells))
    }
}

impl GridPath {
    /// A path through `cells` (consecutive cells 8-adjacent), with its geometric length.
    pub fn new(grid: &GridSpec, cells: Vec<Cell>) -> Self {
        let length_m = cells
            .windows(2)
            .map(|w| {
                let diagonal = w[0].x != w[1].x && w[0].y != w[1].y;
                if diagonal {
                    grid.res * std::f64::consts::SQRT_2
                } else {
                    grid.res
                }
            })
            .sum();
        GridPath { cells, length_m }
    }
}

impl Search {
    /// A workspace for grids of `grid.cells()` cells.
    pub fn new(grid: &GridSpec) -> Self {
        let n = grid.cells();
        Search {
            cells: n,
            generation: 0,
            state: vec![
                NodeState {
                    stamp: 0,
                    g: f32::INFINITY,
                };
                n
            ],
            parent: vec![u32::MAX; n],
            heap: BinaryHeap::new(),
            astar_calls: 0,
        }
    }

    fn begin(&mut self, grid: &GridSpec) {
        assert_eq!(
            grid.cells(),
            self.cells,
            "search workspace built for another grid"
        );
        self.heap.clear();
        self.generation = self.generation.wrapping_add(2);
        if self.generation == 0 {
            // Wrapped: stale stamps could alias the new generation.
            for s in &mut self.state {
                s.stamp = 0;
            }
            self.generation = 2;
        }
    }

    /// Marks `cell` reached at cost `g` from `parent`.
    fn reach(&mut self, cell: usize, g: f32, parent: usize) {
        self.state[cell] = NodeState {
            stamp: self.generation,
            g,
        };
        self.parent[cell] = parent as u32;
    }

    /// Marks `cell` settled; false if it already was (a stale heap entry).
    fn settle(&mut self, cell: usize) -> bool {
        let settled = self.generation + 1;
        let s = &mut self.state[cell];
        if s.stamp == settled {
            return false;
        }
        s.stamp = settled;
        true
    }

    /// Relaxes the neighbours of `at`; `push` receives each improved neighbour and its new g.
    ///
    /// Neighbours are found by index offsets: only the four orthogonal ones need a bounds check,
    /// because a diagonal is entered only when both orthogonal neighbours beside it are open (no
    /// corner cutting), which also keeps it on the grid. The order of relaxation does not matter:
    /// each neighbour is a different cell and the heap orders entries by (priority, cell).
    fn expand(
        &mut self,
        grid: &GridSpec,
        cost: &impl Fn(usize) -> Option<f32>,
        at: usize,
        mut push: impl FnMut(&mut BinaryHeap<Entry>, usize, f32),
    ) {
        let nx = grid.nx;
        let (x, y) = (at % nx, at / nx);
        let g_at = self.state[at].g;
        let straight = grid.res as f32;
        let diagonal = straight * SQRT2;
        // +x, −x, +y, −y (the first four of `NEIGHBOURS_8`): the cell if it is on the grid and may
        // be entered, `usize::MAX` otherwise.
        let mut ortho = [usize::MAX; 4];
        for (k, (inside, ni)) in [
            (x + 1 < nx, at + 1),
            (x > 0, at.wrapping_sub(1)),
            (y + 1 < grid.ny, at + nx),
            (y > 0, at.wrapping_sub(nx)),
        ]
        .into_iter()
        .enumerate()
        {
            if !inside {
                continue;
            }
            if let Some(m) = cost(ni) {
                ortho[k] = ni;
                self.relax(at, ni, g_at + m * straight, &mut push);
            }
        }
        for (a, b) in [(0, 2), (0, 3), (1, 2), (1, 3)] {
            let (na, nb) = (ortho[a], ortho[b]);
            if na == usize::MAX || nb == usize::MAX {
                continue;
            }
            let ni = na + nb - at;
            if let Some(m) = cost(ni) {
                self.relax(at, ni, g_at + m * diagonal, &mut push);
            }
        }
    }

    /// Lowers the g of `ni` (reached from `at`) to `g_new` if that improves it and `ni` is not
    /// settled yet.
    #[inline]
    fn relax(
        &mut self,
        at: usize,
        ni: usize,
        g_new: f32,
        push: &mut impl FnMut(&mut BinaryHeap<Entry>, usize, f32),
    ) {
        let s = self.state[ni];
        if s.stamp == self.generation + 1 || (s.stamp == self.generation && g_new >= s.g) {
            return;
        }
        self.reach(ni, g_new, at);
        push(&mut self.heap, ni, g_new);
    }

    /// Least-cost 8-connected path from `start` to `goal` under `cost` (see the module doc).
    /// The start cell itself need not be enterable (the robot may stand in an inflated band).
    pub fn astar(
        &mut self,
        grid: &GridSpec,
        cost: impl Fn(usize) -> Option<f32>,
        start: usize,
        goal: usize,
    ) -> Option<GridPath> {
        self.begin(grid);
        self.astar_calls += 1;
        if start != goal && cost(goal).is_none() {
            return None;
        }
        let gc = grid.cell(goal);
        let res = grid.res as f32;
        let heuristic = move |i: usize| {
            let c = grid.cell(i);
            let dx = (c.x - gc.x).unsigned_abs() as f32;
            let dy = (c.y - gc.y).unsigned_abs() as f32;
            res * (dx.max(dy) + (SQRT2 - 1.0) * dx.min(dy))
        };
        self.reach(start, 0.0, start);
        self.heap.push(Entry::new(heuristic(start), start));
        while let Some(entry) = self.heap.pop() {
            let at = entry.cell();
            if !self.settle(at) {
                continue;
            }
            if at == goal {
                return Some(self.extract(grid, start, goal));
            }
            self.expand(grid, &cost, at, |heap, ni, g| {
                heap.push(Entry::new(g + heuristic(ni), ni))
            });
        }
        None
    }

    fn extract(&self, grid: &GridSpec, start: usize, goal: usize) -> GridPath {
        let mut cells = vec![grid.cell(goal)];
        let mut at = goal;
        while at != start {
            at = self.parent[at] as usize;
            cells.push(grid.cell(at));
        }
        cells.reverse();
        GridPath::new(grid, cells)
    }

    /// Dijkstra from `source` under `cost` (the source need not be enterable): settles cells in
    /// order of cost, calling `on_settle(cell, cost, parent)` for each, until it answers `true`,
    /// every remaining cell costs more than `max_cost`, or nothing is left.
    fn dijkstra(
        &mut self,
        grid: &GridSpec,
        cost: &impl Fn(usize) -> Option<f32>,
        source: usize,
        max_cost: f32,
        mut on_settle: impl FnMut(usize, f32, u32) -> bool,
    ) {
        self.begin(grid);
        self.reach(source, 0.0, source);
        self.heap.push(Entry::new(0.0, source));
        while let Some(entry) = self.heap.pop() {
            // Every entry left is at least as costly, stale or not.
            if entry.priority() > max_cost {
                break;
            }
            let at = entry.cell();
            if !self.settle(at) {
                continue;
            }
            if on_settle(at, self.state[at].g, self.parent[at]) {
                break;
            }
            self.expand(grid, cost, at, |heap, ni, g| heap.push(Entry::new(g, ni)));
        }
    }

    /// Dijkstra least-cost field from `source` under `cost` (the source need not be enterable),
    /// stopping once every remaining cell costs more than `max_cost`.
    pub fn distance_field(
        &mut self,
        grid: &GridSpec,
        cost: impl Fn(usize) -> Option<f32>,
        source: usize,
        max_cost: f32,
    ) -> DistanceField {
        let mut out = DistanceField::default();
        self.distance_field_into(grid, cost, source, max_cost, &mut out);
        out
    }

    /// [`Search::distance_field`] written into `out`, reusing its buffers: a planner that floods the
    /// map at every planning step keeps one field and saves two grid-sized allocations (and the
    /// page faults of touching fresh memory) per step.
    pub fn distance_field_into(
        &mut self,
        grid: &GridSpec,
        cost: impl Fn(usize) -> Option<f32>,
        source: usize,
        max_cost: f32,
        out: &mut DistanceField,
    ) {
        out.source = source;
        if out.cost.len() == self.cells {
            for &at in &out.written {
                out.cost[at as usize] = f32::INFINITY;
                out.parent[at as usize] = u32::MAX;
            }
        } else {
            out.cost = vec![f32::INFINITY; self.cells];
            out.parent = vec![u32::MAX; self.cells];
        }
        out.written.clear();
        let (costs, parent, written) = (&mut out.cost, &mut out.parent, &mut out.written);
        self.dijkstra(grid, &cost, source, max_cost, |at, g, from| {
            costs[at] = g;
            parent[at] = from;
            written.push(at as u32);
            false
        });
    }
}

impl Search {
    /// Least costs from `source` to each of `targets` (`None` where unreachable): one Dijkstra that
    /// stops as soon as every target is settled or the frontier exceeds `max_cost`. Unlike
    /// [`Search::distance_field`] it allocates nothing grid-sized, so the planners can afford one
    /// per TSP node (THP §3.3: path-length costs between anchors).
    pub fn costs_to_targets(
        &mut self,
        grid: &GridSpec,
        cost: impl Fn(usize) -> Option<f32>,
        source: usize,
        targets: &[usize],
        max_cost: f32,
    ) -> Vec<Option<f32>> {
        let mut left = targets.iter().filter(|&&t| t != source).count();
        let mut out: Vec<Option<f32>> = targets
            .iter()
            .map(|&t| (t == source).then_some(0.0))
            .collect();
        if left == 0 {
            return out;
        }
        // One bit per cell marks the targets, so a settled cell that is none costs one lookup.
        let mut is_target = vec![0u64; self.cells.div_ceil(64)];
        for &t in targets {
            is_target[t / 64] |= 1 << (t % 64);
        }
        self.dijkstra(grid, &cost, source, max_cost, |at, g, _| {
            if is_target[at / 64] & (1 << (at % 64)) == 0 {
                return false;
            }
            for (k, &t) in targets.iter().enumerate() {
                if t == at && out[k].is_none() {
                    out[k] = Some(g);
                    left -= 1;
                }
            }
            left == 0
        });
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point2;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn grid(n: usize) -> GridSpec {
        GridSpec::covering(
            Point2::new(0.0, 0.0),
            Point2::new(n as f64 * 0.1, n as f64 * 0.1),
            1.0,
            0.1,
        )
    }

    #[test]
    fn open_grid_distance_is_octile() {
        let g = grid(20);
        let mut s = Search::new(&g);
        let start = g.index(Cell::new(1, 2));
        let goal = g.index(Cell::new(11, 6));
        let p = s.astar(&g, |_| Some(1.0), start, goal).unwrap();
        let expected = 0.1 * (6.0 + 4.0 * 2f64.sqrt());
        assert!((p.length_m - expected).abs() < 1e-5);
        assert_eq!(p.cells.first(), Some(&Cell::new(1, 2)));
        assert_eq!(p.cells.last(), Some(&Cell::new(11, 6)));
        // Consecutive cells are 8-neighbours.
        for w in p.cells.windows(2) {
            assert!((w[0].x - w[1].x).abs() <= 1 && (w[0].y - w[1].y).abs() <= 1);
        }
    }

    #[test]
    fn wall_forces_detour_and_blocked_goal_fails() {
        let g = grid(10);
        // Wall at x = 5 for y in 0..9, open at y = 9.
        let open = |i: usize| {
            let c = g.cell(i);
            !(c.x == 5 && c.y < 9)
        };
        let wall = |i: usize| open(i).then_some(1.0);
        let mut s = Search::new(&g);
        let p = s
            .astar(&g, wall, g.index(Cell::new(2, 0)), g.index(Cell::new(8, 0)))
            .unwrap();
        assert!(p.cells.iter().any(|c| c.x == 5 && c.y == 9));
        assert!(p.cells.iter().all(|c| open(g.index(*c))));
        let closed = |i: usize| (g.cell(i).x != 5).then_some(1.0);
        assert!(s
            .astar(
                &g,
                closed,
                g.index(Cell::new(2, 0)),
                g.index(Cell::new(8, 0))
            )
            .is_none());
    }

    #[test]
    fn no_corner_cutting() {
        let g = grid(3);
        // Block (1,0) and (0,1): the diagonal from (0,0) to (1,1) must not be taken.
        let open = |i: usize| {
            let c = g.cell(i);
            (!((c.x == 1 && c.y == 0) || (c.x == 0 && c.y == 1))).then_some(1.0)
        };
        let mut s = Search::new(&g);
        assert!(s
            .astar(&g, open, g.index(Cell::new(0, 0)), g.index(Cell::new(1, 1)))
            .is_none());
    }

    /// A* lengths equal Dijkstra distances on random obstacle grids, and Dijkstra paths have the
    /// length they claim.
    #[test]
    fn astar_agrees_with_dijkstra_on_random_grids() {
        let g = grid(30);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut s = Search::new(&g);
        for _ in 0..20 {
            let blocked: Vec<bool> = (0..g.cells()).map(|_| rng.random::<f64>() < 0.25).collect();
            // Random costs: open cells cost 1–3 per metre.
            let weight: Vec<f32> = (0..g.cells()).map(|_| rng.random_range(1.0..3.0)).collect();
            let cost = |i: usize| (!blocked[i]).then_some(weight[i]);
            let src = (0..g.cells()).find(|&i| !blocked[i]).unwrap();
            let df = s.distance_field(&g, cost, src, f32::INFINITY);
            for _ in 0..10 {
                let t = rng.random_range(0..g.cells());
                let a = s.astar(&g, cost, src, t);
                match (a, df.cost_to(t)) {
                    (Some(p), Some(d)) => {
                        // Both are least-cost paths: their costs agree (their cells may differ).
                        let path_cost = |cells: &[Cell]| -> f64 {
                            cells
                                .windows(2)
                                .map(|w| {
                                    let diag = w[0].x != w[1].x && w[0].y != w[1].y;
                                    let step = if diag { 0.1 * 2f64.sqrt() } else { 0.1 };
                                    step * weight[g.index(w[1])] as f64
                                })
                                .sum()
                        };
                        assert!((path_cost(&p.cells) - d as f64).abs() < 1e-3);
                        let via = df.path_to(&g, t).unwrap();
                        assert!((path_cost(&via.cells) - d as f64).abs() < 1e-3);
                        assert_eq!(GridPath::new(&g, via.cells.clone()).length_m, via.length_m);
                    }
                    (None, None) => {}
                    (a, d) => panic!(
                        "A* {:?} vs Dijkstra {:?} for target {t}",
                        a.map(|p| p.length_m),
                        d
                    ),
                }
            }
        }
    }

    /// A workspace reused many times (and across the wrap of its generation counter), and a distance
    /// field whose buffers are reused, answer as fresh ones do.
    #[test]
    fn reused_workspaces_answer_as_fresh_ones() {
        let g = grid(25);
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let blocked: Vec<bool> = (0..g.cells()).map(|_| rng.random::<f64>() < 0.3).collect();
        let cost = |i: usize| (!blocked[i]).then_some(1.0 + (i % 3) as f32);
        let open: Vec<usize> = (0..g.cells()).filter(|&i| !blocked[i]).collect();
        let mut reused = Search::new(&g);
        // Three queries before the counter wraps.
        reused.generation = u32::MAX - 5;
        let mut field = DistanceField::default();
        for k in 0..8 {
            let src = open[k * 37 % open.len()];
            // Every other field is bounded, so it reaches fewer cells than the one before it.
            let max_cost = if k % 2 == 0 { f32::INFINITY } else { 2.0 };
            reused.distance_field_into(&g, cost, src, max_cost, &mut field);
            let fresh = Search::new(&g).distance_field(&g, cost, src, max_cost);
            assert_eq!(field.source, fresh.source);
            assert_eq!(field.cost, fresh.cost);
            assert_eq!(field.parent, fresh.parent);
            let t = open[(k * 53 + 7) % open.len()];
            assert_eq!(
                reused.astar(&g, cost, src, t),
                Search::new(&g).astar(&g, cost, src, t)
            );
        }
        assert!(reused.generation < 100, "the counter wrapped");
    }

    #[test]
    fn distance_field_respects_limit() {
        let g = grid(40);
        let mut s = Search::new(&g);
        let src = g.index(Cell::new(0, 0));
        let df = s.distance_field(&g, |_| Some(1.0), src, 1.0);
        assert!(df.cost_to(g.index(Cell::new(5, 0))).is_some());
        assert!(df.cost_to(g.index(Cell::new(30, 0))).is_none());
    }

    #[test]
    fn costs_to_targets_agree_with_the_distance_field() {
        let g = grid(30);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let blocked: Vec<bool> = (0..g.cells()).map(|_| rng.random_bool(0.25)).collect();
        let cost = |i: usize| (!blocked[i]).then_some(1.0 + (i % 3) as f32);
        let mut s = Search::new(&g);
        let source = (0..g.cells()).find(|&i| !blocked[i]).unwrap();
        let df = s.distance_field(&g, cost, source, f32::INFINITY);
        let targets: Vec<usize> = (0..40).map(|_| rng.random_range(0..g.cells())).collect();
        let costs = s.costs_to_targets(&g, cost, source, &targets, f32::INFINITY);
        for (t, c) in targets.iter().zip(&costs) {
            assert_eq!(*c, df.cost_to(*t), "target {t}");
        }
        // A bound cuts off the far targets and nothing else.
        let bounded = s.costs_to_targets(&g, cost, source, &targets, 1.0);
        for (t, c) in targets.iter().zip(&bounded) {
            assert_eq!(*c, df.cost_to(*t).filter(|&d| d <= 1.0), "target {t}");
        }
    }
}
