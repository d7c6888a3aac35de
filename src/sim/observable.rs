//! What the robot could ever observe: the ceiling that completeness is measured against.
//!
//! **Observable set.** The height-band voxels that the configured depth camera marks as known (the
//! hit voxel of a valid ray, or a voxel a ray passes through) from some pose of the reachable
//! region (`GroundTruth::reachable`). It is computed under the same sensor model and voxel
//! traversal the map uses: the camera's own ray directions and range rule, `MeshBvh::cast`, and
//! `map::occupancy::traverse` (a test checks agreement with `Occupancy::integrate` frame by frame).
//!
//! **Sampling.** The reachable region is cut into squares of side `metrics.observable_spacing_m`; in
//! each square, every 8-connected patch of reachable cells gets one position, the patch cell nearest
//! its centroid (so a narrow corridor or an alcove that crosses no lattice point is still sampled).
//! At each position the camera looks along `metrics.observable_yaws` headings evenly spread over the
//! full turn (the robot turns in place, so every heading is reachable). A ray only matters while it
//! is inside the height band, so it is cast and traversed up to where it leaves the band; that gives
//! the same band voxels as a full-length ray (a ray leaves a horizontal slab once).
//!
//! **Finer where the view depends on the position.** What the camera sees through a gap too narrow
//! to pass (a narrow door, a slot beside furniture, an opening onto the outside) changes sharply with
//! the position: the gap is an aperture, and a planner that looks through it from a pose between two
//! lattice points sees a wedge neither of them does. So the sampling runs twice. The first pass uses
//! the lattice above and notes every position whose view holds at least [`REFINE_BEYOND_M3`] of band
//! voxels over *beyond* cells (free floor farther than the inflation radius plus two cells from every
//! reachable cell: space behind such gaps, see [`beyond_cells`]). The second pass samples the 3 × 3
//! squares around each of those positions again on a lattice of half the side (rounded down to whole
//! cells: 0.2 m at the defaults), with the same rule of one position per patch. The set is the union
//! of both passes. Scenes whose rooms are all drivable have no such views and cost no more.
//!
//! **Walking the rays.** The reference is one ray at a time (`VoxelCaster::observe`): a voxel walk
//! that tests the triangles of each occupied voxel it enters. The set is computed faster, with the
//! same result, by sweeping each pixel column's rays together through the floor cells they share
//! (`VoxelCaster::sweep_column`): a run of rays that meets no occupied voxel in a cell marks one span
//! of layers there, and single rays are walked only where they meet occupied voxels. A column where
//! some distance falls within 1e-9 m of a voxel boundary (where rounding could decide the map's walk)
//! is walked ray by ray instead (about 0.3 % of the columns on the shipped scenes). A test checks the
//! two ways bit for bit; cameras of more than 64 rows or grids of more than 64 layers use the
//! reference walk only.
//!
//! **Cost and cache.** This costs seconds, so [`ObservableCache`] keeps one file per scene and the
//! config keys the set depends on, written atomically and checked on read (length, key and
//! checksum): a damaged file is recomputed and reported, never trusted.

#[cfg(test)]
use crate::config::Config;
use crate::config::{CameraConfig, MetricsConfig};
use crate::grid::{floor_both, floor_i64, Cell, GridSpec, NEIGHBOURS_8, TIE_M};
use crate::map::occupancy::traverse_while;
use crate::scene::{GroundTruth, Scene, VoxelTriangles};
use crate::sensor::{DepthCamera, MeshBvh};
use crate::util::fnv1a64;
use crate::{Error, Result};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The voxels the camera could observe from the reachable region.
#[derive(Clone, Debug, PartialEq)]
pub struct ObservableSet {
    /// One bit per voxel of the grid (flat voxel index); set only in the height band.
    bits: Vec<u64>,
    voxels: usize,
    /// Observable voxels that the ground truth marks occupied (observable surface), ascending.
    surface: Vec<u32>,
    /// Sampled positions (each seen from every heading).
    positions: usize,
    voxel_volume: f64,
}

/// The pose sampling, from the config (the sensor model is the `DepthCamera`'s).
#[derive(Clone, Debug, PartialEq)]
pub struct ObservableParams {
    pub spacing_m: f64,
    pub yaws: usize,
}

impl ObservableParams {
    pub fn from_config(metrics: &MetricsConfig) -> Self {
        ObservableParams {
            spacing_m: metrics.observable_spacing_m,
            yaws: metrics.observable_yaws,
        }
    }
}

impl ObservableSet {
    /// Samples the camera over the reachable region of `gt` (see the module doc).
    pub fn compute(
        gt: &GroundTruth,
        bvh: &MeshBvh,
        camera: &DepthCamera,
        p: &ObservableParams,
    ) -> ObservableSet {
        let grid = gt.grid;
        let band = gt.band_layers();
        let reach = gt.reachable_mask();
        let k = lattice_cells(&grid, p.spacing_m);
        let coarse = sample_positions(&grid, reach, k, |_, _| true);
        // The band as a z interval: a ray is cast and walked only while inside it.
        let (z_lo, z_hi) = (band.start as f64 * grid.res, band.end as f64 * grid.res);
        let yaws: Vec<(f32, f32)> = (0..p.yaws)
            .map(|k| {
                let yaw = std::f64::consts::TAU * k as f64 / p.yaws as f64;
                (yaw.sin() as f32, yaw.cos() as f32)
            })
            .collect();
        let caster = VoxelCaster::new(gt, bvh, camera, (z_lo, z_hi));
        let beyond = beyond_cells(gt);
        let sweep = caster.sweep_applies(camera);
        let frames = |positions: &[usize]| {
            if sweep {
                caster.frames_by_columns(positions, &yaws, camera, &beyond)
            } else {
                caster.frames_by_rays(positions, &yaws, camera, &beyond)
            }
        };
        let first = frames(&coarse);
        let fine = refined_positions(&grid, reach, k, &first.looked_beyond, &coarse);
        let mut bits = first.bits;
        if !fine.is_empty() {
            let second = frames(&fine);
            bits.iter_mut().zip(&second.bits).for_each(|(a, b)| *a |= b);
        }
        ObservableSet::from_bits(gt, bits, coarse.len() + fine.len())
    }

    /// A set holding exactly the band voxels among `voxels` (flat indices), for tests that need an
    /// observable set known by construction.
    #[cfg(test)]
    pub(crate) fn of_voxels(gt: &GroundTruth, voxels: &[usize]) -> ObservableSet {
        let mut bits = vec![0u64; gt.grid.voxels().div_ceil(64)];
        for &v in voxels {
            bits[v >> 6] |= 1 << (v & 63);
        }
        ObservableSet::from_bits(gt, bits, 0)
    }

    /// Completes a set from its bits: keeps band voxels only, counts them, lists the surface.
    fn from_bits(gt: &GroundTruth, mut bits: Vec<u64>, positions: usize) -> ObservableSet {
        let grid = gt.grid;
        let band = gt.band_layers();
        let (lo, hi) = (band.start * grid.cells(), band.end * grid.cells());
        for v in (0..lo).chain(hi..grid.voxels()) {
            bits[v >> 6] &= !(1 << (v & 63));
        }
        let has = |v: usize| bits[v >> 6] >> (v & 63) & 1 == 1;
        let voxels = (lo..hi).filter(|&v| has(v)).count();
        let surface = (lo..hi)
            .filter(|&v| has(v) && gt.occupied(v))
            .map(|v| v as u32)
            .collect();
        ObservableSet {
            bits,
            voxels,
            surface,
            positions,
            voxel_volume: grid.voxel_volume(),
        }
    }

    /// Whether flat voxel `v` is observable.
    #[inline]
    pub fn contains(&self, v: usize) -> bool {
        self.bits
            .get(v >> 6)
            .is_some_and(|w| w >> (v & 63) & 1 == 1)
    }

    /// Number of observable voxels.
    pub fn voxels(&self) -> usize {
        self.voxels
    }

    /// Observable volume, m³.
    pub fn volume_m3(&self) -> f64 {
        self.voxels as f64 * self.voxel_volume
    }

    /// Observable voxels that are occupied in the ground truth, ascending.
    pub fn surface_voxels(&self) -> &[u32] {
        &self.surface
    }

    /// Positions the camera was sampled at.
    pub fn positions(&self) -> usize {
        self.positions
    }

    /// Whether any band voxel of `cell`'s column is observable.
    pub fn column_observable(&self, gt: &GroundTruth, cell: usize) -> bool {
        gt.band_layers()
            .any(|iz| self.contains(iz * gt.grid.cells() + cell))
    }
}

/// Casts camera rays by walking the voxel grid, testing only the triangles that overlap each
/// occupied voxel it enters (`MeshBvh::cast_among`, the BVH cast's own arithmetic): the first hit is
/// the mesh's first hit, found without the tree.
struct VoxelCaster<'a> {
    grid: &'a GridSpec,
    /// The triangles of every occupied voxel, dense (the lists of `GroundTruth::voxel_triangles`,
    /// indexed without a search).
    tris: TriangleIndex,
    bvh: &'a MeshBvh,
    /// The height band `[z_lo, z_hi)`, metres.
    band: (f64, f64),
    /// The camera's nearest and farthest depth, metres.
    range: (f32, f32),
    /// The band's layers, and the same one bit each (all bits when the grid has over 64 layers).
    band_layers: std::ops::Range<usize>,
    band_mask: u64,
}

/// [`VoxelTriangles`] indexed densely by voxel, for the caster's hot loop.
struct TriangleIndex {
    /// `GroundTruth::occupied`, one byte per voxel (the walk's test, kept beside the lists).
    occupied: Vec<bool>,
    /// Per floor cell, its occupied layers, one bit each (empty when the grid has over 64 layers).
    layers: Vec<u64>,
    /// Cell-major, per voxel of floor cell `c` and layer `iz`: where its triangle list starts in
    /// `lists` (`list[c * nz + iz]`, 0 for an empty list).
    list: Vec<u32>,
    /// The distinct lists, each its length then its triangles (ascending). Voxels with the same
    /// triangles share one list (a wall's face covers every layer of its cell, and the cells on
    /// both sides of a cell line it lies on), so a ray that has been tested against a list knows it
    /// from its start alone (see [`RayHits::tested`]).
    lists: Vec<u32>,
    nz: usize,
}

impl TriangleIndex {
    fn new(gt: &GroundTruth, lists: &VoxelTriangles) -> TriangleIndex {
        let grid = &gt.grid;
        let n = grid.voxels();
        let (cells, nz) = (grid.cells(), grid.nz);
        let occupied: Vec<bool> = (0..n).map(|v| gt.occupied(v)).collect();
        let mut list = Vec::with_capacity(n);
        let mut stored = vec![0u32];
        let mut known: std::collections::HashMap<&[u32], u32> = std::collections::HashMap::new();
        known.insert(&[], 0);
        for c in 0..cells {
            for iz in 0..nz {
                let v = iz * cells + c;
                if !occupied[v] {
                    list.push(0);
                    continue;
                }
                let tris = lists.of(v);
                list.push(*known.entry(tris).or_insert_with(|| {
                    let start = stored.len() as u32;
                    stored.push(tris.len() as u32);
                    stored.extend_from_slice(tris);
                    start
                }));
            }
        }
        let mut layers = Vec::new();
        if nz <= 64 {
            layers = vec![0u64; cells];
            for (v, _) in occupied.iter().enumerate().filter(|(_, &o)| o) {
                let (c, iz) = grid.voxel_parts(v);
                layers[c] |= 1 << iz;
            }
        }
        TriangleIndex {
            occupied,
            layers,
            list,
            lists: stored,
            nz,
        }
    }

    /// The triangle list of the voxel of floor cell `c` and layer `iz`: its start in `lists`.
    #[inline]
    fn list(&self, c: usize, iz: usize) -> u32 {
        self.list[c * self.nz + iz]
    }

    /// The triangles of the list that starts at `start`.
    #[inline]
    fn triangles(&self, start: u32) -> &[u32] {
        let start = start as usize;
        let len = self.lists[start] as usize;
        &self.lists[start + 1..start + 1 + len]
    }
}

impl<'a> VoxelCaster<'a> {
    fn new(
        gt: &'a GroundTruth,
        bvh: &'a MeshBvh,
        camera: &DepthCamera,
        band: (f64, f64),
    ) -> VoxelCaster<'a> {
        let band_layers = gt.band_layers();
        let band_mask = if gt.grid.nz > 64 {
            u64::MAX
        } else {
            band_layers.clone().fold(0u64, |m, l| m | 1 << l)
        };
        VoxelCaster {
            grid: &gt.grid,
            tris: TriangleIndex::new(gt, gt.voxel_triangles()),
            bvh,
            band,
            range: camera.range_limits(),
            band_layers,
            band_mask,
        }
    }

    /// The nearest hit of the ray on the triangles of list `list` (see [`TriangleIndex::list`]), or
    /// infinity. Kept out of line so that the walk's loop stays small.
    #[inline(never)]
    fn hit_in(&self, list: u32, origin: Point3<f32>, dir: Vector3<f32>) -> f64 {
        self.bvh
            .cast_among(origin, dir, self.tris.triangles(list), self.range.1)
            .map_or(f64::INFINITY, |t| t as f64)
    }

    /// The voxels one camera ray makes known in the map, as `Occupancy::integrate` does: every voxel
    /// the ray passes through up to its first hit and the voxel of that hit; nothing when the hit is
    /// nearer than the minimum range (no reading); free space up to the maximum range when there is
    /// no hit. The ray is cut where it leaves the band, which changes no band voxel (a ray leaves a
    /// horizontal slab once). `buf` is scratch space; the result borrows it.
    #[inline]
    fn observe<'b>(
        &self,
        origin: Point3<f32>,
        dir: Vector3<f32>,
        buf: &'b mut Vec<usize>,
    ) -> &'b [usize] {
        buf.clear();
        let (min_range, max_range) = self.range;
        let (oz, dz) = (origin.z as f64, dir.z as f64);
        let leave = if dz > 0.0 {
            (self.band.1 - oz) / dz
        } else if dz < 0.0 {
            (self.band.0 - oz) / dz
        } else {
            f64::INFINITY
        };
        if leave < 0.0 {
            return buf;
        }
        let cut = (leave + 1e-6).max(min_range as f64).min(max_range as f64);
        let (o, d) = (origin.cast::<f64>(), dir.cast::<f64>());
        // The nearest hit so far (an f32 distance, held as f64).
        let mut best = f64::INFINITY;
        let occupied = &self.tris.occupied[..];
        traverse_while(self.grid, o, d, cut, |v, t_in, t_out| {
            if occupied[v] {
                let (c, iz) = self.grid.voxel_parts(v);
                best = best.min(self.hit_in(self.tris.list(c, iz), origin, dir));
            }
            // A face on this voxel's entry face can lie a hair before it in world coordinates (the
            // voxelisation is half-open): the map's ray ends there and never enters this voxel.
            if best <= t_in {
                return false;
            }
            buf.push(v);
            // A hit found in an earlier voxel's triangles may lie further on: stop only once the
            // walk has reached it.
            best > t_out
        });
        if best.is_finite() {
            if best < min_range as f64 {
                buf.clear();
            } else if let Some(v) = self.grid.voxel_of(o + d * best) {
                buf.push(v);
            }
        }
        buf
    }
}

/// Rotates a camera-frame ray to the world frame for heading (sin, cos), as the camera does.
#[inline]
fn world_ray(sin: f32, cos: f32, d: &Vector3<f32>) -> Vector3<f32> {
    Vector3::new(cos * d.x - sin * d.y, sin * d.x + cos * d.y, d.z)
}

/// A part of a run that meets an occupied voxel in a cell is halved while it holds more rays than
/// this (see [`VoxelCaster::sweep_column`]): the halves that meet none are marked as runs, the rest
/// walked one by one.
const MIN_SPLIT: usize = 4;

/// One ray of a pixel column during a sweep (see [`VoxelCaster::sweep_column`]).
#[derive(Clone, Copy, Debug, Default)]
struct ColumnRay {
    dir: Vector3<f32>,
    d: [f64; 3],
    /// `1 / d`, per axis.
    inv: [f64; 3],
    /// Where the ray's walk ends: the band cut or the range (as [`VoxelCaster::observe`]), or the
    /// grid's top or bottom face.
    t1: f64,
    /// `t1` is the grid's top or bottom face: the last layer is the grid's, whatever the rounding.
    z_clamped: bool,
    /// `t1` times the ray's horizontal length: how far from the camera, on the floor, it ends.
    h1: f64,
}

/// What a sweep has found of one ray of its column so far (see [`VoxelCaster::sweep_column`]): kept
/// apart from the [`ColumnRay`]s, which are the same for every position and so are not copied.
#[derive(Clone, Copy, Debug)]
struct RayHits {
    /// Nearest hit found so far (infinity until the ray has entered an occupied voxel).
    best: f64,
    /// The triangle list ([`TriangleIndex::list`]) of the last occupied voxel the ray was tested
    /// against: a ray that meets a wall lying on a cell line finds the same list in the voxels on
    /// both sides (about a third of the lists met were such repeats on `office_large`).
    tested: u32,
}

impl RayHits {
    const NONE: RayHits = RayHits {
        best: f64::INFINITY,
        tested: u32::MAX,
    };
}

/// A pixel column's rays as [`VoxelCaster::sweep_column`] sees them, whatever the position (see
/// [`VoxelCaster::column_setup`]).
#[derive(Clone, Copy, Debug)]
struct ColumnSetup {
    /// The reference horizontal direction (the middle row's), unit length.
    u: [f64; 2],
    /// How far along a grid line of axis `a` a ray may cross it from where the reference ray does,
    /// per metre from the camera.
    drift: [f64; 2],
    /// The farthest any ray reaches on the floor, metres.
    h_max: f64,
    /// The layers whose occupied voxels make a run be walked ray by ray.
    occ_mask: u64,
}

/// Layers `a..=b` (or `b..=a`), one bit each.
#[inline]
fn layer_span(a: usize, b: usize) -> u64 {
    let (a, b) = (a.min(b), a.max(b));
    (u64::MAX >> (63 - b)) & (u64::MAX << a)
}

/// One floor cell of a pixel column's path: the cell, and the grid line the path leaves it by.
#[derive(Clone, Copy, Debug, Default)]
struct PathCell {
    cell: usize,
    /// 0 for a line x = `exit`, 1 for y = `exit`.
    exit_axis: usize,
    exit: f64,
    /// Horizontal distance from the camera where the reference ray leaves the cell.
    h_out: f64,
    /// The path leaves the grid, or reaches no ray's end, here.
    last: bool,
}

/// Scratch space of one worker of the sweep.
#[derive(Default)]
struct SweepScratch {
    hits: Vec<RayHits>,
    marks: Vec<(usize, u64)>,
    buf: Vec<usize>,
    /// The marks of the current position in cells beyond the reachable region.
    beyond: Vec<(usize, u64)>,
}

/// A pixel column's walk found a case it does not decide exactly: walk its rays one by one.
struct Ambiguous;

impl VoxelCaster<'_> {
    /// Whether the column sweep applies: at most 64 layers and 64 rows (one bit each), and adjacent
    /// rows of a column closer than a voxel at the farthest range (so the voxels of a run of rays are
    /// one span per cell, see [`VoxelCaster::sweep_column`]).
    fn sweep_applies(&self, camera: &DepthCamera) -> bool {
        let (w, h) = camera.image_size();
        if self.grid.nz > 64 || !(2..=64).contains(&h) {
            return false;
        }
        let dirs = camera.camera_dirs();
        (0..w).all(|u| {
            (1..h).all(|k| {
                let slope = |d: &Vector3<f32>| d.z as f64 / (d.x as f64).hypot(d.y as f64);
                let gap = slope(&dirs[(k - 1) * w + u]) - slope(&dirs[k * w + u]);
                gap > 0.0 && gap * self.range.1 as f64 <= 0.9 * self.grid.res
            })
        })
    }

    /// The observable bits by walking every ray through the voxels ([`VoxelCaster::observe`]).
    fn frames_by_rays(
        &self,
        positions: &[usize],
        yaws: &[(f32, f32)],
        camera: &DepthCamera,
        beyond: &[bool],
    ) -> Frames {
        let grid = self.grid;
        let words = grid.voxels().div_ceil(64);
        let min_beyond = min_beyond_voxels(grid);
        let band = self.band_layers.clone();
        let (bits, looked_beyond) = positions
            .par_iter()
            .fold(
                || (vec![0u64; words], Vec::new(), Vec::new(), Vec::new()),
                |(mut bits, mut looked, mut buf, mut seen_beyond), &cell| {
                    let c = grid.center(grid.cell(cell));
                    let origin = Point3::new(c.x as f32, c.y as f32, camera.mount_height());
                    seen_beyond.clear();
                    for &(sin, cos) in yaws {
                        for d in camera.camera_dirs() {
                            for &v in self.observe(origin, world_ray(sin, cos, d), &mut buf) {
                                bits[v >> 6] |= 1 << (v & 63);
                                let (c, iz) = grid.voxel_parts(v);
                                if beyond[c] && band.contains(&iz) {
                                    seen_beyond.push(v);
                                }
                            }
                        }
                    }
                    seen_beyond.sort_unstable();
                    seen_beyond.dedup();
                    if seen_beyond.len() >= min_beyond {
                        looked.push(cell);
                    }
                    (bits, looked, buf, seen_beyond)
                },
            )
            .map(|(bits, looked, _, _)| (bits, looked))
            .reduce(
                || (vec![0u64; words], Vec::new()),
                |(mut a, mut la), (b, lb)| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x |= y);
                    la.extend(lb);
                    (a, la)
                },
            );
        let mut looked_beyond = looked_beyond;
        looked_beyond.sort_unstable();
        Frames {
            bits,
            looked_beyond,
            by_rays: 0,
        }
    }

    /// The observable bits by sweeping pixel columns ([`VoxelCaster::sweep_column`]); a column the
    /// sweep cannot decide exactly is walked ray by ray. Per worker, a mask of layers per floor cell.
    fn frames_by_columns(
        &self,
        positions: &[usize],
        yaws: &[(f32, f32)],
        camera: &DepthCamera,
        beyond: &[bool],
    ) -> Frames {
        let grid = self.grid;
        let cells = grid.cells();
        let min_beyond = min_beyond_voxels(grid);
        let (w, h) = camera.image_size();
        let dirs = camera.camera_dirs();
        // Every position has the same mount height, and a column ray's setup uses no other part of
        // the origin: set up each heading's columns once, `(yaw * w + u) * h + row`.
        let at_mount = Point3::new(0.0, 0.0, camera.mount_height());
        let columns: Vec<ColumnRay> = yaws
            .iter()
            .flat_map(|&(sin, cos)| {
                (0..w).flat_map(move |u| (0..h).map(move |k| world_ray(sin, cos, &dirs[k * w + u])))
            })
            .map(|dir| self.column_ray(at_mount, dir))
            .collect();
        let setups: Vec<Option<ColumnSetup>> = columns
            .chunks_exact(h)
            .map(|rays| self.column_setup(at_mount.z as f64, rays))
            .collect();
        let (seen, looked_beyond, by_rays) = positions
            .par_iter()
            .fold(
                || {
                    (
                        vec![0u64; cells],
                        Vec::new(),
                        SweepScratch::default(),
                        0usize,
                    )
                },
                |(mut seen, mut looked, mut sc, mut by_rays), &cell| {
                    let c = grid.center(grid.cell(cell));
                    let origin = Point3::new(c.x as f32, c.y as f32, camera.mount_height());
                    sc.beyond.clear();
                    for (column, setup) in columns.chunks_exact(h).zip(&setups) {
                        sc.hits.clear();
                        sc.hits.resize(h, RayHits::NONE);
                        sc.marks.clear();
                        let swept = setup.as_ref().map_or(Err(Ambiguous), |setup| {
                            self.sweep_column(origin, column, setup, &mut sc.hits, &mut sc.marks)
                        });
                        if swept.is_ok() {
                            for &(c, m) in &sc.marks {
                                seen[c] |= m;
                                if beyond[c] {
                                    sc.beyond.push((c, m));
                                }
                            }
                        } else {
                            by_rays += 1;
                            for ray in column {
                                for &v in self.observe(origin, ray.dir, &mut sc.buf) {
                                    let (c, iz) = grid.voxel_parts(v);
                                    seen[c] |= 1 << iz;
                                    if beyond[c] {
                                        sc.beyond.push((c, 1 << iz));
                                    }
                                }
                            }
                        }
                    }
                    if beyond_voxels(&mut sc.beyond, self.band_mask) >= min_beyond {
                        looked.push(cell);
                    }
                    (seen, looked, sc, by_rays)
                },
            )
            .map(|(seen, looked, _, by_rays)| (seen, looked, by_rays))
            .reduce(
                || (vec![0u64; cells], Vec::new(), 0),
                |(mut a, mut la, na), (b, lb, nb)| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x |= y);
                    la.extend(lb);
                    (a, la, na + nb)
                },
            );
        let mut bits = vec![0u64; grid.voxels().div_ceil(64)];
        for (c, &m) in seen.iter().enumerate() {
            let mut m = m;
            while m != 0 {
                let v = m.trailing_zeros() as usize * cells + c;
                m &= m - 1;
                bits[v >> 6] |= 1 << (v & 63);
            }
        }
        let mut looked_beyond = looked_beyond;
        looked_beyond.sort_unstable();
        Frames {
            bits,
            looked_beyond,
            by_rays,
        }
    }

    /// A ray's walk limits, as [`VoxelCaster::observe`] and the voxel walk's clip to the grid's
    /// top and bottom faces set them.
    fn column_ray(&self, origin: Point3<f32>, dir: Vector3<f32>) -> ColumnRay {
        let (min_range, max_range) = self.range;
        let (oz, dz) = (origin.z as f64, dir.z as f64);
        let leave = if dz > 0.0 {
            (self.band.1 - oz) / dz
        } else if dz < 0.0 {
            (self.band.0 - oz) / dz
        } else {
            f64::INFINITY
        };
        let cut = (leave + 1e-6).max(min_range as f64).min(max_range as f64);
        let top = self.grid.nz as f64 * self.grid.res;
        let face = if dz > 0.0 {
            (top - oz) / dz
        } else if dz < 0.0 {
            -oz / dz
        } else {
            f64::INFINITY
        };
        let d = [dir.x as f64, dir.y as f64, dz];
        let t1 = cut.min(face);
        ColumnRay {
            dir,
            d,
            inv: d.map(|x| 1.0 / x),
            t1,
            z_clamped: face <= cut,
            h1: t1 * (d[0] * d[0] + d[1] * d[1]).sqrt(),
        }
    }

    /// What [`VoxelCaster::sweep_column`] needs of a pixel column's rays alone (not of the
    /// position): the same for every position, so set up once per heading and column. `None` when
    /// the column is to be walked ray by ray wherever the camera stands.
    fn column_setup(&self, oz: f64, rays: &[ColumnRay]) -> Option<ColumnSetup> {
        let (res, nz) = (self.grid.res, self.grid.nz);
        let n = rays.len();
        let span = layer_span;
        if !(self.band.0..self.band.1).contains(&oz) || n == 0 || n > 64 {
            return None;
        }
        // The reference horizontal direction (the middle row's) and the largest angle to it.
        let r = rays[n / 2].d;
        let g = (r[0] * r[0] + r[1] * r[1]).sqrt();
        let u = [r[0] / g, r[1] / g];
        let mut spread = 0.0f64;
        let mut h_max = 0.0f64;
        for ray in rays.iter() {
            let gk = (ray.d[0] * ray.d[0] + ray.d[1] * ray.d[1]).sqrt();
            if gk == 0.0 {
                return None;
            }
            spread = spread.max(((u[0] * ray.d[1] - u[1] * ray.d[0]) / gk).abs());
            h_max = h_max.max(ray.h1);
        }
        // Rays end in order from both ends of the column toward its most horizontal row.
        let peak = (0..n)
            .max_by(|&a, &b| rays[a].h1.total_cmp(&rays[b].h1))
            .unwrap_or(0);
        if (1..=peak).any(|k| rays[k].h1 < rays[k - 1].h1)
            || (peak + 1..n).any(|k| rays[k].h1 > rays[k - 1].h1)
        {
            return None;
        }
        // How far along a grid line of axis `a` a ray may cross it from where the reference ray does,
        // per metre from the camera.
        let mut drift = [f64::INFINITY; 2];
        for (a, dr) in drift.iter_mut().enumerate() {
            let slack = u[a].abs() - spread;
            if slack > 0.0 {
                *dr = spread / slack;
            }
        }
        // Outside the band only a ray's last voxel lies (the walk is cut where it leaves the band),
        // and what it marks there is dropped; an occupied voxel there matters only through a hit
        // nearer than the minimum range, impossible when the band is left beyond it. Then runs need
        // to meet occupied voxels of the band only to be walked one by one.
        let (z_lo, z_hi) = self.band;
        let (mut rise, mut fall) = (0.0f64, 0.0f64);
        for ray in rays.iter() {
            rise = rise.max(ray.d[2]);
            fall = fall.max(-ray.d[2]);
        }
        let leaves_beyond_min_range =
            |gap: f64, speed: f64| speed <= 0.0 || gap / speed > self.range.0 as f64 + 10.0 * res;
        let in_band = span(
            floor_i64(z_lo / res + 0.5).max(0) as usize,
            (floor_i64(z_hi / res + 0.5) as usize).clamp(1, nz) - 1,
        );
        let occ_mask = if leaves_beyond_min_range(oz - z_lo, fall)
            && leaves_beyond_min_range(z_hi - oz, rise)
        {
            in_band
        } else {
            u64::MAX
        };
        Some(ColumnSetup {
            u,
            drift,
            h_max,
            occ_mask,
        })
    }

    /// Marks, as `(floor cell, layer mask)` pairs, the voxels that the rays of one pixel column
    /// (top row first) make known: the same voxels as [`VoxelCaster::observe`] gives ray by ray.
    ///
    /// The rays of a pixel column lie in one vertical plane, so they cross the same floor cells
    /// (checked: no ray passes a cell corner on the other side than the reference ray). In a cell,
    /// a ray walks the layers between its heights where it enters and leaves the cell; consecutive
    /// rows are less than a voxel apart (see [`VoxelCaster::sweep_applies`]), so a run of rays that
    /// meets no occupied voxel in the cell makes known exactly the span of layers between its top
    /// ray's highest point and its bottom ray's lowest one (and the lowest/highest point of a ray
    /// that ends in the cell). Those runs cost a few operations per cell instead of a voxel walk per
    /// ray. Where a run meets an occupied voxel, it is halved (down to [`MIN_SPLIT`] rays): a part
    /// that meets none is a run of its own (above or below a table top, say), and the rays of the
    /// rest are walked through the cell's layers one voxel at a time, with `observe`'s rule for
    /// hits; a ray that has found a hit beyond the cell goes on that way. (A part, like a run, has
    /// only the heights of its top and bottom rays and of its rays that end in the cell checked
    /// against the layer boundaries.) Every distance and height is computed from the ray's own
    /// direction; where one lies within [`TIE_M`] of a voxel boundary (so that rounding could decide
    /// which side the map's walk takes), the column is given up ([`Ambiguous`]) and walked ray by ray.
    fn sweep_column(
        &self,
        origin: Point3<f32>,
        rays: &[ColumnRay],
        setup: &ColumnSetup,
        hits: &mut [RayHits],
        marks: &mut Vec<(usize, u64)>,
    ) -> std::result::Result<(), Ambiguous> {
        let grid = self.grid;
        let res = grid.res;
        let inv_res = 1.0 / res;
        let nz = grid.nz;
        let n = rays.len();
        let o = [origin.x as f64, origin.y as f64, origin.z as f64];
        let lo = [grid.origin_x, grid.origin_y];
        let dims = [grid.nx as i64, grid.ny as i64];
        let ColumnSetup {
            u,
            drift,
            h_max,
            occ_mask,
        } = *setup;
        // The floor cells of the path, leaving each by its nearer grid line: made one at a time as
        // the sweep reaches them, so the cells past where every ray has stopped (behind a wall) cost
        // nothing and cannot make the column ambiguous.
        let cell_of = |a: usize| floor_i64((o[a] - lo[a]) / res);
        let mut idx = [cell_of(0), cell_of(1)];
        if (0..2).any(|a| idx[a] < 0 || idx[a] >= dims[a]) {
            return Err(Ambiguous);
        }
        // The grid line of axis `a` ahead of the cell `idx[a]`, and how far along `u` it lies (kept
        // from cell to cell, and made again for the axis stepped only).
        let ahead = |a: usize, i: i64| {
            let line = if u[a] > 0.0 {
                lo[a] + (i + 1) as f64 * res
            } else if u[a] < 0.0 {
                lo[a] + i as f64 * res
            } else {
                return (0.0, f64::INFINITY);
            };
            (line, (line - o[a]) / u[a])
        };
        let (mut line, mut next) = ([0.0f64; 2], [f64::INFINITY; 2]);
        for a in 0..2 {
            (line[a], next[a]) = ahead(a, idx[a]);
        }
        let mut next_cell = || -> std::result::Result<PathCell, Ambiguous> {
            let a = if next[0] < next[1] { 0 } else { 1 };
            let h_out = next[a];
            if !h_out.is_finite() {
                return Err(Ambiguous);
            }
            // Every ray of the column crosses this line away from the other axis's grid lines.
            let b = 1 - a;
            let along = o[b] + u[b] * h_out;
            let f = (along - lo[b]) * inv_res;
            let corner = (f - floor_both(f + 0.5).1).abs() * res;
            if corner <= h_out * drift[a] + TIE_M {
                return Err(Ambiguous);
            }
            let cell = (idx[1] * dims[0] + idx[0]) as usize;
            let exit = line[a];
            idx[a] += if u[a] > 0.0 { 1 } else { -1 };
            (line[a], next[a]) = ahead(a, idx[a]);
            let leaves = idx[a] < 0 || idx[a] >= dims[a];
            let last = leaves || h_out > h_max + 1e-6;
            Ok(PathCell {
                cell,
                exit_axis: a,
                exit,
                h_out,
                last,
            })
        };
        let cross = |ray: &ColumnRay, axis: usize, line: f64| (line - o[axis]) * ray.inv[axis];
        let z_at = |ray: &ColumnRay, t: f64| o[2] + ray.d[2] * t;
        // The layer of height `z`, or Ambiguous when `z` is within TIE_M of a layer boundary.
        let layer = |z: f64, clamped: bool| -> std::result::Result<usize, Ambiguous> {
            let (l, l_f) = floor_both(z * inv_res);
            let base = l_f * res;
            if !clamped && (z - base < TIE_M || base + res - z < TIE_M) {
                return Err(Ambiguous);
            }
            Ok((l.max(0) as usize).min(nz - 1))
        };
        let span = layer_span;
        let all = if n == 64 { u64::MAX } else { (1u64 << n) - 1 };
        // Rays walked as runs, rays walked one by one (a hit found beyond the cell), rays not ended.
        let mut runs = all;
        let mut single = 0u64;
        let (mut first, mut last_ray) = (0usize, n - 1);
        let mut ended_all = false;
        let mut entry: Option<(usize, f64)> = None;
        loop {
            let step = next_cell()?;
            let occ = self.occupied_layers(step.cell);
            let t_in = |ray: &ColumnRay| entry.map_or(0.0, |(a, line)| cross(ray, a, line));
            let t_out = |ray: &ColumnRay| cross(ray, step.exit_axis, step.exit);
            // Where a ray's walk leaves this cell, and whether that is the grid's top or bottom.
            let t_end = |ray: &ColumnRay, ends: bool| {
                let t = t_out(ray);
                if ends && ray.t1 <= t {
                    (ray.t1, ray.z_clamped)
                } else {
                    (t, false)
                }
            };
            // The rays that end in this cell: from both ends of the rows not yet ended.
            let mut enders = 0u64;
            if step.last {
                enders = (runs | single) & span(first, last_ray);
            } else {
                let tol = 1e-5 * (1.0 + step.h_out);
                let check = |k: usize| -> std::result::Result<bool, Ambiguous> {
                    let ray = &rays[k];
                    if ray.h1 > step.h_out + tol {
                        return Ok(false);
                    }
                    let te = t_out(ray);
                    if ray.t1 < te - TIE_M {
                        Ok(true)
                    } else if ray.t1 > te + tol {
                        Ok(false)
                    } else {
                        Err(Ambiguous)
                    }
                };
                while first <= last_ray && !ended_all && check(first)? {
                    enders |= 1 << first;
                    if first == last_ray {
                        ended_all = true;
                    } else {
                        first += 1;
                    }
                }
                while first <= last_ray && !ended_all && check(last_ray)? {
                    enders |= 1 << last_ray;
                    if first == last_ray {
                        ended_all = true;
                    } else {
                        last_ray -= 1;
                    }
                }
            }
            // One ray through this cell's layers, voxel by voxel, with observe's rule for hits.
            // Returns whether the ray stops here.
            let walk =
                |k: usize, hits: &mut [RayHits], here: &mut u64, marks: &mut Vec<(usize, u64)>| {
                    let ray = &rays[k];
                    let ends = enders >> k & 1 == 1;
                    let t0 = t_in(ray);
                    let (t_end, clamped) = t_end(ray, ends);
                    let l0 = layer(z_at(ray, t0), false)?;
                    let l1 = layer(z_at(ray, t_end), clamped)?;
                    let up = ray.d[2] > 0.0;
                    let hit = &mut hits[k];
                    if hit.best == f64::INFINITY && span(l0, l1) & occ & occ_mask == 0 {
                        // No occupied voxel on the way through this cell: all its layers, no hit.
                        *here |= span(l0, l1);
                        return Ok(ends);
                    }
                    let mut best = hit.best;
                    let mut l = l0;
                    let mut stopped = false;
                    let mut mask = 0u64;
                    loop {
                        let tv_in = if l == l0 {
                            t0
                        } else {
                            let z = if up {
                                l as f64 * res
                            } else {
                                (l + 1) as f64 * res
                            };
                            (z - o[2]) * ray.inv[2]
                        };
                        let tv_out = if l == l1 {
                            t_end
                        } else {
                            let z = if up {
                                (l + 1) as f64 * res
                            } else {
                                l as f64 * res
                            };
                            (z - o[2]) * ray.inv[2]
                        };
                        // `occ` holds the cell's occupied layers: `tris.occupied` without a load.
                        if occ >> l & 1 == 1 {
                            let list = self.tris.list(step.cell, l);
                            // The ray's nearest hit is the least over every triangle it was tested
                            // against, in any order: a list tested again changes nothing.
                            if list != hit.tested {
                                hit.tested = list;
                                best = best.min(self.hit_in(list, origin, ray.dir));
                            }
                        }
                        if best <= tv_in {
                            stopped = true;
                            break;
                        }
                        mask |= 1 << l;
                        if best <= tv_out {
                            stopped = true;
                            break;
                        }
                        if l == l1 {
                            break;
                        }
                        l = if up { l + 1 } else { l - 1 };
                    }
                    *here |= mask;
                    hit.best = best;
                    let done = stopped || ends;
                    if done && best.is_finite() {
                        if best < self.range.0 as f64 {
                            // No reading: the map integrates nothing of this ray, not even the cells
                            // already marked. Rare (a hit within the minimum range): walk ray by ray.
                            return Err(Ambiguous);
                        }
                        let p = Point3::new(o[0], o[1], o[2]) + ray.dir.cast::<f64>() * best;
                        // `grid.voxel_of(p)`, its floors taken without a libm call (the same values).
                        let ix = floor_i64((p.x - grid.origin_x) / res);
                        let iy = floor_i64((p.y - grid.origin_y) / res);
                        let iz = floor_i64(p.z / res);
                        if (0..dims[0]).contains(&ix)
                            && (0..dims[1]).contains(&iy)
                            && (0..nz as i64).contains(&iz)
                        {
                            let c = (iy * dims[0] + ix) as usize;
                            // Usually this cell's: joined to its mark rather than a mark of its own.
                            if c == step.cell {
                                *here |= 1 << iz;
                            } else {
                                marks.push((c, 1 << iz));
                            }
                        }
                    }
                    Ok(done)
                };
            // The layers marked in this cell.
            let mut here = 0u64;
            // The rays walked one by one here: the single rays, and the runs that meet an
            // occupied voxel (gathered first, so that the walk has one call site and is inlined).
            let mut walked = single;
            // The layers of a part `a..=b` of a run: from its lowest to its highest point, which are
            // those of its top and bottom rays and of its rays that end here.
            let cover = |a: usize, b: usize| -> std::result::Result<u64, Ambiguous> {
                let (mut z_min, mut z_max) = (f64::INFINITY, f64::NEG_INFINITY);
                let (mut c_min, mut c_max) = (false, false);
                let mut ext = (enders & span(a, b)) | 1 << a | 1 << b;
                while ext != 0 {
                    let k = ext.trailing_zeros() as usize;
                    ext &= ext - 1;
                    let ray = &rays[k];
                    let ends = enders >> k & 1 == 1;
                    let (t_e, clamped_e) = t_end(ray, ends);
                    for (z, clamped) in [(z_at(ray, t_in(ray)), false), (z_at(ray, t_e), clamped_e)]
                    {
                        if z < z_min {
                            (z_min, c_min) = (z, clamped);
                        }
                        if z > z_max {
                            (z_max, c_max) = (z, clamped);
                        }
                    }
                }
                Ok(span(layer(z_min, c_min)?, layer(z_max, c_max)?))
            };
            let blocked = occ & occ_mask;
            // Parts of runs that meet an occupied voxel, still to be split.
            let mut parts = [(0usize, 0usize); 16];
            let mut m = runs;
            while m != 0 {
                let a = m.trailing_zeros() as usize;
                let len = (!(m >> a)).trailing_zeros() as usize;
                let b = a + len - 1;
                m &= !span(a, b);
                let mut todo = 0;
                let mut part = (a, b);
                loop {
                    let (a, b) = part;
                    let layers = cover(a, b)?;
                    if layers & blocked == 0 {
                        here |= layers;
                    } else if b - a < MIN_SPLIT || layers & self.band_mask & !blocked == 0 {
                        // Too few rays to split, or every ray meets an occupied voxel (each passes
                        // a band layer of the part's, all occupied): walked one by one.
                        walked |= span(a, b);
                    } else {
                        // The halves that meet no occupied voxel are runs of their own.
                        let mid = (a + b) / 2;
                        parts[todo] = (mid + 1, b);
                        part = (a, mid);
                        todo += 1;
                        continue;
                    }
                    if todo == 0 {
                        break;
                    }
                    todo -= 1;
                    part = parts[todo];
                }
            }
            let mut stopped = 0u64;
            while walked != 0 {
                let k = walked.trailing_zeros() as usize;
                walked &= walked - 1;
                if walk(k, hits, &mut here, marks)? {
                    stopped |= 1 << k;
                } else if hits[k].best.is_finite() {
                    // A hit beyond this cell: walked one by one from now on.
                    runs &= !(1 << k);
                    single |= 1 << k;
                }
            }
            if here != 0 {
                marks.push((step.cell, here));
            }
            runs &= !(enders | stopped);
            single &= !(enders | stopped);
            if runs | single == 0 {
                return Ok(());
            }
            if step.last {
                // Rays left when the path ended: a case the checks above should exclude.
                return Err(Ambiguous);
            }
            entry = Some((step.exit_axis, step.exit));
        }
    }

    /// The occupied layers of floor cell `cell`, one bit each.
    #[inline]
    fn occupied_layers(&self, cell: usize) -> u64 {
        self.tris.layers.get(cell).copied().unwrap_or(u64::MAX)
    }
}

/// One sample cell per 8-connected patch of reachable cells in each square of `k` × `k` cells whose
/// first cell `(bx, by)` passes `want`: the patch cell nearest the patch centroid (ties: lowest
/// index). Ascending.
fn sample_positions(
    grid: &GridSpec,
    reachable: &[bool],
    k: usize,
    want: impl Fn(usize, usize) -> bool,
) -> Vec<usize> {
    let k = k.max(1);
    let mut out = Vec::new();
    let mut label = vec![false; grid.cells()];
    for by in (0..grid.ny).step_by(k) {
        for bx in (0..grid.nx).step_by(k) {
            if !want(bx, by) {
                continue;
            }
            let (x1, y1) = ((bx + k).min(grid.nx), (by + k).min(grid.ny));
            let inside = |c: Cell| {
                (bx as i32..x1 as i32).contains(&c.x) && (by as i32..y1 as i32).contains(&c.y)
            };
            for y in by..y1 {
                for x in bx..x1 {
                    let start = y * grid.nx + x;
                    if !reachable[start] || label[start] {
                        continue;
                    }
                    let mut patch = vec![start];
                    label[start] = true;
                    let mut i = 0;
                    while i < patch.len() {
                        let c = grid.cell(patch[i]);
                        i += 1;
                        for (dx, dy) in NEIGHBOURS_8 {
                            let n = Cell::new(c.x + dx, c.y + dy);
                            if inside(n) {
                                let j = grid.index(n);
                                if reachable[j] && !label[j] {
                                    label[j] = true;
                                    patch.push(j);
                                }
                            }
                        }
                    }
                    let (sx, sy) = patch.iter().fold((0.0, 0.0), |(sx, sy), &j| {
                        let c = grid.cell(j);
                        (sx + c.x as f64, sy + c.y as f64)
                    });
                    let (mx, my) = (sx / patch.len() as f64, sy / patch.len() as f64);
                    let dist = |j: usize| {
                        let c = grid.cell(j);
                        (c.x as f64 - mx).powi(2) + (c.y as f64 - my).powi(2)
                    };
                    let best = patch
                        .iter()
                        .copied()
                        .min_by(|&a, &b| dist(a).total_cmp(&dist(b)).then(a.cmp(&b)))
                        .expect("a patch has its start cell");
                    out.push(best);
                }
            }
        }
    }
    out.sort_unstable();
    out
}

/// The side of the sampling squares in cells, for a spacing in metres.
fn lattice_cells(grid: &GridSpec, spacing_m: f64) -> usize {
    ((spacing_m / grid.res).round() as usize).max(1)
}

/// What one pass of the sampling gives: the observed bits, the sample positions (ascending) that
/// looked into space beyond the reachable region (see [`beyond_cells`]), and the pixel columns walked
/// ray by ray.
struct Frames {
    bits: Vec<u64>,
    looked_beyond: Vec<usize>,
    #[cfg_attr(not(test), allow(dead_code))]
    by_rays: usize,
}

/// How much of the space beyond the reachable region (see [`beyond_cells`]) one sample position
/// must see, m³, for the squares around it to be sampled again on the finer lattice. A view through
/// a narrow door into a room holds several m³; the views through the open outer doors of
/// `office_large` onto the thin strip of grid outside the building hold under 0.2 m³, and refining
/// those would triple that scene's cost for nothing (what GREEDY explores there is already inside
/// the set).
const REFINE_BEYOND_M3: f64 = 0.2;

/// Floor cells that are free (no obstacle column) and lie beyond the reachable region: farther than
/// the inflation radius plus two cells from every reachable cell. The free cells between the
/// reachable region and the walls around it are within that distance; what is left is space behind
/// gaps too narrow to pass (a room behind a narrow door, a slot beside furniture, the outside seen
/// through a door), which the camera sees only through the gap, so from a narrow set of positions.
fn beyond_cells(gt: &GroundTruth) -> Vec<bool> {
    let grid = gt.grid;
    let reach = gt.reachable_mask();
    let r = gt.inflation_m() / grid.res + 2.0;
    let ri = r.ceil() as i32;
    let disc: Vec<(i32, i32)> = (-ri..=ri)
        .flat_map(|dy| (-ri..=ri).map(move |dx| (dx, dy)))
        .filter(|&(dx, dy)| ((dx * dx + dy * dy) as f64) <= r * r)
        .collect();
    (0..grid.cells())
        .into_par_iter()
        .map(|i| {
            if reach[i] || gt.obstacle_column(i) {
                return false;
            }
            let c = grid.cell(i);
            !disc.iter().any(|&(dx, dy)| {
                grid.checked_index(Cell::new(c.x + dx, c.y + dy))
                    .is_some_and(|j| reach[j])
            })
        })
        .collect()
}

/// The number of distinct band voxels among `marks` (cell, layer mask), which it sorts.
fn beyond_voxels(marks: &mut [(usize, u64)], band: u64) -> usize {
    marks.sort_unstable_by_key(|&(c, _)| c);
    let mut n = 0;
    let mut i = 0;
    while i < marks.len() {
        let (c, mut m) = marks[i];
        i += 1;
        while i < marks.len() && marks[i].0 == c {
            m |= marks[i].1;
            i += 1;
        }
        n += (m & band).count_ones() as usize;
    }
    n
}

/// The band voxels beyond the reachable region that one position must see for its neighbourhood to
/// be sampled again: [`REFINE_BEYOND_M3`] in voxels.
fn min_beyond_voxels(grid: &GridSpec) -> usize {
    ((REFINE_BEYOND_M3 / grid.voxel_volume()).ceil() as usize).max(1)
}

/// The second pass of the sampling, where the view depends strongly on the position: around every
/// coarse position that looked beyond the reachable region (through a gap too narrow to pass), the
/// squares of the coarse lattice around it (3 × 3) are sampled again on a lattice of half the side.
/// Positions already sampled are left out. Ascending.
fn refined_positions(
    grid: &GridSpec,
    reachable: &[bool],
    k: usize,
    looked_beyond: &[usize],
    coarse: &[usize],
) -> Vec<usize> {
    if looked_beyond.is_empty() {
        return Vec::new();
    }
    let (sx, sy) = (grid.nx.div_ceil(k), grid.ny.div_ceil(k));
    let mut refine = vec![false; sx * sy];
    for &cell in looked_beyond {
        let c = grid.cell(cell);
        let (qx, qy) = (c.x as usize / k, c.y as usize / k);
        for y in qy.saturating_sub(1)..(qy + 2).min(sy) {
            for x in qx.saturating_sub(1)..(qx + 2).min(sx) {
                refine[y * sx + x] = true;
            }
        }
    }
    let fine = (k / 2).max(1);
    sample_positions(grid, reachable, fine, |bx, by| {
        refine[(by / k) * sx + bx / k]
    })
    .into_iter()
    .filter(|c| coarse.binary_search(c).is_err())
    .collect()
}

/// How a cached set was obtained (reported to the user).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CacheOutcome {
    /// Read from the cache file.
    Hit(PathBuf),
    /// Computed and written to the cache file.
    Computed(PathBuf),
    /// The cache file was damaged (the reason); the set was recomputed and the file rewritten.
    Repaired(PathBuf, String),
    /// Computed without a cache (none configured, or the folder could not be written: the reason).
    Uncached(Option<String>),
}

/// The on-disk cache of observable sets: one file per scene and relevant config, under a folder the
/// user can see and clear. The folder is `$TENSORSCOUT_CACHE_DIR`, else `$XDG_CACHE_HOME/tensorscout`,
/// else `~/.cache/tensorscout`; files live in its `observable/` subfolder.
#[derive(Clone, Debug)]
pub struct ObservableCache {
    dir: Option<PathBuf>,
    /// Say on stderr, before computing a set, that it is being computed (see
    /// [`ObservableCache::announcing`]).
    announce: bool,
}

/// File layout: magic, key, voxel count, positions, word count, words (little-endian u64), then the
/// FNV-1a checksum of everything before it.
const MAGIC: &[u8; 8] = b"TSOBS01\n";

/// Revision of the computation, part of every key: bump it whenever the sampling, the sensor model
/// or the traversal changes, so that no cache file of an older computation is ever read.
const REVISION: u32 = 3;

impl ObservableCache {
    /// The cache in the user's cache folder (see the type doc); `None` folder when no home is known.
    pub fn user() -> ObservableCache {
        let base = std::env::var_os("TENSORSCOUT_CACHE_DIR")
            .filter(|s| !s.is_empty())
            .map(PathBuf::from)
            .or_else(|| {
                std::env::var_os("XDG_CACHE_HOME")
                    .filter(|s| !s.is_empty())
                    .map(|d| PathBuf::from(d).join("tensorscout"))
            })
            .or_else(|| {
                std::env::var_os("HOME")
                    .filter(|s| !s.is_empty())
                    .map(|h| PathBuf::from(h).join(".cache").join("tensorscout"))
            });
        ObservableCache {
            dir: base.map(|b| b.join("observable")),
            announce: false,
        }
    }

    /// A cache in `dir` (tests, or a user's `--cache-dir`).
    pub fn at(dir: impl Into<PathBuf>) -> ObservableCache {
        ObservableCache {
            dir: Some(dir.into()),
            announce: false,
        }
    }

    /// No cache: always compute.
    pub fn none() -> ObservableCache {
        ObservableCache {
            dir: None,
            announce: false,
        }
    }

    /// This cache, saying on stderr (when `on`) before it computes a set that it is doing so: at a
    /// full camera resolution that takes minutes (8 minutes for `office_large` at 640 × 480), with
    /// nothing else on the screen. The command-line tools turn it on where they would show a
    /// progress bar.
    pub fn announcing(mut self, on: bool) -> ObservableCache {
        self.announce = on;
        self
    }

    /// The folder the files go to, if any.
    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    /// The cache key: the scene's content, the grid, the reachable region (which holds the robot's
    /// size, the inflation and the spawn's component), the band, the camera and the sampling.
    pub fn key(
        scene_hash: &str,
        gt: &GroundTruth,
        camera: &CameraConfig,
        params: &ObservableParams,
    ) -> u64 {
        let reach: Vec<u8> = gt.reachable_mask().iter().map(|&r| r as u8).collect();
        let text = format!(
            "observable r{REVISION}|{scene_hash}|{:?}|{:016x}|{:?}|{}|{}|{}",
            gt.grid,
            fnv1a64(&reach),
            gt.band_layers(),
            toml::to_string(camera).unwrap_or_default(),
            params.spacing_m,
            params.yaws,
        );
        fnv1a64(text.as_bytes())
    }

    /// The observable set of `gt`: from the cache file when it is intact, else computed (and
    /// written, atomically).
    pub fn get_or_compute(
        &self,
        scene: &Scene,
        gt: &GroundTruth,
        bvh: &MeshBvh,
        camera: &CameraConfig,
        params: &ObservableParams,
    ) -> (ObservableSet, CacheOutcome) {
        let compute = || {
            if self.announce {
                let cached = match &self.dir {
                    Some(dir) => format!("it is cached in {}", dir.display()),
                    None => "no cache folder is known".to_string(),
                };
                eprintln!(
                    "computing the volume the camera can observe in this scene, once per scene and \
                     camera ({cached})"
                );
            }
            ObservableSet::compute(gt, bvh, &DepthCamera::new(camera), params)
        };
        let Some(dir) = &self.dir else {
            return (compute(), CacheOutcome::Uncached(None));
        };
        let key = Self::key(&scene.content_hash, gt, camera, params);
        let path = dir.join(format!("{key:016x}.bin"));
        let damage = match std::fs::read(&path) {
            Ok(bytes) => match decode(&bytes, key, gt) {
                Ok(set) => return (set, CacheOutcome::Hit(path)),
                Err(why) => Some(why),
            },
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => Some(format!("unreadable: {e}")),
        };
        let set = compute();
        let outcome = match write_atomic(dir, &path, &encode(&set, key)) {
            Ok(()) => match damage {
                Some(why) => CacheOutcome::Repaired(path, why),
                None => CacheOutcome::Computed(path),
            },
            Err(e) => CacheOutcome::Uncached(Some(e.to_string())),
        };
        (set, outcome)
    }
}

impl CacheOutcome {
    /// A line for the user when something about the cache deserves one (damage, unwritable folder).
    pub fn warning(&self) -> Option<String> {
        match self {
            CacheOutcome::Repaired(p, why) => Some(format!(
                "warning: observable-volume cache {} was damaged ({why}); recomputed and rewritten",
                p.display()
            )),
            CacheOutcome::Uncached(Some(why)) => Some(format!(
                "warning: observable-volume cache not written ({why}); set TENSORSCOUT_CACHE_DIR to a writable folder"
            )),
            _ => None,
        }
    }
}

fn encode(set: &ObservableSet, key: u64) -> Vec<u8> {
    let mut out = Vec::with_capacity(48 + 8 * set.bits.len());
    out.extend_from_slice(MAGIC);
    for v in [
        key,
        set.voxels as u64,
        set.positions as u64,
        set.bits.len() as u64,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for w in &set.bits {
        out.extend_from_slice(&w.to_le_bytes());
    }
    let sum = fnv1a64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// Reads a cache file back, or says what is wrong with it.
fn decode(bytes: &[u8], key: u64, gt: &GroundTruth) -> std::result::Result<ObservableSet, String> {
    let words = gt.grid.voxels().div_ceil(64);
    let expected = MAGIC.len() + 32 + 8 * words + 8;
    if bytes.len() != expected {
        return Err(format!("{} bytes, expected {expected}", bytes.len()));
    }
    if &bytes[..8] != MAGIC {
        return Err("not an observable-volume cache file".into());
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    let u64_at = |b: &[u8], i: usize| u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
    if u64_at(sum, 0) != fnv1a64(body) {
        return Err("checksum mismatch".into());
    }
    if u64_at(body, 8) != key || u64_at(body, 32) != words as u64 {
        return Err("written for another scene or config".into());
    }
    let voxels = u64_at(body, 16) as usize;
    let positions = u64_at(body, 24) as usize;
    let bits: Vec<u64> = (0..words).map(|k| u64_at(body, 40 + 8 * k)).collect();
    let set = ObservableSet::from_bits(gt, bits, positions);
    if set.voxels != voxels {
        return Err("voxel count does not match its bits".into());
    }
    Ok(set)
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, so a reader
/// never sees a partial file.
fn write_atomic(dir: &Path, path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    // Unique per process and call: bench workers may write the same key at once.
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!(
        ".{}.{}.{n}.tmp",
        path.file_name().and_then(|n| n.to_str()).unwrap_or("cache"),
        std::process::id()
    ));
    std::fs::write(&tmp, bytes).map_err(|e| Error::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, e)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::Occupancy;
    use crate::scene::Scene;
    use crate::sensor::raycast::testing::{furnished_room, push_box};
    use crate::Pose2;

    fn scene(mesh: crate::scene::TriMesh) -> Scene {
        Scene {
            name: "test".into(),
            path: "test.obj".into(),
            mesh,
            spawn: None,
            content_hash: "test".into(),
            floor_z: 0.0,
            source: "obj".into(),
            warnings: Vec::new(),
        }
    }

    /// A 6 × 6 m room (inside x, y ∈ [0.1, 6.1]) with a table, plus a 3 × 2 m closet east of it
    /// (x ∈ [6.2, 9.2], y ∈ [0.1, 2.1]) behind a 0.5 m door (y ∈ [0.8, 1.3]) in the 0.1 m wall: the
    /// door is narrower than the inflated robot, so the closet is observable through it but not
    /// reachable.
    fn room_with_closet() -> crate::scene::TriMesh {
        let (nx, ny) = (94, 63);
        let solid: Vec<bool> = (0..nx * ny)
            .map(|i| {
                let (x, y) = (i % nx, i / nx);
                let room = (1..61).contains(&x) && (1..61).contains(&y);
                let closet = (62..92).contains(&x) && (1..21).contains(&y);
                let door = x == 61 && (8..13).contains(&y);
                !(room || closet || door)
            })
            .collect();
        let mut mesh = crate::scene::extrude::extrude_grid(&solid, nx, ny, [0.0, 0.0], 0.1, 2.5);
        push_box(&mut mesh, [2.0, 4.0, 0.0], [3.0, 5.0, 0.75]);
        mesh
    }

    #[test]
    fn rays_mark_what_the_map_integrates() {
        // Every band voxel a frame makes known in the map, and no other, is what the caster marks.
        let cfg = Config::default();
        let mesh = furnished_room(6.0);
        let gt = GroundTruth::build(&mesh, None, &cfg).unwrap();
        let bvh = MeshBvh::new(&mesh).unwrap();
        let camera = DepthCamera::new(&cfg.camera);
        let band = gt.band_layers();
        let caster = VoxelCaster::new(
            &gt,
            &bvh,
            &camera,
            (
                band.start as f64 * gt.grid.res,
                band.end as f64 * gt.grid.res,
            ),
        );
        let in_band = |v: usize| band.contains(&gt.grid.voxel_parts(v).1);
        let (mut total, mut differ) = (0usize, 0usize);
        let mut buf = Vec::new();
        for (k, pose) in [
            Pose2::new(3.0, 3.0, 0.3),
            Pose2::new(1.0, 4.5, -2.0),
            Pose2::new(5.2, 5.2, 3.9),
            Pose2::new(0.6, 0.7, 0.8),
        ]
        .into_iter()
        .enumerate()
        {
            let frame = camera.capture(&bvh, pose);
            let mut occ = Occupancy::new(
                gt.grid,
                crate::map::LogOdds::from_config(&cfg.map),
                band.clone(),
            );
            let mut map: Vec<u32> = occ.integrate(&frame).newly_known;
            map.retain(|&v| in_band(v as usize));
            let mut cast: Vec<u32> = Vec::new();
            for d in &frame.dirs {
                cast.extend(
                    caster
                        .observe(frame.origin, *d, &mut buf)
                        .iter()
                        .filter(|&&v| in_band(v))
                        .map(|&v| v as u32),
                );
            }
            cast.sort_unstable();
            cast.dedup();
            total += map.len();
            differ += map.len() + cast.len()
                - 2 * map.iter().filter(|v| cast.binary_search(v).is_ok()).count();
            assert!(map.len() > 1000, "pose {k}: {} voxels", map.len());
        }
        // Exact agreement but for ties of floating-point rounding at voxel faces.
        assert_eq!(differ, 0, "{differ} of {total} voxels differ");
    }

    /// The column sweep against the ray-by-ray walk over a scene's sampled poses: the same bits, and
    /// the sweep decides almost every column itself. Returns the number of observed voxels.
    fn sweep_equals_rays(
        mesh: &crate::scene::TriMesh,
        spawn: Option<Pose2>,
        spacing: f64,
    ) -> usize {
        let cfg = Config::default();
        let gt = GroundTruth::build(mesh, spawn, &cfg).unwrap();
        let bvh = MeshBvh::new(mesh).unwrap();
        let camera = DepthCamera::new(&cfg.camera);
        let band = gt.band_layers();
        let res = gt.grid.res;
        let caster = VoxelCaster::new(
            &gt,
            &bvh,
            &camera,
            (band.start as f64 * res, band.end as f64 * res),
        );
        assert!(caster.sweep_applies(&camera));
        let k = lattice_cells(&gt.grid, spacing);
        let positions = sample_positions(&gt.grid, gt.reachable_mask(), k, |_, _| true);
        let beyond = beyond_cells(&gt);
        let yaws: Vec<(f32, f32)> = (0..8)
            .map(|k| {
                let yaw = std::f64::consts::TAU * k as f64 / 8.0;
                (yaw.sin() as f32, yaw.cos() as f32)
            })
            .collect();
        let rays = caster.frames_by_rays(&positions, &yaws, &camera, &beyond);
        assert!(!positions.is_empty());
        let columns = positions.len() * yaws.len() * camera.image_size().0;
        // Voxels outside the band are dropped from the set (the walks differ there: the sweep does
        // not mark the floor voxel of a ray's last, out-of-band step).
        let rays_set = ObservableSet::from_bits(&gt, rays.bits, positions.len());
        // On one thread and on two (the workers' shares of the positions differ).
        for threads in [1, 2] {
            let swept = crate::util::on_threads(threads, || {
                caster.frames_by_columns(&positions, &yaws, &camera, &beyond)
            });
            // The two ways agree on which positions looked beyond the reachable region, too.
            assert_eq!(rays.looked_beyond, swept.looked_beyond);
            let by_rays = swept.by_rays;
            assert!(
                by_rays * 100 < columns,
                "{by_rays} of {columns} columns walked ray by ray"
            );
            let swept = ObservableSet::from_bits(&gt, swept.bits, positions.len());
            let differ = (0..gt.grid.voxels())
                .filter(|&v| rays_set.contains(v) != swept.contains(v))
                .count();
            assert_eq!(
                differ,
                0,
                "{threads} threads: {differ} of {} voxels differ",
                rays_set.voxels()
            );
        }
        rays_set.voxels()
    }

    /// The sweep against the ray-by-ray walk on every shipped scene and three plans (one of them
    /// the benchmark's, with views through narrow gaps), every fourth square of positions.
    #[test]
    fn column_sweep_marks_what_rays_mark_on_shipped_scenes() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let mut paths: Vec<std::path::PathBuf> = std::fs::read_dir(&root)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "obj"))
            .collect();
        paths.sort();
        assert!(paths.len() >= 8, "{paths:?}");
        for plan in ["plan_7fdb16a896", "plan_052ce6767b", "plan_2eea8ff97b"] {
            paths.push(root.join("floorplans").join(format!("{plan}.obj")));
        }
        for path in paths {
            let scene = crate::scene::load(&path, &Config::default().scene).unwrap();
            let voxels = sweep_equals_rays(&scene.mesh, scene.spawn, 2.0);
            assert!(voxels > 1000, "{}: {voxels}", path.display());
        }
    }

    #[test]
    fn column_sweep_marks_what_rays_mark() {
        assert!(sweep_equals_rays(&furnished_room(6.0), None, 0.5) > 10_000);
        let closet = room_with_closet();
        assert!(sweep_equals_rays(&closet, Some(Pose2::new(3.0, 3.0, 0.0)), 0.5) > 10_000);
        // A real plan (furniture, doors, diagonal walls): every third square of positions.
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes/floorplans/plan_a64cda6b6a.obj");
        let scene = crate::scene::load(&path, &Config::default().scene).unwrap();
        assert!(sweep_equals_rays(&scene.mesh, scene.spawn, 1.5) > 10_000);
    }

    #[test]
    fn views_through_a_narrow_door_are_sampled_again_finer() {
        let cfg = Config::default();
        let mesh = room_with_closet();
        let gt = GroundTruth::build(&mesh, Some(Pose2::new(3.0, 3.0, 0.0)), &cfg).unwrap();
        let grid = gt.grid;
        let beyond = beyond_cells(&gt);
        let cell = |x: f64, y: f64| grid.index(grid.cell_at(x, y));
        // The closet lies beyond the reachable region; nothing of the room does, not even the free
        // band along its walls and around the table that the inflation keeps the robot out of.
        assert!(beyond[cell(7.55, 1.05)] && beyond[cell(9.15, 2.05)] && beyond[cell(6.55, 0.25)]);
        for (i, &b) in beyond.iter().enumerate() {
            let p = grid.center(grid.cell(i));
            if p.x > 0.1 && p.x < 6.1 && p.y > 0.1 && p.y < 6.1 {
                assert!(!b, "{p:?}");
            }
        }
        // The first pass alone, as `compute` runs it.
        let bvh = MeshBvh::new(&mesh).unwrap();
        let camera = DepthCamera::new(&cfg.camera);
        let band = gt.band_layers();
        let res = grid.res;
        let caster = VoxelCaster::new(
            &gt,
            &bvh,
            &camera,
            (band.start as f64 * res, band.end as f64 * res),
        );
        let yaws: Vec<(f32, f32)> = (0..cfg.metrics.observable_yaws)
            .map(|k| {
                let yaw = std::f64::consts::TAU * k as f64 / cfg.metrics.observable_yaws as f64;
                (yaw.sin() as f32, yaw.cos() as f32)
            })
            .collect();
        let k = lattice_cells(&grid, cfg.metrics.observable_spacing_m);
        let coarse = sample_positions(&grid, gt.reachable_mask(), k, |_, _| true);
        let first = caster.frames_by_columns(&coarse, &yaws, &camera, &beyond);
        // Some positions look into the closet through the door, and only those of the room's
        // eastern part (the closet is out of range of the rest).
        assert!(!first.looked_beyond.is_empty());
        assert!(first
            .looked_beyond
            .iter()
            .all(|&c| grid.center(grid.cell(c)).x > 1.0));
        let fine = refined_positions(&grid, gt.reachable_mask(), k, &first.looked_beyond, &coarse);
        assert!(fine.len() > first.looked_beyond.len());
        assert!(fine
            .iter()
            .all(|&c| gt.reachable(c) && !coarse.contains(&c)));
        // Every refined position lies in a square next to one that looked beyond.
        let square = |c: usize| {
            let c = grid.cell(c);
            (c.x / k as i32, c.y / k as i32)
        };
        assert!(fine.iter().all(|&f| first.looked_beyond.iter().any(|&l| {
            let (a, b) = (square(f), square(l));
            (a.0 - b.0).abs() <= 1 && (a.1 - b.1).abs() <= 1
        })));
        // The set holds the first pass and sees more of the closet.
        let coarse_set = ObservableSet::from_bits(&gt, first.bits, coarse.len());
        let set = ObservableSet::compute(
            &gt,
            &bvh,
            &camera,
            &ObservableParams::from_config(&cfg.metrics),
        );
        assert_eq!(set.positions(), coarse.len() + fine.len());
        assert!((0..grid.voxels()).all(|v| !coarse_set.contains(v) || set.contains(v)));
        let in_closet = |s: &ObservableSet| {
            (0..grid.voxels())
                .filter(|&v| s.contains(v) && beyond[grid.voxel_parts(v).0])
                .count()
        };
        let (before, after) = (in_closet(&coarse_set), in_closet(&set));
        assert!(after > before, "{before} → {after} closet voxels");
    }

    #[test]
    fn closet_is_observable_not_reachable() {
        let cfg = Config::default();
        let mesh = room_with_closet();
        let gt = GroundTruth::build(&mesh, Some(Pose2::new(3.0, 3.0, 0.0)), &cfg).unwrap();
        let bvh = MeshBvh::new(&mesh).unwrap();
        let set = ObservableSet::compute(
            &gt,
            &bvh,
            &DepthCamera::new(&cfg.camera),
            &ObservableParams::from_config(&cfg.metrics),
        );
        let cell = |x: f64, y: f64| gt.grid.index(gt.grid.cell_at(x, y));
        // The door (0.5 m) is narrower than 2 × 0.29 m: the closet is not reachable ...
        assert!(gt.reachable(cell(3.0, 3.0)));
        assert!(!gt.reachable(cell(6.15, 1.05)) && !gt.reachable(cell(7.5, 1.0)));
        // ... but the camera sees into it through the door, and not into its corners beside the
        // door, hidden behind the wall from every reachable pose.
        assert!(set.column_observable(&gt, cell(7.5, 1.05)));
        assert!(!set.column_observable(&gt, cell(6.25, 0.15)));
        // Reachable floor: the room's inside less a band of the inflation radius along its walls
        // and around the table: (6 − 2·0.3)² − (1 + 2·0.3)² ≈ 26.6 m², to a cell.
        let area = gt.reachable_area_m2();
        assert!((area - 26.6).abs() < 1.5, "{area}");
        // Observable: at most the room's and closet's band volume plus their walls' faces.
        let v = set.volume_m3();
        assert!(
            v > 0.9 * 36.0 * 1.7 && v < (6.2 * 6.2 + 3.2 * 2.2) * 1.7,
            "{v}"
        );
    }

    #[test]
    fn cache_round_trip_and_damage() {
        let cfg = Config::default();
        let mesh = furnished_room(5.0);
        let scene = scene(mesh.clone());
        let gt = GroundTruth::build(&mesh, None, &cfg).unwrap();
        let bvh = MeshBvh::new(&mesh).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let cache = ObservableCache::at(dir.path());
        let (fresh, how) = ObservableCache::none().get_or_compute(
            &scene,
            &gt,
            &bvh,
            &cfg.camera,
            &ObservableParams::from_config(&cfg.metrics),
        );
        assert_eq!(how, CacheOutcome::Uncached(None));
        let (first, how) = cache.get_or_compute(
            &scene,
            &gt,
            &bvh,
            &cfg.camera,
            &ObservableParams::from_config(&cfg.metrics),
        );
        let CacheOutcome::Computed(path) = how else {
            panic!("{how:?}")
        };
        assert_eq!(first, fresh);
        let (hit, how) = cache.get_or_compute(
            &scene,
            &gt,
            &bvh,
            &cfg.camera,
            &ObservableParams::from_config(&cfg.metrics),
        );
        assert_eq!(how, CacheOutcome::Hit(path.clone()));
        assert_eq!(hit, fresh);
        // A truncated file, a flipped byte and a file of another key are each found, recomputed and
        // reported; the set is the fresh one every time.
        let good = std::fs::read(&path).unwrap();
        let mut flipped = good.clone();
        flipped[good.len() / 2] ^= 0x10;
        let mut other = good.clone();
        other[8] ^= 1; // the key, with a checksum that matches
        let n = other.len();
        let sum = fnv1a64(&other[..n - 8]).to_le_bytes();
        other[n - 8..].copy_from_slice(&sum);
        for (bytes, why) in [
            (&good[..good.len() - 9], "bytes, expected"),
            (&flipped[..], "checksum mismatch"),
            (&other[..], "written for another scene or config"),
            (&b""[..], "0 bytes"),
        ] {
            std::fs::write(&path, bytes).unwrap();
            let (set, how) = cache.get_or_compute(
                &scene,
                &gt,
                &bvh,
                &cfg.camera,
                &ObservableParams::from_config(&cfg.metrics),
            );
            assert_eq!(set, fresh);
            let CacheOutcome::Repaired(p, reason) = &how else {
                panic!("{how:?}")
            };
            assert_eq!(p, &path);
            assert!(reason.contains(why), "{reason}");
            assert!(how.warning().unwrap().contains("was damaged"));
            assert_eq!(std::fs::read(&path).unwrap(), good);
        }
        // Another sampling is another file.
        let mut coarse = cfg.clone();
        coarse.metrics.observable_spacing_m = 1.0;
        assert_ne!(
            ObservableCache::key(
                "test",
                &gt,
                &cfg.camera,
                &ObservableParams::from_config(&cfg.metrics)
            ),
            ObservableCache::key(
                "test",
                &gt,
                &coarse.camera,
                &ObservableParams::from_config(&coarse.metrics)
            )
        );
    }

    #[test]
    fn set_does_not_depend_on_thread_count() {
        let cfg = Config::default();
        let mesh = room_with_closet();
        let gt = GroundTruth::build(&mesh, Some(Pose2::new(3.0, 3.0, 0.0)), &cfg).unwrap();
        let bvh = MeshBvh::new(&mesh).unwrap();
        let compute = |threads: usize| {
            crate::util::on_threads(threads, || {
                ObservableSet::compute(
                    &gt,
                    &bvh,
                    &DepthCamera::new(&cfg.camera),
                    &ObservableParams::from_config(&cfg.metrics),
                )
            })
        };
        assert_eq!(compute(1), compute(2));
    }

    #[test]
    fn every_reachable_patch_gets_a_position() {
        // A 1-cell-wide reachable corridor and an isolated cell: sampled although they cross no
        // lattice point.
        let grid = GridSpec::covering(
            nalgebra::Point2::new(0.0, 0.0),
            nalgebra::Point2::new(2.0, 2.0),
            1.0,
            0.1,
        );
        let mut reach = vec![false; grid.cells()];
        for x in 2..18 {
            reach[grid.index(Cell::new(x, 7))] = true;
        }
        reach[grid.index(Cell::new(13, 13))] = true;
        let pos = sample_positions(&grid, &reach, lattice_cells(&grid, 0.5), |_, _| true);
        // Corridor cells 2..18 fall in blocks x 0..5, 5..10, 10..15, 15..20: one each; plus the cell.
        assert_eq!(pos.len(), 5, "{pos:?}");
        assert!(pos.contains(&grid.index(Cell::new(13, 13))));
        assert!(pos.iter().all(|&c| reach[c]));
    }
}
