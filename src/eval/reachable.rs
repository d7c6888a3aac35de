//! The reachable region: where the robot can ever be. The floor cells whose centre keeps the
//! planners' inflation radius (`robot.radius_m + map.inflation_margin_m`) from every obstacle
//! column's square, connected to the spawn under the searches' move rule (8-connected, a diagonal
//! step only when both orthogonal cells beside it are open). Real plans have doors narrower than the
//! robot and openings onto the outside: what lies beyond those is not counted against any planner.
//! What the camera can observe from that region is the observable set ([`super::observable`]).

use crate::config::Config;
use crate::grid::{Cell, GridSpec, NEIGHBOURS_8};
use crate::scene::geometry::triangle_meets_cylinder;
use crate::scene::{SceneTruth, TriMesh, VoxelTriangles};
use rayon::prelude::*;

/// The reachable region of one scene and spawn, and the clearance that decides random starts.
#[derive(Clone, Debug)]
pub(crate) struct Reachable {
    /// Distance from each cell centre to the nearest obstacle column's square, metres: exact below
    /// `fit_limit_m`, a lower bound at or above it.
    pub fit_clearance: Vec<f32>,
    pub fit_limit_m: f64,
    pub inflation_m: f64,
    pub mask: Vec<bool>,
    pub cells: usize,
}

impl Reachable {
    /// The region of `truth` reachable from its spawn (`mesh` is the mesh it voxelised).
    pub fn new(mesh: &TriMesh, truth: &SceneTruth, cfg: &Config) -> Reachable {
        let grid = truth.grid;
        let start = grid.index(
            grid.cell_of(truth.spawn.position())
                .expect("spawn is in the grid"),
        );
        let robot_layers = grid.layers_in(cfg.map.band_min_m, cfg.robot.height_m);
        let inflation_m = cfg.robot.radius_m + cfg.map.inflation_margin_m;
        let fit_limit_m = inflation_m + cfg.sim.random_spawn_margin_m + grid.res;
        let obstacle = truth.obstacle_columns();
        let fit_clearance = square_clearance(&grid, obstacle, truth.clearances(), fit_limit_m);
        let body = (
            cfg.map.band_min_m,
            cfg.robot.height_m.min(cfg.map.band_max_m),
        );
        let fits = disc_fits(
            mesh,
            &grid,
            truth.voxel_triangles(),
            obstacle,
            &fit_clearance,
            robot_layers,
            body,
            inflation_m,
        );
        let mask = flood_fill_moves(&grid, &fits, start);
        let cells = mask.iter().filter(|&&r| r).count();
        Reachable {
            fit_clearance,
            fit_limit_m,
            inflation_m,
            mask,
            cells,
        }
    }
}

/// Distance from each cell centre to the nearest obstacle column's square (`[i, i+1)` in cells),
/// metres. Exact where it is below `limit_m`; elsewhere a lower bound of at least `limit_m`. The
/// centre-to-centre `clearance` bounds it from above, and from below by half a cell diagonal, so
/// only cells near an obstacle need the exact local search.
fn square_clearance(
    grid: &GridSpec,
    obstacle: &[bool],
    clearance: &[f32],
    limit_m: f64,
) -> Vec<f32> {
    let res = grid.res;
    let half_diag = std::f64::consts::FRAC_1_SQRT_2;
    (0..grid.cells())
        .into_par_iter()
        .map(|i| {
            let dc = clearance[i] as f64 / res; // cells
            if !dc.is_finite() || dc - half_diag >= limit_m / res {
                return if dc.is_finite() {
                    ((dc - half_diag) * res) as f32
                } else {
                    f32::INFINITY
                };
            }
            if obstacle[i] {
                return 0.0;
            }
            let c = grid.cell(i);
            // The nearest square's centre lies within dc + half a diagonal.
            let r = (dc + half_diag).ceil() as i32;
            let mut best = f64::INFINITY;
            for dy in -r..=r {
                for dx in -r..=r {
                    let Some(j) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) else {
                        continue;
                    };
                    if obstacle[j] {
                        // Gap from the centre (offset 0.5 into the cell) to the square, per axis.
                        let gx = (dx.abs() as f64 - 0.5).max(0.0);
                        let gy = (dy.abs() as f64 - 0.5).max(0.0);
                        best = best.min(gx * gx + gy * gy);
                    }
                }
            }
            (best.sqrt() * res) as f32
        })
        .collect()
}

/// Whether the robot's disc, grown to the inflation radius, fits at each cell centre without
/// touching the mesh between `body.0` and `body.1` (the collision test's height range). Cells whose
/// centre keeps more than the radius from every obstacle column's square fit for certain (every
/// triangle part in the body's layers lies inside such squares); the others, near an obstacle, are
/// decided exactly against the triangles of the obstacle voxels around them.
#[allow(clippy::too_many_arguments)]
fn disc_fits(
    mesh: &TriMesh,
    grid: &GridSpec,
    triangles: &VoxelTriangles,
    obstacle: &[bool],
    square_clearance: &[f32],
    body_layers: std::ops::Range<usize>,
    body: (f64, f64),
    radius: f64,
) -> Vec<bool> {
    let reach = (radius / grid.res).ceil() as i32 + 1;
    // The columns whose square comes within the radius of a cell's centre (a little more, against
    // rounding): a triangle meets the disc's cylinder only inside such a column, and it is listed
    // in every voxel it overlaps.
    let squares_within: Vec<(i32, i32)> = (-reach..=reach)
        .flat_map(|dy| (-reach..=reach).map(move |dx| (dx, dy)))
        .filter(|&(dx, dy)| {
            let gap = |d: i32| (d.abs() as f64 - 0.5).max(0.0) * grid.res;
            gap(dx).hypot(gap(dy)) <= radius + 1e-6
        })
        .collect();
    (0..grid.cells())
        .into_par_iter()
        .map_init(Vec::new, |near: &mut Vec<u32>, i| {
            if square_clearance[i] as f64 > radius {
                return true;
            }
            if obstacle[i] {
                return false;
            }
            let c = grid.cell(i);
            near.clear();
            for &(dx, dy) in &squares_within {
                let Some(j) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) else {
                    continue;
                };
                if obstacle[j] {
                    for iz in body_layers.clone() {
                        near.extend_from_slice(triangles.of(iz * grid.cells() + j));
                    }
                }
            }
            near.sort_unstable();
            near.dedup();
            let p = grid.center(c);
            !near.iter().any(|&t| {
                let tri = mesh.triangles[t as usize].map(|k| {
                    let v = mesh.vertices[k as usize];
                    [v.x as f64, v.y as f64, v.z as f64]
                });
                triangle_meets_cylinder(tri, p.x, p.y, radius, body.0, body.1)
            })
        })
        .collect()
}

/// The cells reachable from `start` through `open` cells under the searches' move rule:
/// 8-connected, a diagonal step only when both orthogonal cells beside it are open. `start` itself is
/// included even when it is not open (a spawn just inside an inflation band can still drive out).
fn flood_fill_moves(grid: &GridSpec, open: &[bool], start: usize) -> Vec<bool> {
    let mut seen = vec![false; grid.cells()];
    seen[start] = true;
    let mut stack = vec![start];
    let is_open = |c: Cell| grid.checked_index(c).filter(|&j| open[j]);
    while let Some(i) = stack.pop() {
        let c = grid.cell(i);
        for (dx, dy) in NEIGHBOURS_8 {
            let Some(j) = is_open(Cell::new(c.x + dx, c.y + dy)) else {
                continue;
            };
            if dx != 0
                && dy != 0
                && (is_open(Cell::new(c.x + dx, c.y)).is_none()
                    || is_open(Cell::new(c.x, c.y + dy)).is_none())
            {
                continue;
            }
            if !seen[j] {
                seen[j] = true;
                stack.push(j);
            }
        }
    }
    seen
}
