//! What the robot could ever observe: the ceiling that completeness is measured against.
//!
//! **Observable set.** The height-band voxels that the configured depth camera marks as known (the
//! hit voxel of a valid ray, or a voxel a ray passes through) from some pose of the reachable
//! region (`GroundTruth::reachable`). It is computed under the same sensor model and voxel
//! traversal the map uses: the camera's own ray directions and range rule, `MeshBvh::cast`, and
//! `map::occupancy::traverse` (a test checks agreement with `Occupancy::integrate` frame by frame).
//!
//! **Sampling.** The reachable region is cut into squares of side `metrics.observable_spacing_m`; in
//! each square, every 8-connected patch of reachable cells gets one position, the patch cell nearest
//! its centroid (so a narrow corridor or an alcove that crosses no lattice point is still sampled).
//! At each position the camera looks along `metrics.observable_yaws` headings evenly spread over the
//! full turn (the robot turns in place, so every heading is reachable). A ray only matters while it
//! is inside the height band, so it is cast and traversed up to where it leaves the band; that gives
//! the same band voxels as a full-length ray (a ray leaves a horizontal slab once).
//!
//! **Finer where the view depends on the position.** What the camera sees through a gap too narrow
//! to pass (a narrow door, a slot beside furniture, an opening onto the outside) changes sharply with
//! the position: the gap is an aperture, and a planner that looks through it from a pose between two
//! lattice points sees a wedge neither of them does. So the sampling runs twice. The first pass uses
//! the lattice above and notes every position whose view holds at least [`sampling::REFINE_BEYOND_M3`] of band
//! voxels over *beyond* cells (free floor farther than the inflation radius plus two cells from every
//! reachable cell: space behind such gaps, see [`sampling::beyond_cells`]). The second pass samples the 3 × 3
//! squares around each of those positions again on a lattice of half the side (rounded down to whole
//! cells: 0.2 m at the defaults), with the same rule of one position per patch. The set is the union
//! of both passes. Scenes whose rooms are all drivable have no such views and cost no more.
//!
//! **Walking the rays.** The reference is one ray at a time (`VoxelCaster::observe`): a voxel walk
//! that tests the triangles of each occupied voxel it enters. The set is computed faster, with the
//! same result, by sweeping each pixel column's rays together through the floor cells they share
//! (`VoxelCaster::sweep_column`): a run of rays that meets no occupied voxel in a cell marks one span
//! of layers there, and single rays are walked only where they meet occupied voxels. A column where
//! some distance falls within 1e-9 m of a voxel boundary (where rounding could decide the map's walk)
//! is walked ray by ray instead (about 0.3 % of the columns on the shipped scenes). A test checks the
//! two ways bit for bit; cameras of more than 64 rows or grids of more than 64 layers use the
//! reference walk only. The map's column sweep (`map::column_sweep`) needs each ray's end before it
//! starts; casting a frame first (`MeshBvh::cast`, whose pruning can keep a hit an ulp farther than
//! the nearest) and integrating it as the map does marked 2 voxels other than this walk in 1 of
//! 328 frames on a real plan, so the set keeps its own sweep.
//!
//! **Cost and cache.** This costs seconds, so [`ObservableCache`] keeps one file per scene and the
//! config keys the set depends on, written atomically and checked on read (length, key and
//! checksum): a damaged file is recomputed and reported, never trusted.

use super::GroundTruth;
use crate::config::MetricsConfig;
use crate::sensor::{DepthCamera, MeshBvh};
use caster::VoxelCaster;
use sampling::{beyond_cells, lattice_cells, refined_positions, sample_positions};

pub use cache::{CacheOutcome, ObservableCache};

/// The voxels the camera could observe from the reachable region.
#[derive(Clone, Debug, PartialEq)]
pub struct ObservableSet {
    /// One bit per voxel of the grid (flat voxel index); set only in the height band.
    bits: Vec<u64>,
    voxels: usize,
    /// Observable voxels that the ground truth marks occupied (observable surface), ascending.
    surface: Vec<u32>,
    /// Sampled positions (each seen from every heading).
    positions: usize,
    voxel_volume: f64,
}

/// The pose sampling, from the config (the sensor model is the `DepthCamera`'s).
#[derive(Clone, Debug, PartialEq)]
pub struct ObservableParams {
    pub spacing_m: f64,
    pub yaws: usize,
}

impl ObservableParams {
    pub fn from_config(metrics: &MetricsConfig) -> Self {
        ObservableParams {
            spacing_m: metrics.observable_spacing_m,
            yaws: metrics.observable_yaws,
        }
    }
}

/// Told how far the computation of an observable set has got, for a progress bar; called from the
/// worker threads.
pub trait SampleProgress: Send + Sync {
    /// `positions` more camera positions are to be sampled (once per pass of the sampling).
    fn add(&self, positions: usize);
    /// One more camera position has been sampled.
    fn sampled(&self);
    /// The set is complete.
    fn finished(&self);
}

/// Nobody to tell.
pub(crate) struct Silent;

impl SampleProgress for Silent {
    fn add(&self, _: usize) {}
    fn sampled(&self) {}
    fn finished(&self) {}
}

impl ObservableSet {
    /// Samples the camera over the reachable region of `gt` (see the module doc).
    pub fn compute(
        gt: &GroundTruth,
        bvh: &MeshBvh,
        camera: &DepthCamera,
        p: &ObservableParams,
    ) -> ObservableSet {
        Self::compute_with_progress(gt, bvh, camera, p, &Silent)
    }

    /// [`ObservableSet::compute`], telling `progress` of the positions to sample and done.
    pub fn compute_with_progress(
        gt: &GroundTruth,
        bvh: &MeshBvh,
        camera: &DepthCamera,
        p: &ObservableParams,
        progress: &dyn SampleProgress,
    ) -> ObservableSet {
        let grid = gt.grid;
        let band = gt.band_layers();
        let reach = gt.reachable_mask();
        let k = lattice_cells(&grid, p.spacing_m);
        let coarse = sample_positions(&grid, reach, k, |_, _| true);
        // The band as a z interval: a ray is cast and walked only while inside it.
        let (z_lo, z_hi) = (band.start as f64 * grid.res, band.end as f64 * grid.res);
        let yaws: Vec<(f32, f32)> = (0..p.yaws)
            .map(|k| {
                let yaw = std::f64::consts::TAU * k as f64 / p.yaws as f64;
                (yaw.sin() as f32, yaw.cos() as f32)
            })
            .collect();
        let caster = VoxelCaster::new(gt, bvh, camera, (z_lo, z_hi));
        let beyond = beyond_cells(gt);
        let sweep = caster.sweep_applies(camera);
        let frames = |positions: &[usize]| {
            progress.add(positions.len());
            if sweep {
                caster.frames_by_columns(positions, &yaws, camera, &beyond, progress)
            } else {
                caster.frames_by_rays(positions, &yaws, camera, &beyond, progress)
            }
        };
        let first = frames(&coarse);
        let fine = refined_positions(&grid, reach, k, &first.looked_beyond, &coarse);
        let mut bits = first.bits;
        if !fine.is_empty() {
            let second = frames(&fine);
            bits.iter_mut().zip(&second.bits).for_each(|(a, b)| *a |= b);
        }
        progress.finished();
        ObservableSet::from_bits(gt, bits, coarse.len() + fine.len())
    }

    /// A set holding exactly the band voxels among `voxels` (flat indices), for tests that need an
    /// observable set known by construction.
    #[cfg(test)]
    pub(crate) fn of_voxels(gt: &GroundTruth, voxels: &[usize]) -> ObservableSet {
        let mut bits = vec![0u64; gt.grid.voxels().div_ceil(64)];
        for &v in voxels {
            bits[v >> 6] |= 1 << (v & 63);
        }
        ObservableSet::from_bits(gt, bits, 0)
    }

    /// Completes a set from its bits: keeps band voxels only, counts them, lists the surface.
    pub(super) fn from_bits(
        gt: &GroundTruth,
        mut bits: Vec<u64>,
        positions: usize,
    ) -> ObservableSet {
        let grid = gt.grid;
        let band = gt.band_layers();
        let (lo, hi) = (band.start * grid.cells(), band.end * grid.cells());
        for v in (0..lo).chain(hi..grid.voxels()) {
            bits[v >> 6] &= !(1 << (v & 63));
        }
        let has = |v: usize| bits[v >> 6] >> (v & 63) & 1 == 1;
        let voxels = (lo..hi).filter(|&v| has(v)).count();
        let surface = (lo..hi)
            .filter(|&v| has(v) && gt.occupied(v))
            .map(|v| v as u32)
            .collect();
        ObservableSet {
            bits,
            voxels,
            surface,
            positions,
            voxel_volume: grid.voxel_volume(),
        }
    }

    /// Whether flat voxel `v` is observable.
    #[inline]
    pub fn contains(&self, v: usize) -> bool {
        self.bits
            .get(v >> 6)
            .is_some_and(|w| w >> (v & 63) & 1 == 1)
    }

    /// Number of observable voxels.
    pub fn voxels(&self) -> usize {
        self.voxels
    }

    /// Observable volume, m³.
    pub fn volume_m3(&self) -> f64 {
        self.voxels as f64 * self.voxel_volume
    }

    /// Observable voxels that are occupied in the ground truth, ascending.
    pub fn surface_voxels(&self) -> &[u32] {
        &self.surface
    }

    /// Positions the camera was sampled at.
    pub fn positions(&self) -> usize {
        self.positions
    }

    /// Whether any band voxel of `cell`'s column is observable.
    pub fn column_observable(&self, gt: &GroundTruth, cell: usize) -> bool {
        gt.band_layers()
            .any(|iz| self.contains(iz * gt.grid.cells() + cell))
    }
}

mod cache;
mod caster;
mod sampling;
mod sweep;
#[cfg(test)]
mod tests;
