//! The map: 3D occupancy voxels and the 2D layers derived from them, updated one depth frame at a time.

mod column_sweep;
pub(crate) mod layers;
pub(crate) mod occupancy;
pub(crate) mod sight;

pub use layers::{CellState, FrontierSegment, Layers};
pub use occupancy::{LogOdds, ObstacleBox, Occupancy, VoxelState, OBSTACLE_BOX_SLACK_M};

use crate::grid::{Cell, CellRect, GridSpec};
use crate::sensor::DepthFrame;
use crate::Config;
use nalgebra::Point2;

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

/// What the map takes from the config: its own section and the robot's size (the inflation radius
/// and the height band the robot sweeps). `Map::new(grid, &cfg)` builds it from a whole `Config`.
#[derive(Clone, Debug)]
pub struct MapParams {
    pub map: crate::config::MapConfig,
    pub robot_radius_m: f64,
    pub robot_height_m: f64,
    /// `camera.mount_height_m`: voxels below it are what a look across a column at eye level shows.
    pub eye_height_m: f64,
}

impl From<&Config> for MapParams {
    fn from(cfg: &Config) -> MapParams {
        MapParams {
            map: cfg.map.clone(),
            robot_radius_m: cfg.robot.radius_m,
            robot_height_m: cfg.robot.height_m,
            eye_height_m: cfg.camera.mount_height_m.get(),
        }
    }
}

impl Map {
    /// An all-unknown map over `grid`.
    pub fn new(grid: GridSpec, params: impl Into<MapParams>) -> Map {
        let params = params.into();
        Map {
            occupancy: Occupancy::new(
                grid,
                LogOdds::from_config(&params.map),
                layers::robot_band(&grid, &params),
            ),
            layers: Layers::new(grid, &params),
        }
    }

    /// Integrates one depth frame into the voxels, then refreshes the affected 2D columns.
    pub fn integrate(&mut self, frame: &DepthFrame) -> FrameUpdate {
        let up = self.occupancy.integrate(frame);
        self.layers
            .update_columns(&self.occupancy, &up.changed_columns, &up.grown_boxes);
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

    /// The cells outside which the map is as before any frame: unknown, never traversable, never a
    /// frontier. Work that only concerns known cells can be confined to it.
    pub fn touched(&self) -> CellRect {
        self.layers.touched()
    }

    /// Free and outside every obstacle's inflation disc: the robot's centre may be here.
    pub fn is_traversable(&self, idx: usize) -> bool {
        self.layers.traversable()[idx]
    }

    pub fn is_obstacle(&self, idx: usize) -> bool {
        self.cell_state(idx) == CellState::Obstacle
    }

    /// Where the obstacle of Obstacle cell `idx` lies (see [`ObstacleBox`]), the whole cell for a
    /// hidden cell ([`Map::is_hidden`]); `None` for other cells.
    pub fn obstacle_box(&self, idx: usize) -> Option<ObstacleBox> {
        self.layers.obstacle_box(idx)
    }

    /// Whether Unknown cell `idx` is known only above the camera (looked over, never across at eye
    /// level): it counts as an obstacle filling the cell.
    pub fn is_hidden(&self, idx: usize) -> bool {
        self.layers.is_hidden(idx)
    }

    /// The known obstacle surface point nearest `p` within `max_m` (the nearest point of the nearest
    /// obstacle box; ties: the first cell in row order), or `None`.
    pub fn nearest_obstacle_point(&self, p: Point2<f64>, max_m: f64) -> Option<Point2<f64>> {
        let grid = self.grid();
        let c = grid.cell_at(p.x, p.y);
        // A box lies inside its cell, so cells one beyond `max_m` can still hold a nearer one.
        let r = (max_m / grid.res).ceil() as i32 + 1;
        let mut best = max_m * max_m;
        let mut found = None;
        for dy in -r..=r {
            for dx in -r..=r {
                let Some(i) = grid.checked_index(Cell::new(c.x + dx, c.y + dy)) else {
                    continue;
                };
                if let Some(b) = self.obstacle_box(i) {
                    let o = b.nearest_point(p);
                    let d2 = (o - p).norm_squared();
                    if d2 < best {
                        best = d2;
                        found = Some(o);
                    }
                }
            }
        }
        found
    }

    /// The hazard point nearest to `p` within `max_m`: a known obstacle surface point (see
    /// [`Map::nearest_obstacle_point`]: measured to the obstacle boxes, which hold the ray hits), or the
    /// nearest point of a never-seen cell grown by half a cell. The camera faces forward and sees nothing
    /// nearer than its minimum range, so a wall beside the robot may be unknown, and the cell holding
    /// its face may count as seen through the free part of its voxels; the guard keeps the disc that far
    /// from cells the robot has no evidence about, as it keeps it off known obstacles.
    pub fn nearest_hazard(&self, p: Point2<f64>, max_m: f64) -> Option<Point2<f64>> {
        let mut best = self.nearest_obstacle_point(p, max_m);
        let mut best_d2 = best.map_or(max_m * max_m, |o| (o - p).norm_squared());
        let grid = self.grid();
        let half = 1.0 * grid.res;
        let c = grid.cell_at(p.x, p.y);
        let r = (max_m / grid.res).ceil() as i32 + 1;
        for dy in -r..=r {
            for dx in -r..=r {
                let n = Cell::new(c.x + dx, c.y + dy);
                let Some(i) = grid.checked_index(n) else {
                    continue;
                };
                if self.is_seen(i) {
                    continue;
                }
                let centre = grid.center(n);
                let q = Point2::new(
                    p.x.clamp(centre.x - half, centre.x + half),
                    p.y.clamp(centre.y - half, centre.y + half),
                );
                let d2 = (q - p).norm_squared();
                if d2 < best_d2 {
                    best_d2 = d2;
                    best = Some(q);
                }
            }
        }
        best
    }

    /// Whether no Unknown cell comes within `radius` of `p`: a disc there stands on floor the camera
    /// has seen (Free cells, or obstacles, which the guard keeps it off). An Unknown cell may hold a
    /// low object no ray has hit.
    pub fn disc_over_seen_floor(&self, p: Point2<f64>, radius: f64) -> bool {
        let grid = self.grid();
        let c = grid.cell_at(p.x, p.y);
        let r = (radius / grid.res).ceil() as i32 + 1;
        let half = 0.5 * grid.res;
        for dy in -r..=r {
            for dx in -r..=r {
                let n = Cell::new(c.x + dx, c.y + dy);
                let Some(i) = grid.checked_index(n) else {
                    continue;
                };
                if !self.is_unknown(i) {
                    continue;
                }
                let centre = grid.center(n);
                let q = Point2::new(
                    p.x.clamp(centre.x - half, centre.x + half),
                    p.y.clamp(centre.y - half, centre.y + half),
                );
                if (q - p).norm_squared() < radius * radius {
                    return false;
                }
            }
        }
        true
    }

    /// Within the inflation radius (robot radius + margin) of a known obstacle's box.
    pub fn is_inflated(&self, idx: usize) -> bool {
        self.layers.is_inflated(idx)
    }

    /// Within `map.proximity_band_m` of the inflation radius of a known obstacle's box.
    pub fn is_near_obstacle(&self, idx: usize) -> bool {
        self.layers.is_near_obstacle(idx)
    }

    /// Whether the robot has any evidence about cell `idx`: a known voxel in its robot band, an
    /// obstacle, or its own footprint. A never-seen cell may hide a wall.
    pub fn is_seen(&self, idx: usize) -> bool {
        self.layers.is_seen(idx)
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

/// Test geometry: maps built by looking at a mesh.
#[cfg(test)]
pub mod testing {
    use super::Map;
    use crate::config::Config;
    use crate::grid::GridSpec;
    use crate::sensor::{DepthCamera, MeshBvh};
    use crate::Pose2;

    /// A map of `grid` from one depth frame taken at each of `poses` in the scene `bvh`.
    pub fn seen_from(
        grid: GridSpec,
        cfg: &Config,
        bvh: &MeshBvh,
        poses: impl IntoIterator<Item = Pose2>,
    ) -> Map {
        let cam = DepthCamera::new(&cfg.camera);
        let mut map = Map::new(grid, cfg);
        for pose in poses {
            map.integrate(&cam.capture(bvh, pose));
        }
        map
    }

    /// The furnished 8 m test room (`raycast::testing::furnished_room`) and a grid covering it.
    pub fn furnished_room_setup(cfg: &Config) -> (GridSpec, MeshBvh) {
        let grid = GridSpec::covering(
            nalgebra::Point2::new(-0.5, -0.5),
            nalgebra::Point2::new(8.5, 8.5),
            cfg.map.band_max_m,
            cfg.map.voxel_m,
        );
        let mesh = crate::sensor::raycast::testing::furnished_room(8.0);
        (grid, MeshBvh::new(&mesh).unwrap())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Cell;
    use crate::sensor::{DepthCamera, MeshBvh};
    use crate::Pose2;
    use nalgebra::Point2;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn room_setup() -> (Config, GridSpec, MeshBvh, DepthCamera) {
        let cfg = Config::default();
        let (grid, bvh) = testing::furnished_room_setup(&cfg);
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
            assert_eq!(scratch.counters(), map.layers.counters());
            let touched = map.touched();
            for i in 0..grid.cells() {
                // Outside the touched rectangle the map is as before any frame.
                if !touched.contains(grid.cell(i)) {
                    assert!(
                        map.is_unknown(i) && !map.is_traversable(i) && !map.layers.frontier()[i]
                    );
                    assert!(!map.is_surface(i) && !map.is_seen(i) && !map.is_hidden(i));
                }
                assert_eq!(scratch.is_seen(i), map.is_seen(i));
                assert_eq!(scratch.is_inflated(i), map.is_inflated(i));
                assert_eq!(scratch.is_near_obstacle(i), map.is_near_obstacle(i));
                assert_eq!(scratch.obstacle_box(i), map.obstacle_box(i));
                assert_eq!(scratch.is_hidden(i), map.is_hidden(i));
                assert_eq!(
                    map.obstacle_box(i).is_some(),
                    map.is_obstacle(i) || map.is_hidden(i)
                );
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
        assert!(map
            .frontiers()
            .iter()
            .all(|s| s.cells.len() >= cfg.map.frontier_min_cells));
        assert!(map.is_unknown(grid.index(Cell::new(0, 0))));
    }

    /// A floor from (-1, -1) to `max` (x, y) with `boxes` (min and max corners) on it, and a 0.1 m
    /// grid over it up to 1.8 m.
    fn floor_with_boxes(max: [f32; 2], boxes: &[([f32; 3], [f32; 3])]) -> (GridSpec, MeshBvh) {
        let grid = GridSpec::covering(
            Point2::new(-1.0, -1.0),
            Point2::new(f64::from(max[0]), f64::from(max[1])),
            1.8,
            0.1,
        );
        let mut mesh = crate::scene::TriMesh::default();
        let push_box = crate::sensor::raycast::testing::push_box;
        push_box(&mut mesh, [-1.0, -1.0, -0.1], [max[0], max[1], 0.0]);
        for &(lo, hi) in boxes {
            push_box(&mut mesh, lo, hi);
        }
        (grid, MeshBvh::new(&mesh).unwrap())
    }

    #[test]
    fn floor_seen_only_over_a_cabinet_taller_than_the_camera_counts_as_an_obstacle() {
        // A cabinet 0.85 m tall (the camera is at 0.6 m) in an open floor, looked at from the west:
        // rays over its top clear the voxels above the floor behind it, none reaches that floor at
        // eye level, and its east face is never in view.
        let cfg = Config::default();
        let (grid, bvh) = floor_with_boxes([6.0, 3.0], &[([2.0, 0.5, 0.0], [2.6, 1.5, 0.85])]);
        let cam = DepthCamera::new(&cfg.camera);
        let mut map = Map::new(grid, &cfg);
        for x in [0.2, 0.5, 0.8] {
            map.integrate(&cam.capture(&bvh, Pose2::new(x, 1.0, 0.0)));
        }
        let idx = |x: f64, y: f64| grid.index(grid.cell_at(x, y));
        let behind = idx(2.75, 1.0);
        assert!(map.is_unknown(behind) && map.is_seen(behind) && map.is_hidden(behind));
        assert!(
            map.obstacle_box(behind).is_some(),
            "a column known only above the camera fills its cell"
        );
        assert!(map.is_inflated(idx(2.95, 1.0)));
        assert!(map
            .nearest_obstacle_point(grid.center(grid.cell(behind)), 0.01)
            .is_some());
        // Free floor beside the hidden cells is still a frontier, though the robot cannot stand
        // there: something to look at, not a place the map is done with.
        assert!((0..grid.cells()).any(|i| map.is_frontier(i) && !map.is_traversable(i)));
        assert!(
            (0..grid.cells()).all(|i| !map.is_frontier(i) || map.cell_state(i) == CellState::Free)
        );
        // Looked at from the east, at eye level, the floor there is known free again.
        map.integrate(&cam.capture(&bvh, Pose2::new(4.5, 1.0, std::f64::consts::PI)));
        assert!(!map.is_unknown(behind) && !map.is_obstacle(behind));
        assert!(map.obstacle_box(behind).is_none());
        assert!(!map.is_inflated(idx(3.05, 1.0)));
    }

    #[test]
    fn a_075_m_corridor_stays_passable_and_clearance_is_measured_to_the_walls() {
        // Floor plus two walls 0.75 m apart, faces at y = 0.02 and y = 0.77 (not on cell edges).
        let cfg = Config::default();
        let (grid, bvh) = floor_with_boxes(
            [5.0, 2.0],
            &[
                ([-1.0, -0.1, 0.0], [5.0, 0.02, 2.0]),
                ([-1.0, 0.77, 0.0], [5.0, 0.9, 2.0]),
            ],
        );
        let cam = DepthCamera::new(&cfg.camera);
        let mut map = Map::new(grid, &cfg);
        for x in [0.0, 0.5, 1.0, 1.5] {
            map.integrate(&cam.capture(&bvh, Pose2::new(x, 0.395, 0.0)));
        }
        // The wall faces lie in the cell rows at y = 0.05 and 0.75. Cell centres at y = 0.35 and 0.45
        // are 0.33 and 0.32 m from the faces, beyond the inflation radius (0.29 m) plus the box slack;
        // measured to the wall cells' centres they would be 0.3 m away.
        let idx = |x: f64, y: f64| grid.index(grid.cell_at(x, y));
        let radius = cfg.robot.radius_m + cfg.map.inflation_margin_m;
        assert!(radius + (OBSTACLE_BOX_SLACK_M as f64) < 0.31);
        // (Farther on, rays graze the walls so flatly that misses erase their voxels: not tested.)
        for i in 0..14 {
            let x = 1.55 + 0.1 * i as f64;
            assert!(
                map.is_obstacle(idx(x, 0.05)) && map.is_obstacle(idx(x, 0.75)),
                "x {x}"
            );
            assert!(map.is_traversable(idx(x, 0.35)), "x {x}");
            assert!(map.is_traversable(idx(x, 0.45)), "x {x}");
            assert!(!map.is_traversable(idx(x, 0.25)) && !map.is_traversable(idx(x, 0.55)));
            // The nearest surface point is on a wall face, within the slack.
            let p = Point2::new(x, 0.3);
            let o = map.nearest_obstacle_point(p, 0.6).unwrap();
            assert!(
                (o.y - 0.02).abs() <= 0.0101 && (o.x - x).abs() < 0.06,
                "{o:?}"
            );
        }
        let p = Point2::new(3.0, 0.395);
        assert!(map.nearest_obstacle_point(p, 0.36).is_none());
        assert!(map.nearest_obstacle_point(p, 0.4).is_some());
    }
}
