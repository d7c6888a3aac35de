//! The reachable region: where the robot can ever be.
//!
//! **The promise.** A floor cell is reachable when the robot's own map, having seen every surface
//! exactly, would let it stand there, and it is connected to the spawn under the searches' move rule
//! (8-connected, a diagonal step only when both orthogonal cells beside it are open). The map
//! inflates a cell whose centre lies within the planners' inflation radius (`robot.radius_m +
//! map.inflation_margin_m`) of an obstacle column's box, the box grown to every ray hit in the
//! column's robot band ([`ObstacleBox`]); the ground truth applies the same rule
//! ([`ObstacleBox::inflates`]) to the box of the true surface in each such column. A hit lies on the
//! surface, so the map's boxes are never larger than these: where the ground truth says the robot
//! fits, a map that has seen the walls around says so too, and a door the ground truth counts as
//! passable is one the robot's map can pass. The unit test `a_map_that_has_seen_every_surface_passes_where_the_ground_truth_does`
//! holds the two to it. Real plans have doors narrower than the robot and openings onto the
//! outside: what lies beyond those is not counted against any planner. What the camera can observe
//! from that region is the observable set ([`super::observable`]).

use crate::config::Config;
use crate::grid::{Cell, GridSpec, NEIGHBOURS_8};
use crate::map::occupancy::{cell_square, ObstacleBox};
use crate::scene::geometry::triangle_extent_in_box;
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
        let boxes = surface_boxes(mesh, &grid, truth.voxel_triangles(), obstacle, robot_layers);
        let fits = box_fits(&grid, &boxes, &fit_clearance, inflation_m);
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

/// Per column, the box of the true surface inside it: the x and y extent of the mesh within the
/// column's square (closed, to a micrometre) and the robot band's layers (`body_layers`), grown by
/// the slack and kept inside the cell exactly as the map grows its box to each ray hit there
/// ([`ObstacleBox::grow_to`]). A hit lies on that surface, so a map's box is never larger than this
/// one. `None` where no surface lies in the column.
fn surface_boxes(
    mesh: &TriMesh,
    grid: &GridSpec,
    triangles: &VoxelTriangles,
    obstacle: &[bool],
    body_layers: std::ops::Range<usize>,
) -> Vec<Option<ObstacleBox>> {
    let (z_lo, z_hi) = (
        body_layers.start as f64 * grid.res,
        body_layers.end as f64 * grid.res,
    );
    (0..grid.cells())
        .into_par_iter()
        .map_init(Vec::new, |tris: &mut Vec<u32>, i| {
            let c = grid.cell(i);
            // A face on a cell line lies in the columns on both sides (a hit on it may round into
            // either), but the voxelisation may list it on one side only.
            let near_obstacle = std::iter::once((0, 0))
                .chain(NEIGHBOURS_8)
                .filter_map(|(dx, dy)| grid.checked_index(Cell::new(c.x + dx, c.y + dy)))
                .any(|j| obstacle[j]);
            if !near_obstacle {
                return None;
            }
            let centre = grid.center(c);
            // A micrometre wider than the column: a face on a cell line belongs to the columns on
            // both sides, whichever the rounding of a hit's floor puts it in.
            let h = 0.5 * grid.res + 1e-6;
            let lo = [centre.x - h, centre.y - h, z_lo - 1e-6];
            let hi = [centre.x + h, centre.y + h, z_hi + 1e-6];
            tris.clear();
            for (dx, dy) in std::iter::once((0, 0)).chain(NEIGHBOURS_8) {
                let Some(j) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) else {
                    continue;
                };
                for iz in body_layers.clone() {
                    tris.extend_from_slice(triangles.of(iz * grid.cells() + j));
                }
            }
            tris.sort_unstable();
            tris.dedup();
            let square = cell_square(grid, c);
            let mut b = ObstacleBox::EMPTY;
            for &t in tris.iter() {
                let tri = mesh.triangles[t as usize].map(|k| {
                    let v = mesh.vertices[k as usize];
                    [v.x as f64, v.y as f64, v.z as f64]
                });
                if let Some((min, max)) = triangle_extent_in_box(tri, lo, hi) {
                    b.grow_to(square, min[0] as f32, min[1] as f32);
                    b.grow_to(square, max[0] as f32, max[1] as f32);
                }
            }
            // An occupied voxel's triangles touch it; a column whose parts all lie on its faces
            // still gets their extent, so an empty box means no triangle there at all.
            (!b.is_empty()).then_some(b)
        })
        .collect()
}

/// How much nearer than the true surface a map's box may lie: its hits are `f32`, whose spacing is
/// under 0.1 mm up to 1 km from the origin. The ground truth inflates by this much more, so that a
/// door the rounding of hits closes by a hair is not counted as passable.
const HIT_ROUNDING_M: f64 = 1e-4;

/// Whether the robot may stand at each cell centre under the map's inflation rule applied to the
/// true surface: no column's surface box ([`surface_boxes`]) inflates it
/// ([`ObstacleBox::inflates`], the radius [`HIT_ROUNDING_M`] larger). Cells whose centre keeps more
/// than that from every obstacle column's square fit for certain (a box lies in its square).
fn box_fits(
    grid: &GridSpec,
    boxes: &[Option<ObstacleBox>],
    square_clearance: &[f32],
    inflation_m: f64,
) -> Vec<bool> {
    let inflation_m = inflation_m + HIT_ROUNDING_M;
    let reach = (inflation_m / grid.res).ceil() as i32 + 1;
    (0..grid.cells())
        .into_par_iter()
        .map(|i| {
            if square_clearance[i] as f64 > inflation_m {
                return true;
            }
            let c = grid.cell(i);
            let p = grid.center(c);
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let Some(j) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) else {
                        continue;
                    };
                    if boxes[j].is_some_and(|b| b.inflates(p, inflation_m)) {
                        return false;
                    }
                }
            }
            true
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::GroundTruth;
    use crate::map::testing::seen_from;
    use crate::scene::doorway::{doorway, DoorKind};
    use crate::sensor::MeshBvh;
    use crate::Pose2;

    /// The promise of the module doc, on doors across the threshold: every box a map grows to its
    /// ray hits lies inside the ground truth's box of that column (to f32 rounding), so no such box
    /// inflates a cell where the ground truth says the robot fits; and the doors the ground truth
    /// passes, the map seen from both rooms passes too.
    #[test]
    fn a_map_that_has_seen_every_surface_passes_where_the_ground_truth_does() {
        let cfg = Config::default();
        let inflation_m = cfg.robot.radius_m + cfg.map.inflation_margin_m;
        let mut passable = [0, 0];
        for (kind, width, offset) in [
            (DoorKind::Thin, 0.60, 0.0),
            (DoorKind::Thin, 0.64, 0.025),
            (DoorKind::Thin, 0.68, 0.05),
            (DoorKind::Thick, 0.70, 0.075),
            (DoorKind::LJamb, 0.72, 0.03),
            (DoorKind::Corridor, 0.76, 0.0),
        ] {
            let scene = doorway(kind, width, offset);
            let gt = GroundTruth::build(&scene.mesh, Some(scene.spawn), &cfg).unwrap();
            let grid = gt.grid;
            let bvh = MeshBvh::new(&scene.mesh).unwrap();
            // Both rooms looked at from a ring of places, each turning once.
            let poses = [1.0, 2.0, 2.6, 4.0, 4.6, 5.5]
                .into_iter()
                .flat_map(|x| [0.8, 1.6, 2.4].map(|y| (x, y)))
                .flat_map(|(x, y)| {
                    (0..16).map(move |k| Pose2::new(x, y, k as f64 * std::f64::consts::FRAC_PI_8))
                });
            let map = seen_from(grid, &cfg, &bvh, poses);
            let robot = grid.layers_in(cfg.map.band_min_m, cfg.robot.height_m);
            let boxes = surface_boxes(
                &scene.mesh,
                &grid,
                gt.voxel_triangles(),
                gt.obstacle_columns(),
                robot,
            );
            let hit_boxes: Vec<(usize, ObstacleBox)> = (0..grid.cells())
                .map(|i| (i, map.occupancy().obstacle_box(i)))
                .filter(|(_, b)| !b.is_empty())
                .collect();
            assert!(hit_boxes.len() > 100);
            for &(i, m) in &hit_boxes {
                let g = boxes[i]
                    .unwrap_or_else(|| panic!("{kind:?} {width}: hits off the surface at {i}"));
                let tol = 1e-6;
                assert!(
                    g.min[0] <= m.min[0] + tol
                        && g.min[1] <= m.min[1] + tol
                        && g.max[0] >= m.max[0] - tol
                        && g.max[1] >= m.max[1] - tol,
                    "{kind:?} {width} {offset}: column {i}: hits {m:?}, surface {g:?}"
                );
            }
            for c in (0..grid.cells()).filter(|&c| gt.reachable(c)) {
                let p = grid.center(grid.cell(c));
                for &(_, m) in &hit_boxes {
                    assert!(!m.inflates(p, inflation_m), "{kind:?} {width}: cell {c}");
                }
            }
            let far = grid.index(grid.cell_of(scene.far_room).unwrap());
            let through = gt.reachable(far);
            passable[usize::from(through)] += 1;
            if through {
                // The map passes the door: the far room is reachable over traversable cells.
                let start = grid.index(grid.cell_of(scene.spawn.position()).unwrap());
                let open: Vec<bool> = (0..grid.cells()).map(|i| map.is_traversable(i)).collect();
                assert!(
                    flood_fill_moves(&grid, &open, start)[far],
                    "{kind:?} {width} {offset}"
                );
            }
        }
        // Doors on both sides of the threshold.
        assert!(passable[0] > 0 && passable[1] > 0, "{passable:?}");
    }
}
