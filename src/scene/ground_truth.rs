//! The scene's ground truth on the map grid: the mesh voxelised, obstacle columns, the region
//! around the spawn, surface voxels and obstacle clearance, and the spawn itself (checked, or chosen
//! automatically). The reachable region and what the camera can observe from it are the evaluation
//! layer's (`eval`), which builds its `GroundTruth` on this one.
//!
//! Voxelisation is an exact triangle–box separating-axis test in grid units, with vertices snapped to
//! 1e-4 of a voxel and voxels treated as half-open `[i, i+1)`: a wall face lying exactly on a voxel
//! boundary (common: generated and imported scenes sit on a 0.05 m raster) marks only the voxel on
//! its upper side, never both, and floating-point noise in the grid origin cannot flip that choice.

use super::geometry::triangle_meets_cylinder;
use super::TriMesh;
use crate::config::Config;
use crate::error::{Error, Result};
use crate::grid::{distance_transform, Cell, GridSpec, NEIGHBOURS_8};
use crate::Pose2;
use nalgebra::Point2;
use rayon::prelude::*;

/// Vertices are snapped to this fraction of a voxel before the overlap test.
const SNAP: f64 = 1e-4;
/// A voxel `[i, i+1)` is tested as the closed box `[i, i + 1 - OPEN]` (OPEN is half a snap step).
const OPEN: f64 = 0.5 * SNAP;

/// Ground truth of one scene on the map grid.
#[derive(Clone, Debug)]
pub struct SceneTruth {
    pub grid: GridSpec,
    pub spawn: Pose2,
    occupied: Vec<bool>,
    obstacle: Vec<bool>,
    region: Vec<bool>,
    region_cells: usize,
    triangles: VoxelTriangles,
    band: std::ops::Range<usize>,
    surface: Vec<u32>,
    clearance: Vec<f32>,
}

/// The voxel grid of a scene: its mesh's xy bounds ± `map.margin_m`, up to `map.band_max_m`, at
/// `map.voxel_m` (`None` for an empty mesh). The ground truth and the robot's map share it.
pub fn scene_grid(mesh: &TriMesh, cfg: &Config) -> Option<GridSpec> {
    let (min, max) = mesh.bounds()?;
    let m = cfg.map.margin_m;
    Some(GridSpec::covering(
        Point2::new(min.x - m, min.y - m),
        Point2::new(max.x + m, max.y + m),
        cfg.map.band_max_m,
        cfg.map.voxel_m,
    ))
}

impl SceneTruth {
    /// Voxelises `mesh` on the grid covering its xy bounds ± `map.margin_m`, up to `map.band_max_m`,
    /// validates or chooses the spawn, and flood-fills the explorable region from it.
    pub fn build(mesh: &TriMesh, spawn: Option<Pose2>, cfg: &Config) -> Result<SceneTruth> {
        let empty = || Error::Runtime("ground truth of an empty mesh".into());
        let (min, max) = mesh.bounds().ok_or_else(empty)?;
        let grid = scene_grid(mesh, cfg).ok_or_else(empty)?;
        // One byte per voxel: refuse grids that would need gigabytes rather than abort on allocation.
        const MAX_VOXELS: usize = 400_000_000;
        if grid.voxels() > MAX_VOXELS {
            return Err(Error::usage(format!(
                "the scene's ground-truth grid ({} × {} × {} voxels) is too large; raise map.voxel_m",
                grid.nx, grid.ny, grid.nz
            )));
        }
        // The voxelisation tests every triangle against every voxel of its bounding box: many large
        // overlapping faces (one huge polygon fanned out, a face repeated thousands of times) would
        // cost minutes and gigabytes. The shipped scenes and real plans span under 250,000.
        let span = triangle_voxel_span(mesh, &grid);
        if span > MAX_TRIANGLE_VOXELS {
            return Err(Error::usage(format!(
                "the scene's triangles span {span} voxels in all (each triangle's bounding box, overlaps counted again), more than {MAX_TRIANGLE_VOXELS}: too many large overlapping faces, or raise map.voxel_m"
            )));
        }
        let triangles = VoxelTriangles::build(mesh, &grid);
        // The observable set's caster tests every triangle listed in each voxel a ray crosses, so
        // faces stacked on one another (thousands of nearly equal faces) multiply its work by their
        // depth.
        let depth = triangles.stacking_depth();
        if depth > MAX_STACKING_DEPTH {
            return Err(Error::usage(format!(
                "the scene's faces stack {depth:.0} deep in its voxels (more than {MAX_STACKING_DEPTH:.0}): nearly repeated faces, or a mesh too fine for map.voxel_m; decimate the mesh, or raise map.voxel_m"
            )));
        }
        let mut occupied = vec![false; grid.voxels()];
        for &v in &triangles.voxels {
            occupied[v as usize] = true;
        }
        let robot_layers = grid.layers_in(cfg.map.band_min_m, cfg.robot.height_m);
        let cells = grid.cells();
        let obstacle: Vec<bool> = (0..cells)
            .map(|c| robot_layers.clone().any(|iz| occupied[iz * cells + c]))
            .collect();
        let clearance: Vec<f32> = distance_transform(&obstacle, grid.nx, grid.ny)
            .into_iter()
            .map(|d2| {
                if d2.is_finite() {
                    (d2.sqrt() * grid.res) as f32
                } else {
                    f32::INFINITY
                }
            })
            .collect();

        // The robot must fit at its start, wherever the start came from: clear of obstacle columns
        // by its radius between cell centres, and its disc exactly clear of every triangle, with
        // the collision test's geometry (a converted plan's start 0.24 m from a wall face, and an
        // automatic spawn in a 0.4 m wide room, both started in collision).
        let fits = |s: Pose2, what: &str| -> Result<()> {
            // Shown to the micrometre: a cell centre computed as 0.3500000000000001 reads 0.35.
            let (x, y) = ((s.x * 1e6).round() / 1e6, (s.y * 1e6).round() / 1e6);
            let cell = grid
                .cell_of(s.position())
                .expect("the spawn lies in the grid");
            let c = clearance[grid.index(cell)];
            if (c as f64) < cfg.robot.radius_m {
                return Err(Error::usage(format!(
                    "{what} ({x}, {y}) is inside an obstacle or closer than the robot radius ({} m) to one (clearance {:.2} m)",
                    cfg.robot.radius_m, c
                )));
            }
            let (z_min, z_max) = (
                cfg.map.band_min_m,
                cfg.robot.height_m.min(cfg.map.band_max_m),
            );
            let touches = mesh.triangles.iter().any(|t| {
                let tri = t.map(|k| {
                    let v = mesh.vertices[k as usize];
                    [v.x as f64, v.y as f64, v.z as f64]
                });
                triangle_meets_cylinder(tri, s.x, s.y, cfg.robot.radius_m, z_min, z_max)
            });
            if touches {
                return Err(Error::usage(format!(
                    "{what} ({x}, {y}) puts the robot's disc (radius {} m, {z_min}–{z_max} m high) into the scene: move it farther from the nearest surface",
                    cfg.robot.radius_m
                )));
            }
            Ok(())
        };
        let spawn = match spawn {
            Some(s) => {
                let inside_mesh = s.x >= min.x && s.x <= max.x && s.y >= min.y && s.y <= max.y;
                if grid
                    .cell_of(s.position())
                    .filter(|_| inside_mesh && s.x.is_finite() && s.y.is_finite())
                    .is_none()
                {
                    return Err(Error::usage(format!(
                        "spawn ({}, {}) is outside the scene bounds [{:.2}, {:.2}] × [{:.2}, {:.2}]",
                        crate::util::short_number(s.x),
                        crate::util::short_number(s.y),
                        min.x,
                        max.x,
                        min.y,
                        max.y
                    )));
                }
                fits(s, "spawn")?;
                s
            }
            None => {
                let s = auto_spawn(&grid, &obstacle, &clearance)?;
                // The automatic spawn is the floor cell farthest from obstacles in the largest
                // enclosed region: if the robot does not fit there, it fits nowhere in that region.
                fits(s, "the automatic spawn").map_err(|e| {
                    Error::Runtime(format!(
                        "{e} (the file has no spawn line, and this floor cell is the farthest from obstacles: the robot fits nowhere in the scene's largest room)"
                    ))
                })?;
                s
            }
        };

        let start = grid.index(
            grid.cell_of(spawn.position())
                .expect("spawn is in the grid"),
        );
        let reached = flood_fill_4(&grid, &obstacle, start);
        let mut region = reached.clone();
        for (i, _) in reached.iter().enumerate().filter(|(_, &r)| r) {
            let c = grid.cell(i);
            for (dx, dy) in NEIGHBOURS_8 {
                if let Some(j) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) {
                    region[j] = true;
                }
            }
        }
        let region_cells = region.iter().filter(|&&r| r).count();
        let band = grid.layers_in(cfg.map.band_min_m, cfg.map.band_max_m);
        let surface: Vec<u32> = band
            .clone()
            .flat_map(|iz| (0..cells).map(move |c| (iz, c)))
            .filter(|&(iz, c)| region[c] && occupied[iz * cells + c])
            .map(|(iz, c)| (iz * cells + c) as u32)
            .collect();
        Ok(SceneTruth {
            grid,
            spawn,
            occupied,
            obstacle,
            region,
            region_cells,
            triangles,
            band,
            surface,
            clearance,
        })
    }

    /// Whether any triangle overlaps voxel `voxel` (layers 0..nz).
    pub fn occupied(&self, voxel: usize) -> bool {
        self.occupied[voxel]
    }

    /// Whether the cell has an occupied voxel in the robot's body band `[band_min_m, robot.height_m]`.
    pub fn obstacle_column(&self, cell: usize) -> bool {
        self.obstacle[cell]
    }

    /// Whether the cell belongs to the region: the floor connected to the spawn through
    /// obstacle-free cells, grown by one cell. It ignores the robot's size, so it leaks through gaps
    /// the robot cannot pass; the metrics use the evaluation layer's reachable region instead.
    pub fn in_region(&self, cell: usize) -> bool {
        self.region[cell]
    }

    /// The mesh's triangles by the voxels they overlap.
    pub fn voxel_triangles(&self) -> &VoxelTriangles {
        &self.triangles
    }

    pub fn region_cells(&self) -> usize {
        self.region_cells
    }

    /// The voxel layers of the height band `[band_min_m, band_max_m]`.
    pub fn band_layers(&self) -> std::ops::Range<usize> {
        self.band.clone()
    }

    /// Region cells × band layers × voxel volume, m³.
    pub fn explorable_volume_m3(&self) -> f64 {
        self.region_cells as f64 * self.band.len() as f64 * self.grid.voxel_volume()
    }

    /// Occupied voxels in the band layers whose cell is in the region, ascending.
    pub fn surface_voxels(&self) -> &[u32] {
        &self.surface
    }

    /// The map's surface layer as if the scene were fully observed: region cells with a surface
    /// voxel in the band.
    pub fn surface_columns(&self) -> Vec<bool> {
        let mut columns = vec![false; self.grid.cells()];
        for &v in &self.surface {
            columns[self.grid.voxel_parts(v as usize).0] = true;
        }
        columns
    }

    /// The obstacle layer as if the scene were fully observed.
    pub fn obstacle_columns(&self) -> &[bool] {
        &self.obstacle
    }

    /// Distance from the cell centre to the nearest obstacle-column cell centre, metres
    /// (`f32::INFINITY` if there is none).
    pub fn clearance_m(&self, cell: usize) -> f32 {
        self.clearance[cell]
    }

    /// [`SceneTruth::clearance_m`] of every cell.
    pub fn clearances(&self) -> &[f32] {
        &self.clearance
    }
}

/// The triangles that overlap each occupied voxel, by the same exact test as the voxelisation: what
/// a ray walking the voxels must test to find the mesh's first hit.
#[derive(Clone, Debug, Default)]
pub struct VoxelTriangles {
    /// Occupied voxels (flat indices), ascending.
    voxels: Vec<u32>,
    /// `triangles[starts[k]..starts[k + 1]]` overlap `voxels[k]`.
    starts: Vec<u32>,
    triangles: Vec<u32>,
}

/// Most voxel tests the voxelisation may make: the sum over triangles of the voxels in each one's
/// bounding box (see [`triangle_voxel_span`]).
pub const MAX_TRIANGLE_VOXELS: u64 = 100_000_000;

/// Most a scene's faces may stack (see [`VoxelTriangles::stacking_depth`]): the shipped scenes and
/// real plans stack at most 3.3 deep, so this leaves room for finely tessellated furniture.
pub const MAX_STACKING_DEPTH: f64 = 64.0;

/// The voxels of `grid` in the bounding boxes of `mesh`'s triangles, summed over the triangles:
/// the work of [`VoxelTriangles::build`].
pub fn triangle_voxel_span(mesh: &TriMesh, grid: &GridSpec) -> u64 {
    let count = |lo: f64, hi: f64, origin: f64, n: usize| -> u64 {
        let a = ((lo - origin) / grid.res).floor().max(0.0);
        let b = ((hi - origin) / grid.res).floor().min(n as f64 - 1.0);
        if a <= b {
            (b - a) as u64 + 1
        } else {
            0
        }
    };
    mesh.triangles
        .iter()
        .map(|t| {
            let p = t.map(|i| mesh.vertices[i as usize]);
            let lo = |k: usize| {
                p.iter()
                    .map(|v| f64::from(v[k]))
                    .fold(f64::INFINITY, f64::min)
            };
            let hi = |k: usize| {
                p.iter()
                    .map(|v| f64::from(v[k]))
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            count(lo(0), hi(0), grid.origin_x, grid.nx)
                * count(lo(1), hi(1), grid.origin_y, grid.ny)
                * count(lo(2), hi(2), 0.0, grid.nz)
        })
        .fold(0u64, u64::saturating_add)
}

impl VoxelTriangles {
    /// How many triangles a triangle shares its voxels with, on average over the listed
    /// (voxel, triangle) pairs: Σ d² / Σ d over the voxels' list lengths d. Unlike the mean
    /// over voxels, a large floor of single triangles does not dilute a stack of repeated faces.
    pub fn stacking_depth(&self) -> f64 {
        let (sum, sum_sq) = self.starts.windows(2).fold((0.0, 0.0), |(s, q), w| {
            let d = f64::from(w[1] - w[0]);
            (s + d, q + d * d)
        });
        if sum > 0.0 {
            sum_sq / sum
        } else {
            0.0
        }
    }

    /// Lists the triangles of `mesh` over every voxel of `grid`.
    pub fn build(mesh: &TriMesh, grid: &GridSpec) -> VoxelTriangles {
        let tris = snapped_triangles(mesh, grid);
        let layers: Vec<Vec<(u32, u32)>> = (0..grid.nz)
            .into_par_iter()
            .map(|iz| {
                let mut pairs = Vec::new();
                layer_overlaps(
                    &tris,
                    grid,
                    iz,
                    |_, _| true,
                    |cell, t| pairs.push(((iz * grid.cells() + cell) as u32, t as u32)),
                );
                pairs.sort_unstable();
                pairs
            })
            .collect();
        let mut out = VoxelTriangles::default();
        for (v, t) in layers.into_iter().flatten() {
            if out.voxels.last() != Some(&v) {
                out.voxels.push(v);
                out.starts.push(out.triangles.len() as u32);
            }
            out.triangles.push(t);
        }
        out.starts.push(out.triangles.len() as u32);
        out
    }

    /// The triangles overlapping voxel `v` (empty for a free voxel).
    #[inline]
    pub fn of(&self, v: usize) -> &[u32] {
        match self.voxels.binary_search(&(v as u32)) {
            Ok(k) => &self.triangles[self.starts[k] as usize..self.starts[k + 1] as usize],
            Err(_) => &[],
        }
    }
}

/// The mesh's triangles in grid units, vertices snapped to `SNAP` (see the module doc).
fn snapped_triangles(mesh: &TriMesh, grid: &GridSpec) -> Vec<[[f64; 3]; 3]> {
    let snap = |v: f64| (v / SNAP).round() * SNAP;
    mesh.triangles
        .iter()
        .map(|t| {
            t.map(|i| {
                let p = mesh.vertices[i as usize];
                [
                    snap((p.x as f64 - grid.origin_x) / grid.res),
                    snap((p.y as f64 - grid.origin_y) / grid.res),
                    snap(p.z as f64 / grid.res),
                ]
            })
        })
        .collect()
}

/// Calls `hit(cell, triangle)` for every cell of layer `iz` that a triangle overlaps, testing only
/// the pairs that `want(cell, triangle)` asks for.
fn layer_overlaps(
    tris: &[[[f64; 3]; 3]],
    grid: &GridSpec,
    iz: usize,
    want: impl Fn(usize, usize) -> bool,
    mut hit: impl FnMut(usize, usize),
) {
    let (nx, ny) = (grid.nx, grid.ny);
    let half = 0.5 * (1.0 - OPEN);
    let z0 = iz as f64;
    for (t, tri) in tris.iter().enumerate() {
        let lo = |k: usize| tri.iter().map(|v| v[k]).fold(f64::INFINITY, f64::min);
        let hi = |k: usize| tri.iter().map(|v| v[k]).fold(f64::NEG_INFINITY, f64::max);
        if lo(2) > z0 + 1.0 - OPEN || hi(2) < z0 {
            continue;
        }
        let range = |k: usize, n: usize| {
            let a = lo(k).floor().max(0.0);
            let b = hi(k).floor().min(n as f64 - 1.0);
            (a <= b).then_some(a as usize..=b as usize)
        };
        let (Some(xs), Some(ys)) = (range(0, nx), range(1, ny)) else {
            continue;
        };
        for iy in ys {
            for ix in xs.clone() {
                let cell = iy * nx + ix;
                if want(cell, t) {
                    let centre = [ix as f64 + half, iy as f64 + half, z0 + half];
                    if triangle_box_overlap(centre, half, tri) {
                        hit(cell, t);
                    }
                }
            }
        }
    }
}

/// Exact separating-axis test (Akenine-Möller) of a triangle against the cube `centre ± half`.
/// Touching counts as overlapping, up to a tolerance far below the snap step.
pub fn triangle_box_overlap(centre: [f64; 3], half: f64, tri: &[[f64; 3]; 3]) -> bool {
    let v: [[f64; 3]; 3] = tri.map(|p| [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]]);
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let separated = |axis: [f64; 3]| {
        let r = half * (axis[0].abs() + axis[1].abs() + axis[2].abs());
        let tol = 1e-7 * (axis[0].abs() + axis[1].abs() + axis[2].abs());
        let p = v.map(|q| dot(axis, q));
        let (mn, mx) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
        mn > r + tol || mx < -r - tol
    };
    // The box's face normals.
    for k in 0..3 {
        let mut axis = [0.0; 3];
        axis[k] = 1.0;
        if separated(axis) {
            return false;
        }
    }
    let e = [sub(v[1], v[0]), sub(v[2], v[1]), sub(v[0], v[2])];
    // The triangle's normal.
    let n = [
        e[0][1] * e[1][2] - e[0][2] * e[1][1],
        e[0][2] * e[1][0] - e[0][0] * e[1][2],
        e[0][0] * e[1][1] - e[0][1] * e[1][0],
    ];
    if separated(n) {
        return false;
    }
    // Cross products of box axes and triangle edges.
    for ed in e {
        for axis in [
            [0.0, -ed[2], ed[1]],
            [ed[2], 0.0, -ed[0]],
            [-ed[1], ed[0], 0.0],
        ] {
            if separated(axis) {
                return false;
            }
        }
    }
    true
}

/// The 4-connected obstacle-free cells reachable from `start`.
fn flood_fill_4(grid: &GridSpec, obstacle: &[bool], start: usize) -> Vec<bool> {
    let mut seen = vec![false; grid.cells()];
    if obstacle[start] {
        return seen;
    }
    let mut stack = vec![start];
    seen[start] = true;
    while let Some(i) = stack.pop() {
        let c = grid.cell(i);
        for &(dx, dy) in &NEIGHBOURS_8[..4] {
            if let Some(j) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) {
                if !seen[j] && !obstacle[j] {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
    }
    seen
}

/// The free cell of largest clearance (ties → lowest index) in the largest 4-connected free region,
/// preferring regions that do not touch the grid border (the scene's outside) when one exists.
fn auto_spawn(grid: &GridSpec, obstacle: &[bool], clearance: &[f32]) -> Result<Pose2> {
    let n = grid.cells();
    let mut label = vec![u32::MAX; n];
    // (size, touches border, best cell)
    let mut regions: Vec<(usize, bool, usize)> = Vec::new();
    for start in 0..n {
        if obstacle[start] || label[start] != u32::MAX {
            continue;
        }
        let id = regions.len() as u32;
        let (mut size, mut border, mut best) = (0, false, start);
        let mut stack = vec![start];
        label[start] = id;
        while let Some(i) = stack.pop() {
            size += 1;
            let c = grid.cell(i);
            border |=
                c.x == 0 || c.y == 0 || c.x as usize == grid.nx - 1 || c.y as usize == grid.ny - 1;
            if clearance[i] > clearance[best] || (clearance[i] == clearance[best] && i < best) {
                best = i;
            }
            for &(dx, dy) in &NEIGHBOURS_8[..4] {
                if let Some(j) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) {
                    if !obstacle[j] && label[j] == u32::MAX {
                        label[j] = id;
                        stack.push(j);
                    }
                }
            }
        }
        regions.push((size, border, best));
    }
    let any_enclosed = regions.iter().any(|r| !r.1);
    let chosen = regions
        .iter()
        .filter(|r| !(any_enclosed && r.1))
        .fold(None::<&(usize, bool, usize)>, |acc, r| match acc {
            Some(a) if a.0 >= r.0 => Some(a),
            _ => Some(r),
        })
        .ok_or_else(|| {
            Error::Runtime("the scene has no obstacle-free floor cell for a spawn".into())
        })?;
    let p = grid.center(grid.cell(chosen.2));
    Ok(Pose2::new(p.x, p.y, 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::extrude::extrude_grid;

    #[test]
    fn sat_known_cases() {
        let tri = [[0.0, 0.0, 0.5], [3.0, 0.0, 0.5], [0.0, 3.0, 0.5]];
        assert!(triangle_box_overlap([0.5, 0.5, 0.5], 0.5, &tri));
        // Beyond the hypotenuse x + y = 3: the box [2.6, 3.6]² is outside.
        assert!(!triangle_box_overlap([3.1, 3.1, 0.5], 0.5, &tri));
        // Its AABB overlaps, but the triangle's plane (z = 0.5) misses the box at z ∈ [1, 2].
        assert!(!triangle_box_overlap([0.5, 0.5, 1.5], 0.5, &tri));
        // A tilted triangle whose AABB covers the box but which passes beside it (edge axis).
        let thin = [[0.0, 0.0, 0.0], [4.0, 4.0, 4.0], [4.0, 4.0, 4.1]];
        assert!(!triangle_box_overlap([3.5, 0.5, 0.5], 0.5, &thin));
        assert!(triangle_box_overlap([2.0, 2.0, 2.0], 0.5, &thin));
    }

    /// A 4 × 3 m room (inner), walls on the 0.1 m grid, extruded to 2.5 m.
    fn box_room() -> TriMesh {
        // 0.1 m raster: 1 solid ring around 40 × 30 free cells.
        let (nx, ny) = (42, 32);
        let solid: Vec<bool> = (0..nx * ny)
            .map(|i| {
                let (x, y) = (i % nx, i / nx);
                x == 0 || y == 0 || x == nx - 1 || y == ny - 1
            })
            .collect();
        extrude_grid(&solid, nx, ny, [0.0, 0.0], 0.1, 2.5)
    }

    #[test]
    fn stacked_faces_are_refused_by_their_stacking_depth() {
        let cfg = Config::default();
        let room = box_room();
        let grid = scene_grid(&room, &cfg).unwrap();
        let once = VoxelTriangles::build(&room, &grid).stacking_depth();
        let mut stacked = room.clone();
        for _ in 1..3 {
            stacked.append(&room);
        }
        // Copies list each triangle again in the same voxels: the depth triples exactly. (Scenes
        // loaded from files lose exact copies, see `TriMesh::drop_repeated_triangles`; nearly equal
        // faces stack the same way.)
        let thrice = VoxelTriangles::build(&stacked, &grid).stacking_depth();
        assert!((thrice - 3.0 * once).abs() < 1e-9, "{once} {thrice}");
        assert!(SceneTruth::build(&stacked, None, &cfg).is_ok());
        let copies = (MAX_STACKING_DEPTH / once).ceil() as usize + 1;
        for _ in 3..copies {
            stacked.append(&room);
        }
        let err = SceneTruth::build(&stacked, None, &cfg)
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("the scene's faces stack ")
                && err.ends_with(" deep in its voxels (more than 64): nearly repeated faces, or a mesh too fine for map.voxel_m; decimate the mesh, or raise map.voxel_m"),
            "{err}"
        );
    }

    #[test]
    fn box_room_known_answers() {
        let cfg = Config::default();
        let mesh = box_room();
        let gt = SceneTruth::build(&mesh, None, &cfg).unwrap();
        // Grid: 4.2 × 3.2 m + 0.5 m margin each side → 52 × 42 cells, 18 layers; 3.2 in f32 is
        // 3.2000000477, so y rounds outwards to one more (empty) row.
        assert_eq!((gt.grid.nx, gt.grid.ny, gt.grid.nz), (52, 43, 18));
        // Inner wall faces at x = 0.1 and x = 4.1 mark cells ix 6 (upper side) and 46; the free
        // interior without obstacle columns is ix 7..=45 (39) × iy 7..=35 (29); the region grows it
        // by one ring: 41 × 31.
        assert_eq!(gt.region_cells(), 41 * 31);
        assert_eq!(gt.band_layers(), 1..18);
        assert!((gt.explorable_volume_m3() - 41.0 * 31.0 * 17.0 * 0.001).abs() < 1e-9);
        // Surface voxels: the ring of 2·41 + 2·29 = 140 wall cells × 17 band layers.
        assert_eq!(gt.surface_voxels().len(), 140 * 17);
        // Automatic spawn: max clearance in the room is 1.5 m (15 cells to the y walls), tied for
        // ix 21..=31 on row iy 21; the lowest index wins: cell (21, 21), centre (1.65, 1.65).
        let s = gt.spawn;
        assert!(
            (s.x - 1.65).abs() < 1e-9 && (s.y - 1.65).abs() < 1e-9,
            "{s:?}"
        );
        let c = gt.grid.index(gt.grid.cell_of(s.position()).unwrap());
        assert!(
            (gt.clearance_m(c) - 1.5).abs() < 1e-6,
            "{}",
            gt.clearance_m(c)
        );
        // The floor (layer 0) is occupied under the room but is not an obstacle.
        assert!(gt.occupied(c) && !gt.obstacle_column(c));
        assert!(gt.in_region(c) && !gt.in_region(0));
        assert!(gt.surface_voxels().windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn spawn_validation_names_the_spawn() {
        let cfg = Config::default();
        let mesh = box_room();
        let e = SceneTruth::build(&mesh, Some(Pose2::new(9.0, 1.0, 0.0)), &cfg).unwrap_err();
        assert_eq!(
            e.to_string(),
            "spawn (9, 1) is outside the scene bounds [0.00, 4.20] × [0.00, 3.20]"
        );
        assert_eq!(e.exit_code(), 2);
        let e = SceneTruth::build(&mesh, Some(Pose2::new(0.25, 1.5, 0.0)), &cfg).unwrap_err();
        assert_eq!(
            e.to_string(),
            "spawn (0.25, 1.5) is inside an obstacle or closer than the robot radius (0.25 m) to one (clearance 0.10 m)"
        );
        let gt = SceneTruth::build(&mesh, Some(Pose2::new(1.0, 1.0, 0.3)), &cfg).unwrap();
        assert_eq!(gt.spawn, Pose2::new(1.0, 1.0, 0.3));
        assert_eq!(gt.region_cells(), 41 * 31);
    }

    /// A spawn whose cell centre keeps the robot radius from the nearest obstacle cell's centre,
    /// while the disc at the spawn itself reaches into the wall, is refused.
    #[test]
    fn spawn_whose_disc_touches_the_mesh_is_refused() {
        let cfg = Config::default();
        let mut mesh = box_room();
        // A wall whose face lies inside a cell: x = 2.08, in the cell 2.0–2.1 (centre 2.05).
        mesh.push_box([2.0, 0.5, 0.0], [2.08, 2.5, 2.5]);
        // x = 2.32 is in the cell centred at 2.35: 0.30 m between centres, 0.24 m to the face.
        let e = SceneTruth::build(&mesh, Some(Pose2::new(2.32, 1.5, 0.0)), &cfg).unwrap_err();
        assert_eq!(
            e.to_string(),
            "spawn (2.32, 1.5) puts the robot's disc (radius 0.25 m, 0.1–1.2 m high) into the scene: move it farther from the nearest surface"
        );
        assert_eq!(e.exit_code(), 2);
        // 0.27 m from the face it is accepted.
        let gt = SceneTruth::build(&mesh, Some(Pose2::new(2.35, 1.5, 0.0)), &cfg).unwrap();
        assert_eq!(gt.spawn, Pose2::new(2.35, 1.5, 0.0));
    }

    #[test]
    fn overhangs_and_high_shelves() {
        // A table top at 0.72–0.76 m is an obstacle column; a shelf at 1.4–1.7 m is not.
        let cfg = Config::default();
        let mut mesh = box_room();
        mesh.push_box([1.0, 1.0, 0.72], [1.6, 1.6, 0.76]);
        mesh.push_box([3.0, 0.1, 1.4], [4.1, 0.4, 1.7]);
        let gt = SceneTruth::build(&mesh, None, &cfg).unwrap();
        let cell = |x: f64, y: f64| gt.grid.index(gt.grid.cell_of(Point2::new(x, y)).unwrap());
        assert!(gt.obstacle_column(cell(1.3, 1.3)));
        assert!(!gt.obstacle_column(cell(3.5, 0.25)));
        let layer7 = 7 * gt.grid.cells() + cell(1.3, 1.3);
        assert!(gt.occupied(layer7) && !gt.occupied(layer7 - 2 * gt.grid.cells()));
    }

    #[test]
    fn results_do_not_depend_on_thread_count() {
        let cfg = Config::default();
        let mesh = box_room();
        let one = crate::util::on_threads(1, || SceneTruth::build(&mesh, None, &cfg).unwrap());
        let many = crate::util::on_threads(3, || SceneTruth::build(&mesh, None, &cfg).unwrap());
        assert_eq!(one.occupied, many.occupied);
        assert_eq!(one.surface, many.surface);
        assert_eq!(one.spawn, many.spawn);
    }
}
