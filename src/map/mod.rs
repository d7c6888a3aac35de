//! The map: 3D occupancy voxels and the 2D layers derived from them, updated one depth frame at a time.

pub mod layers;
pub mod occupancy;

pub use layers::{CellState, FrontierSegment, Layers};
pub use occupancy::{LogOdds, Occupancy, VoxelState};

use crate::grid::GridSpec;
use crate::sensor::DepthFrame;
use crate::Config;

/// What one frame changed, for the simulator's incremental metrics.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameUpdate {
    /// Voxels (flat indices, all layers) that went from Unknown to known, ascending.
    pub newly_known: Vec<u32>,
    /// Number of columns with a voxel whose state changed (the columns the 2D layers recomputed).
    pub touched_columns: usize,
}

/// Occupancy voxels plus 2D layers over one [`GridSpec`].
#[derive(Clone, Debug)]
pub struct Map {
    occupancy: Occupancy,
    layers: Layers,
}

impl Map {
    /// An all-unknown map over `grid`.
    pub fn new(grid: GridSpec, cfg: &Config) -> Map {
        Map {
            occupancy: Occupancy::new(grid, LogOdds::from_config(&cfg.map)),
            layers: Layers::new(grid, cfg),
        }
    }

    /// Integrates one depth frame into the voxels, then refreshes the affected 2D columns.
    pub fn integrate(&mut self, frame: &DepthFrame) -> FrameUpdate {
        let up = self.occupancy.integrate(frame);
        self.layers
            .update_columns(&self.occupancy, &up.changed_columns);
        FrameUpdate {
            newly_known: up.newly_known,
            touched_columns: up.changed_columns.len(),
        }
    }

    pub fn grid(&self) -> &GridSpec {
        self.occupancy.grid()
    }

    pub fn occupancy(&self) -> &Occupancy {
        &self.occupancy
    }

    pub fn layers(&self) -> &Layers {
        &self.layers
    }

    /// State of voxel `v` (flat index).
    pub fn voxel_state(&self, v: usize) -> VoxelState {
        self.occupancy.state(v)
    }

    /// Number of known voxels (all layers).
    pub fn known_voxels(&self) -> usize {
        self.occupancy.known_voxels()
    }

    /// State of cell `idx` (flat index).
    pub fn cell_state(&self, idx: usize) -> CellState {
        self.layers.states()[idx]
    }

    /// Free and outside every obstacle's inflation disc: the robot's centre may be here.
    pub fn is_traversable(&self, idx: usize) -> bool {
        self.layers.traversable()[idx]
    }

    pub fn is_obstacle(&self, idx: usize) -> bool {
        self.cell_state(idx) == CellState::Obstacle
    }

    /// Within the inflation radius (robot radius + margin) of a known obstacle cell.
    pub fn is_inflated(&self, idx: usize) -> bool {
        self.layers.is_inflated(idx)
    }

    /// Within `map.proximity_band_m` of the inflation radius of a known obstacle.
    pub fn is_near_obstacle(&self, idx: usize) -> bool {
        self.layers.is_near_obstacle(idx)
    }

    /// Whether voxel `v` has been observed (free or occupied).
    pub fn is_voxel_known(&self, v: usize) -> bool {
        self.voxel_state(v) != VoxelState::Unknown
    }

    pub fn is_unknown(&self, idx: usize) -> bool {
        self.cell_state(idx) == CellState::Unknown
    }

    /// An occupied voxel lies somewhere in the height band above this cell.
    pub fn is_surface(&self, idx: usize) -> bool {
        self.layers.surface()[idx]
    }

    /// Traversable and 4-adjacent to an Unknown cell.
    pub fn is_frontier(&self, idx: usize) -> bool {
        self.layers.frontier()[idx]
    }

    /// Whole-layer views, indexed by flat cell index.
    pub fn cell_states(&self) -> &[CellState] {
        self.layers.states()
    }
    pub fn traversable_cells(&self) -> &[bool] {
        self.layers.traversable()
    }
    pub fn surface_cells(&self) -> &[bool] {
        self.layers.surface()
    }
    pub fn frontier_cells(&self) -> &[bool] {
        self.layers.frontier()
    }

    /// See [`Layers::clear_footprint`].
    pub fn clear_footprint(&mut self, x: f64, y: f64, radius: f64) {
        self.layers.clear_footprint(x, y, radius);
    }

    /// See [`Layers::frontiers`].
    pub fn frontiers(&self) -> Vec<FrontierSegment> {
        self.layers.frontiers()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Cell;
    use crate::sensor::raycast::testing::furnished_room;
    use crate::sensor::{DepthCamera, MeshBvh};
    use crate::Pose2;
    use nalgebra::Point2;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn room_setup() -> (Config, GridSpec, MeshBvh, DepthCamera) {
        let cfg = Config::default();
        let grid = GridSpec::covering(
            Point2::new(-0.5, -0.5),
            Point2::new(8.5, 8.5),
            cfg.map.band_max_m,
            cfg.map.voxel_m,
        );
        let bvh = MeshBvh::new(&furnished_room(8.0)).unwrap();
        let cam = DepthCamera::new(&cfg.camera);
        (cfg, grid, bvh, cam)
    }

    #[test]
    fn incremental_layers_equal_layers_recomputed_from_scratch() {
        let (cfg, grid, bvh, cam) = room_setup();
        let mut map = Map::new(grid, &cfg);
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut known = 0;
        for step in 0..40 {
            let pose = Pose2::new(
                rng.random_range(0.5..7.5),
                rng.random_range(0.5..7.5),
                rng.random_range(-3.2..3.2),
            );
            let up = map.integrate(&cam.capture(&bvh, pose));
            known += up.newly_known.len();
            assert_eq!(known, map.known_voxels());
            if step % 3 == 0 {
                map.clear_footprint(pose.x, pose.y, cfg.robot.radius_m);
            }
            let mut scratch = map.layers.clone();
            scratch.recompute_all(&map.occupancy);
            assert_eq!(scratch.states(), map.layers.states(), "step {step}");
            assert_eq!(scratch.surface(), map.layers.surface());
            assert_eq!(scratch.traversable(), map.layers.traversable());
            assert_eq!(scratch.frontier(), map.layers.frontier());
            for i in 0..grid.cells() {
                assert_eq!(scratch.is_inflated(i), map.is_inflated(i));
                assert_eq!(scratch.is_near_obstacle(i), map.is_near_obstacle(i));
            }
        }
        // The room got mapped: most of the wall at x = 0 is obstacle, most of the wall at x = 8 is
        // surface, and much of the floor is traversable.
        let idx = |x: f64, y: f64| grid.index(grid.cell_at(x, y));
        let along = |f: &dyn Fn(f64) -> bool| (0..80).filter(|&i| f(0.05 + i as f64 * 0.1)).count();
        assert!(along(&|y| map.is_obstacle(idx(-0.05, y)) || map.is_obstacle(idx(0.05, y))) > 40);
        assert!(along(&|y| map.is_surface(idx(7.95, y)) || map.is_surface(idx(8.05, y))) > 40);
        let traversable = map.traversable_cells().iter().filter(|&&t| t).count();
        assert!(traversable > 2000, "{traversable}");
        // Outside the walls nothing can be seen.
        assert!(map.is_unknown(idx(-0.4, -0.4)));
    }

    #[test]
    fn floor_hits_do_not_make_obstacles_and_overhangs_do_not_block() {
        // Empty floor except a shelf slab at 1.3–1.4 m (above the 1.2 m robot).
        let cfg = Config::default();
        let grid = GridSpec::covering(Point2::new(0.0, -3.0), Point2::new(6.0, 3.0), 1.8, 0.1);
        let mut mesh = crate::scene::TriMesh::default();
        crate::sensor::raycast::testing::push_box(&mut mesh, [-1.0, -4.0, -0.1], [7.0, 4.0, 0.0]);
        crate::sensor::raycast::testing::push_box(&mut mesh, [2.0, -1.0, 1.3], [2.5, 1.0, 1.4]);
        let bvh = MeshBvh::new(&mesh).unwrap();
        let cam = DepthCamera::new(&cfg.camera);
        let mut map = Map::new(grid, &cfg);
        for _ in 0..3 {
            map.integrate(&cam.capture(&bvh, Pose2::new(0.3, 0.0, 0.0)));
        }
        let below_shelf = grid.index(grid.cell_at(2.25, 0.0));
        assert!(map.is_surface(below_shelf));
        assert!(!map.is_obstacle(below_shelf));
        assert!(map.cell_states().iter().all(|&s| s != CellState::Obstacle));
        // Floor seen ahead of the robot becomes free.
        assert!(map.is_traversable(grid.index(grid.cell_at(3.5, 0.0))));
        let c = grid.cell_at(3.5, 0.0);
        assert_eq!(
            map.voxel_state(grid.voxel_index(c, 0)),
            VoxelState::Occupied,
            "the floor layer does record hits"
        );
        assert!(map.frontiers().iter().all(|s| s.cells.len() >= 3));
        assert!(map.is_unknown(grid.index(Cell::new(0, 0))));
    }
}
