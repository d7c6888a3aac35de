//! The map against the ground truth: how well a map built from noisy frames at an estimated pose
//! matches the scene. Reported when noise is on (`[noise]`); with exact frames at the true pose
//! the map agrees with the ground truth by construction, up to the voxelisation.

use super::{GroundTruth, ObservableSet};
use crate::grid::{Cell, GridSpec};
use crate::map::{Map, VoxelState};

/// How the map's voxels agree with the ground truth's, in the height band.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapQuality {
    /// Share of the map's occupied band voxels with a truly occupied voxel within one voxel (the
    /// 26 neighbours and itself); 1 when the map has none.
    pub precision: f64,
    /// Share of the observable surface voxels with an occupied map voxel within one voxel; 0 when
    /// there are none.
    pub recall: f64,
    /// Share of the map's known-free band voxels that are truly occupied (exactly that voxel):
    /// space the robot believes it may pass through that holds the scene; 0 when none is free.
    pub free_but_occupied: f64,
}

/// Whether `pred` holds for voxel `v` or one of its 26 neighbours inside the grid's layers
/// `layers`.
fn within_one(
    grid: &GridSpec,
    v: usize,
    layers: &std::ops::Range<usize>,
    pred: impl Fn(usize) -> bool,
) -> bool {
    let (cell, layer) = grid.voxel_parts(v);
    let c = grid.cell(cell);
    for dz in -1i64..=1 {
        let z = layer as i64 + dz;
        if z < layers.start as i64 || z >= layers.end as i64 {
            continue;
        }
        for dy in -1..=1 {
            for dx in -1..=1 {
                let n = Cell {
                    x: c.x + dx,
                    y: c.y + dy,
                };
                if grid.contains(n) && pred(grid.voxel_index(n, z as usize)) {
                    return true;
                }
            }
        }
    }
    false
}

/// The map's quality against the ground truth, over the height band's layers.
pub fn map_quality(gt: &GroundTruth, observable: &ObservableSet, map: &Map) -> MapQuality {
    let grid = gt.grid;
    let band = gt.band_layers();
    let cells = grid.cells();
    let (mut occupied, mut true_hits, mut free, mut free_hits) = (0u64, 0u64, 0u64, 0u64);
    for v in band.start * cells..band.end * cells {
        match map.voxel_state(v) {
            VoxelState::Occupied => {
                occupied += 1;
                true_hits += u64::from(within_one(&grid, v, &band, |u| gt.occupied(u)));
            }
            VoxelState::Free => {
                free += 1;
                free_hits += u64::from(gt.occupied(v));
            }
            VoxelState::Unknown => {}
        }
    }
    let surface = observable.surface_voxels();
    let found = surface
        .iter()
        .filter(|&&v| {
            within_one(&grid, v as usize, &band, |u| {
                map.voxel_state(u) == VoxelState::Occupied
            })
        })
        .count();
    let share = |a: u64, b: u64, empty: f64| if b == 0 { empty } else { a as f64 / b as f64 };
    MapQuality {
        precision: share(true_hits, occupied, 1.0),
        recall: share(found as u64, surface.len() as u64, 0.0),
        free_but_occupied: share(free_hits, free, 0.0),
    }
}
