//! Where the camera is sampled: one position per reachable patch of each lattice square, and the
//! second, finer pass around positions that look beyond the reachable region.

use super::GroundTruth;
use crate::grid::{Cell, GridSpec, NEIGHBOURS_8};
use rayon::prelude::*;

/// One sample cell per 8-connected patch of reachable cells in each square of `k` × `k` cells whose
/// first cell `(bx, by)` passes `want`: the patch cell nearest the patch centroid (ties: lowest
/// index). Ascending.
pub(super) fn sample_positions(
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
pub(super) fn lattice_cells(grid: &GridSpec, spacing_m: f64) -> usize {
    ((spacing_m / grid.res).round() as usize).max(1)
}

/// How much of the space beyond the reachable region (see [`beyond_cells`]) one sample position
/// must see, m³, for the squares around it to be sampled again on the finer lattice. A view through
/// a narrow door into a room holds several m³; the views through the open outer doors of
/// `office_large` onto the thin strip of grid outside the building hold under 0.2 m³, and refining
/// those would triple that scene's cost for nothing (what GREEDY explores there is already inside
/// the set).
pub(super) const REFINE_BEYOND_M3: f64 = 0.2;

/// Floor cells that are free (no obstacle column) and lie beyond the reachable region: farther than
/// the inflation radius plus two cells from every reachable cell. The free cells between the
/// reachable region and the walls around it are within that distance; what is left is space behind
/// gaps too narrow to pass (a room behind a narrow door, a slot beside furniture, the outside seen
/// through a door), which the camera sees only through the gap, so from a narrow set of positions.
pub(super) fn beyond_cells(gt: &GroundTruth) -> Vec<bool> {
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
pub(super) fn beyond_voxels(marks: &mut [(usize, u64)], band: u64) -> usize {
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
pub(super) fn min_beyond_voxels(grid: &GridSpec) -> usize {
    ((REFINE_BEYOND_M3 / grid.voxel_volume()).ceil() as usize).max(1)
}

/// The second pass of the sampling, where the view depends strongly on the position: around every
/// coarse position that looked beyond the reachable region (through a gap too narrow to pass), the
/// squares of the coarse lattice around it (3 × 3) are sampled again on a lattice of half the side.
/// Positions already sampled are left out. Ascending.
pub(super) fn refined_positions(
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
