//! The one place that converts between world coordinates and grid indices.
//!
//! A [`GridSpec`] describes a regular grid of square cells (2D layers) stacked into `nz` layers of cubic
//! voxels starting at the floor (z = 0). Cell `(ix, iy)` covers
//! `[origin_x + ix·res, origin_x + (ix+1)·res) × [origin_y + iy·res, origin_y + (iy+1)·res)` and voxel
//! layer `iz` covers `[iz·res, (iz+1)·res)`. Flat indices are row-major: `iy·nx + ix` for cells and
//! `(iz·ny + iy)·nx + ix` for voxels, so that one horizontal layer is contiguous.

use nalgebra::{Point2, Point3};
use rayon::prelude::*;
use serde::Serialize;

/// A 2D cell index. Signed so that neighbours of border cells can be formed and then rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct Cell {
    pub x: i32,
    pub y: i32,
}

impl Cell {
    pub const fn new(x: i32, y: i32) -> Self {
        Cell { x, y }
    }
}

/// Offsets of the 8-connected neighbourhood; the first four are the 4-connected ones.
pub const NEIGHBOURS_8: [(i32, i32); 8] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (1, -1),
    (-1, 1),
    (-1, -1),
];

/// Geometry of the 2D layers and the 3D voxel grid that share one footprint.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GridSpec {
    /// World x of the minimum corner of cell (0, 0), metres.
    pub origin_x: f64,
    /// World y of the minimum corner of cell (0, 0), metres.
    pub origin_y: f64,
    /// Cell and voxel edge, metres.
    pub res: f64,
    pub nx: usize,
    pub ny: usize,
    /// Number of voxel layers above the floor.
    pub nz: usize,
}

impl GridSpec {
    /// A grid covering `[min, max]` in x and y (rounded outwards to whole cells) and `[0, top_z]` in z.
    pub fn covering(min: Point2<f64>, max: Point2<f64>, top_z: f64, res: f64) -> Self {
        let nx = (((max.x - min.x) / res).ceil() as usize).max(1);
        let ny = (((max.y - min.y) / res).ceil() as usize).max(1);
        let nz = ((top_z / res).ceil() as usize).max(1);
        GridSpec {
            origin_x: min.x,
            origin_y: min.y,
            res,
            nx,
            ny,
            nz,
        }
    }

    /// Number of 2D cells.
    pub fn cells(&self) -> usize {
        self.nx * self.ny
    }

    /// Number of 3D voxels.
    pub fn voxels(&self) -> usize {
        self.nx * self.ny * self.nz
    }

    /// Area of one cell, m².
    pub fn cell_area(&self) -> f64 {
        self.res * self.res
    }

    /// Volume of one voxel, m³.
    pub fn voxel_volume(&self) -> f64 {
        self.res * self.res * self.res
    }

    /// The cell containing world point `(x, y)`, whether or not it lies inside the grid.
    pub fn cell_at(&self, x: f64, y: f64) -> Cell {
        Cell::new(
            ((x - self.origin_x) / self.res).floor() as i32,
            ((y - self.origin_y) / self.res).floor() as i32,
        )
    }

    /// The cell containing `p`, or `None` outside the grid.
    pub fn cell_of(&self, p: Point2<f64>) -> Option<Cell> {
        let c = self.cell_at(p.x, p.y);
        self.contains(c).then_some(c)
    }

    /// Whether `c` lies inside the grid.
    pub fn contains(&self, c: Cell) -> bool {
        c.x >= 0 && c.y >= 0 && (c.x as usize) < self.nx && (c.y as usize) < self.ny
    }

    /// World centre of cell `c`.
    pub fn center(&self, c: Cell) -> Point2<f64> {
        Point2::new(
            self.origin_x + (c.x as f64 + 0.5) * self.res,
            self.origin_y + (c.y as f64 + 0.5) * self.res,
        )
    }

    /// Flat index of an in-grid cell.
    pub fn index(&self, c: Cell) -> usize {
        debug_assert!(self.contains(c));
        c.y as usize * self.nx + c.x as usize
    }

    /// Flat index of `c`, or `None` outside the grid.
    pub fn checked_index(&self, c: Cell) -> Option<usize> {
        self.contains(c).then(|| self.index(c))
    }

    /// The cell of a flat index.
    pub fn cell(&self, index: usize) -> Cell {
        Cell::new((index % self.nx) as i32, (index / self.nx) as i32)
    }

    /// Voxel layer containing height `z` (may be out of range).
    pub fn layer_at(&self, z: f64) -> i32 {
        (z / self.res).floor() as i32
    }

    /// Height of the centre of voxel layer `iz`.
    pub fn layer_center(&self, iz: usize) -> f64 {
        (iz as f64 + 0.5) * self.res
    }

    /// The layers whose centres lie in `[z_min, z_max]`, clipped to the grid.
    pub fn layers_in(&self, z_min: f64, z_max: f64) -> std::ops::Range<usize> {
        let lo = ((z_min / self.res - 0.5).ceil().max(0.0)) as usize;
        let hi = (((z_max / self.res - 0.5).floor() + 1.0).max(0.0) as usize).min(self.nz);
        lo.min(hi)..hi
    }

    /// Flat index of voxel `(c, iz)`; `c` must be in the grid and `iz < nz`.
    pub fn voxel_index(&self, c: Cell, iz: usize) -> usize {
        debug_assert!(self.contains(c) && iz < self.nz);
        (iz * self.ny + c.y as usize) * self.nx + c.x as usize
    }

    /// Voxel containing world point `p`, or `None` outside the grid.
    pub fn voxel_of(&self, p: Point3<f64>) -> Option<usize> {
        let c = self.cell_at(p.x, p.y);
        let iz = self.layer_at(p.z);
        (self.contains(c) && iz >= 0 && (iz as usize) < self.nz)
            .then(|| self.voxel_index(c, iz as usize))
    }

    /// The (cell index, layer) of a flat voxel index.
    pub fn voxel_parts(&self, voxel: usize) -> (usize, usize) {
        let layer_len = self.nx * self.ny;
        (voxel % layer_len, voxel / layer_len)
    }

    /// World x, y of the grid's minimum corner and maximum corner.
    pub fn bounds(&self) -> (Point2<f64>, Point2<f64>) {
        (
            Point2::new(self.origin_x, self.origin_y),
            Point2::new(
                self.origin_x + self.nx as f64 * self.res,
                self.origin_y + self.ny as f64 * self.res,
            ),
        )
    }
}

/// A rectangle of cells, bounds inclusive, or empty: the part of a grid some work is confined to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellRect {
    pub min: Cell,
    pub max: Cell,
}

impl Default for CellRect {
    fn default() -> Self {
        CellRect::EMPTY
    }
}

impl CellRect {
    /// Holds no cell; grows to the first one added.
    pub const EMPTY: CellRect = CellRect {
        min: Cell::new(i32::MAX, i32::MAX),
        max: Cell::new(i32::MIN, i32::MIN),
    };

    /// Every cell of `grid`.
    pub fn all(grid: &GridSpec) -> CellRect {
        CellRect {
            min: Cell::new(0, 0),
            max: Cell::new(grid.nx as i32 - 1, grid.ny as i32 - 1),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y
    }

    pub fn contains(&self, c: Cell) -> bool {
        (self.min.x..=self.max.x).contains(&c.x) && (self.min.y..=self.max.y).contains(&c.y)
    }

    /// Grows to hold `c`.
    #[inline]
    pub fn add(&mut self, c: Cell) {
        self.min = Cell::new(self.min.x.min(c.x), self.min.y.min(c.y));
        self.max = Cell::new(self.max.x.max(c.x), self.max.y.max(c.y));
    }

    /// The smallest rectangle holding both.
    pub fn union(self, other: CellRect) -> CellRect {
        let mut r = self;
        if !other.is_empty() {
            r.add(other.min);
            r.add(other.max);
        }
        r
    }

    /// The cells within `r` metres (in x and in y) of `p`, clipped to `grid`.
    pub fn around(grid: &GridSpec, p: Point2<f64>, r: f64) -> CellRect {
        let lo = grid.cell_at(p.x - r, p.y - r);
        let hi = grid.cell_at(p.x + r, p.y + r);
        CellRect { min: lo, max: hi }.clip(grid)
    }

    /// The part inside `grid`.
    pub fn clip(self, grid: &GridSpec) -> CellRect {
        if self.is_empty() {
            return CellRect::EMPTY;
        }
        let r = CellRect {
            min: Cell::new(self.min.x.max(0), self.min.y.max(0)),
            max: Cell::new(
                self.max.x.min(grid.nx as i32 - 1),
                self.max.y.min(grid.ny as i32 - 1),
            ),
        };
        if r.is_empty() {
            CellRect::EMPTY
        } else {
            r
        }
    }

    /// Width in cells (0 when empty).
    pub fn width(&self) -> usize {
        if self.is_empty() {
            0
        } else {
            (self.max.x - self.min.x + 1) as usize
        }
    }

    /// Its cells with their flat indices in `grid`, ascending (the rectangle lies in `grid`).
    pub fn cells(self, grid: &GridSpec) -> impl Iterator<Item = (Cell, usize)> {
        let x0 = self.min.x;
        self.rows(grid).enumerate().flat_map(move |(k, row)| {
            let y = self.min.y + k as i32;
            let start = row.start;
            row.map(move |i| (Cell::new(x0 + (i - start) as i32, y), i))
        })
    }

    /// Its rows as ranges of flat cell indices of `grid`, ascending (the rectangle lies in `grid`).
    pub fn rows(self, grid: &GridSpec) -> impl Iterator<Item = std::ops::Range<usize>> {
        let (x0, w, nx) = (self.min.x.max(0) as usize, self.width(), grid.nx);
        let ys = if self.is_empty() {
            0..0
        } else {
            self.min.y as usize..self.max.y as usize + 1
        };
        ys.map(move |y| {
            let start = y * nx + x0;
            start..start + w
        })
    }
}

/// What is known about one floor cell: of the robot's map, or of a ROS map file (where `Obstacle` is
/// map_server's "occupied").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellState {
    Unknown,
    Free,
    Obstacle,
}

/// Distances closer than this to a voxel boundary (metres) count as ties that rounding could
/// decide: a distance or height computed one way might fall on the other side of the boundary than
/// the voxel walk puts it (the two round differently, by ~1e-15 m). The column sweeps of the map and
/// of the observable set walk such rays one by one instead.
pub const TIE_M: f64 = 1e-9;

/// `x.floor()` as an integer, without a libm call (the baseline x86-64 target has no rounding
/// instruction). The voxel walk and every lookup that must agree with it take their floors here.
/// Far outside any grid it is clamped: above 2^52 to 2^52, below -2^52 to -2^52 - 1; NaN gives
/// -2^52.
#[inline(always)]
pub fn floor_i64(x: f64) -> i64 {
    floor_both(x).0
}

/// Voxel layers `a..=b` (or `b..=a`) of a column as a bit mask, one bit a layer: how the column
/// sweeps of the map and of the observable set mark a ray's span of a column (at most 64 layers).
#[inline(always)]
pub fn layer_span(a: usize, b: usize) -> u64 {
    let (a, b) = (a.min(b), a.max(b));
    (u64::MAX >> (63 - b)) & (u64::MAX << a)
}

/// [`floor_i64`]`(x)`, and the same as an `f64` taken from the conversion already made rather than
/// converted back. `(l, lf)` has `lf == l as f64` exactly.
#[inline(always)]
pub fn floor_both(x: f64) -> (i64, f64) {
    let t = truncate(x);
    let tf = t as f64;
    if x < tf {
        (t - 1, tf - 1.0)
    } else {
        (t, tf)
    }
}

/// `x`'s integer part, with `x` first clamped to ±2^52 (where every f64 is already an integer,
/// far outside any grid) and NaN taken as -2^52. `x as i64` saturates at i64's ends and takes NaN
/// to 0 instead: those rules cost several instructions besides the conversion itself, in the voxel
/// lookups of every ray; these two compares are one instruction each.
#[inline(always)]
fn truncate(x: f64) -> i64 {
    // 2^52.
    const LIMIT: f64 = 4_503_599_627_370_496.0;
    // (Written so that a NaN fails the first test.)
    let c = if x > -LIMIT { x } else { -LIMIT };
    let c = if c < LIMIT { c } else { LIMIT };
    // SAFETY: `c` is finite and at most 2^52 in magnitude: its integer part fits an i64.
    unsafe { c.to_int_unchecked::<i64>() }
}

/// Exact squared Euclidean distance transform (Felzenszwalb–Huttenlocher), in cells², from every
/// cell to the nearest `true` cell; `f64::INFINITY` where there is none.
pub fn distance_transform(sites: &[bool], nx: usize, ny: usize) -> Vec<f64> {
    const FAR: f64 = 1e20;
    // Columns first (transposed so each column is contiguous), then rows.
    let mut cols = vec![FAR; nx * ny];
    for iy in 0..ny {
        for ix in 0..nx {
            if sites[iy * nx + ix] {
                cols[ix * ny + iy] = 0.0;
            }
        }
    }
    cols.par_chunks_mut(ny).for_each(edt_1d);
    let mut rows = vec![0.0; nx * ny];
    for ix in 0..nx {
        for iy in 0..ny {
            rows[iy * nx + ix] = cols[ix * ny + iy];
        }
    }
    rows.par_chunks_mut(nx).for_each(edt_1d);
    rows.into_iter()
        .map(|d| if d >= FAR * 0.5 { f64::INFINITY } else { d })
        .collect()
}

/// One 1D pass: `f[q] ← min_p (q − p)² + f[p]` via the lower envelope of parabolas.
fn edt_1d(f: &mut [f64]) {
    let n = f.len();
    if n == 0 {
        return;
    }
    let input = f.to_vec();
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        loop {
            let p = v[k];
            let s = ((input[q] + (q * q) as f64) - (input[p] + (p * p) as f64))
                / (2.0 * (q as f64 - p as f64));
            if s <= z[k] && k > 0 {
                k -= 1;
                continue;
            }
            if s <= z[k] {
                // k == 0: the new parabola replaces the first one entirely.
                v[0] = q;
                z[1] = f64::INFINITY;
                break;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
            break;
        }
    }
    k = 0;
    for (q, out) in f.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        let d = q as f64 - p as f64;
        *out = d * d + input[p];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layer_span_sets_exactly_the_layers_between_its_ends() {
        assert_eq!(layer_span(2, 4), 0b11100);
        assert_eq!(layer_span(4, 2), 0b11100);
        assert_eq!(layer_span(5, 5), 1 << 5);
        assert_eq!(layer_span(0, 63), u64::MAX);
        assert_eq!(layer_span(63, 63), 1 << 63);
        for (a, b) in [(0, 0), (3, 17), (40, 12)] {
            let expect: u64 = (a.min(b)..=a.max(b)).map(|l| 1u64 << l).sum();
            assert_eq!(layer_span(a, b), expect, "{a}..={b}");
        }
    }
    use rand::{Rng, SeedableRng};

    #[test]
    fn floors_are_libms_within_two_to_the_52() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let limit = 2f64.powi(52);
        // Integers, their neighbours an ulp away, ±0, tiny and huge magnitudes, and random values
        // of every scale.
        let mut xs = vec![
            0.0,
            -0.0,
            1e-300,
            -1e-300,
            0.5,
            -0.5,
            limit,
            -limit,
            limit - 0.5,
        ];
        for k in -60i64..=60 {
            let x = k as f64;
            xs.extend([x, x.next_up(), x.next_down(), x + 0.5, x * 1e9 + 0.25]);
        }
        for _ in 0..20_000 {
            let scale = 10f64.powi(rng.random_range(-12..16));
            xs.push(rng.random_range(-1.0..1.0) * scale);
        }
        for x in xs {
            let (l, lf) = floor_both(x);
            // (Equal as numbers: the floor of -0.0 is -0.0, and 0 as f64 is +0.0.)
            assert_eq!(lf, x.floor(), "floor_both({x}).1");
            assert_eq!(lf.to_bits(), (l as f64).to_bits(), "floor_both({x}).1");
            assert_eq!(l, x.floor() as i64, "floor_both({x}).0");
            assert_eq!(floor_i64(x), l);
        }
        // Beyond ±2^52 and NaN: clamped, far outside any grid.
        for (x, l) in [
            (2f64.powi(60), 1i64 << 52),
            (f64::INFINITY, 1 << 52),
            (-2f64.powi(60), -(1 << 52) - 1),
            (f64::NEG_INFINITY, -(1 << 52) - 1),
            (f64::NAN, -(1 << 52)),
        ] {
            assert_eq!(floor_both(x), (l, l as f64), "floor_both({x})");
        }
    }

    #[test]
    fn edt_matches_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for (nx, ny, p) in [(37, 23, 0.05), (16, 40, 0.3), (9, 9, 0.0), (30, 1, 0.1)] {
            let sites: Vec<bool> = (0..nx * ny).map(|_| rng.random_bool(p)).collect();
            let fast = distance_transform(&sites, nx, ny);
            for (i, &fast_d2) in fast.iter().enumerate() {
                let (x, y) = ((i % nx) as f64, (i / nx) as f64);
                let brute = (0..nx * ny)
                    .filter(|&j| sites[j])
                    .map(|j| {
                        let (a, b) = ((j % nx) as f64, (j / nx) as f64);
                        (a - x).powi(2) + (b - y).powi(2)
                    })
                    .fold(f64::INFINITY, f64::min);
                assert_eq!(fast_d2, brute, "{nx}×{ny} cell {i}");
            }
        }
    }

    fn spec() -> GridSpec {
        GridSpec::covering(Point2::new(-1.0, 2.0), Point2::new(3.0, 4.05), 1.8, 0.1)
    }

    #[test]
    fn covering_rounds_outwards() {
        let g = spec();
        assert_eq!((g.nx, g.ny, g.nz), (40, 21, 18));
    }

    #[test]
    fn cell_and_center_round_trip() {
        let g = spec();
        for idx in [0, 7, 40, 839] {
            let c = g.cell(idx);
            assert_eq!(g.index(c), idx);
            let p = g.center(c);
            assert_eq!(g.cell_of(p), Some(c));
        }
        assert_eq!(g.cell_of(Point2::new(-1.01, 2.5)), None);
        assert_eq!(g.cell_of(Point2::new(3.0, 2.5)), None);
    }

    #[test]
    fn voxel_index_round_trip() {
        let g = spec();
        let c = Cell::new(5, 9);
        let v = g.voxel_index(c, 3);
        assert_eq!(g.voxel_parts(v), (g.index(c), 3));
        let p = Point3::new(g.center(c).x, g.center(c).y, g.layer_center(3));
        assert_eq!(g.voxel_of(p), Some(v));
        assert_eq!(g.voxel_of(Point3::new(0.0, 3.0, -0.01)), None);
        assert_eq!(g.voxel_of(Point3::new(0.0, 3.0, 1.8)), None);
    }

    #[test]
    fn layers_in_band() {
        let g = spec();
        // Centres 0.15 .. 1.75 lie in [0.1, 1.8]: layers 1..=17.
        assert_eq!(g.layers_in(0.1, 1.8), 1..18);
        // Robot band [0.1, 1.2]: centres 0.15 .. 1.15.
        assert_eq!(g.layers_in(0.1, 1.2), 1..12);
        assert_eq!(g.layers_in(5.0, 6.0), 18..18);
    }
}
