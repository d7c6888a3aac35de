//! Clearance (distance to the nearest obstacle cell) queried per cell instead of a full distance
//! transform every key frame: the field needs it only at its degenerate points and along the few
//! climbs of topological control, a few hundred cells against the whole grid.

use crate::grid::{Cell, CellRect, GridSpec};
use std::sync::Arc;

/// Block edge, cells.
const BLOCK: i32 = 8;

/// The obstacle layer with a count of obstacle cells per 8×8 block, so that a nearest-obstacle
/// query skips empty blocks. The mask is shared (`Arc`) so that a topology graph built later can
/// keep the layer of its own key frame without a copy.
#[derive(Clone, Debug)]
pub struct ObstacleIndex {
    grid: GridSpec,
    obstacle: Arc<Vec<bool>>,
    counts: Vec<u32>,
    bx: i32,
}

impl ObstacleIndex {
    /// The index of the cells of `within` where `is_obstacle` holds (none outside it).
    pub fn from_fn(
        grid: GridSpec,
        within: CellRect,
        mut is_obstacle: impl FnMut(usize) -> bool,
    ) -> Self {
        let bx = (grid.nx as i32 + BLOCK - 1) / BLOCK;
        let by = (grid.ny as i32 + BLOCK - 1) / BLOCK;
        let mut counts = vec![0u32; (bx * by) as usize];
        let mut obstacle = vec![false; grid.cells()];
        let within = within.clip(&grid);
        for (c, i) in within.cells(&grid) {
            if is_obstacle(i) {
                obstacle[i] = true;
                counts[(c.y / BLOCK * bx + c.x / BLOCK) as usize] += 1;
            }
        }
        ObstacleIndex {
            grid,
            obstacle: Arc::new(obstacle),
            counts,
            bx,
        }
    }

    /// The obstacle flags, one per cell of the grid.
    pub fn mask(&self) -> &Arc<Vec<bool>> {
        &self.obstacle
    }

    /// Squared distance, in cells², from `c` to the nearest obstacle cell (`None` if there is none):
    /// the same exact integer minimum as [`crate::grid::distance_transform`].
    pub fn nearest_d2(&self, c: Cell) -> Option<i64> {
        let (px, py) = (c.x.div_euclid(BLOCK), c.y.div_euclid(BLOCK));
        let mut best = i64::MAX;
        let by = self.counts.len() as i32 / self.bx;
        let max_ring = self.bx.max(by) + 1;
        for ring in 0..=max_ring {
            for y in (py - ring)..=(py + ring) {
                if y < 0 || y >= by {
                    continue;
                }
                for x in (px - ring)..=(px + ring) {
                    if (x - px).abs() != ring && (y - py).abs() != ring {
                        continue;
                    }
                    if x < 0 || x >= self.bx || self.counts[(y * self.bx + x) as usize] == 0 {
                        continue;
                    }
                    let x1 = ((x + 1) * BLOCK).min(self.grid.nx as i32);
                    let y1 = ((y + 1) * BLOCK).min(self.grid.ny as i32);
                    for cy in y * BLOCK..y1 {
                        let row = cy as usize * self.grid.nx;
                        let dy = i64::from(cy - c.y);
                        for cx in x * BLOCK..x1 {
                            if self.obstacle[row + cx as usize] {
                                let dx = i64::from(cx - c.x);
                                best = best.min(dx * dx + dy * dy);
                            }
                        }
                    }
                }
            }
            // Cells of ring + 1 are at least ring·BLOCK + 1 cells away along x or y.
            let next = i64::from(ring * BLOCK + 1);
            if best <= next * next {
                break;
            }
        }
        (best != i64::MAX).then_some(best)
    }

    /// Clearance of cell index `i`, metres: `sqrt(d²)·res` of the exact distance transform
    /// ([`crate::grid::distance_transform`]; ∞ without obstacles).
    pub fn clearance(&self, i: usize) -> f64 {
        self.nearest_d2(self.grid.cell(i))
            .map_or(f64::INFINITY, |d2| (d2 as f64).sqrt() * self.grid.res)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point2;

    #[test]
    fn queries_equal_the_full_distance_transform() {
        let grid = GridSpec::covering(Point2::new(0.0, 0.0), Point2::new(4.1, 3.3), 1.0, 0.05);
        let mut mask = vec![false; grid.cells()];
        // Empty, a pseudo-random scatter plus a wall, then some of it cleared again.
        let mut state = 12345u64;
        for round in 0..4 {
            if round > 0 {
                for _ in 0..40 {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    mask[(state >> 33) as usize % grid.cells()] = round != 3;
                }
                for x in 10..60 {
                    mask[grid.index(Cell::new(x, 30))] = round < 3;
                }
            }
            let index = ObstacleIndex::from_fn(grid, CellRect::all(&grid), |i| mask[i]);
            let full = crate::grid::distance_transform(&mask, grid.nx, grid.ny);
            for (i, &d2) in full.iter().enumerate() {
                let d = d2.sqrt() * grid.res;
                assert_eq!(index.clearance(i), d, "round {round} cell {i}");
            }
        }
    }
}
