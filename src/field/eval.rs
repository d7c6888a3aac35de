//! Evaluating THP Eq. 11 on a grid: the brute-force f64 reference, and the fast incremental evaluator.
//!
//! Both evaluate `Σ_c exp(-d(‖p−c‖² − d_min(p)²)/σ²) ρ_c (cos 2θ_c, sin 2θ_c)`, i.e. Eq. 11 scaled at
//! each point by `exp(d·d_min²/σ²)`, with `d_min(p)` the distance from `p` to its nearest
//! constraint: the factor is the same for every term at `p`, so it changes no direction, and it keeps
//! magnitudes O(1) where the plain sum would underflow far from every constraint.
//!
//! The fast evaluator works in square tiles of 8×8 cells. For a tile it finds the nearest-constraint
//! distance `D0` from the tile centre, gathers (from 8×8-cell bins) every constraint within
//! `reach = t + sqrt((D0+t)² + R²)` (t = tile half-diagonal, `R² = -ln(cutoff)·σ²/d`), which provably
//! includes every term whose relative weight reaches `cutoff` at any cell of the tile, and sums them
//! with the separable Gaussian `exp(-c dx²)·exp(-c dy²)`. Surface constraints sit at cell centres, so
//! their factors come from a table indexed by exact integer half-cell offsets (no `exp` per term).
//! Incremental updates recompute only tiles whose `reach` contains an added or removed constraint;
//! a tile's result depends only on the constraint set (bins are kept sorted), so the incremental field
//! is bit-identical to a full recompute.
//!
//! A constraint with a finite radius of influence (THP's path constraints, see
//! [`Constraint::radius`]) counts only at cells within that radius, for the sums and for `d_min`. The
//! tile bounds above use the unlimited constraints alone; limited ones are gathered within
//! `t + radius`, added term by term, and mark only the tiles within `t + radius` as changed.

use super::constraints::Constraint;
use crate::grid::{Cell, GridSpec};
use nalgebra::{Point2, Vector2};
use rayon::prelude::*;

/// Tile edge, cells.
const TILE: usize = 8;
/// Bin edge, fine cells.
const BIN: i32 = 8;
/// Largest `c·q0` for the separable path (keeps every factor far from under/overflow).
const FAR_LIMIT: f64 = 250.0;

/// The Gaussian of Eq. 11: `c = d/σ²` (1/m²) and `r2 = -ln(cutoff)/c` (m²), the squared distance
/// beyond the nearest constraint at which a term's relative weight falls below the cutoff.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kernel {
    pub c: f64,
    pub r2: f64,
}

impl Kernel {
    pub fn new(sigma_m: f64, decay: f64, cutoff: f64) -> Self {
        let c = decay / (sigma_m * sigma_m);
        Kernel {
            c,
            r2: -cutoff.ln() / c,
        }
    }
}

/// The field at one point: `(a, b)` and the scaled weight sum `Σ w ρ` (for the coherence μ/Σwρ).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TensorSample {
    pub a: f64,
    pub b: f64,
    pub weight: f64,
}

impl TensorSample {
    /// Anisotropy μ = |(a, b)| (the eigenvalues of the traceless tensor are ±μ).
    pub fn mu(&self) -> f64 {
        self.a.hypot(self.b)
    }

    /// μ relative to the weight sum, in [0, 1]: 1 where all nearby constraints agree.
    pub fn coherence(&self) -> f64 {
        if self.weight > 0.0 {
            self.mu() / self.weight
        } else {
            0.0
        }
    }

    /// Angle of the major eigenvector, (-π/2, π/2].
    pub fn theta(&self) -> f64 {
        0.5 * self.b.atan2(self.a)
    }

    /// Unit major eigenvector.
    pub fn major(&self) -> Vector2<f64> {
        let t = self.theta();
        Vector2::new(t.cos(), t.sin())
    }

    /// Unit minor eigenvector.
    pub fn minor(&self) -> Vector2<f64> {
        let m = self.major();
        Vector2::new(-m.y, m.x)
    }
}

/// Brute-force reference: every constraint that counts at `p`, f64, no cutoff.
pub fn reference_at(constraints: &[Constraint], p: Point2<f64>, k: &Kernel) -> TensorSample {
    let q0 = constraints
        .iter()
        .filter(|c| c.counts_at(p))
        .map(|c| (p - c.pos).norm_squared())
        .fold(f64::INFINITY, f64::min);
    let mut s = TensorSample::default();
    if !q0.is_finite() {
        return s;
    }
    for c in constraints.iter().filter(|c| c.counts_at(p)) {
        let w = (-k.c * ((p - c.pos).norm_squared() - q0)).exp();
        s.a += w * c.tensor[0];
        s.b += w * c.tensor[1];
        s.weight += w * c.strength;
    }
    s
}

/// The reference evaluated at every cell centre of `spec` (single-threaded, as the bench baseline).
pub fn reference_grid(constraints: &[Constraint], spec: &GridSpec, k: &Kernel) -> FieldGrid {
    let mut g = FieldGrid::zeros(*spec);
    for i in 0..spec.cells() {
        let s = reference_at(constraints, spec.center(spec.cell(i)), k);
        g.ab[i] = [s.a, s.b];
        g.weight[i] = s.weight;
    }
    g
}

/// A grid of `(a, b)` at cell centres, with weight sums: what topology, advection and drawing read.
#[derive(Debug, PartialEq)]
pub struct FieldGrid {
    pub spec: GridSpec,
    pub ab: Vec<[f64; 2]>,
    pub weight: Vec<f64>,
}

impl Clone for FieldGrid {
    fn clone(&self) -> Self {
        FieldGrid {
            spec: self.spec,
            ab: self.ab.clone(),
            weight: self.weight.clone(),
        }
    }

    /// Reuses the buffers: a key frame copies a grid-sized field, and fresh memory costs a page
    /// fault per page touched.
    fn clone_from(&mut self, source: &Self) {
        self.spec = source.spec;
        self.ab.clone_from(&source.ab);
        self.weight.clone_from(&source.weight);
    }
}

impl FieldGrid {
    pub fn zeros(spec: GridSpec) -> Self {
        FieldGrid {
            spec,
            ab: vec![[0.0; 2]; spec.cells()],
            weight: vec![0.0; spec.cells()],
        }
    }

    /// The stored sample of cell index `i`.
    pub fn at_index(&self, i: usize) -> TensorSample {
        TensorSample {
            a: self.ab[i][0],
            b: self.ab[i][1],
            weight: self.weight[i],
        }
    }

    /// Bilinear interpolation between cell centres; `None` outside the square of centres.
    pub fn sample(&self, p: Point2<f64>) -> Option<TensorSample> {
        let (c0, u, v) = self.bilinear_cell(p)?;
        let s = &self.spec;
        let i00 = s.index(c0);
        let i10 = i00 + 1;
        let i01 = i00 + s.nx;
        let i11 = i01 + 1;
        let mix = |f: &dyn Fn(usize) -> f64| {
            f(i00) * (1.0 - u) * (1.0 - v)
                + f(i10) * u * (1.0 - v)
                + f(i01) * (1.0 - u) * v
                + f(i11) * u * v
        };
        Some(TensorSample {
            a: mix(&|i| self.ab[i][0]),
            b: mix(&|i| self.ab[i][1]),
            weight: mix(&|i| self.weight[i]),
        })
    }

    /// The lower-left cell of the interpolation square around `p` and the fractions in it.
    pub fn bilinear_cell(&self, p: Point2<f64>) -> Option<(Cell, f64, f64)> {
        let s = &self.spec;
        let c0 = s.cell_at(p.x - 0.5 * s.res, p.y - 0.5 * s.res);
        let c1 = Cell::new(c0.x + 1, c0.y + 1);
        if !s.contains(c0) || !s.contains(c1) {
            return None;
        }
        let o = s.center(c0);
        Some((c0, (p.x - o.x) / s.res, (p.y - o.y) / s.res))
    }
}

/// Constraints binned on the fine grid; bins stay sorted by position so that sums do not depend on
/// the order constraints were added in.
#[derive(Clone, Debug)]
pub struct ConstraintStore {
    fine: GridSpec,
    slots: Vec<Option<Constraint>>,
    free: Vec<u32>,
    /// Per bin, its constraints with their ids, sorted by [`ConstraintStore::order`]. The constraints
    /// are stored here by value (besides `slots`) so that the tile gathers, the hot loop of every
    /// refresh, read each bin as one contiguous run instead of chasing ids.
    bins: Vec<Vec<(u32, Constraint)>>,
    bx: i32,
    by: i32,
    /// The largest finite radius of influence ever inserted (0 if none): how far around a tile
    /// limited constraints are gathered.
    max_radius: f64,
}

impl ConstraintStore {
    pub fn new(fine: GridSpec) -> Self {
        let bx = (fine.nx as i32 + BIN - 1) / BIN;
        let by = (fine.ny as i32 + BIN - 1) / BIN;
        ConstraintStore {
            fine,
            slots: Vec::new(),
            free: Vec::new(),
            bins: vec![Vec::new(); (bx * by) as usize],
            bx,
            by,
            max_radius: 0.0,
        }
    }

    fn bin_of(&self, p: Point2<f64>) -> (i32, i32) {
        let c = self.fine.cell_at(p.x, p.y);
        (
            (c.x.div_euclid(BIN)).clamp(0, self.bx - 1),
            (c.y.div_euclid(BIN)).clamp(0, self.by - 1),
        )
    }

    fn key(c: &Constraint) -> (f64, f64) {
        (c.pos.y, c.pos.x)
    }

    /// The order of constraints within a bin: by position (y, then x), then id.
    fn order((a, ca): &(u32, Constraint), (b, cb): &(u32, Constraint)) -> std::cmp::Ordering {
        let (ka, kb) = (Self::key(ca), Self::key(cb));
        ka.0.total_cmp(&kb.0)
            .then(ka.1.total_cmp(&kb.1))
            .then(a.cmp(b))
    }

    /// Adds a constraint; returns its id.
    pub fn insert(&mut self, c: Constraint) -> u32 {
        if c.is_limited() {
            self.max_radius = self.max_radius.max(c.radius);
        }
        let id = match self.free.pop() {
            Some(id) => {
                self.slots[id as usize] = Some(c);
                id
            }
            None => {
                self.slots.push(Some(c));
                (self.slots.len() - 1) as u32
            }
        };
        let (x, y) = self.bin_of(c.pos);
        let bin = (y * self.bx + x) as usize;
        let list = &mut self.bins[bin];
        let entry = (id, c);
        let pos = list
            .binary_search_by(|o| Self::order(o, &entry))
            .unwrap_or_else(|e| e);
        list.insert(pos, entry);
        id
    }

    /// Removes constraint `id`; returns it.
    pub fn remove(&mut self, id: u32) -> Option<Constraint> {
        let c = self.slots.get_mut(id as usize)?.take()?;
        let (x, y) = self.bin_of(c.pos);
        self.bins[(y * self.bx + x) as usize].retain(|&(o, _)| o != id);
        self.free.push(id);
        Some(c)
    }

    pub fn get(&self, id: u32) -> Option<&Constraint> {
        self.slots.get(id as usize).and_then(|c| c.as_ref())
    }

    /// Every live constraint, in id order.
    pub fn all(&self) -> Vec<Constraint> {
        self.slots.iter().flatten().copied().collect()
    }

    pub fn len(&self) -> usize {
        self.slots.len() - self.free.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Distance from `p` to the nearest constraint of unlimited radius (ring search over bins).
    pub fn nearest_distance(&self, p: Point2<f64>) -> Option<f64> {
        self.nearest_within(p, f64::INFINITY)
    }

    /// [`ConstraintStore::nearest_distance`] if it is at most `r`, else `None`; the search stops
    /// at the rings beyond `r`.
    pub fn nearest_within(&self, p: Point2<f64>, r: f64) -> Option<f64> {
        let (px, py) = self.bin_of(p);
        let bin_m = BIN as f64 * self.fine.res;
        let mut best = f64::INFINITY;
        let max_ring = self.bx.max(self.by);
        let bin_min = |x: i32, y: i32| -> f64 {
            (self.bins[(y * self.bx + x) as usize].iter())
                .filter(|(_, c)| !c.is_limited())
                .map(|(_, c)| (p - c.pos).norm_squared())
                .fold(f64::INFINITY, f64::min)
        };
        for ring in 0..=max_ring {
            // The ring's bins inside the grid, each once: its top and bottom rows, then the rest of
            // its left and right columns. Walking only the ring (not its whole square) keeps a
            // query from a tile far from every constraint, as on a large map mostly unknown,
            // quadratic in the distance rather than cubic. The minimum of the same distances is
            // the same whatever the order.
            let (x0, x1) = ((px - ring).max(0), (px + ring).min(self.bx - 1));
            for y in [py - ring, py + ring] {
                if (0..self.by).contains(&y) {
                    best = (x0..=x1).map(|x| bin_min(x, y)).fold(best, f64::min);
                }
                if ring == 0 {
                    break;
                }
            }
            let (y0, y1) = ((py - ring + 1).max(0), (py + ring - 1).min(self.by - 1));
            for x in [px - ring, px + ring] {
                if ring > 0 && (0..self.bx).contains(&x) {
                    best = (y0..=y1).map(|y| bin_min(x, y)).fold(best, f64::min);
                }
            }
            // Bins of the next ring are at least `ring` bins away from p's bin, whose extent p is in.
            if (best.is_finite() && best.sqrt() <= ring as f64 * bin_m) || ring as f64 * bin_m > r {
                break;
            }
        }
        (best.is_finite() && best.sqrt() <= r).then(|| best.sqrt())
    }

    /// Every constraint within `r` of `p`, in bin order (deterministic).
    pub fn within(&self, p: Point2<f64>, r: f64, out: &mut Vec<Constraint>) {
        out.clear();
        let (x0, y0) = self.bin_of(Point2::new(p.x - r, p.y - r));
        let (x1, y1) = self.bin_of(Point2::new(p.x + r, p.y + r));
        let r2 = r * r;
        for y in y0..=y1 {
            for x in x0..=x1 {
                for (_, c) in &self.bins[(y * self.bx + x) as usize] {
                    if (p - c.pos).norm_squared() <= r2 {
                        out.push(*c);
                    }
                }
            }
        }
    }
}

/// One incremental field grid: a constraint store, a kernel, and the evaluated [`FieldGrid`] on a grid
/// whose cells are `factor` fine cells wide (1 for the planning field; coarser for topology).
#[derive(Clone, Debug)]
pub struct FieldLevel {
    fine: GridSpec,
    factor: usize,
    kernel: Kernel,
    store: ConstraintStore,
    pub grid: FieldGrid,
    tiles_x: usize,

    /// No unlimited constraint counts at a cell farther than this from the nearest one (∞: all
    /// count); see [`FieldLevel::set_range`].
    range: f64,
    /// Per tile: the `reach` its last evaluation used (∞ before any constraint existed).
    reach: Vec<f64>,
    dirty: Vec<bool>,
    /// `g[k] = exp(-c (k·h)²)` for half-cell offsets k (h = fine.res/2).
    g: Vec<f64>,
}

/// Per-task buffers of [`FieldLevel::compute_tile`], reused from tile to tile (a refresh computes
/// hundreds of tiles; their gathers and factor tables would otherwise be allocated each time).
#[derive(Default)]
struct TileScratch {
    cands: Vec<Constraint>,
    col: Vec<f64>,
    row: Vec<f64>,
    ta: Vec<f64>,
    tb: Vec<f64>,
    st: Vec<f64>,
}

struct TileOut {
    tile: usize,
    reach: f64,
    values: Vec<(usize, [f64; 2], f64)>,
}

impl FieldLevel {
    pub fn new(fine: GridSpec, factor: usize, kernel: Kernel) -> Self {
        let factor = factor.max(1);
        let spec = GridSpec {
            origin_x: fine.origin_x,
            origin_y: fine.origin_y,
            res: fine.res * factor as f64,
            nx: fine.nx.div_ceil(factor),
            ny: fine.ny.div_ceil(factor),
            nz: 1,
        };
        let tiles_x = spec.nx.div_ceil(TILE);
        let tiles_y = spec.ny.div_ceil(TILE);
        let h = fine.res / 2.0;
        let t = (TILE as f64) * spec.res;
        let far = (FAR_LIMIT / kernel.c).sqrt() + 4.0 * t + kernel.r2.sqrt();
        let n = (far / h).ceil() as usize + 2;
        let g = (0..n)
            .map(|k| (-kernel.c * (k as f64 * h).powi(2)).exp())
            .collect();
        FieldLevel {
            fine,
            factor,
            kernel,
            store: ConstraintStore::new(fine),
            grid: FieldGrid::zeros(spec),
            tiles_x,

            range: f64::INFINITY,
            reach: vec![f64::INFINITY; tiles_x * tiles_y],
            dirty: vec![false; tiles_x * tiles_y],
            g,
        }
    }

    /// Limits the field to cells within `range` of an unlimited constraint: farther, only limited
    /// constraints count (none: no field). A change of a constraint then alters only tiles within a
    /// bounded distance of it, so the work of a refresh follows what changed, not the grid's size.
    /// Call before inserting constraints.
    pub fn set_range(&mut self, range: f64) {
        debug_assert!(self.store.is_empty(), "set the range before any constraint");
        self.range = range;
        let t = self.tile_half();
        // Before any constraint every tile is far: it changes when one comes within range of a cell.
        self.reach.fill(if range.is_finite() {
            range + t
        } else {
            f64::INFINITY
        });
    }

    /// Half the diagonal of a whole tile, metres.
    fn tile_half(&self) -> f64 {
        0.5 * (TILE - 1) as f64 * self.grid.spec.res * std::f64::consts::SQRT_2
    }

    /// The largest `reach` a tile can have under a finite range (∞ without one).
    fn max_reach(&self) -> f64 {
        let t = self.tile_half();
        t + ((self.range + 2.0 * t).powi(2) + self.kernel.r2).sqrt()
    }

    pub fn kernel(&self) -> &Kernel {
        &self.kernel
    }

    pub fn store(&self) -> &ConstraintStore {
        &self.store
    }

    fn tile_center_and_half(&self, tile: usize) -> (Point2<f64>, f64) {
        let (tx, ty) = (tile % self.tiles_x, tile / self.tiles_x);
        let s = &self.grid.spec;
        let a = s.center(Cell::new((tx * TILE) as i32, (ty * TILE) as i32));
        let b = s.center(Cell::new(
            ((tx * TILE + TILE).min(s.nx) - 1) as i32,
            ((ty * TILE + TILE).min(s.ny) - 1) as i32,
        ));
        (
            Point2::new(0.5 * (a.x + b.x), 0.5 * (a.y + b.y)),
            0.5 * (b - a).norm(),
        )
    }

    /// Marks the tiles a change of constraint `c` can alter: those whose last `reach` contains it,
    /// or for a limited constraint those with a cell within its radius.
    fn mark(&mut self, c: &Constraint) {
        for tile in self.tiles_near(c) {
            if !self.dirty[tile] {
                let (centre, t) = self.tile_center_and_half(tile);
                let reach = if c.is_limited() {
                    t + c.radius
                } else {
                    self.reach[tile]
                };
                if (centre - c.pos).norm() <= reach {
                    self.dirty[tile] = true;
                }
            }
        }
    }

    /// The tiles [`FieldLevel::mark`] must test for `c`: all of them for an unlimited constraint,
    /// and for a limited one only those whose extent comes within a tile's half-diagonal plus its
    /// radius (a path constraint reaches a few tiles, and a path lays dozens of them per step).
    fn tiles_near(&self, c: &Constraint) -> impl Iterator<Item = usize> {
        let s = &self.grid.spec;
        let tiles_y = self.reach.len() / self.tiles_x;
        let (mut x_range, mut y_range) = (0..=self.tiles_x - 1, 0..=tiles_y - 1);
        if c.is_limited() || self.range.is_finite() {
            let span = TILE as f64 * s.res;
            let reach = if c.is_limited() {
                span * std::f64::consts::SQRT_2 + c.radius
            } else {
                self.max_reach()
            };
            // One tile of slack on each side covers rounding at the tile borders.
            let range = |v: f64, origin: f64, n: usize| {
                let lo = ((v - reach - origin) / span).floor() - 1.0;
                let hi = ((v + reach - origin) / span).floor() + 1.0;
                (lo.max(0.0) as usize)..=(hi.clamp(0.0, (n - 1) as f64) as usize)
            };
            x_range = range(c.pos.x, s.origin_x, self.tiles_x);
            y_range = range(c.pos.y, s.origin_y, tiles_y);
        }
        let tiles_x = self.tiles_x;
        y_range.flat_map(move |ty| x_range.clone().map(move |tx| ty * tiles_x + tx))
    }

    /// Adds a constraint (the field is updated by the next [`FieldLevel::refresh`]).
    pub fn insert(&mut self, c: Constraint) -> u32 {
        self.mark(&c);
        self.store.insert(c)
    }

    /// Removes a constraint (the field is updated by the next [`FieldLevel::refresh`]).
    pub fn remove(&mut self, id: u32) {
        if let Some(c) = self.store.remove(id) {
            self.mark(&c);
        }
    }

    /// Recomputes the tiles that changed constraints can reach; returns how many cells it evaluated.
    pub fn refresh(&mut self) -> usize {
        let tiles: Vec<usize> = self.dirty_tiles(|_| true).collect();
        self.recompute(&tiles)
    }

    /// Recomputes the changed tiles that may hold a cell centre within `r` (per axis) of one of
    /// `points`; returns how many tiles it recomputed (0: every such tile was up to date).
    pub fn refresh_along(&mut self, points: impl Iterator<Item = Point2<f64>>, r: f64) -> usize {
        let s = self.grid.spec;
        let last = |v: i32, n: usize| (v.max(0) as usize).min(n - 1);
        let mut tiles = Vec::new();
        for p in points {
            // A centre within `r` lies in a cell between those holding `p - r` and `p + r`.
            let (lo, hi) = (s.cell_at(p.x - r, p.y - r), s.cell_at(p.x + r, p.y + r));
            if hi.x < 0 || hi.y < 0 || lo.x >= s.nx as i32 || lo.y >= s.ny as i32 {
                continue;
            }
            let (x0, x1) = (last(lo.x, s.nx) / TILE, last(hi.x, s.nx) / TILE);
            let (y0, y1) = (last(lo.y, s.ny) / TILE, last(hi.y, s.ny) / TILE);
            for ty in y0..=y1 {
                for tx in x0..=x1 {
                    let t = ty * self.tiles_x + tx;
                    if self.dirty[t] {
                        tiles.push(t);
                    }
                }
            }
        }
        if tiles.is_empty() {
            return 0;
        }
        tiles.sort_unstable();
        tiles.dedup();
        self.recompute(&tiles);
        tiles.len()
    }

    /// Whether some tile waits for a refresh.
    pub fn is_stale(&self) -> bool {
        self.dirty.iter().any(|&d| d)
    }

    /// The changed tiles that `keep` accepts, ascending.
    fn dirty_tiles<'a>(
        &'a self,
        keep: impl Fn(usize) -> bool + 'a,
    ) -> impl Iterator<Item = usize> + 'a {
        (0..self.dirty.len()).filter(move |&t| self.dirty[t] && keep(t))
    }

    /// The grid a [`FieldLevel::refresh`] would leave, computed without changing the level (for
    /// readers holding only `&self`).
    pub fn refreshed_grid(&self) -> FieldGrid {
        let tiles: Vec<usize> = self.dirty_tiles(|_| true).collect();
        let mut grid = self.grid.clone();
        for out in self.compute_tiles(&tiles) {
            for (i, ab, w) in out.values {
                grid.ab[i] = ab;
                grid.weight[i] = w;
            }
        }
        grid
    }

    /// Recomputes every tile (the "full recompute" of the bench).
    pub fn recompute_all(&mut self) -> usize {
        let tiles: Vec<usize> = (0..self.dirty.len()).collect();
        self.recompute(&tiles)
    }

    fn recompute(&mut self, tiles: &[usize]) -> usize {
        let mut cells = 0;
        for out in self.compute_tiles(tiles) {
            self.reach[out.tile] = out.reach;
            self.dirty[out.tile] = false;
            cells += out.values.len();
            for (i, ab, w) in out.values {
                self.grid.ab[i] = ab;
                self.grid.weight[i] = w;
            }
        }
        cells
    }

    /// The new values of `tiles`, computed in parallel (each tile on its own: the same whatever the
    /// split).
    fn compute_tiles(&self, tiles: &[usize]) -> Vec<TileOut> {
        tiles
            .par_iter()
            .map_init(TileScratch::default, |buf, &t| self.compute_tile(t, buf))
            .collect()
    }

    fn compute_tile(&self, tile: usize, scratch: &mut TileScratch) -> TileOut {
        let TileScratch {
            cands,
            col,
            row,
            ta,
            tb,
            st,
        } = scratch;
        let s = &self.grid.spec;
        let (tx, ty) = (tile % self.tiles_x, tile / self.tiles_x);
        let xs: Vec<usize> = (tx * TILE..(tx * TILE + TILE).min(s.nx)).collect();
        let ys: Vec<usize> = (ty * TILE..(ty * TILE + TILE).min(s.ny)).collect();
        let (center, t) = self.tile_center_and_half(tile);
        let cells: Vec<(usize, Point2<f64>)> = ys
            .iter()
            .flat_map(|&y| {
                xs.iter().map(move |&x| {
                    let c = Cell::new(x as i32, y as i32);
                    (s.index(c), s.center(c))
                })
            })
            .collect();
        let k = &self.kernel;
        // Beyond the range every cell of the tile is farther than it from the unlimited constraints.
        let d0 = self.store.nearest_within(center, self.range + t);
        // Unlimited constraints within `reach`; limited ones within `t + radius` (filtered per cell).
        let reach = d0.map_or(self.range + t, |d0| t + ((d0 + t).powi(2) + k.r2).sqrt());
        let gather = if d0.is_some() {
            reach.max(t + self.store.max_radius)
        } else {
            t + self.store.max_radius
        };
        self.store.within(center, gather, cands);
        let limited: Vec<Constraint> = cands.iter().filter(|c| c.is_limited()).copied().collect();
        let reach2 = reach * reach;
        cands.retain(|c| !c.is_limited() && (c.pos - center).norm_squared() <= reach2);
        // d_min² per cell: the nearest unlimited constraint (all within `D0 + 2t` of the centre) and
        // the limited ones that count there.
        let near_r2 = d0.map_or(0.0, |d0| (d0 + 2.0 * t).powi(2) + 1e-9);
        let near: Vec<Point2<f64>> = cands
            .iter()
            .filter(|c| (c.pos - center).norm_squared() <= near_r2)
            .map(|c| c.pos)
            .collect();
        // A cell farther than the range from every unlimited constraint (`beyond`) keeps only the
        // limited terms, relative to the nearest limited one.
        let range2 = self.range * self.range;
        let (dmin2, beyond): (Vec<f64>, Vec<bool>) = cells
            .iter()
            .map(|(_, p)| {
                let du2 = near
                    .iter()
                    .map(|q| (p - q).norm_squared())
                    .fold(f64::INFINITY, f64::min);
                let dl2 = limited
                    .iter()
                    .filter(|c| c.counts_at(*p))
                    .map(|c| (p - c.pos).norm_squared())
                    .fold(f64::INFINITY, f64::min);
                if du2 > range2 {
                    (dl2, true)
                } else {
                    (du2.min(dl2), false)
                }
            })
            .unzip();
        // The limited terms of one cell, relative to its d_min.
        let limited_terms = |ci: usize, p: Point2<f64>| -> [f64; 3] {
            let mut out = [0.0; 3];
            for c in limited.iter().filter(|c| c.counts_at(p)) {
                let wt = (-k.c * ((p - c.pos).norm_squared() - dmin2[ci])).exp();
                out[0] += wt * c.tensor[0];
                out[1] += wt * c.tensor[1];
                out[2] += wt * c.strength;
            }
            out
        };
        let Some(d0) = d0 else {
            // No unlimited constraint: only limited ones, where they count.
            let values = cells
                .iter()
                .enumerate()
                .map(|(ci, &(i, p))| {
                    let [a, b, w] = limited_terms(ci, p);
                    (i, [a, b], w)
                })
                .collect();
            return TileOut {
                tile,
                reach,
                values,
            };
        };
        let q0 = (d0 - t).max(0.0).powi(2);
        let mut values = Vec::with_capacity(cells.len());
        if k.c * q0 > FAR_LIMIT {
            // Far from every constraint: direct exponentials per term (rare: open space early on).
            for (ci, (i, p)) in cells.iter().enumerate() {
                let [mut a, mut b, mut w] = limited_terms(ci, *p);
                for c in cands.iter().filter(|_| !beyond[ci]) {
                    let wt = (-k.c * ((p - c.pos).norm_squared() - dmin2[ci])).exp();
                    a += wt * c.tensor[0];
                    b += wt * c.tensor[1];
                    w += wt * c.strength;
                }
                values.push((*i, [a, b], w));
            }
            return TileOut {
                tile,
                reach,
                values,
            };
        }
        // Separable factors: col[j][k] = exp(-c dx²), row[i][k] = exp(c q0 − c dy²).
        let n = cands.len();
        let e0 = (k.c * q0).exp();
        let f = self.factor as i64;
        col.clear();
        col.resize(xs.len() * n, 0.0);
        row.clear();
        row.resize(ys.len() * n, 0.0);
        let h = self.fine.res / 2.0;
        let gval = |d: i64| -> f64 {
            let d = d.unsigned_abs() as usize;
            match self.g.get(d) {
                Some(&v) => v,
                None => (-k.c * (d as f64 * h).powi(2)).exp(),
            }
        };
        for (ci, c) in cands.iter().enumerate() {
            match c.cell {
                Some(cell) => {
                    let (hx, hy) = (2 * cell.x as i64 + 1, 2 * cell.y as i64 + 1);
                    for (j, &x) in xs.iter().enumerate() {
                        col[j * n + ci] = gval((2 * x as i64 + 1) * f - hx);
                    }
                    for (i, &y) in ys.iter().enumerate() {
                        row[i * n + ci] = gval((2 * y as i64 + 1) * f - hy) * e0;
                    }
                }
                None => {
                    for (j, &x) in xs.iter().enumerate() {
                        let px = s.center(Cell::new(x as i32, 0)).x;
                        col[j * n + ci] = (-k.c * (px - c.pos.x).powi(2)).exp();
                    }
                    for (i, &y) in ys.iter().enumerate() {
                        let py = s.center(Cell::new(0, y as i32)).y;
                        row[i * n + ci] = (k.c * (q0 - (py - c.pos.y).powi(2))).exp();
                    }
                }
            }
        }
        ta.clear();
        ta.extend(cands.iter().map(|c| c.tensor[0]));
        tb.clear();
        tb.extend(cands.iter().map(|c| c.tensor[1]));
        st.clear();
        st.extend(cands.iter().map(|c| c.strength));
        let mut ci = 0;
        for i in 0..ys.len() {
            let r = &row[i * n..(i + 1) * n];
            for j in 0..xs.len() {
                let cl = &col[j * n..(j + 1) * n];
                let [la, lb, lw] = limited_terms(ci, cells[ci].1);
                if beyond[ci] {
                    values.push((cells[ci].0, [la, lb], lw));
                } else {
                    let [a, b, w] = weighted_sums(cl, r, ta, tb, st);
                    let scale = (k.c * (dmin2[ci] - q0)).exp();
                    values.push((
                        cells[ci].0,
                        [a * scale + la, b * scale + lb],
                        w * scale + lw,
                    ));
                }
                ci += 1;
            }
        }
        TileOut {
            tile,
            reach,
            values,
        }
    }
}

/// `Σ col·row·(ta, tb, st)` over slices of one length, with four independent accumulators per sum
/// (lanes `k mod 4`), combined as `(l0 + l1) + (l2 + l3)`, then the last `n mod 4` terms in turn.
/// The fixed order keeps results identical whatever the thread count, and whichever version runs:
/// on a CPU with AVX the four lanes are one 256-bit register ([`weighted_sums_avx`]): the same
/// products and sums in the same order, and no fused multiply-add, so the same bits.
fn weighted_sums(col: &[f64], row: &[f64], ta: &[f64], tb: &[f64], st: &[f64]) -> [f64; 3] {
    let n = col.len();
    assert!(row.len() == n && ta.len() == n && tb.len() == n && st.len() == n);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX (checked just above) and the five slices have one length.
        return unsafe { weighted_sums_avx(col, row, ta, tb, st) };
    }
    weighted_sums_lanes(col, row, ta, tb, st)
}

/// [`weighted_sums`] in portable code (the compiler vectorises the lanes for the baseline target).
fn weighted_sums_lanes(col: &[f64], row: &[f64], ta: &[f64], tb: &[f64], st: &[f64]) -> [f64; 3] {
    let mut acc = [[0.0f64; 4]; 3];
    let quads = col.chunks_exact(4).zip(row.chunks_exact(4)).zip(
        ta.chunks_exact(4)
            .zip(tb.chunks_exact(4))
            .zip(st.chunks_exact(4)),
    );
    for ((c, r), ((x, y), z)) in quads {
        // Fixed-size arrays, so that the lanes carry no bounds checks and become vector operations.
        let c: &[f64; 4] = c.try_into().expect("chunk of 4");
        let r: &[f64; 4] = r.try_into().expect("chunk of 4");
        let x: &[f64; 4] = x.try_into().expect("chunk of 4");
        let y: &[f64; 4] = y.try_into().expect("chunk of 4");
        let z: &[f64; 4] = z.try_into().expect("chunk of 4");
        for l in 0..4 {
            let w = c[l] * r[l];
            acc[0][l] += w * x[l];
            acc[1][l] += w * y[l];
            acc[2][l] += w * z[l];
        }
    }
    finish_weighted_sums(acc, col, row, ta, tb, st)
}

/// [`weighted_sums`] with AVX intrinsics.
///
/// # Safety
/// The CPU must support AVX, and the five slices must have one length.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn weighted_sums_avx(
    col: &[f64],
    row: &[f64],
    ta: &[f64],
    tb: &[f64],
    st: &[f64],
) -> [f64; 3] {
    use std::arch::x86_64::*;
    let quads = col.len() / 4 * 4;
    let (mut a0, mut a1, mut a2) = (
        _mm256_setzero_pd(),
        _mm256_setzero_pd(),
        _mm256_setzero_pd(),
    );
    let mut k = 0;
    while k < quads {
        // SAFETY: k + 4 <= quads <= the length of every slice.
        let load = |v: &[f64]| unsafe { _mm256_loadu_pd(v.as_ptr().add(k)) };
        let w = _mm256_mul_pd(load(col), load(row));
        a0 = _mm256_add_pd(a0, _mm256_mul_pd(w, load(ta)));
        a1 = _mm256_add_pd(a1, _mm256_mul_pd(w, load(tb)));
        a2 = _mm256_add_pd(a2, _mm256_mul_pd(w, load(st)));
        k += 4;
    }
    let mut acc = [[0.0f64; 4]; 3];
    for (out, a) in acc.iter_mut().zip([a0, a1, a2]) {
        // SAFETY: `out` holds four f64.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), a) };
    }
    finish_weighted_sums(acc, col, row, ta, tb, st)
}

/// The lanes combined, then the terms past the last whole group of four.
#[inline(always)]
fn finish_weighted_sums(
    acc: [[f64; 4]; 3],
    col: &[f64],
    row: &[f64],
    ta: &[f64],
    tb: &[f64],
    st: &[f64],
) -> [f64; 3] {
    let mut out = acc.map(|a| (a[0] + a[1]) + (a[2] + a[3]));
    for k in col.len() / 4 * 4..col.len() {
        let w = col[k] * row[k];
        out[0] += w * ta[k];
        out[1] += w * tb[k];
        out[2] += w * st[k];
    }
    out
}

/// Largest orientation difference (radians, of the major eigenvector) between two grids over cells
/// where `reference` has coherence at least `min_coherence`.
pub fn max_orientation_difference(
    fast: &FieldGrid,
    reference: &FieldGrid,
    min_coherence: f64,
) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..reference.ab.len() {
        let r = reference.at_index(i);
        if r.coherence() < min_coherence {
            continue;
        }
        let f = fast.at_index(i);
        let d = crate::util::wrap_angle(2.0 * (f.theta() - r.theta())).abs() / 2.0;
        worst = worst.max(d);
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::constraints::path_constraints;

    /// The ring search finds exactly the nearest unlimited constraint (brute force over all of
    /// them), from points near and far from the constraints, inside and outside the grid; and none
    /// where only limited ones are stored.
    #[test]
    fn nearest_distance_is_the_brute_force_minimum() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let fine = GridSpec::covering(Point2::new(-3.0, 1.0), Point2::new(37.0, 22.0), 0.1, 0.1);
        for round in 0..20 {
            let mut store = ConstraintStore::new(fine);
            let constraint = |rng: &mut rand_chacha::ChaCha8Rng, radius: f64| Constraint {
                // Clustered in a corner on some rounds, as a map's first views are.
                pos: Point2::new(
                    rng.random_range(-3.0..[37.0, 2.0][round % 2]),
                    rng.random_range(1.0..[22.0, 4.0][round % 2]),
                ),
                tensor: [1.0, 0.0],
                strength: 1.0,
                cell: None,
                radius,
            };
            let limited = constraint(&mut rng, 0.5);
            store.insert(limited);
            let q = Point2::new(10.0, 10.0);
            assert_eq!(store.nearest_distance(q), None, "round {round}");
            let n = rng.random_range(1..40);
            let unlimited: Vec<Constraint> = (0..n)
                .map(|_| constraint(&mut rng, f64::INFINITY))
                .collect();
            for c in &unlimited {
                store.insert(*c);
            }
            for _ in 0..200 {
                let p = Point2::new(rng.random_range(-8.0..42.0), rng.random_range(-4.0..27.0));
                let brute = (unlimited.iter())
                    .map(|c| (p - c.pos).norm_squared())
                    .fold(f64::INFINITY, f64::min)
                    .sqrt();
                assert_eq!(store.nearest_distance(p), Some(brute), "round {round}, {p}");
            }
        }
    }

    /// Every version of the weighted sums gives the same bits, for every length of the slices
    /// (whole groups of four and the terms past them).
    #[test]
    fn weighted_sums_versions_agree_bit_for_bit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for n in 0..41 {
            let mut v = || -> Vec<f64> { (0..n).map(|_| rng.random_range(-2.0..2.0)).collect() };
            let (col, row, ta, tb, st) = (v(), v(), v(), v(), v());
            let lanes = weighted_sums_lanes(&col, &row, &ta, &tb, &st);
            // A plain loop in the documented order.
            let mut acc = [[0.0f64; 4]; 3];
            for k in 0..n / 4 * 4 {
                let w = col[k] * row[k];
                acc[0][k % 4] += w * ta[k];
                acc[1][k % 4] += w * tb[k];
                acc[2][k % 4] += w * st[k];
            }
            let plain = finish_weighted_sums(acc, &col, &row, &ta, &tb, &st);
            assert_eq!(lanes.map(f64::to_bits), plain.map(f64::to_bits), "n = {n}");
            let dispatched = weighted_sums(&col, &row, &ta, &tb, &st);
            assert_eq!(
                dispatched.map(f64::to_bits),
                plain.map(f64::to_bits),
                "n = {n}"
            );
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx") {
                // SAFETY: the CPU has AVX; the slices have one length.
                let avx = unsafe { weighted_sums_avx(&col, &row, &ta, &tb, &st) };
                assert_eq!(avx.map(f64::to_bits), plain.map(f64::to_bits), "n = {n}");
            }
        }
    }

    fn fine() -> GridSpec {
        GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(9.0, 7.0), 1.0, 0.1)
    }

    fn wall_constraints(g: &GridSpec) -> Vec<Constraint> {
        let mut cs = Vec::new();
        for x in (10..80).step_by(2) {
            let c = Cell::new(x, 10);
            cs.push(Constraint::along(g.center(c), Vector2::new(1.0, 0.0), 1.0, Some(c)).unwrap());
        }
        for y in (10..60).step_by(2) {
            let c = Cell::new(12, y);
            cs.push(Constraint::along(g.center(c), Vector2::new(1.0, 2.0), 1.0, Some(c)).unwrap());
        }
        cs
    }

    #[test]
    fn fast_matches_reference_on_both_levels_and_with_free_constraints() {
        let g = fine();
        let mut cs = wall_constraints(&g);
        cs.extend(path_constraints(
            &[Point2::new(2.0, 5.0), Point2::new(7.5, 2.3)],
            0.2,
            1.0,
            f64::INFINITY,
        ));
        // A path whose constraints count only within 0.6 m, crossing the others.
        cs.extend(path_constraints(
            &[Point2::new(1.0, 1.5), Point2::new(8.0, 6.0)],
            0.2,
            1.0,
            0.6,
        ));
        for (factor, sigma) in [(1, 0.5), (2, 1.0), (3, 0.7)] {
            let k = Kernel::new(sigma, 1.0, 1e-12);
            let mut lvl = FieldLevel::new(g, factor, k);
            for c in &cs {
                lvl.insert(*c);
            }
            lvl.refresh();
            let r = reference_grid(&cs, &lvl.grid.spec, &k);
            let d = max_orientation_difference(&lvl.grid, &r, 1e-4);
            assert!(d < 1e-6, "factor {factor}: {d}");
            for i in 0..r.ab.len() {
                let (f, rr) = (lvl.grid.at_index(i), r.at_index(i));
                assert!(
                    (f.weight - rr.weight).abs() <= 1e-9 * rr.weight.max(1.0),
                    "factor {factor} cell {i}: {f:?} vs {rr:?}"
                );
            }
        }
    }

    #[test]
    fn incremental_equals_full_recompute_bit_for_bit() {
        let g = fine();
        let cs = wall_constraints(&g);
        let k = Kernel::new(0.5, 1.0, 1e-12);
        let mut inc = FieldLevel::new(g, 1, k);
        for c in &cs[..20] {
            inc.insert(*c);
        }
        inc.refresh();
        let mut ids = Vec::new();
        for c in &cs[20..] {
            ids.push(inc.insert(*c));
        }
        let partial = inc.refresh();
        assert!(partial > 0);
        inc.remove(ids[3]);
        inc.refresh();
        let mut full = FieldLevel::new(g, 1, k);
        for (n, c) in cs.iter().enumerate() {
            if n != 23 {
                full.insert(*c);
            }
        }
        full.recompute_all();
        assert_eq!(inc.grid, full.grid);
    }

    #[test]
    fn limited_constraints_change_the_field_only_within_their_radius_and_incrementally() {
        let g = fine();
        let k = Kernel::new(0.5, 1.0, 1e-12);
        let walls = wall_constraints(&g);
        let mut inc = FieldLevel::new(g, 1, k);
        for c in &walls {
            inc.insert(*c);
        }
        inc.refresh();
        let before = inc.grid.clone();
        let radius = 0.5;
        let path = path_constraints(
            &[Point2::new(2.0, 2.0), Point2::new(6.0, 5.0)],
            0.2,
            1.0,
            radius,
        );
        let ids: Vec<u32> = path.iter().map(|c| inc.insert(*c)).collect();
        let partial = inc.refresh();
        assert!(
            partial > 0 && partial < g.cells() / 2,
            "{partial} cells evaluated"
        );
        // Unchanged beyond the radius, changed on the path.
        for i in 0..g.cells() {
            let p = g.center(g.cell(i));
            let near = path.iter().any(|c| (p - c.pos).norm() <= radius);
            if !near {
                assert_eq!(inc.grid.ab[i], before.ab[i], "cell {i} at {p:?}");
            }
        }
        let on = g.index(g.cell_of(Point2::new(4.0, 3.5)).unwrap());
        assert_ne!(inc.grid.ab[on], before.ab[on]);
        // Incremental equals a full recompute, and removing the path restores the field exactly.
        let mut full = FieldLevel::new(g, 1, k);
        for c in walls.iter().chain(&path) {
            full.insert(*c);
        }
        full.recompute_all();
        assert_eq!(inc.grid, full.grid);
        for id in ids {
            inc.remove(id);
        }
        inc.refresh();
        assert_eq!(inc.grid, before);
    }

    #[test]
    fn a_bounded_range_keeps_the_field_within_it_and_only_path_terms_beyond() {
        let g = fine();
        let k = Kernel::new(0.5, 1.0, 1e-12);
        let walls = wall_constraints(&g);
        let path = path_constraints(
            &[Point2::new(2.0, 2.0), Point2::new(7.5, 6.0)],
            0.2,
            1.0,
            0.5,
        );
        let range = 1.5;
        // Built incrementally: some walls, then the rest and a path, then one wall removed.
        let mut ranged = FieldLevel::new(g, 1, k);
        ranged.set_range(range);
        for c in &walls[..20] {
            ranged.insert(*c);
        }
        ranged.refresh();
        let ids: Vec<u32> = walls[20..]
            .iter()
            .chain(&path)
            .map(|c| ranged.insert(*c))
            .collect();
        ranged.refresh();
        ranged.remove(ids[3]);
        ranged.refresh();
        let kept: Vec<Constraint> = walls
            .iter()
            .chain(&path)
            .enumerate()
            .filter(|(n, _)| *n != 23)
            .map(|(_, c)| *c)
            .collect();
        let mut full = FieldLevel::new(g, 1, k);
        full.set_range(range);
        let mut unbounded = FieldLevel::new(g, 1, k);
        for c in &kept {
            full.insert(*c);
            unbounded.insert(*c);
        }
        full.recompute_all();
        unbounded.recompute_all();
        assert_eq!(ranged.grid, full.grid);
        let limited: Vec<Constraint> = kept.iter().filter(|c| c.is_limited()).copied().collect();
        let (mut within, mut beyond, mut beyond_on_path) = (0, 0, 0);
        for i in 0..g.cells() {
            let p = g.center(g.cell(i));
            let d = kept
                .iter()
                .filter(|c| !c.is_limited())
                .map(|c| (p - c.pos).norm())
                .fold(f64::INFINITY, f64::min);
            let f = ranged.grid.at_index(i);
            if d < range - 1e-9 {
                // Within the range: Eq. 11 itself, bit for bit.
                assert_eq!(f, unbounded.grid.at_index(i), "cell {i} at {p:?}");
                within += 1;
            } else if d > range + 1e-9 {
                // Beyond it: the path's terms alone, and nothing off the path.
                let r = reference_at(&limited, p, &k);
                assert!(
                    (f.a - r.a).abs() <= 1e-9
                        && (f.b - r.b).abs() <= 1e-9
                        && (f.weight - r.weight).abs() <= 1e-9,
                    "cell {i} at {p:?}: {f:?} vs {r:?}"
                );
                beyond += 1;
                beyond_on_path += usize::from(r.weight > 0.0);
            }
        }
        assert!(
            within > 1000 && beyond > 500 && beyond_on_path > 20,
            "{within} {beyond} {beyond_on_path}"
        );
    }

    #[test]
    fn far_field_is_finite_and_directional() {
        // One constraint, evaluated 8 m away: unscaled weights would be exp(-256); scaled they are 1.
        let g = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(10.0, 2.0), 1.0, 0.1);
        let c = Cell::new(0, 0);
        let mut lvl = FieldLevel::new(g, 1, Kernel::new(0.5, 1.0, 1e-12));
        lvl.insert(Constraint::along(g.center(c), Vector2::new(0.0, 1.0), 1.0, Some(c)).unwrap());
        lvl.refresh();
        let far = lvl.grid.at_index(g.index(Cell::new(95, 10)));
        assert_eq!([far.a, far.b, far.weight], [-1.0, 0.0, 1.0]);
    }
}
