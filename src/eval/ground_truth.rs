//! The ground truth as the evaluation sees it: the scene's ([`SceneTruth`]: voxels, obstacle
//! columns, region, clearance, spawn) and the reachable region from its spawn
//! ([`super::reachable`]).

use super::reachable::Reachable;
use crate::config::Config;
use crate::error::{Error, Result};
use crate::grid::GridSpec;
use crate::scene::{Scene, SceneTruth, TriMesh, SPAWN_MARKER};
use crate::Pose2;
use serde::Serialize;

/// Ground truth of one scene on the map grid, with its reachable region. It reads as the scene's
/// [`SceneTruth`] (through `Deref`) for everything but the reachable region.
#[derive(Clone, Debug)]
pub struct GroundTruth {
    scene: SceneTruth,
    reachable: Reachable,
}

impl std::ops::Deref for GroundTruth {
    type Target = SceneTruth;

    fn deref(&self) -> &SceneTruth {
        &self.scene
    }
}

impl GroundTruth {
    /// Voxelises `mesh` on the grid covering its xy bounds ± `map.margin_m`, up to `map.band_max_m`,
    /// validates or chooses the spawn, flood-fills the explorable region from it and finds the
    /// reachable region (see [`super::reachable`]).
    pub fn build(mesh: &TriMesh, spawn: Option<Pose2>, cfg: &Config) -> Result<GroundTruth> {
        let scene = SceneTruth::build(mesh, spawn, cfg)?;
        let reachable = Reachable::new(mesh, &scene, cfg);
        Ok(GroundTruth { scene, reachable })
    }

    /// The scene's part: voxels, obstacle columns, region, clearance and spawn.
    pub fn scene(&self) -> &SceneTruth {
        &self.scene
    }

    /// Whether the robot can ever stand on the cell (see [`super::reachable`]).
    pub fn reachable(&self, cell: usize) -> bool {
        self.reachable.mask[cell]
    }

    /// The reachable region, one flag per cell.
    pub fn reachable_mask(&self) -> &[bool] {
        &self.reachable.mask
    }

    pub fn reachable_cells(&self) -> usize {
        self.reachable.cells
    }

    /// Floor area of the reachable region, m².
    pub fn reachable_area_m2(&self) -> f64 {
        self.reachable.cells as f64 * self.grid.cell_area()
    }

    /// The planners' inflation radius, metres.
    pub fn inflation_m(&self) -> f64 {
        self.reachable.inflation_m
    }

    /// The reachable cells whose centre keeps at least `inflation_m() + margin_m` from every obstacle
    /// column's square, ascending. `margin_m` at most `sim.random_spawn_margin_m` (the clearance is
    /// exact up to there).
    pub fn spawn_candidates(&self, margin_m: f64) -> Vec<usize> {
        let r = &self.reachable;
        let need = r.inflation_m + margin_m;
        debug_assert!(need <= r.fit_limit_m);
        (0..self.grid.cells())
            .filter(|&c| r.mask[c] && r.fit_clearance[c] as f64 >= need)
            .collect()
    }

    /// The same ground truth with another spawn in the same reachable region (a random start): only
    /// the pose changes, so nothing is recomputed. Fails when the pose is not on a reachable cell.
    pub fn with_spawn(mut self, spawn: Pose2) -> Result<GroundTruth> {
        match self.grid.cell_of(spawn.position()) {
            Some(c) if self.reachable.mask[self.grid.index(c)] => {
                self.scene.spawn = spawn;
                Ok(self)
            }
            _ => Err(Error::usage(format!(
                "start ({:.2}, {:.2}) is not in the reachable region",
                spawn.x, spawn.y
            ))),
        }
    }
}

/// The ground truth of `scene` from `spawn`, else the scene's own spawn line, else automatic. A
/// spawn line that the ground truth refuses (inside a wall) is named with its file.
pub fn build_ground_truth(
    scene: &Scene,
    spawn: Option<Pose2>,
    cfg: &Config,
) -> Result<GroundTruth> {
    GroundTruth::build(&scene.mesh, spawn.or(scene.spawn), cfg).map_err(|e| match (spawn, e) {
        (None, Error::Usage(msg)) if scene.spawn.is_some() && msg.starts_with("spawn ") => {
            Error::usage(format!(
                "{}: the file's `{SPAWN_MARKER}` line: {msg}",
                scene.path.display()
            ))
        }
        (_, e) => e,
    })
}
/// [`build_ground_truth`] for a run's start: a random start (`sim.spawn = "random"`) does not use
/// the file's spawn line, so a line the ground truth refuses leaves the region to the automatic
/// spawn (the largest enclosed room) instead of failing the run; the warning says so.
pub fn build_ground_truth_for_start(
    scene: &Scene,
    spawn: Option<Pose2>,
    cfg: &Config,
) -> Result<(GroundTruth, Option<String>)> {
    match build_ground_truth(scene, spawn, cfg) {
        Err(Error::Usage(msg))
            if cfg.sim.spawn == crate::config::SpawnMode::Random
                && spawn.is_none()
                && scene.spawn.is_some()
                && msg.contains(SPAWN_MARKER) =>
        {
            let gt = GroundTruth::build(&scene.mesh, None, cfg)?;
            let warning =
                format!("warning: {msg}; random starts are drawn from the largest room instead");
            Ok((gt, Some(warning)))
        }
        other => other.map(|gt| (gt, None)),
    }
}

/// What `scene info` prints.
#[derive(Clone, Debug, Serialize)]
pub struct SceneInfo {
    pub name: String,
    pub path: String,
    pub source: String,
    pub content_hash: String,
    pub bounds_min: [f64; 3],
    pub bounds_max: [f64; 3],
    pub vertices: usize,
    pub triangles: usize,
    /// The original floor height before the mesh was moved to z = 0, metres.
    pub floor_z: f64,
    /// Floor area the robot can reach from the spawn, m².
    pub reachable_area_m2: f64,
    /// Volume the camera could observe from the reachable floor, m³ (filled in by the caller, which
    /// owns the sensor; 0 until then).
    pub observable_volume_m3: f64,
    /// Ground-truth surface voxels in the band among the observable ones.
    pub observable_surface_voxels: usize,
    /// Camera positions sampled for the observable volume.
    pub observable_positions: usize,
    pub spawn: Pose2,
    /// Whether the spawn came from the file (true) or was chosen automatically.
    pub spawn_from_file: bool,
    pub grid: GridSpec,
}

/// Summarises a scene and its ground truth.
pub fn info(scene: &Scene, gt: &GroundTruth) -> SceneInfo {
    let (min, max) = scene.mesh.bounds().unwrap_or_default();
    SceneInfo {
        name: scene.name.clone(),
        path: scene.path.display().to_string(),
        source: scene.source.clone(),
        content_hash: scene.content_hash.clone(),
        bounds_min: [min.x, min.y, min.z],
        bounds_max: [max.x, max.y, max.z],
        vertices: scene.mesh.vertices.len(),
        triangles: scene.mesh.triangles.len(),
        floor_z: scene.floor_z,
        reachable_area_m2: gt.reachable_area_m2(),
        observable_volume_m3: 0.0,
        observable_surface_voxels: 0,
        observable_positions: 0,
        spawn: gt.spawn,
        spawn_from_file: scene.spawn.is_some(),
        grid: gt.grid,
    }
}
