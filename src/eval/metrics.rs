//! Run metrics (the guide's "Metrics" section defines them): explored volume and completeness (counted incrementally
//! from the voxels each frame makes known), surface coverage, the unseen observable patches and the
//! frontiers left at the end. Path length, collisions and stage timings are the simulator's
//! (`sim::RunResult`).

use super::ground_truth::GroundTruth;
use super::observable::ObservableSet;
use crate::grid::{Cell, GridSpec, NEIGHBOURS_8};
use crate::map::Map;
use serde::{Deserialize, Serialize};

/// Explored volume and completeness, counted incrementally: a voxel counts once, when it first
/// becomes known, if it lies in the height band (ε); it also counts towards completeness if it is
/// observable (see [`ObservableSet`]).
pub struct ExploredVolume {
    known_in_band: u64,
    known_observable: u64,
    observable_voxels: u64,
    voxel_volume: f64,
    band: std::ops::Range<usize>,
}

impl ExploredVolume {
    pub fn new(gt: &GroundTruth, observable: &ObservableSet) -> Self {
        ExploredVolume {
            known_in_band: 0,
            known_observable: 0,
            observable_voxels: observable.voxels() as u64,
            voxel_volume: gt.grid.voxel_volume(),
            band: gt.band_layers(),
        }
    }

    /// Counts the voxels a frame made known.
    pub fn add(&mut self, gt: &GroundTruth, observable: &ObservableSet, newly_known: &[u32]) {
        for &v in newly_known {
            let (_, layer) = gt.grid.voxel_parts(v as usize);
            if self.band.contains(&layer) {
                self.known_in_band += 1;
                self.known_observable += observable.contains(v as usize) as u64;
            }
        }
    }

    /// ε: known voxels in the height band, m³.
    pub fn volume_m3(&self) -> f64 {
        self.known_in_band as f64 * self.voxel_volume
    }

    /// Known observable voxels over all observable voxels (0 when nothing is observable).
    pub fn completeness(&self) -> f64 {
        if self.observable_voxels == 0 {
            0.0
        } else {
            self.known_observable as f64 / self.observable_voxels as f64
        }
    }

    /// Share of the known band voxels that the observable set does not hold: how much the sampling
    /// of the observable set missed (0 when nothing is known).
    pub fn outside_observable_fraction(&self) -> f64 {
        if self.known_in_band == 0 {
            0.0
        } else {
            (self.known_in_band - self.known_observable) as f64 / self.known_in_band as f64
        }
    }
}

/// Observed surface voxels (known in the map) over the observable surface voxels.
pub fn surface_coverage(observable: &ObservableSet, map: &Map) -> f64 {
    let surface = observable.surface_voxels();
    if surface.is_empty() {
        return 0.0;
    }
    let seen = surface
        .iter()
        .filter(|&&v| map.is_voxel_known(v as usize))
        .count();
    seen as f64 / surface.len() as f64
}

/// A connected patch of observable voxels that the run left unseen (columns 8-connected on the floor
/// plan): where the observable region still holds something, and how much.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UnseenPatch {
    /// Centroid of the patch's columns, metres.
    pub x: f64,
    pub y: f64,
    pub volume_m3: f64,
    /// Lowest and highest unseen voxel, metres above the floor (voxel bottoms and tops).
    pub z_min_m: f64,
    pub z_max_m: f64,
    /// Whether some column of the patch is reachable floor (else it lies over furniture, walls or
    /// floor the robot cannot stand on).
    pub over_reachable_floor: bool,
}

/// Patches reported per run, largest first.
pub const UNSEEN_PATCHES: usize = 5;

/// Unseen observable voxels per column: for each cell, how many band voxels of its column are
/// observable and not known in `map`, and the lowest and highest such layer.
fn unseen_columns(
    gt: &GroundTruth,
    observable: &ObservableSet,
    map: &Map,
) -> (Vec<u32>, Vec<(u32, u32)>) {
    let cells = gt.grid.cells();
    let mut count = vec![0u32; cells];
    let mut layers = vec![(u32::MAX, 0u32); cells];
    for iz in gt.band_layers() {
        for c in 0..cells {
            let v = iz * cells + c;
            if observable.contains(v) && !map.is_voxel_known(v) {
                count[c] += 1;
                layers[c].0 = layers[c].0.min(iz as u32);
                layers[c].1 = layers[c].1.max(iz as u32);
            }
        }
    }
    (count, layers)
}

/// The 8-connected groups of the cells with `member` set, each in the order a depth-first walk
/// from its lowest cell visits them; groups ordered by lowest cell.
fn groups_8(grid: &GridSpec, member: impl Fn(usize) -> bool) -> Vec<Vec<usize>> {
    let cells = grid.cells();
    let mut seen = vec![false; cells];
    let mut groups = Vec::new();
    for start in 0..cells {
        if seen[start] || !member(start) {
            continue;
        }
        seen[start] = true;
        let mut stack = vec![start];
        let mut group = Vec::new();
        while let Some(i) = stack.pop() {
            group.push(i);
            let c = grid.cell(i);
            for (dx, dy) in NEIGHBOURS_8 {
                if let Some(j) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) {
                    if !seen[j] && member(j) {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        groups.push(group);
    }
    groups
}

/// The largest patches of observable voxels that `map` does not know, largest first (at most
/// [`UNSEEN_PATCHES`]).
pub fn unseen_patches(gt: &GroundTruth, observable: &ObservableSet, map: &Map) -> Vec<UnseenPatch> {
    let grid = gt.grid;
    let (count, layers) = unseen_columns(gt, observable, map);
    let mut patches: Vec<UnseenPatch> = groups_8(&grid, |c| count[c] > 0)
        .into_iter()
        .map(|group| {
            let (mut n, mut sx, mut sy, mut lo, mut hi, mut reach) =
                (0u64, 0.0, 0.0, u32::MAX, 0, false);
            for i in group {
                let p = grid.center(grid.cell(i));
                n += count[i] as u64;
                sx += p.x * count[i] as f64;
                sy += p.y * count[i] as f64;
                lo = lo.min(layers[i].0);
                hi = hi.max(layers[i].1);
                reach |= gt.reachable(i);
            }
            UnseenPatch {
                x: sx / n as f64,
                y: sy / n as f64,
                volume_m3: n as f64 * grid.voxel_volume(),
                z_min_m: lo as f64 * grid.res,
                z_max_m: (hi + 1) as f64 * grid.res,
                over_reachable_floor: reach,
            }
        })
        .collect();
    patches.sort_by(|a, b| {
        b.volume_m3
            .total_cmp(&a.volume_m3)
            .then(a.x.total_cmp(&b.x))
            .then(a.y.total_cmp(&b.y))
    });
    patches.truncate(UNSEEN_PATCHES);
    patches
}

/// An 8-connected group of frontier cells a run left (see [`frontiers_left`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrontierGroup {
    /// Number of frontier cells in the group.
    pub cells: u64,
    /// Centroid of the cells' centres, metres.
    pub x: f64,
    pub y: f64,
}

/// Frontier groups reported per run, largest first (as many as unseen patches).
pub const FRONTIER_GROUPS: usize = UNSEEN_PATCHES;

/// What [`frontiers_left`] counts.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrontiersLeft {
    /// Frontier cells left, in all groups.
    pub cells: u64,
    /// The largest groups, largest first (at most [`FRONTIER_GROUPS`]).
    pub groups: Vec<FrontierGroup>,
}

/// The frontiers a run left that it could have reached and that show observable space: the cells
/// `map` flags as frontier (free, outside known obstacles' inflation, with a 4-neighbour in state
/// Unknown) that lie in the ground truth's reachable region and have a 4-neighbour in state Unknown
/// whose column holds an observable voxel `map` does not know. Returns their number and their
/// largest 8-connected groups.
pub fn frontiers_left(gt: &GroundTruth, observable: &ObservableSet, map: &Map) -> FrontiersLeft {
    let grid = gt.grid;
    let (unseen, _) = unseen_columns(gt, observable, map);
    let left = |i: usize| {
        map.is_frontier(i) && gt.reachable(i) && {
            let c = grid.cell(i);
            NEIGHBOURS_8[..4].iter().any(|&(dx, dy)| {
                grid.checked_index(Cell::new(c.x + dx, c.y + dy))
                    .is_some_and(|j| map.is_unknown(j) && unseen[j] > 0)
            })
        }
    };
    let groups = groups_8(&grid, left);
    let mut out: Vec<FrontierGroup> = groups
        .iter()
        .map(|group| {
            let (sx, sy) = group.iter().fold((0.0, 0.0), |(sx, sy), &i| {
                let p = grid.center(grid.cell(i));
                (sx + p.x, sy + p.y)
            });
            let n = group.len() as f64;
            FrontierGroup {
                cells: group.len() as u64,
                x: sx / n,
                y: sy / n,
            }
        })
        .collect();
    out.sort_by(|a, b| {
        b.cells
            .cmp(&a.cells)
            .then(a.x.total_cmp(&b.x))
            .then(a.y.total_cmp(&b.y))
    });
    out.truncate(FRONTIER_GROUPS);
    FrontiersLeft {
        cells: groups.iter().map(|g| g.len() as u64).sum(),
        groups: out,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 × 4 m room (inside x, y ∈ [0.1, 4.1]) and a 2 × 2 m closet east of it (x ∈ [4.2, 6.2],
    /// y ∈ [0.1, 2.1]) behind a 0.5 m door narrower than the inflated robot: the closet is not
    /// reachable.
    fn room_and_closet() -> crate::scene::TriMesh {
        let (nx, ny) = (64, 42);
        let solid: Vec<bool> = (0..nx * ny)
            .map(|i| {
                let (x, y) = (i % nx, i / nx);
                let room = (1..41).contains(&x) && (1..41).contains(&y);
                let closet = (42..62).contains(&x) && (1..21).contains(&y);
                let door = x == 41 && (8..13).contains(&y);
                !(room || closet || door)
            })
            .collect();
        crate::scene::extrude::extrude_grid(&solid, nx, ny, [0.0, 0.0], 0.1, 2.5)
    }

    /// Frontier cells left, on a map whose free cells are single footprint cells placed by hand, an
    /// observable set of a few voxels placed by hand, and one observable voxel the map knows from a
    /// one-ray frame: which frontier cells count, and how they group, is known by construction.
    #[test]
    fn frontiers_left_counts_reachable_frontiers_beside_unseen_observable_columns() {
        use crate::config::Config;
        use crate::map::CellState;
        use crate::sensor::DepthFrame;
        use crate::Pose2;
        use nalgebra::{Point3, Vector3};

        let cfg = Config::default();
        let gt =
            GroundTruth::build(&room_and_closet(), Some(Pose2::new(2.0, 2.0, 0.0)), &cfg).unwrap();
        let grid = gt.grid;
        let cell = |x: f64, y: f64| grid.index(grid.cell_at(x, y));
        // A band layer above the robot's body (1.5–1.6 m): a known voxel there leaves its column's
        // 2D state Unknown.
        let layer = grid.layer_at(1.55) as usize;
        assert!(gt.band_layers().contains(&layer) && 1.5 > cfg.robot.height_m);
        let voxel = |x: f64, y: f64| layer * grid.cells() + cell(x, y);

        let mut map = Map::new(grid, &cfg);
        // One ray at 1.55 m from (2.9, 1.05) east to a hit at (3.15, 1.05): it makes the voxel at
        // (3.15, 1.05) known (and those it passes), not any voxel of the robot band.
        let dir = Vector3::new(1.0f32, 0.0, 0.0);
        map.integrate(&DepthFrame {
            origin: Point3::new(2.9, 1.05, 1.55),
            axis: dir,
            dirs: vec![dir],
            range: vec![0.25],
            width: 1,
            height: 1,
            max_range: 5.0,
        });
        assert!(map.is_voxel_known(voxel(3.15, 1.05)));
        assert_eq!(map.cell_state(cell(3.15, 1.05)), CellState::Unknown);
        // Free cells, each only its own footprint: every one is a frontier (nothing else is known).
        let free = [
            // Counted, one group of four (the first cell touches the second diagonally only).
            (1.45, 1.95),
            (1.55, 2.05),
            (1.65, 2.05),
            (1.75, 2.05),
            // Not counted: no unknown 4-neighbour column holds an observable voxel (its free
            // neighbour (1.75, 2.05) does).
            (1.85, 2.05),
            // Counted, alone: it touches the group above only through (1.85, 2.05).
            (1.95, 1.95),
            // Counted, alone.
            (3.05, 3.05),
            // Not counted: its neighbour column's observable voxel is known.
            (3.05, 1.05),
            // Not counted: outside the reachable region (in the closet).
            (5.05, 1.05),
        ];
        for &(x, y) in &free {
            let p = grid.center(grid.cell_at(x, y));
            map.clear_footprint(p.x, p.y, 0.01);
        }
        for &(x, y) in &free {
            assert!(map.is_frontier(cell(x, y)), "({x}, {y})");
            assert_eq!(gt.reachable(cell(x, y)), x < 4.1, "({x}, {y})");
        }
        assert_eq!(
            map.frontier_cells().iter().filter(|&&f| f).count(),
            free.len()
        );
        let observable = ObservableSet::of_voxels(
            &gt,
            &[
                voxel(1.45, 1.85),
                voxel(1.55, 2.15),
                voxel(1.65, 2.15),
                voxel(1.75, 2.15),
                voxel(2.05, 1.95),
                voxel(3.15, 3.05),
                voxel(3.15, 1.05),
                voxel(5.15, 1.05),
                // Under a free cell: its column is not Unknown, so its frontier neighbour
                // (1.85, 2.05) does not count it.
                voxel(1.75, 2.05),
            ],
        );
        let left = frontiers_left(&gt, &observable, &map);
        assert_eq!(left.cells, 6);
        // Largest first, then by x: the group of four, then the single cells; each centroid the
        // mean of its cells' centres.
        let centroid = |cells: &[(f64, f64)]| {
            let n = cells.len() as f64;
            let (sx, sy) = cells.iter().fold((0.0, 0.0), |(sx, sy), &(x, y)| {
                let p = grid.center(grid.cell_at(x, y));
                (sx + p.x, sy + p.y)
            });
            (sx / n, sy / n)
        };
        let expected = [
            (4, centroid(&free[..4])),
            (1, centroid(&free[5..6])),
            (1, centroid(&free[6..7])),
        ];
        assert_eq!(left.groups.len(), expected.len(), "{:?}", left.groups);
        for (g, (n, (x, y))) in left.groups.iter().zip(expected) {
            assert_eq!(g.cells, n, "{:?}", left.groups);
            assert!(
                (g.x - x).abs() < 1e-9 && (g.y - y).abs() < 1e-9,
                "{:?}",
                left.groups
            );
        }
        assert!((left.groups[0].x - 1.6).abs() < 1e-9 && (left.groups[0].y - 2.025).abs() < 1e-9);
        // Once the map knows every observable voxel, no frontier is left.
        let all_known = ObservableSet::of_voxels(&gt, &[voxel(3.15, 1.05)]);
        assert_eq!(
            frontiers_left(&gt, &all_known, &map),
            FrontiersLeft::default()
        );
    }
}
