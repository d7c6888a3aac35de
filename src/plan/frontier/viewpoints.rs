//! Where to look at a frontier from: rings of reachable floor cells around it, and the first from
//! which the camera sees the unknown voxels beside it ([`crate::map::sight`]).

use crate::config::CameraConfig;
use crate::grid::{Cell, GridSpec};
use crate::map::occupancy::VoxelState;
use crate::map::sight::{camera_sees, Sight};
use crate::map::Map;
use crate::plan::search::DistanceField;
use nalgebra::Point2;

/// For the frontier cell `aim` in the camera's blind zone: the least-cost traversable cell `view_m`
/// to `2·view_m` from it from which the camera surely, then possibly, sees the floor beside it
/// ([`FrontierVisits::sighted_viewpoint`]'s first and third tiers); if none of that ring does, the
/// least-cost cell of the ring.
pub fn blind_zone_viewpoint(
    map: &Map,
    df: &DistanceField,
    aim: usize,
    view_m: f64,
    camera: &CameraConfig,
) -> Option<usize> {
    let ring = viewpoint_ring(map, df, aim, view_m, 2.0 * view_m);
    let lowest = lowest_unknown_beside(map, aim);
    first_sighted(map, &ring, &lowest, camera, Sight::Sure)
        .or_else(|| first_sighted(map, &ring, &lowest, camera, Sight::Possible))
        .or(ring.first().map(|&(_, v)| v))
}

/// The cells of `ring` farther than `away_m` from every point of `from`.
pub(super) fn away_from(
    grid: &GridSpec,
    from: &[Point2<f64>],
    ring: &[(f32, usize)],
    away_m: f64,
) -> Vec<(f32, usize)> {
    (ring.iter().copied())
        .filter(|&(_, v)| {
            let p = grid.center(grid.cell(v));
            from.iter().all(|f| (p - f).norm() > away_m)
        })
        .collect()
}

/// The reachable traversable cells `from_m` to `to_m` from `aim`, by cost (then index).
pub(super) fn viewpoint_ring(
    map: &Map,
    df: &DistanceField,
    aim: usize,
    from_m: f64,
    to_m: f64,
) -> Vec<(f32, usize)> {
    let grid = map.grid();
    let f = grid.center(grid.cell(aim));
    let mut ring: Vec<(f32, usize)> = (0..grid.cells())
        .filter(|&i| map.is_traversable(i))
        .filter_map(|i| {
            let d = (grid.center(grid.cell(i)) - f).norm();
            (d >= from_m && d <= to_m)
                .then(|| df.cost_to(i).map(|c| (c, i)))
                .flatten()
        })
        .collect();
    ring.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    ring
}

/// The first cell of `ring` from which the camera sees one of the voxels `targets` (as sure as
/// `sight`).
pub(super) fn first_sighted(
    map: &Map,
    ring: &[(f32, usize)],
    targets: &[usize],
    camera: &CameraConfig,
    sight: Sight,
) -> Option<usize> {
    ring.iter().map(|&(_, v)| v).find(|&v| {
        targets
            .iter()
            .any(|&t| camera_sees(map, v, t, camera, sight))
    })
}

/// The Unknown 4-neighbour columns of `cell`.
fn unknown_columns_beside(map: &Map, cell: usize) -> impl Iterator<Item = usize> + '_ {
    let grid = map.grid();
    let c = grid.cell(cell);
    crate::grid::NEIGHBOURS_8[..4]
        .iter()
        .filter_map(move |&(dx, dy)| grid.checked_index(Cell::new(c.x + dx, c.y + dy)))
        .filter(|&j| map.is_unknown(j))
}

/// The unknown voxels of column `j` above the floor layer, lowest first.
fn unknown_voxels_of(map: &Map, j: usize) -> impl Iterator<Item = usize> + '_ {
    let occ = map.occupancy();
    let grid = occ.grid();
    (1..grid.nz)
        .map(move |iz| grid.voxel_index(grid.cell(j), iz))
        .filter(|&v| occ.state(v) == VoxelState::Unknown)
}

/// The lowest unknown voxel above the floor layer of each Unknown 4-neighbour column of `cell`.
pub(super) fn lowest_unknown_beside(map: &Map, cell: usize) -> Vec<usize> {
    unknown_columns_beside(map, cell)
        .filter_map(|j| unknown_voxels_of(map, j).next())
        .collect()
}

/// Every unknown voxel above the floor layer of each Unknown 4-neighbour column of `cell`.
pub(super) fn unknown_beside(map: &Map, cell: usize) -> Vec<usize> {
    unknown_columns_beside(map, cell)
        .flat_map(|j| unknown_voxels_of(map, j))
        .collect()
}

/// Whether no obstacle cell lies on the straight line between two cell centres (sampled every half
/// cell).
pub fn line_of_sight(map: &Map, grid: &GridSpec, a: usize, b: usize) -> bool {
    let (pa, pb) = (grid.center(grid.cell(a)), grid.center(grid.cell(b)));
    let steps = (((pb - pa).norm() / (0.5 * grid.res)).ceil() as usize).max(1);
    (0..=steps).all(|s| {
        let p = pa + (pb - pa) * (s as f64 / steps as f64);
        grid.cell_of(p)
            .is_some_and(|c| !map.is_obstacle(grid.index(c)))
    })
}
